//! The plateaus method on the GPU (`FinMethod::Plateaus`, `plateaus.wgsl`)
//! against its CPU semantics: the raster oracle's hard shadow at the same
//! map resolution, and on the receiver plane outside it the core's plateau
//! texture (`PlateauTexture::value`).
//!
//! Tolerance: mean |GPU − oracle| ≤ 0.01 and at most 3% of pixels off by
//! more than 0.1 (the view's geometric edges, where the rasterised depth and
//! the oracle's ray hit land on different surfaces, as for the fins). The
//! sheets' τ is f32 on the GPU, f64 in the core.

use bevy_shadow_fins::{FinMethod, FinShadowSettings};
use shadow_fins::{
    oracle::{FinShadowModel, Method},
    peers::{PlateauTexture, ReceiverPlane},
    scene::LightSpaceScene,
    scenes::SceneId,
};
use shadow_fins_app::harness::Setup;

use super::{common::*, rect_light::rect_setup, sun::sun_setup, sun::unfitted};

fn plateau_settings() -> FinShadowSettings {
    FinShadowSettings { method: FinMethod::Plateaus, ..settings() }
}

/// Per pixel: 0 in the hard shadow (raster oracle), the plateau texture on
/// the plane, 1 elsewhere.
fn plateau_oracle(setup: &Setup) -> Vec<f32> {
    let faces = LightSpaceScene::faces(&setup.scene, setup.light);
    let s = setup.settings.clamped();
    let hard: Vec<FinShadowModel> =
        faces.iter().map(|ls| FinShadowModel::new(&setup.scene, ls, Method::Hard, s.core())).collect();
    let maps: Vec<_> = hard.iter().map(|m| m.raster(s.map_resolution)).collect();
    let textures: Vec<PlateauTexture> = faces
        .iter()
        .map(|ls| PlateauTexture::on_plane(&setup.scene, ls, ReceiverPlane::largest_flat(&setup.scene, ls)))
        .collect();
    per_pixel_in_faces(setup, &setup.camera, &faces, |face, r| {
        if maps[face].visibility(r) == 0.0 {
            0.0
        } else if textures[face].holds(r.position) {
            textures[face].value(r.position)
        } else {
            1.0
        }
    })
}

fn assert_matches_its_model(setup: &Setup, tag: &str) -> shadow_fins_app::harness::Shot {
    let shot = render_bevy_lights(setup);
    save(&shot, &format!("plateaus_{tag}"));
    assert_not_trivial(&shot);
    let (mad, far) = compare(&shot.visibility, &plateau_oracle(setup));
    println!("plateaus {tag}: mean |gpu − oracle| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.01 && far <= 0.03, "{tag}: {mad} / {far}");
    let penumbra = shot.visibility.iter().filter(|v| (0.05..0.95).contains(*v)).count();
    assert!(penumbra > 100, "{tag}: only {penumbra} penumbra pixels: are the sheets drawn at all?");
    assert_eq!(shot.stats.fins, 0, "{tag}: plateaus build no fins");
    assert!(shot.stats.silhouettes > 0, "{tag}: the sheets' silhouette edges are counted");
    shot
}

#[test]
fn gpu_plateaus_match_their_model_under_disk_rect_and_sun_lights() {
    for id in [SceneId::BoxOverPlane, SceneId::Kitbash, SceneId::NearContact] {
        assert_matches_its_model(&setup(id, plateau_settings()), &format!("disk_{}", id.name()));
    }
    assert_matches_its_model(&rect_setup(SceneId::BoxOverPlane, plateau_settings()), "rect_box_over_plane");
    let sun = FinShadowSettings { method: FinMethod::Plateaus, ..unfitted() };
    assert_matches_its_model(&sun_setup(SceneId::BoxOverPlane, sun), "sun_box_over_plane");
}

/// Haines' plateaus only widen the hard shadow: at radius 0 they are the
/// hard shadow, and at any radius no pixel the hard shadow darkens is lit.
#[test]
fn gpu_plateaus_reproduce_the_hard_shadow_at_radius_zero_and_never_brighten_it() {
    let mut setup = setup(SceneId::Kitbash, plateau_settings());
    let soft = render(&setup);
    let hard = oracle(&setup, Method::Hard);
    let brightened = hard.iter().zip(&soft.visibility).filter(|(h, v)| **h == 0.0 && **v > 0.01).count();
    // The view's geometric edges: at most the share the tolerance allows.
    assert!(brightened * 100 <= 3 * hard.len(), "{brightened} hard-shadow pixels lit by plateaus");
    setup.light = setup.light.with_zero_size();
    let shot = render(&setup);
    assert_not_trivial(&shot);
    let (mad, far) = compare(&shot.visibility, &oracle(&setup, Method::Hard));
    println!("radius 0: mean |gpu − hard oracle| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.01 && far <= 0.03, "{mad} / {far}");
}
