//! Bevy's `RectLight` with fin shadows: the rectangle's support function sizes
//! the fins on the GPU, the coverage method samples the rectangle, and the
//! compositing pass takes `(1 − V)` of Bevy's own `lighting::rect_light` away.
//! Bevy itself gives a `RectLight` no shadow at all.
//!
//! Tolerances as in `oracle_agreement.rs` (mean |GPU − oracle| ≤ 0.01, at most
//! 3% of pixels off by more than 0.1: the view's geometric edges) and in
//! `lights.rs` for colour (8-bit sRGB steps).

use bevy_shadow_fins::{FinExtraction, FinMethod, FinShadowSettings};
use shadow_fins::{
    light::{Light, RectLight},
    oracle::Method,
    scenes::SceneId,
};
use shadow_fins_app::harness::Setup;

use super::{
    common::*,
    coverage::{coverage_oracle, coverage_settings},
};

/// A built-in scene with its disk light replaced by a rectangle of the same
/// area, four times as wide as high: penumbrae of the size the scene was built
/// to show, a different width across each side of the rectangle.
pub(super) fn rect_setup(id: SceneId, settings: FinShadowSettings) -> Setup {
    let mut s = setup(id, settings);
    let Light::Disk(d) = s.light else { unreachable!("the built-in scenes have disk lights") };
    s.light = Light::Rect(RectLight::with_area_of(&d, 4.0).expect("a valid rectangle"));
    s
}

#[test]
fn a_fin_shadowed_rect_light_matches_the_raster_oracle_on_three_scenes() {
    for extraction in [FinExtraction::Gpu, FinExtraction::Cpu] {
        assert_matches_the_oracle("rect", &[SceneId::BoxOverPlane, SceneId::NearContact, SceneId::RingPlate], |id| {
            rect_setup(id, FinShadowSettings { extraction, ..settings() })
        });
    }
}

#[test]
fn the_rectangles_shape_is_in_the_shadow_not_only_its_area() {
    // The same area as a disk and as a 4 : 1 rectangle: if the GPU sized the
    // fins by the bounding circle (or ignored the aperture), the two would
    // cast the same penumbra up to its scale. The oracle of each tells them
    // apart, and the GPU must follow the rectangle's.
    let rect = rect_setup(SceneId::BoxOverPlane, settings());
    let disk = setup(SceneId::BoxOverPlane, settings());
    let shot = render_bevy_lights(&rect);
    let (to_rect, _) = compare(&shot.visibility, &oracle(&rect, Method::MultiLayer));
    let (to_disk, _) = compare(&shot.visibility, &oracle(&disk, Method::MultiLayer));
    println!("rect light's shadow vs its oracle {to_rect:.4}, vs the disk's {to_disk:.4}");
    assert!(to_disk > 2.0 * to_rect && to_disk > 0.005, "rect {to_rect}, disk {to_disk}");
}

#[test]
fn a_rect_light_on_the_coverage_method_matches_its_cpu_model() {
    // The GPU samples the rectangle (the same R2 points as the core), as the
    // coverage oracle does; tolerance as in `coverage.rs` (same rules, f32).
    let setup = rect_setup(SceneId::BoxOverPlane, coverage_settings());
    let shot = render_bevy_lights(&setup);
    save(&shot, "rect_coverage");
    assert_not_trivial(&shot);
    let (mad, far) = compare(&shot.visibility, &coverage_oracle(&setup));
    println!("rect, coverage: mean |gpu − core| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.002 && far <= 0.005, "{mad} / {far}");
}

#[test]
fn a_rect_light_of_size_zero_gives_the_hard_shadow() {
    for method in [FinMethod::MultiLayer, FinMethod::Coverage] {
        let mut setup = rect_setup(SceneId::BoxOverPlane, FinShadowSettings { method, ..coverage_settings() });
        setup.light = setup.light.with_zero_size();
        let shot = render_bevy_lights(&setup);
        assert_not_trivial(&shot);
        assert_eq!(shot.stats.fins, 0, "{method:?}: 0 × 0 must build no fins");
        assert!(shot.visibility.iter().all(|v| *v == 0.0 || *v == 1.0), "{method:?}: 0 × 0 must give only 0 and 1");
        // Each method's own hard shadow: the fins' one-layer slab map, the
        // coverage method's one sample through its depth lists.
        let expected = match method {
            FinMethod::Coverage => coverage_oracle(&setup),
            _ => oracle(&setup, Method::Hard),
        };
        let (mad, far) = compare(&shot.visibility, &expected);
        println!("rect 0 × 0, {method:?}: mean |gpu − hard oracle| = {mad:.5}");
        assert!(mad <= 0.01 && far <= 0.03, "{method:?} hard: {mad} / {far}");
    }
}

#[test]
fn a_fin_shadowed_rect_light_is_bevys_light_times_the_visibility() {
    // As for the spot light (`lights.rs`): per pixel, with tonemapping off,
    // shadowed = dark + V × (lit − dark); `lit` is the same Bevy rectangle
    // with nothing casting (Bevy's own LTC shading, untouched), `dark` the
    // rectangle at zero intensity.
    let mut shadowed = rect_setup(SceneId::BoxOverPlane, settings());
    // Dim enough that nothing clips at white.
    shadowed.intensity = 2.0e4;
    let mut dark = shadowed.clone();
    dark.intensity = 0.0;
    SingleLightComposite::render(&shadowed, &dark, "rect").assert_is_the_light_times_visibility("rect light");
}
