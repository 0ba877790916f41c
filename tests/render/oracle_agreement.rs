//! The GPU's visibility buffer against the raster oracle at the same map
//! resolution.
//!
//! Tolerance: mean absolute difference ≤ 0.01 over the image. What may differ:
//! fin weights are quantised on the GPU (15 bits: ≤ 1.5e-5; depths are exact
//! f32), and pixels on geometric edges of the camera view, where the GPU's
//! rasterised depth and the oracle's ray hit may land on different surfaces; a
//! 96×72 view has a few dozen such pixels, each off by up to 1, which is why
//! the share of pixels off by more than 0.1 is bounded separately (≤ 3%).

use shadow_fins::{oracle::Method, scenes::SceneId};

use super::common::*;

#[test]
fn visibility_matches_the_raster_oracle_on_three_scenes() {
    for id in [SceneId::BoxOverPlane, SceneId::NearContact, SceneId::RingPlate] {
        let setup = setup(id, settings());
        let shot = render(&setup);
        assert_not_trivial(&shot);
        let expected = oracle(&setup, Method::MultiLayer);
        let (mad, far) = compare(&shot.visibility, &expected);
        println!("{}: mean |gpu − oracle| = {mad:.5}, share > 0.1 = {:.2}%", id.name(), far * 100.0);
        assert!(mad <= 0.01, "{}: mean difference {mad}", id.name());
        assert!(far <= 0.03, "{}: {far} of pixels differ by more than 0.1", id.name());
    }
}

#[test]
fn radius_zero_gives_the_hard_shadow() {
    let mut setup = setup(SceneId::BoxOverPlane, settings());
    setup.light = setup.light.with_zero_size();
    let shot = render(&setup);
    assert_not_trivial(&shot);
    assert!(shot.stats.fins == 0, "radius 0 must build no fins");
    assert_eq!(shot.stats.layers, 1, "radius 0 needs one layer: the slab is the exact hard shadow");
    let (mad, far) = compare(&shot.visibility, &oracle(&setup, Method::Hard));
    assert!(mad <= 0.01 && far <= 0.03, "hard: {mad} / {far}");
    assert!(shot.visibility.iter().all(|v| *v == 0.0 || *v == 1.0), "radius 0 must give only 0 and 1");
}

#[test]
fn no_caster_means_lit_everywhere() {
    let mut setup = setup(SceneId::BoxOverPlane, settings());
    for o in &mut setup.scene.objects {
        o.casts_shadows = false;
    }
    let shot = render(&setup);
    assert!(shot.visibility.iter().all(|v| *v == 1.0), "nothing casts, so everything is lit");
    assert_eq!((shot.stats.casters, shot.stats.fins, shot.stats.layers), (0, 0, 0), "no caster: no fin, no layer");
}

/// A camera drawing into part of its target (`Camera::viewport`, split
/// screen) reads the prepass and writes its visibility at target pixels: the
/// right half of the target must hold what the oracle sees through a camera
/// with that half's aspect, and the left half (not drawn) stays lit.
#[test]
fn a_camera_viewport_gets_its_shadows_at_its_own_pixels() {
    use bevy::math::UVec2;
    let mut setup = setup(SceneId::BoxOverPlane, settings());
    let half = WIDTH / 2;
    setup.viewport = Some((UVec2::new(half, 0), UVec2::new(half, HEIGHT)));
    let shot = render(&setup);
    let right: Vec<f32> = (0..HEIGHT)
        .flat_map(|y| (half..WIDTH).map(move |x| (x, y)))
        .map(|(x, y)| shot.visibility[(y * WIDTH + x) as usize])
        .collect();
    assert_visibility_not_trivial(&right);
    let mut narrow = setup.clone();
    (narrow.width, narrow.viewport) = (half, None);
    let (mad, far) = compare(&right, &oracle(&narrow, Method::MultiLayer));
    println!("viewport: mean |gpu − oracle| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.01 && far <= 0.03, "viewport: {mad} / {far}");
}
