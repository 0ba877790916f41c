//! The raster oracle (what the GPU renders) converges to the analytic oracle as
//! the map resolution doubles, and radius 0 reproduces hard shadows exactly.

use shadow_fins::{
    bvh::Bvh,
    camera::{Camera, pixel_receiver},
    light::Light,
    oracle::{FinSettings, FinShadowModel, Method, Receiver},
    scene::{LightSpaceScene, Scene},
    scenes::SceneId,
};

use super::common::mean_abs_diff;

/// Receivers seen by the scene's camera on a small image.
pub fn view_receivers(
    scene: &Scene,
    light: Light,
    camera: &Camera,
    w: u32,
    h: u32,
) -> (LightSpaceScene, Vec<Receiver>) {
    let ls = LightSpaceScene::new(scene, light);
    let bvh = Bvh::new(&ls.casters);
    let out = (0..w * h).filter_map(|i| pixel_receiver(camera, (i % w, i / w, w, h), &ls, &bvh)).collect();
    (ls, out)
}

#[test]
fn raster_converges_to_analytic_as_resolution_doubles() {
    for id in [SceneId::BoxOverPlane, SceneId::RingPlate, SceneId::SphereGrid] {
        let s = id.build();
        let (ls, receivers) = view_receivers(&s.scene, s.light, &s.camera, 64, 48);
        let model = FinShadowModel::new(&s.scene, &ls, Method::MultiLayer, FinSettings::default());
        let index = model.analytic();
        let exact: Vec<f32> = receivers.iter().map(|r| index.visibility(*r)).collect();
        let errors: Vec<f32> = [128, 256, 512, 1024]
            .iter()
            .map(|&res| {
                let maps = model.raster(res);
                let v: Vec<f32> = receivers.iter().map(|r| maps.visibility(*r)).collect();
                mean_abs_diff(&v, &exact)
            })
            .collect();
        for w in errors.windows(2) {
            assert!(w[1] < w[0] * 0.9 || w[1] < 2e-3, "{}: raster error does not shrink: {errors:?}", id.name());
        }
        // What remains at 1024² is texel-sized: terminators of the spheres, where
        // the raster's one-texel normal offset moves a receiver across an edge.
        assert!(errors[3] < 0.015, "{}: raster at 1024² still off by {errors:?}", id.name());
    }
}

#[test]
fn radius_zero_equals_the_hard_shadow_exactly() {
    for id in SceneId::ALL.into_iter().filter(|s| *s != SceneId::DenseBlob) {
        let s = id.build();
        let light = s.light.with_zero_size();
        let (ls, receivers) = view_receivers(&s.scene, light, &s.camera, 48, 36);
        let hard = FinShadowModel::new(&s.scene, &ls, Method::Hard, FinSettings::default());
        let hard_index = hard.analytic();
        let hard_v: Vec<f32> = receivers.iter().map(|r| hard_index.visibility(*r)).collect();
        assert!(
            hard_v.iter().any(|v| *v == 0.0) && hard_v.iter().any(|v| *v == 1.0),
            "{}: no shadow in view",
            id.name()
        );
        for method in Method::ALL {
            let model = FinShadowModel::new(&s.scene, &ls, method, FinSettings::default());
            assert!(model.fins.is_empty(), "radius 0 must build no fins");
            let index = model.analytic();
            let v: Vec<f32> = receivers.iter().map(|r| index.visibility(*r)).collect();
            assert_eq!(v, hard_v, "{} / {}: radius 0 differs from hard shadows", id.name(), method.name());
        }
    }
}

#[test]
fn a_sun_of_zero_angle_equals_the_hard_shadow_exactly() {
    use shadow_fins::light::SunLight;
    for id in [SceneId::BoxOverPlane, SceneId::SphereGrid, SceneId::TiltedReceiver] {
        let s = id.build();
        let sun = Light::Sun(SunLight::new(shadow_fins::glam::Vec3::new(0.2, -1.0, 0.1), 0.0).unwrap());
        let (ls, receivers) = view_receivers(&s.scene, sun, &s.camera, 48, 36);
        let eval = |method| {
            let m = FinShadowModel::new(&s.scene, &ls, method, FinSettings::default());
            let i = m.analytic();
            receivers.iter().map(|r| i.visibility(*r)).collect::<Vec<f32>>()
        };
        let hard = eval(Method::Hard);
        assert!(hard.iter().any(|v| *v == 0.0), "{}: no shadow in view", id.name());
        assert_eq!(eval(Method::MultiLayer), hard, "{}", id.name());
    }
}
