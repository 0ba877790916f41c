//! The fig-7 configuration: a ring above a plate above the ground. Under the
//! plate's umbra, the ring's inner fins wrongly brighten the ground when
//! everything shares one layer; layers keep them where they belong.

use shadow_fins::{
    glam::Vec3,
    oracle::{FinSettings, FinShadowModel, Method},
    scene::LightSpaceScene,
    scenes::SceneId,
};

use super::common::*;

fn points_under_the_ring() -> Vec<Vec3> {
    // The ring body (radius 1.2 at y = 2, light at y = 5) shadows ground radii
    // 1.75..2.25; the plate (half size 2.1 at y = 1) keeps all of it in umbra.
    (0..24)
        .flat_map(|k| {
            let a = k as f32 / 24.0 * std::f32::consts::TAU;
            [1.85f32, 2.0, 2.15].map(|r| Vec3::new(r * a.cos(), 0.0, r * a.sin()))
        })
        .collect()
}

#[test]
fn single_layer_leaks_under_the_plate_and_multi_layer_does_not() {
    let s = SceneId::RingPlate.build();
    let pts = points_under_the_ring();
    let gt = ground_truth(&s.scene, s.light, 1024, &pts);
    assert!(gt.iter().all(|v| *v < 0.005), "ground truth says umbra here");
    let single = method_visibility(&s.scene, s.light, Method::SingleLayer, FinSettings::default(), &pts);
    let multi = method_visibility(&s.scene, s.light, Method::MultiLayer, FinSettings::default(), &pts);
    // The ring's inner fins reach 0.12..0.24 here through a single layer.
    assert!(single.iter().all(|v| *v > 0.1), "single layer should leak at every point: {single:?}");
    assert!(multi.iter().all(|v| *v < 0.02), "multi-layer must keep the umbra: {multi:?}");
}

#[test]
fn ring_and_plate_fall_in_different_layers() {
    let s = SceneId::RingPlate.build();
    let ls = LightSpaceScene::new(&s.scene, s.light);
    let model = FinShadowModel::new(&s.scene, &ls, Method::MultiLayer, FinSettings::default());
    let ring_depth = ls.frame.to_frame(Vec3::new(1.35, 2.0, 0.0)).z;
    let plate_depth = ls.frame.to_frame(Vec3::new(2.1, 1.03, 0.0)).z;
    assert!(model.plan.len() >= 2);
    assert!(model.plan.layer_of(ring_depth) < model.plan.layer_of(plate_depth));
}
