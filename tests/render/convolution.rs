//! The convolution method on the GPU (`FinMethod::Convolution`:
//! `convolution_maps.wgsl`, `convolution.wgsl`) against the core's
//! convolution model built on the raster oracle's hard shadow map at the
//! same resolution (`ConvolutionModel::on_depth_map`, mipmaps).
//!
//! Tolerance: mean |GPU − oracle| ≤ 0.01 and at most 3% of pixels off by more
//! than 0.1 (the view's geometric edges, as for the fins). Both sides run the
//! same series and filters; the GPU sums its basis images and series in f32
//! where the core accumulates in f64.

use bevy_shadow_fins::{FinExtraction, FinMethod, FinShadowSettings};
use shadow_fins::{
    ground_truth::GroundTruth,
    metrics::ErrorMetrics,
    oracle::{FinShadowModel, Method},
    peers::convolution::{ConvolutionModel, ConvolutionSettings, Prefilter, VARIANCE_MATCHED_MIP_BIAS},
    scene::LightSpaceScene,
    scenes::SceneId,
};
use shadow_fins_app::harness::Setup;

use super::{common::*, point_light::point_setup, rect_light::rect_setup, sun::sun_setup, sun::unfitted};

fn convolution_settings() -> FinShadowSettings {
    FinShadowSettings { method: FinMethod::Convolution, ..settings() }
}

/// The core's convolution model of `setup`'s light, per light frame, on the
/// hard shadow map the raster oracle draws at the plugin's resolution.
fn convolution_models(setup: &Setup) -> (Vec<LightSpaceScene>, Vec<ConvolutionModel>) {
    let faces = LightSpaceScene::faces(&setup.scene, setup.light);
    let s = setup.settings.clamped();
    let settings = ConvolutionSettings {
        resolution: s.map_resolution,
        order: s.convolution_order,
        prefilter: Prefilter::Mipmap,
        sharpening: Some((30.0, 20.0)),
        mip_bias: VARIANCE_MATCHED_MIP_BIAS,
    };
    let models = faces
        .iter()
        .map(|ls| {
            let hard = FinShadowModel::new(&setup.scene, ls, Method::Hard, s.core());
            let maps = hard.raster(s.map_resolution);
            let texels = maps.layers.first().map_or(0, Vec::len);
            let depth: Vec<f32> = (0..texels)
                .map(|i| maps.layers.iter().map(|l| l[i].slab_depth).fold(f32::INFINITY, f32::min))
                .collect();
            ConvolutionModel::on_depth_map(ls, settings, maps.region, &depth)
        })
        .collect();
    (faces, models)
}

fn convolution_oracle(setup: &Setup) -> Vec<f32> {
    let (faces, models) = convolution_models(setup);
    per_pixel_in_faces(setup, &setup.camera, &faces, |face, r| models[face].visibility(r))
}

