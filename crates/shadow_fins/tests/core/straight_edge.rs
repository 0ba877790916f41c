//! A straight edge far from corners: the case the fin model is built on.
//!
//! Half-plane occluder `x < 0` at height 3, light of radius 0.5 at height 5,
//! ground at 0: `L_b = 2`, `L_r = 5`, so the penumbra half-width on the ground is
//! `R (L_r − L_b) / L_b = 0.75`, centred on the hard-shadow boundary `x = 0`.

use shadow_fins::{
    glam::Vec3,
    oracle::{FinSettings, Method},
    refine::Falloff,
};

use super::common::*;

const HALF_WIDTH: f32 = 0.5 * (5.0 - 2.0) / 2.0;

fn visibility_at(x: f32, settings: FinSettings) -> f32 {
    let (scene, light) = straight_edge_scene(3.0, 5.0, 0.5);
    method_visibility(&scene, light, Method::MultiLayer, settings, &[Vec3::new(x, 0.0, 0.3)])[0]
}

/// Smallest x with `pred(V(x))` true, by bisection on `[lo, hi]` (pred false at lo).
fn bisect(lo: f32, hi: f32, settings: FinSettings, pred: impl Fn(f32) -> bool) -> f32 {
    let (mut a, mut b) = (lo, hi);
    for _ in 0..40 {
        let m = 0.5 * (a + b);
        if pred(visibility_at(m, settings)) { b = m } else { a = m }
    }
    b
}

#[test]
fn visibility_is_one_half_on_the_hard_shadow_boundary() {
    for falloff in Falloff::ALL {
        let v = visibility_at(0.0, FinSettings { falloff, ..FinSettings::default() });
        assert!((v - 0.5).abs() < 1e-3, "{falloff:?}: V(0) = {v}");
    }
}

#[test]
fn penumbra_half_width_matches_similar_triangles_within_two_percent() {
    let s = linear();
    // Outer edge of the penumbra: where V first reaches 1; inner: where it leaves 0.
    let outer = bisect(0.0, 2.0, s, |v| v >= 1.0);
    let inner = -bisect(-2.0, 0.0, s, |v| v > 0.0).abs();
    for (name, w) in [("outer", outer), ("inner", -inner)] {
        assert!((w - HALF_WIDTH).abs() < 0.02 * HALF_WIDTH, "{name} half-width {w}, expected {HALF_WIDTH}");
    }
}

#[test]
fn disk_segment_falloff_is_exact_for_a_straight_edge_and_matches_ground_truth() {
    let (scene, light) = straight_edge_scene(3.0, 5.0, 0.5);
    let xs: Vec<Vec3> = (-20..=20).map(|i| Vec3::new(i as f32 * 0.045, 0.0, 0.3)).collect();
    let fins = method_visibility(&scene, light, Method::MultiLayer, FinSettings::default(), &xs);
    let gt = ground_truth(&scene, light, 1024, &xs);
    for ((p, f), g) in xs.iter().zip(&fins).zip(&gt) {
        let exact = disk_segment_fraction(p.x / HALF_WIDTH);
        assert!((f - exact).abs() < 2e-3, "x {}: fins {f} vs exact {exact}", p.x);
        assert!((g - exact).abs() < 0.01, "x {}: ground truth {g} vs exact {exact}", p.x);
    }
}

#[test]
fn refinement_makes_a_nearer_receiver_penumbra_narrower() {
    // A receiver plate at height 1.5 (L_r = 3.5) in front of the ground.
    let mut objects = vec![ground(), object("edge", quad(-40.0, 0.0, -20.0, 20.0, 3.0))];
    objects.push(object("plate", quad(-3.0, 3.0, 1.0, 3.0, 1.5)));
    let scene = shadow_fins::scene::Scene::new(objects);
    let light = down_light(Vec3::new(0.0, 5.0, 0.0), 0.5);
    let expected = 0.5 * (3.5 - 2.0) / 2.0;
    let xs: Vec<Vec3> = (0..=400).map(|i| Vec3::new(i as f32 * 0.005, 1.5, 2.0)).collect();
    let width = |refinement: bool| {
        let v = method_visibility(&scene, light, Method::MultiLayer, FinSettings { refinement, ..linear() }, &xs);
        xs.iter().zip(&v).find(|(_, v)| **v >= 1.0).map(|(p, _)| p.x).unwrap_or(2.0)
    };
    let refined = width(true);
    assert!((refined - expected).abs() < 0.02, "refined outer half-width {refined}, expected {expected}");
    // Without refinement the fin keeps its map width from the reference plane
    // (L0 = 5): R (1/L_b − 1/L0) · L_r = 0.525 world units on the plate.
    let unrefined = width(false);
    assert!((unrefined - 0.525).abs() < 0.02, "unrefined outer half-width {unrefined}");
}

