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
