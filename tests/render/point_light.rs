//! Bevy's `PointLight` with fin shadows: a sphere of the light's radius,
//! modelled by six cube-face frames (`shadow_fins::light`), each with
//! its own extraction and maps, whose visibility passes fill the light's one
//! layer between them; the compositing pass takes `(1 − V)` of Bevy's own
//! `lighting::point_light` away.
//!
//! Tolerances as in `oracle_agreement.rs` (mean |GPU − oracle| ≤ 0.01, at
//! most 3% of pixels off by more than 0.1) and `coverage.rs` (≤ 0.002 mean
//! against the coverage method's CPU model), colour as in `lights.rs`.

use bevy::prelude::*;
use bevy_shadow_fins::{FinExtraction, FinMethod, FinShadowSettings, FinShadows};
use shadow_fins::{
    light::{Light, SphereLight},
    oracle::Method,
    scene::LightSpaceScene,
    scenes::SceneId,
};
use shadow_fins_app::harness::{Session, Setup};

use super::{
    common::*,
    coverage::{coverage_oracle, coverage_settings},
};

/// A built-in scene lit by a sphere: the lamp room's own, or for the others
/// a sphere of their disk's radius at the disk's centre.
pub(super) fn point_setup(id: SceneId, settings: FinShadowSettings) -> Setup {
    let mut s = setup(id, settings);
    if let Light::Disk(d) = s.light {
        s.light = Light::Sphere(SphereLight::new(d.center, d.radius).expect("a valid sphere"));
    }
    s
}

/// How many of the view's receivers each cube face shades.
fn faces_used(setup: &Setup) -> [usize; 6] {
    let faces = LightSpaceScene::faces(&setup.scene, setup.light);
    let mut used = [0; 6];
    // Background pixels are 1: faces come back as 10 + their index.
    for face in per_pixel_in_faces(setup, &setup.camera, &faces, |face, _| 10.0 + face as f32) {
        if face >= 10.0 {
            used[face as usize - 10] += 1;
        }
    }
    used
}

#[test]
fn a_fin_shadowed_point_light_matches_the_raster_oracle_on_three_scenes() {
    // The lamp room's shadows fall on the floor and two walls, across four faces.
    let used = faces_used(&point_setup(SceneId::LampRoom, settings()));
    assert!(used.iter().filter(|n| **n > 100).count() >= 3, "faces the lamp room's view uses: {used:?}");
    for extraction in [FinExtraction::Gpu, FinExtraction::Cpu] {
        assert_matches_the_oracle("point", &[SceneId::LampRoom, SceneId::BoxOverPlane, SceneId::NearContact], |id| {
            point_setup(id, FinShadowSettings { extraction, ..settings() })
        });
    }
}

