use shadow_fins::{glam::Vec3, oracle::Method, scenes::SceneId};

use super::common::*;

#[test]
fn debug_profile() {
    let b = SceneId::BoxOverPlane.build();
    let (scene, light) = (b.scene, b.light);
    let mut pts = vec![];
    for j in -6..=6 { for i in -6..=6 { pts.push(Vec3::new(0.66 + i as f32 * 0.1, 0.0, 0.74 + j as f32 * 0.1)); } }
    let v = method_visibility(&scene, light, Method::SingleLayer, linear(), &pts);
    let gt = ground_truth(&scene, light, 1024, &pts);
    for j in 0..13 { let row: Vec<String> = (0..13).map(|i| format!("{:.2}", v[j*13+i])).collect(); println!("F {}", row.join(" ")); }
    for j in 0..13 { let row: Vec<String> = (0..13).map(|i| format!("{:.2}", gt[j*13+i])).collect(); println!("G {}", row.join(" ")); }
    panic!();
}
