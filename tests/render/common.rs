//! Shared helpers: scenes, the oracle's visibility per pixel, comparisons.

use bevy_shadow_fins::FinShadowSettings;
use shadow_fins::{
    bvh::Bvh,
    camera::pixel_receiver,
    oracle::{FinShadowModel, Method},
    scene::LightSpaceScene,
    scenes::SceneId,
};
use shadow_fins_app::harness::{Setup, Shot};

/// sRGB byte → linear.
pub fn linear(byte: u8) -> f32 {
    let c = byte as f32 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

pub const WIDTH: u32 = 96;
pub const HEIGHT: u32 = 72;
pub const MAP: u32 = 256;

pub fn setup(id: SceneId, settings: FinShadowSettings) -> Setup {
    let s = id.build();
    Setup::new(s.scene, s.light, s.camera, settings, (WIDTH, HEIGHT))
}

pub fn settings() -> FinShadowSettings {
    FinShadowSettings { map_resolution: MAP, ..Default::default() }
}

/// The raster oracle's visibility at every pixel's receiver (1 for background).
pub fn oracle(setup: &Setup, method: Method) -> Vec<f32> {
    oracle_for(setup, &setup.camera, method)
}

/// [`oracle`] seen from another camera.
pub fn oracle_for(setup: &Setup, camera: &shadow_fins::camera::Camera, method: Method) -> Vec<f32> {
    let ls = LightSpaceScene::new(&setup.scene, setup.light);
    let model = FinShadowModel::new(&setup.scene, &ls, method, setup.settings.core());
    let maps = model.raster(setup.settings.clamped().map_resolution);
    per_pixel(setup, camera, &ls, |r| maps.visibility(r))
}

/// `visibility` at every pixel's receiver seen from `camera` (1 for background).
pub fn per_pixel(
    setup: &Setup,
    camera: &shadow_fins::camera::Camera,
    ls: &LightSpaceScene,
    visibility: impl Fn(shadow_fins::oracle::Receiver) -> f32,
) -> Vec<f32> {
    let bvh = Bvh::new(&ls.casters);
    (0..setup.width * setup.height)
        .map(|i| {
            let pixel = (i % setup.width, i / setup.width, setup.width, setup.height);
            pixel_receiver(camera, pixel, ls, &bvh).map_or(1.0, &visibility)
        })
        .collect()
}

/// Mean absolute difference and the share of pixels off by more than 0.1.
pub fn compare(visibility: &[f32], oracle: &[f32]) -> (f32, f32) {
    let n = oracle.len() as f32;
    let mad = visibility.iter().zip(oracle).map(|(a, b)| (a - b).abs()).sum::<f32>() / n;
    let far = visibility.iter().zip(oracle).filter(|(a, b)| (*a - *b).abs() > 0.1).count() as f32 / n;
    (mad, far)
}

/// Mean and 99th percentile of per-pixel errors (at least one).
pub fn mean_and_p99(mut errors: Vec<f32>) -> (f32, f32) {
    assert!(!errors.is_empty(), "no pixel to compare");
    errors.sort_by(f32::total_cmp);
    let mean = errors.iter().sum::<f32>() / errors.len() as f32;
    (mean, errors[errors.len() * 99 / 100])
}

/// Linear RGB of every pixel of a shot's sRGB colour.
pub fn linear_rgb(shot: &Shot) -> Vec<[f32; 3]> {
    shot.color.iter().map(|p| [linear(p[0]), linear(p[1]), linear(p[2])]).collect()
}

/// Writes a test's image to `<target>/tmp/test-images/` when `SHADOW_FINS_TEST_IMAGES` is set.
pub fn save(shot: &Shot, name: &str) {
    if std::env::var_os("SHADOW_FINS_TEST_IMAGES").is_some() {
        shot.save_color(&format!("{}/test-images/{name}.png", env!("CARGO_TARGET_TMPDIR"))).expect("write test image");
    }
}

pub fn render(setup: &Setup) -> Shot {
    shadow_fins_app::harness::render(setup, 6).expect("headless render")
}

/// [`render`] for tests of Bevy's own lights: at least 16 frames, since
/// Bevy's clustering adds lights a few frames late (later the more lights
/// and the busier the machine; seen as frames without a light on lavapipe),
/// and a stable image before that is not the settled one.
pub fn render_bevy_lights(setup: &Setup) -> Shot {
    shadow_fins_app::harness::render(setup, 16).expect("headless render")
}

/// A shot must show both shadow and light: a test that passes on a black (or
/// white) image is a bug.
pub fn assert_not_trivial(shot: &Shot) {
    assert_visibility_not_trivial(&shot.visibility);
}

/// [`assert_not_trivial`] for one visibility buffer.
pub fn assert_visibility_not_trivial(visibility: &[f32]) {
    let dark = visibility.iter().filter(|v| **v < 0.05).count();
    let lit = visibility.iter().filter(|v| **v > 0.95).count();
    assert!(dark > 50 && lit > 50, "visibility buffer is trivial: {dark} dark, {lit} lit pixels");
}

/// Per pixel (linear green): |image − (dark + Σ_k V_k·(lit_k − dark))|, the
/// composite of several fin-shadowed lights against each light's own shadowed
/// contribution, with `lights` = (V_k, the image of light k alone over casters
/// that do not cast). Over the pixels where nothing clips at white and some
/// light's V passes `counted`.
pub fn composite_sum_errors(
    image: &Shot,
    lights: &[(&[f32], &Shot)],
    dark: &Shot,
    counted: impl Fn(f32) -> bool,
) -> Vec<f32> {
    let (ic, dc) = (linear_rgb(image), linear_rgb(dark));
    let lit: Vec<Vec<[f32; 3]>> = lights.iter().map(|(_, shot)| linear_rgb(shot)).collect();
    (0..ic.len())
        .filter(|&i| lit.iter().map(|l| l[i][1] - dc[i][1]).sum::<f32>() + dc[i][1] < 0.95 && ic[i][1] < 0.95)
        .filter(|&i| lights.iter().any(|(v, _)| counted(v[i])))
        .map(|i| {
            let expected =
                dc[i][1] + lights.iter().zip(&lit).map(|((v, _), l)| v[i] * (l[i][1] - dc[i][1])).sum::<f32>();
            (ic[i][1] - expected).abs()
        })
        .collect()
}
