//! Finite output in [0, 1] at the extremes: radius from 0 to 100× the scene,
//! and the whole scene offset by 1e5.

use shadow_fins::{
    ground_truth::GroundTruth,
    oracle::{FinSettings, FinShadowModel, Method},
    scene::Scene,
    scenes::SceneId,
};

use super::convergence::view_receivers;

fn assert_all_sane(scene: &Scene, light: shadow_fins::light::Light, camera: &shadow_fins::camera::Camera, what: &str) {
    let (ls, receivers) = view_receivers(scene, light, camera, 20, 15);
    assert!(!receivers.is_empty(), "{what}: camera sees nothing");
    let gt = GroundTruth::new(&ls, 64);
    for r in &receivers {
        let v = gt.visibility(*r);
        assert!(v.is_finite() && (0.0..=1.0).contains(&v), "{what}: ground truth {v}");
    }
    for method in Method::ALL {
        let model = FinShadowModel::new(scene, &ls, method, FinSettings::default());
        let index = model.analytic();
        let maps = model.raster(64);
        for r in &receivers {
            for v in [index.visibility(*r), maps.visibility(*r)] {
                assert!(v.is_finite() && (0.0..=1.0).contains(&v), "{what} {}: visibility {v}", method.name());
            }
        }
    }
}

#[test]
fn every_scene_stays_finite_for_every_light_size() {
    for id in SceneId::ALL.into_iter().filter(|s| *s != SceneId::DenseBlob) {
        let s = id.build();
        let (lo, hi) = s.scene.bounds().unwrap();
        let size = (hi - lo).length();
        for factor in [0.0, 1e-6, 1e-3, 1.0, 100.0] {
            let light = match s.light {
                shadow_fins::light::Light::Disk(d) => shadow_fins::light::Light::Disk(
                    shadow_fins::light::DiskLight::new(d.center, d.normal, factor * size).unwrap(),
                ),
                sun => sun,
            };
            assert_all_sane(&s.scene, light, &s.camera, &format!("{} radius {factor}×", id.name()));
        }
    }
}

#[test]
fn a_scene_offset_by_1e5_stays_finite_and_close() {
    let offset = shadow_fins::glam::Vec3::new(1e5, -1e5, 1e5);
    for id in [SceneId::BoxOverPlane, SceneId::NearContact, SceneId::RingPlate] {
        let s = id.build();
        let moved = s.scene.translated(offset);
        let light = match s.light {
            shadow_fins::light::Light::Disk(d) => shadow_fins::light::Light::Disk(
                shadow_fins::light::DiskLight::new(d.center + offset, d.normal, d.radius).unwrap(),
            ),
            sun => sun,
        };
        let mut camera = s.camera;
        camera.position += offset;
        camera.target += offset;
        assert_all_sane(&moved, light, &camera, &format!("{} offset 1e5", id.name()));
        // Light space is relative to the light in f64: the answer barely moves.
        let near = view_receivers(&s.scene, s.light, &s.camera, 20, 15);
        let far = view_receivers(&moved, light, &camera, 20, 15);
        let eval = |(ls, r): &(shadow_fins::scene::LightSpaceScene, Vec<shadow_fins::oracle::Receiver>),
                    scene: &Scene| {
            let m = FinShadowModel::new(scene, ls, Method::MultiLayer, FinSettings::default());
            let i = m.analytic();
            r.iter().map(|x| i.visibility(*x)).collect::<Vec<f32>>()
        };
        let (a, b) = (eval(&near, &s.scene), eval(&far, &moved));
        if a.len() == b.len() {
            let diff = super::common::mean_abs_diff(&a, &b);
            assert!(diff < 0.02, "{}: offset changed visibility by {diff} on average", id.name());
        }
    }
}

#[test]
fn a_light_inside_a_closed_caster_shadows_everything_outside_it() {
    use shadow_fins::{glam::Vec3, light::DiskLight, light::Light};
    // box-over-plane: the box spans y 1..2 above the ground; the light's centre
    // in its middle, facing down. Every ground point is in shadow (truth 0).
    let s = SceneId::BoxOverPlane.build();
    let light = Light::Disk(DiskLight::new(Vec3::new(0.0, 1.5, 0.0), Vec3::NEG_Y, 0.1).unwrap());
    let ls = shadow_fins::scene::LightSpaceScene::new(&s.scene, light);
    assert!(ls.object_frames.iter().any(|f| f.light_inside), "the box is found to hold the light");
    let points: Vec<Vec3> =
        (0..25).map(|i| Vec3::new((i % 5) as f32 * 0.6 - 1.2, 0.0, (i / 5) as f32 * 0.6 - 1.2)).collect();
    let receivers = super::common::ground_receivers(&ls, &points);
    let gt = GroundTruth::new(&ls, 256);
    for method in Method::ALL {
        let model = FinShadowModel::new(&s.scene, &ls, method, FinSettings::default());
        let (index, maps) = (model.analytic(), model.raster(256));
        for r in &receivers {
            let truth = gt.visibility(*r);
            assert!(truth < 0.01, "truth {truth}: the disk is inside the box");
            for v in [index.visibility(*r), maps.visibility(*r)] {
                assert!(v <= 0.01, "{}: ground point lit ({v}) by a light shut in a box", method.name());
            }
        }
    }
}

#[test]
fn receivers_beyond_the_scene_get_fins_as_wide_as_their_penumbra() {
    use shadow_fins::{glam::Vec3, metrics::ErrorMetrics, oracle::Receiver};
    // The box of box-over-plane without its ground, and receivers 1.5× and 10×
    // deeper than its deepest vertex (with the ground they would lie under it,
    // in its umbra): without covering them the fins end too early.
    let mut s = SceneId::BoxOverPlane.build();
    s.scene.objects.retain(|o| o.name != "ground");
    assert_eq!(s.scene.objects.len(), 1);
    let ls = shadow_fins::scene::LightSpaceScene::new(&s.scene, s.light);
    let l0 = ls.reference_depth;
    let mut receivers = vec![];
    for depth in [1.5f32, 10.0] {
        for i in 0..400 {
            let (x, y) = ((i % 20) as f32 / 19.0 - 0.5, (i / 20) as f32 / 19.0 - 0.5);
            let d = depth * l0;
            receivers.push(Receiver { position: Vec3::new(x * d * 0.5, y * d * 0.5, d), normal: Vec3::NEG_Z });
        }
    }
    let error = |ls: &shadow_fins::scene::LightSpaceScene| {
        let model = FinShadowModel::new(&s.scene, ls, Method::MultiLayer, FinSettings::default());
        let index = model.analytic();
        let gt = GroundTruth::new(ls, 1024);
        let v: Vec<f32> = receivers.iter().map(|r| index.visibility(*r)).collect();
        let t: Vec<f32> = receivers.iter().map(|r| gt.visibility(*r)).collect();
        ErrorMetrics::compute(&v, &t)
    };
    let clamped = error(&ls);
    let mut covered = ls.clone();
    covered.cover_receivers(receivers.iter().map(|r| r.position));
    assert_eq!(covered.reference_depth, 10.0 * l0);
    let covered = error(&covered);
    assert!(covered.count > 100, "the receivers see the box's penumbra ({} scored)", covered.count);
    assert!(
        covered.mae < 0.6 * clamped.mae && covered.p99 < clamped.p99,
        "covering the receivers: MAE {} (p99 {}) vs clamped {} (p99 {})",
        covered.mae,
        covered.p99,
        clamped.mae,
        clamped.p99
    );
}