fn assert_matches_its_model(setup: &Setup, tag: &str) -> shadow_fins_app::harness::Shot {
    let shot = render_bevy_lights(setup);
    save(&shot, &format!("convolution_{tag}"));
    let (mad, far) = compare(&shot.visibility, &convolution_oracle(setup));
    println!("convolution {tag}: mean |gpu − oracle| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.01 && far <= 0.03, "{tag}: {mad} / {far}");
    assert_not_trivial(&shot);
    let penumbra = shot.visibility.iter().filter(|v| (0.05..0.95).contains(*v)).count();
    assert!(penumbra > 100, "{tag}: only {penumbra} penumbra pixels: is the light soft at all?");
    assert_eq!(shot.stats.fins, 0, "{tag}: convolution builds no fins");
    shot
}

#[test]
fn gpu_convolution_matches_its_model_under_disk_rect_sun_and_sphere_lights() {
    for id in [SceneId::BoxOverPlane, SceneId::Kitbash, SceneId::NearContact] {
        assert_matches_its_model(&setup(id, convolution_settings()), &format!("disk_{}", id.name()));
    }
    let cpu = FinShadowSettings { extraction: FinExtraction::Cpu, ..convolution_settings() };
    assert_matches_its_model(&setup(SceneId::Kitbash, cpu), "disk_kitbash_cpu_extraction");
    assert_matches_its_model(&rect_setup(SceneId::BoxOverPlane, convolution_settings()), "rect_box_over_plane");
    let sun = FinShadowSettings { method: FinMethod::Convolution, ..unfitted() };
    assert_matches_its_model(&sun_setup(SceneId::BoxOverPlane, sun), "sun_box_over_plane");
    assert_matches_its_model(&point_setup(SceneId::LampRoom, convolution_settings()), "sphere_lamp_room");
}

#[test]
fn gpu_convolution_at_radius_zero_is_the_hard_shadow() {
    let mut setup = setup(SceneId::Kitbash, convolution_settings());
    setup.light = setup.light.with_zero_size();
    let shot = render(&setup);
    assert_not_trivial(&shot);
    assert!(shot.visibility.iter().all(|v| *v == 0.0 || *v == 1.0), "radius 0 gives only 0 and 1");
    let (mad, far) = compare(&shot.visibility, &oracle(&setup, Method::Hard));
    println!("radius 0: mean |gpu − hard oracle| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.01 && far <= 0.03, "{mad} / {far}");
}

/// The order is a live setting: a higher one reconstructs the step more
/// sharply (Annen et al. Figure 3), so the GPU's result changes with it and
/// still matches the model at that order.
#[test]
fn the_convolution_order_changes_the_shadow_and_each_matches_its_model() {
    let low = setup(SceneId::BoxOverPlane, FinShadowSettings { convolution_order: 2, ..convolution_settings() });
    let high = setup(SceneId::BoxOverPlane, FinShadowSettings { convolution_order: 8, ..convolution_settings() });
    let (a, b) = (assert_matches_its_model(&low, "order_2"), assert_matches_its_model(&high, "order_8"));
    let (differ, _) = compare(&a.visibility, &b.visibility);
    assert!(differ > 0.002, "orders 2 and 8 give the same image ({differ})");
}

/// Against ground truth the GPU's error is the model's (it is the method's
/// error, not the port's), and softer than the hard shadow's.
#[test]
fn gpu_convolution_is_as_close_to_the_truth_as_its_model_and_closer_than_hard() {
    let setup = setup(SceneId::BoxOverPlane, convolution_settings());
    let shot = render(&setup);
    let ls = LightSpaceScene::new(&setup.scene, setup.light);
    let truth = GroundTruth::new(&ls, 4096);
    let oracle = convolution_oracle(&setup);
    let hard = super::common::oracle(&setup, Method::Hard);
    let reference = per_pixel(&setup, &setup.camera, &ls, |r| truth.visibility(r));
    let lit: Vec<usize> = (0..reference.len()).filter(|i| reference[*i] < 1.0 || shot.visibility[*i] < 1.0).collect();
    let pick = |v: &[f32]| lit.iter().map(|i| v[*i]).collect::<Vec<f32>>();
    let truth_values = pick(&reference);
    let gpu = ErrorMetrics::compute(&pick(&shot.visibility), &truth_values);
    let cpu = ErrorMetrics::compute(&pick(&oracle), &truth_values);
    let hard = ErrorMetrics::compute(&pick(&hard), &truth_values);
    println!("against 4096-sample truth: GPU CSM MAE {:.4}, model {:.4}, hard {:.4}", gpu.mae, cpu.mae, hard.mae);
    assert!((gpu.mae - cpu.mae).abs() <= 0.01, "GPU {gpu:?} vs model {cpu:?}");
    assert!(gpu.mae < 0.8 * hard.mae, "GPU {gpu:?} vs hard {hard:?}");
}

/// The editor's demo scene under its light (a disk of radius 1, 5 above the
/// ground): objects at several heights over a caster ground, at the
/// editor's 512² maps.
#[test]
fn gpu_convolution_matches_its_model_on_the_editors_demo_scene() {
    use shadow_fins::{
        glam::Vec3,
        light::{DiskLight, Light},
    };
    let import = shadow_fins::gltf_import::load_gltf(asset("demo.gltf")).expect("the demo scene");
    let (_, camera) = shadow_fins::scenes::default_view(&import.scene).expect("a view");
    let light = Light::Disk(DiskLight::new(Vec3::new(0.2, 5.0, 0.3), Vec3::NEG_Y, 1.0).expect("a disk"));
    let settings = FinShadowSettings { map_resolution: 512, ..convolution_settings() };
    let setup = Setup::new(import.scene, light, camera, settings, (WIDTH, HEIGHT));
    let shot = render(&setup);
    save(&shot, "convolution_demo");
    let (mad, far) = compare(&shot.visibility, &convolution_oracle(&setup));
    println!("convolution demo: mean |gpu − oracle| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.01 && far <= 0.03, "demo: {mad} / {far}");
    // A light this large leaves little umbra: judged against the truth
    // instead of by dark pixels, and against the hard shadow it softens.
    let ls = LightSpaceScene::new(&setup.scene, setup.light);
    let truth = GroundTruth::new(&ls, 4096);
    let reference = per_pixel(&setup, &setup.camera, &ls, |r| truth.visibility(r));
    let hard = super::common::oracle(&setup, Method::Hard);
    let shadowed = reference.iter().filter(|v| **v < 0.5).count();
    assert!(shadowed > 40, "only {shadowed} pixels of the truth are darker than ½");
    let (gpu, _) = compare(&shot.visibility, &reference);
    let (hard, _) = compare(&hard, &reference);
    println!("demo against 4096-sample truth: GPU convolution MAE {gpu:.4}, hard {hard:.4}");
    assert!(gpu < 0.7 * hard, "convolution {gpu} vs hard {hard}");
}

/// A sun fitted to the views (the default) draws its maps over a window
/// onto casters that go on past it: the lookups read its border there, and
/// the shadow is the unfitted one's up to the finer texels.
#[test]
fn gpu_convolution_under_a_sun_fitted_to_the_view_agrees_with_the_unfitted_one() {
    let fitted = sun_setup(SceneId::Kitbash, convolution_settings());
    let unfitted = sun_setup(SceneId::Kitbash, FinShadowSettings { method: FinMethod::Convolution, ..unfitted() });
    let (a, b) = (render_bevy_lights(&fitted), render_bevy_lights(&unfitted));
    save(&a, "convolution_sun_fitted");
    assert_not_trivial(&a);
    assert!(a.stats.degraded.is_empty(), "{}", a.stats.degraded);
    let (mad, far) = compare(&a.visibility, &b.visibility);
    println!("fitted against unfitted sun: mean {mad:.4}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.02 && far <= 0.05, "{mad} / {far}");
}

/// A map budget that leaves the basis less room than its full chain drops
/// its finest levels, says so in the light's stats, and still shadows much
/// as the full chain does; one that leaves no room for even the coarsest
/// allowed chain says so and computes no convolution (no NaN, no garbage).
#[test]
fn the_convolution_basis_fits_the_map_budget_and_says_what_it_dropped() {
    use bevy_shadow_fins::{FinDegradation, FinShadowBudget};
    use shadow_fins_app::harness::Session;
    let setup = setup(SceneId::BoxOverPlane, convolution_settings());
    let full = render(&setup);
    // 256² maps take 2.25 MiB when every tile is drawn (the plane under the
    // box covers the map), plus the sparse maps' header and page table
    // (4 + 32² words); the full basis (order 4) 5.9 MiB, without level 0 1.5 MiB.
    let maps = 256u64 * 256 * 36 + (4 + 32 * 32) * 4;
    for (room, dropped) in [(2 << 20, true), (1 << 10, false)] {
        let mut session = Session::new(&setup);
        session.app.world_mut().insert_resource(FinShadowBudget { map_bytes: maps + room, ..Default::default() });
        let shot = session.settle(6).expect("render");
        println!("room {room}: {:?}", shot.stats.degraded.to_string());
        assert!(shot.visibility.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
        if dropped {
            assert!(
                matches!(shot.stats.degraded.first(), Some(FinDegradation::ConvolutionLevels { dropped: 1, .. })),
                "{:?}",
                shot.stats.degraded
            );
            assert_not_trivial(&shot);
            let (mad, _) = compare(&shot.visibility, &full.visibility);
            println!("one level dropped against the full chain: mean {mad:.4}");
            assert!(mad <= 0.02, "{mad}");
        } else {
            assert!(
                matches!(shot.stats.degraded.first(), Some(FinDegradation::ConvolutionBasis { .. })),
                "{:?}",
                shot.stats.degraded
            );
        }
    }
}