#[test]
fn a_point_light_on_the_coverage_method_matches_its_cpu_model() {
    let setup = point_setup(SceneId::LampRoom, coverage_settings());
    let shot = render_bevy_lights(&setup);
    save(&shot, "point_coverage");
    assert_not_trivial(&shot);
    let (mad, far) = compare(&shot.visibility, &coverage_oracle(&setup));
    println!("point, coverage: mean |gpu − core| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.002 && far <= 0.005, "{mad} / {far}");
}

#[test]
fn a_point_light_of_radius_zero_gives_the_hard_shadow() {
    for method in [FinMethod::MultiLayer, FinMethod::Coverage] {
        let mut setup = point_setup(SceneId::LampRoom, FinShadowSettings { method, ..coverage_settings() });
        setup.light = setup.light.with_zero_size();
        let shot = render_bevy_lights(&setup);
        assert_not_trivial(&shot);
        assert_eq!(shot.stats.fins, 0, "{method:?}: radius 0 must build no fins");
        assert!(shot.visibility.iter().all(|v| *v == 0.0 || *v == 1.0), "{method:?}: radius 0 must give only 0 and 1");
        let expected = match method {
            FinMethod::Coverage => coverage_oracle(&setup),
            _ => oracle(&setup, Method::Hard),
        };
        let (mad, far) = compare(&shot.visibility, &expected);
        println!("point radius 0, {method:?}: mean |gpu − hard oracle| = {mad:.5}");
        assert!(mad <= 0.01 && far <= 0.03, "{method:?} hard: {mad} / {far}");
    }
}

#[test]
fn a_fin_shadowed_point_light_is_bevys_light_times_the_visibility() {
    // As for the spot light (`lights.rs`): with tonemapping off, per pixel
    // shadowed = dark + V × (lit − dark); `lit` is the same Bevy point light
    // with nothing casting (Bevy's own shading, its shadow map off), `dark`
    // the light at zero. Bevy's cube map must be off: it would darken the
    // inner penumbra a second time.
    let mut shadowed = point_setup(SceneId::BoxOverPlane, settings());
    shadowed.intensity = 2.0e5;
    let mut dark = shadowed.clone();
    dark.intensity = 0.0;
    SingleLightComposite::render(&shadowed, &dark, "point").assert_is_the_light_times_visibility("point light");
}

#[test]
fn removing_fin_shadows_gives_the_point_light_its_bevy_cube_map_back() {
    let setup = point_setup(SceneId::BoxOverPlane, settings());
    let mut session = Session::new(&setup);
    let fin = session.settle(16).expect("render");
    let world = session.app.world_mut();
    let light = world.query_filtered::<Entity, With<PointLight>>().single(world).expect("one point light");
    assert!(world.get::<PointLight>(light).unwrap().shadow_maps_enabled, "the user's setting is left alone");
    world.entity_mut(light).remove::<FinShadows>();
    let bevy = session.settle(16).expect("render");
    let (fc, bc) = (linear_rgb(&fin), linear_rgb(&bevy));
    let umbra: Vec<usize> = (0..fc.len()).filter(|&i| fin.visibility[i] < 0.02).collect();
    assert!(umbra.len() > 50, "no umbra");
    let umbra_gap = umbra.iter().map(|&i| (fc[i][1] - bc[i][1]).abs()).sum::<f32>() / umbra.len() as f32;
    println!("umbra: mean |fins − Bevy's cube map| {umbra_gap:.4}");
    assert!(umbra_gap <= 0.01, "Bevy's cube map is not back: umbra differs by {umbra_gap}");
}

#[test]
fn point_spot_and_rect_lights_at_once_each_match_their_shadow_alone() {
    // Three kinds in one view, each light's layer read back: a point light's
    // six frames must fill its own layer, not its neighbours'.
    let base = point_setup(SceneId::BoxOverPlane, settings());
    let Light::Sphere(sphere) = base.light else { unreachable!("a sphere") };
    let spot = shadow_fins::light::DiskLight::new(sphere.center + Vec3::new(1.5, 0.0, 0.5), Vec3::NEG_Y, 0.4)
        .expect("a valid disk");
    let rect =
        shadow_fins::light::RectLight::new(sphere.center + Vec3::new(-1.2, -0.5, -0.8), Vec3::NEG_Y, Vec3::X, 1.2, 0.3)
            .expect("a valid rectangle");
    let mut all = base.clone();
    all.spot = true;
    all.extra_lights = vec![Light::Disk(spot), Light::Rect(rect)];
    let shot = render_bevy_lights(&all);
    assert_eq!(shot.light_visibility.len(), 3);
    let lights = [base.light, Light::Disk(spot), Light::Rect(rect)];
    let mut apart = Vec::new();
    for (k, light) in lights.iter().enumerate() {
        let mut alone = base.clone();
        alone.spot = true;
        alone.light = *light;
        let single = render_bevy_lights(&alone);
        assert_visibility_not_trivial(&single.visibility);
        let (mad, _) = compare(&shot.light_visibility[k], &single.visibility);
        println!("light {k} together vs alone: {mad:.2e}");
        assert!(mad <= 1e-4, "light {k}: {mad}");
        apart.push(single.visibility);
    }
    let (differ, _) = compare(&apart[0], &apart[1]);
    assert!(differ > 0.01, "the lights cast the same shadow ({differ}): the test would prove nothing");
}
