//! An occluder touching the receiver: the penumbra collapses to a hard edge at
//! the contact line, with no NaN anywhere near it.

use shadow_fins::{
    glam::{Affine3A, Vec3},
    oracle::{FinSettings, Method},
    scene::{Scene, SceneObject},
    shapes,
};

use super::common::*;

fn resting_box() -> (Scene, shadow_fins::light::Light) {
    let cube =
        SceneObject::new("box", shapes::cuboid(Vec3::splat(0.5)), Affine3A::from_translation(Vec3::Y * 0.5)).unwrap();
    (Scene::new(vec![ground(), cube]), down_light(Vec3::new(2.0, 3.0, 0.0), 0.5))
}

/// Width of the region `0.01 < V < 0.99` across the shadow of the vertical edge
/// at (0.5, ·, 0.5), at distance `s` from where it meets the ground.
fn penumbra_width(values: impl Fn(&[Vec3]) -> Vec<f32>, s: f32) -> f32 {
    let along = Vec3::new(-1.5, 0.0, 0.5).normalize();
    let across = Vec3::new(0.5, 0.0, 1.5).normalize();
    let base = Vec3::new(0.5, 0.0, 0.5) + along * s;
    let step = 0.002;
    let pts: Vec<Vec3> = (-300..=300).map(|i| base + across * (i as f32 * step)).collect();
    let v = values(&pts);
    assert!(v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)), "non-finite visibility near contact");
    v.iter().filter(|x| **x > 0.01 && **x < 0.99).count() as f32 * step
}

#[test]
fn penumbra_width_goes_to_zero_at_the_contact_line() {
    let (scene, light) = resting_box();
    let fins = |p: &[Vec3]| method_visibility(&scene, light, Method::MultiLayer, FinSettings::default(), p);
    let gt = |p: &[Vec3]| ground_truth(&scene, light, 1024, p);
    let distances = [0.6, 0.3, 0.15, 0.05, 0.01];
    let widths: Vec<f32> = distances.iter().map(|&s| penumbra_width(fins, s)).collect();
    let truth: Vec<f32> = distances.iter().map(|&s| penumbra_width(gt, s)).collect();
    for w in widths.windows(2) {
        assert!(w[1] <= w[0] + 0.004, "penumbra does not shrink towards contact: {widths:?}");
    }
    assert!(widths[4] < 0.15 * widths[0], "penumbra at contact {widths:?}");
    for ((s, w), t) in distances.iter().zip(&widths).zip(&truth) {
        assert!((w - t).abs() < 0.3 * t.max(0.02), "s = {s}: fins width {w}, ground truth {t}");
    }
}

#[test]
fn exactly_at_contact_everything_is_finite() {
    let (scene, light) = resting_box();
    // Points on the contact line itself and on the box's base edges.
    let pts: Vec<Vec3> = (0..=20).map(|i| Vec3::new(0.5, 0.0, -0.5 + i as f32 * 0.05)).collect();
    for method in Method::ALL {
        for v in method_visibility(&scene, light, method, FinSettings::default(), &pts) {
            assert!(v.is_finite() && (0.0..=1.0).contains(&v));
        }
    }
}
