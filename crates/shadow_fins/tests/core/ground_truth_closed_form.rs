//! Ground truth against closed forms: occluders parallel to the light and the
//! receiver block a region of the disk that is known exactly.

use shadow_fins::glam::Vec3;

use super::common::*;

/// Area of the unit disk inside the axis-aligned rectangle `[x0,x1]×[y0,y1]`,
/// by integrating chord lengths (converges to ~1e-7 here).
fn disk_rect_area(x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let n = 200_000;
    let (a, b) = (x0.max(-1.0), x1.min(1.0));
    if a >= b {
        return 0.0;
    }
    let h = (b - a) / n as f64;
    (0..n)
        .map(|i| {
            let x = a + (i as f64 + 0.5) * h;
            let c = (1.0 - x * x).max(0.0).sqrt();
            (y1.min(c) - y0.max(-c)).max(0.0) * h
        })
        .sum()
}

#[test]
fn half_plane_occluder_matches_the_circular_segment() {
    // Light R = 0.5 at height 5, half-plane x < 0 at height 3 → on the light
    // plane, a receiver at x sees the disk cut at s = −(2/3)x.
    let (scene, light) = straight_edge_scene(3.0, 5.0, 0.5);
    let xs: Vec<Vec3> = (-18..=18).map(|i| Vec3::new(i as f32 * 0.05, 0.0, 0.7)).collect();
    let gt = ground_truth(&scene, light, 1024, &xs);
    let mut worst = 0.0f32;
    for (p, g) in xs.iter().zip(&gt) {
        let exact = disk_segment_fraction((2.0 / 3.0) * p.x / 0.5);
        worst = worst.max((g - exact).abs());
    }
    assert!(worst < 0.006, "1024-sample ground truth off by {worst}");
}

#[test]
fn rectangle_occluder_matches_the_covered_area_and_converges() {
    // Rectangle [-0.3, 0.2] × [-0.1, 0.4] at height 3; light R = 0.5 at height 5.
    // From a ground point p, the rectangle projects onto the light plane as
    // p + (rect − p)·5/3 (scaling about p by L_r / (L_r − L_b)).
    let rect = (-0.3f32, 0.2f32, -0.1f32, 0.4f32);
    let scene =
        shadow_fins::scene::Scene::new(vec![ground(), object("rect", quad(rect.0, rect.1, rect.2, rect.3, 3.0))]);
    let light = down_light(Vec3::new(0.0, 5.0, 0.0), 0.5);
    let pts: Vec<Vec3> = (0..40).map(|i| Vec3::new(-0.8 + i as f32 * 0.04, 0.0, 0.1 + (i % 7) as f32 * 0.05)).collect();
    let exact: Vec<f32> = pts
        .iter()
        .map(|p| {
            let k = 5.0 / 3.0;
            // Light-plane coordinates (world x, z), in units of R; light centre at the origin.
            let map = |v: f32, c: f32| ((c + (v - c) * k) / 0.5) as f64;
            let covered = disk_rect_area(map(rect.0, p.x), map(rect.1, p.x), map(rect.2, p.z), map(rect.3, p.z));
            (1.0 - covered / std::f64::consts::PI) as f32
        })
        .collect();
    let err = |samples| mean_abs_diff(&ground_truth(&scene, light, samples, &pts), &exact);
    let (e256, e1024, e4096) = (err(256), err(1024), err(4096));
    assert!(e1024 < 0.004, "mean error at 1024 samples {e1024}");
    assert!(e4096 < e256, "more samples must be closer: {e256} → {e4096}");
}