#[test]
fn a_thin_strip_under_a_wide_penumbra_needs_the_union_of_its_two_inner_fins() {
    // Strip |x| < 0.15 at height 3: both edges' inner fins cover the whole strip
    // shadow. The paper's min keeps one edge's light; the union keeps both.
    use shadow_fins::oracle::Overlap;
    let scene = shadow_fins::scene::Scene::new(vec![ground(), object("strip", quad(-0.15, 0.15, -20.0, 20.0, 3.0))]);
    let light = down_light(Vec3::new(0.0, 5.0, 0.0), 0.5);
    let xs: Vec<Vec3> = (-30..=30).map(|i| Vec3::new(i as f32 * 0.04, 0.0, 0.2)).collect();
    let gt = ground_truth(&scene, light, 1024, &xs);
    let error = |overlap| {
        let v = method_visibility(
            &scene,
            light,
            Method::MultiLayer,
            FinSettings { overlap, ..FinSettings::default() },
            &xs,
        );
        mean_abs_diff(&v, &gt)
    };
    let (paper, union) = (error(Overlap::MinMax), error(Overlap::Union));
    assert!(union < 0.5 * paper, "union {union} vs min-max {paper}");
    assert!(union < 0.03, "union mean error {union}");
}

#[test]
fn a_sun_casts_penumbrae_of_tan_theta_times_distance() {
    // Sun straight down, θ = 0.1: half-width tan θ · (L_r − L_b) = tan(0.1) · 3.
    let scene = shadow_fins::scene::Scene::new(vec![ground(), object("edge", quad(-40.0, 0.0, -20.0, 20.0, 3.0))]);
    let sun = shadow_fins::light::Light::Sun(shadow_fins::light::SunLight::new(Vec3::NEG_Y, 0.1).unwrap());
    let half = 0.1f32.tan() * 3.0;
    let xs: Vec<Vec3> = (-20..=20).map(|i| Vec3::new(i as f32 * half / 16.0, 0.0, 0.3)).collect();
    let fins = method_visibility(&scene, sun, Method::MultiLayer, FinSettings::default(), &xs);
    let gt = ground_truth(&scene, sun, 1024, &xs);
    for ((p, f), g) in xs.iter().zip(&fins).zip(&gt) {
        let exact = disk_segment_fraction(p.x / half);
        assert!((f - exact).abs() < 3e-3, "x {}: fins {f} vs exact {exact}", p.x);
        assert!((g - exact).abs() < 0.01, "x {}: ground truth {g} vs exact {exact}", p.x);
    }
}

#[test]
fn a_sun_over_a_scene_wider_than_a_perspective_map_shadows_all_of_it() {
    // The sun's map coordinates are world units: nothing may clamp them to a
    // perspective map's tan-of-angle range (±8), or a 200-wide scene's edge
    // at x = 90 comes out lit. Sun straight down, θ = 0.05, edge 3 above the
    // ground at x = 90; the scene spans x ∈ [−100, 100].
    let ground = object("ground", quad(-100.0, 100.0, -100.0, 100.0, 0.0));
    let scene = shadow_fins::scene::Scene::new(vec![ground, object("edge", quad(-100.0, 90.0, -20.0, 20.0, 3.0))]);
    let sun = shadow_fins::light::Light::Sun(shadow_fins::light::SunLight::new(Vec3::NEG_Y, 0.05).unwrap());
    let half = 0.05f32.tan() * 3.0;
    let xs: Vec<Vec3> = (-8..=8).map(|i| Vec3::new(90.0 + i as f32 * half / 6.0, 0.0, 0.3)).collect();
    let ls = shadow_fins::scene::LightSpaceScene::new(&scene, sun);
    let model = shadow_fins::oracle::FinShadowModel::new(&scene, &ls, Method::MultiLayer, FinSettings::default());
    let raster = model.raster(4096);
    let analytic = model.analytic();
    for (p, r) in xs.iter().zip(ground_receivers(&ls, &xs)) {
        let exact = disk_segment_fraction((p.x - 90.0) / half);
        let (a, m) = (analytic.visibility(r), raster.visibility(r));
        assert!((a - exact).abs() < 0.02, "x {}: analytic {a} vs exact {exact}", p.x);
        // 4096 texels over 200 units: a texel is 0.05, a third of the penumbra.
        assert!((m - exact).abs() < 0.2, "x {}: raster {m} vs exact {exact}", p.x);
    }
}
