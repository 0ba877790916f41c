//! Helpers shared by the integration tests.

use shadow_fins::{
    glam::{Affine3A, Vec3},
    ground_truth::GroundTruth,
    light::{DiskLight, Light},
    mesh::Mesh,
    oracle::{FinSettings, FinShadowModel, Method, Receiver},
    refine::Falloff,
    scene::{LightSpaceScene, Scene, SceneObject},
    shapes,
};

/// A flat quad facing +Y, covering `[x0, x1] × [z0, z1]` at height `y`.
pub fn quad(x0: f32, x1: f32, z0: f32, z1: f32, y: f32) -> Mesh {
    let p = vec![Vec3::new(x0, y, z0), Vec3::new(x0, y, z1), Vec3::new(x1, y, z1), Vec3::new(x1, y, z0)];
    Mesh::new(p, vec![0, 1, 2, 0, 2, 3]).unwrap()
}

pub fn object(name: &str, mesh: Mesh) -> SceneObject {
    SceneObject::new(name, mesh, Affine3A::IDENTITY).unwrap()
}

/// A wide ground at y = 0.
pub fn ground() -> SceneObject {
    object("ground", shapes::plane(60.0, 2))
}

pub fn down_light(center: Vec3, radius: f32) -> Light {
    Light::Disk(DiskLight::new(center, Vec3::NEG_Y, radius).unwrap())
}

/// A half-plane occluder `x < 0` at height `h` (a quad 40 wide), the ground,
/// and a light of radius `r` at height `light_h` above x = 0.
pub fn straight_edge_scene(h: f32, light_h: f32, r: f32) -> (Scene, Light) {
    let scene = Scene::new(vec![ground(), object("half-plane", quad(-40.0, 0.0, -20.0, 20.0, h))]);
    (scene, down_light(Vec3::new(0.0, light_h, 0.0), r))
}

/// Receivers on the ground (normal up), world points.
pub fn ground_receivers(ls: &LightSpaceScene, points: &[Vec3]) -> Vec<Receiver> {
    points
        .iter()
        .map(|p| Receiver { position: ls.frame.to_frame(*p), normal: ls.frame.dir_to_frame(Vec3::Y) })
        .collect()
}

/// Visibility of `method` at world ground points, exact oracle.
pub fn method_visibility(
    scene: &Scene,
    light: Light,
    method: Method,
    settings: FinSettings,
    points: &[Vec3],
) -> Vec<f32> {
    let ls = LightSpaceScene::new(scene, light);
    let model = FinShadowModel::new(scene, &ls, method, settings);
    let index = model.analytic();
    ground_receivers(&ls, points).into_iter().map(|r| index.visibility(r)).collect()
}

pub fn ground_truth(scene: &Scene, light: Light, samples: u32, points: &[Vec3]) -> Vec<f32> {
    let ls = LightSpaceScene::new(scene, light);
    let gt = GroundTruth::new(&ls, samples);
    ground_receivers(&ls, points).into_iter().map(|r| gt.visibility(r)).collect()
}

pub fn linear() -> FinSettings {
    FinSettings { falloff: Falloff::Linear, ..FinSettings::default() }
}

/// Visible fraction of a unit-radius disk on the side `s > -offset` of a chord.
pub fn disk_segment_fraction(offset: f32) -> f32 {
    let x = offset.clamp(-1.0, 1.0);
    0.5 + (x * (1.0 - x * x).sqrt() + x.asin()) / std::f32::consts::PI
}

pub fn mean_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32
}
