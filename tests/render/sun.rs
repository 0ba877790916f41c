//! The sun: `FinShadows` on a Bevy `DirectionalLight`, sized by its
//! `SunDisk::angular_size`, rendered through orthographic maps.
//!
//! Tolerances as in `oracle_agreement.rs` (mean |GPU − oracle| ≤ 0.01, at most
//! 3% of pixels off by more than 0.1: the view's geometric edges) and in
//! `lights.rs` for colour (8-bit sRGB steps).

use bevy_shadow_fins::{FinExtraction, FinMethod, FinShadowSettings};
use shadow_fins::{ground_truth::GroundTruth, light::Light, oracle::Method, scene::LightSpaceScene, scenes::SceneId};
use shadow_fins_app::harness::{Setup, Shot};

use super::common::*;

/// A built-in scene under a sun from about where its disk light is, tilted a
/// little so that shadows fall sideways, and as soft as the disk seen from the
/// scene's origin (`tan θ = R / |c|`): penumbrae of the size the scene was
/// built to show.
pub(super) fn sun_setup(id: SceneId, settings: FinShadowSettings) -> Setup {
    let mut s = setup(id, settings);
    let Light::Disk(d) = s.light else { unreachable!("the built-in scenes have disk lights") };
    s.light = Light::Sun(shadow_fins_app::render_lab::sun::sun_over(&d, None));
    s
}

/// Maps over the whole scene, as the oracle's (fitted maps are pinned by
/// `fitting_the_suns_maps_to_the_view_brings_it_closer_to_the_truth`).
pub(super) fn unfitted() -> FinShadowSettings {
    FinShadowSettings { fit_sun_to_views: false, ..settings() }
}

#[test]
fn a_fin_shadowed_sun_matches_the_raster_oracle_on_three_scenes() {
    for extraction in [FinExtraction::Gpu, FinExtraction::Cpu] {
        assert_matches_the_oracle("sun", &[SceneId::BoxOverPlane, SceneId::NearContact, SceneId::RingPlate], |id| {
            sun_setup(id, FinShadowSettings { extraction, ..unfitted() })
        });
    }
}

#[test]
fn a_sun_of_angular_size_zero_gives_the_hard_shadow() {
    let mut setup = sun_setup(SceneId::BoxOverPlane, unfitted());
    setup.light = setup.light.with_zero_size();
    let shot = render_bevy_lights(&setup);
    assert_not_trivial(&shot);
    assert_eq!(shot.stats.fins, 0, "θ = 0 must build no fins");
    assert_eq!(shot.stats.layers, 1, "θ = 0 needs one layer: the slab is the exact hard shadow");
    assert!(shot.visibility.iter().all(|v| *v == 0.0 || *v == 1.0), "θ = 0 must give only 0 and 1");
    let (mad, far) = compare(&shot.visibility, &oracle(&setup, Method::Hard));
    assert!(mad <= 0.01 && far <= 0.03, "hard: {mad} / {far}");
}

#[test]
fn a_fin_shadowed_sun_is_bevys_light_times_the_visibility() {
    // As for the spot light (`lights.rs`): per pixel, with tonemapping off,
    // shadowed = dark + V × (lit − dark); `lit` is the same Bevy sun with
    // nothing casting, `dark` the sun at zero illuminance. Bevy's cascades
    // must be off, or the umbra would be darkened twice.
    let mut shadowed = sun_setup(SceneId::BoxOverPlane, settings());
    shadowed.sun_illuminance = 1500.0;
    let mut dark = shadowed.clone();
    dark.sun_illuminance = 0.0;
    let c = SingleLightComposite::render(&shadowed, &dark, "sun");
    assert_not_trivial(&c.shadowed);
    let n = c.errors.len();
    assert!(n > 1000, "only {n} unclipped lit pixels");
    assert!(c.lit_umbra() > 50, "no lit-but-shadowed umbra to check");
    let (mean, p99) = mean_and_p99(c.errors);
    println!("sun composite vs dark + V·(lit − dark): mean {mean:.4}, p99 {p99:.4} over {n} pixels");
    assert!(mean <= 0.005 && p99 <= 0.02, "mean {mean}, p99 {p99}");
}

#[test]
fn fitting_the_suns_maps_to_the_view_brings_it_closer_to_the_truth() {
    // The box over a ground 20 times wider than it: maps over all of the
    // ground give the box's shadow a few texels; fitted to what the camera
    // sees, many more. Judged by the 1024-sample truth.
    let mut setup = sun_setup(SceneId::BoxOverPlane, settings());
    let ground = setup.scene.objects.iter().position(|o| o.name == "ground").expect("a ground");
    let wide = shadow_fins::shapes::plane(200.0, 4);
    setup.scene.objects[ground] = shadow_fins::scene::SceneObject::new("ground", wide, Default::default()).unwrap();
    let mut whole = setup.clone();
    whole.settings.fit_sun_to_views = false;
    let (fitted, whole) = (render_bevy_lights(&setup), render_bevy_lights(&whole));
    save(&fitted, "sun_fitted");
    save(&whole, "sun_whole_scene");
    assert_not_trivial(&fitted);
    let ls = LightSpaceScene::new(&setup.scene, setup.light);
    let truth = GroundTruth::new(&ls, 1024);
    let expected = per_pixel(&setup, &setup.camera, &ls, |r| truth.visibility(r));
    let (fitted_error, _) = compare(&fitted.visibility, &expected);
    let (whole_error, _) = compare(&whole.visibility, &expected);
    println!("sun vs 1024-sample truth: fitted maps {fitted_error:.4}, whole-scene maps {whole_error:.4}");
    assert!(fitted_error < 0.5 * whole_error, "fitted {fitted_error} vs whole scene {whole_error}");
}

#[test]
fn a_sun_on_the_coverage_method_matches_the_ground_truth() {
    // The coverage method counts blockers per light sample: against the
    // ray-traced truth it is off by its sample count's noise only (64
    // samples: about 0.01 mean on the disk's scenes).
    let setup = sun_setup(
        SceneId::NearContact,
        FinShadowSettings { method: FinMethod::Coverage, coverage_samples: 64, ..settings() },
    );
    let shot = render_bevy_lights(&setup);
    assert_not_trivial(&shot);
    let ls = LightSpaceScene::new(&setup.scene, setup.light);
    let truth = GroundTruth::new(&ls, 1024);
    let expected = per_pixel(&setup, &setup.camera, &ls, |r| truth.visibility(r));
    let (mad, far) = compare(&shot.visibility, &expected);
    println!("sun, coverage (64 samples) vs 1024-sample truth: mean {mad:.4}, share > 0.1 = {:.2}%", far * 100.0);
    assert!(mad <= 0.02 && far <= 0.05, "{mad} / {far}");
}

/// The sun over the box and plane, dimmed so that sun and spot together stay
/// below white, and one fin-shadowed spot light beside it.
fn sun_and_spot() -> (Setup, shadow_fins::light::DiskLight) {
    let mut s = sun_setup(SceneId::BoxOverPlane, settings());
    s.sun_illuminance = 800.0;
    s.intensity = 8e4;
    let Light::Disk(d) = setup(SceneId::BoxOverPlane, settings()).light else { unreachable!("a disk light") };
    (s, shadow_fins::light::DiskLight { center: d.center + bevy::math::Vec3::new(1.5, 0.0, 0.5), ..d })
}

#[test]
fn a_sun_and_a_spot_light_each_match_their_shadow_alone_and_add_up() {
    // Visibility: each light's layer next to the other equals its layer
    // alone (float noise, 1e-4). Colour, linear: image(sun + spot) =
    // dark + V_sun·(lit_sun − dark) + V_spot·(lit_spot − dark), which pins the
    // composite's directional slot beside a clustered one.
    let (sun, spot) = sun_and_spot();
    let mut both = sun.clone();
    both.extra_lights = vec![Light::Disk(spot)];
    let mut spot_alone = sun.clone();
    spot_alone.light = Light::Disk(spot);
    spot_alone.spot = true;
    let unshadowed = |mut s: Setup| {
        for o in &mut s.scene.objects {
            o.casts_shadows = false;
        }
        s
    };
    let mut dark = sun.clone();
    dark.sun_illuminance = 0.0;
    let (shot, alone_sun, alone_spot) =
        (render_bevy_lights(&both), render_bevy_lights(&sun), render_bevy_lights(&spot_alone));
    let (lit_sun, lit_spot, dark) = (
        render_bevy_lights(&unshadowed(sun.clone())),
        render_bevy_lights(&unshadowed(spot_alone.clone())),
        render_bevy_lights(&dark),
    );
    assert_eq!(shot.light_visibility.len(), 2);
    // Slot order is entity order: the sun was spawned first, but find it by content.
    let (v_sun, v_spot) = {
        let (a, b) = (&shot.light_visibility[0], &shot.light_visibility[1]);
        if compare(a, &alone_sun.visibility).0 <= compare(b, &alone_sun.visibility).0 { (a, b) } else { (b, a) }
    };
    assert_not_trivial(&alone_sun);
    assert_visibility_not_trivial(&alone_spot.visibility);
    let (mad_sun, _) = compare(v_sun, &alone_sun.visibility);
    let (mad_spot, _) = compare(v_spot, &alone_spot.visibility);
    let (apart, _) = compare(&alone_sun.visibility, &alone_spot.visibility);
    println!("together vs alone: sun {mad_sun:.2e}, spot {mad_spot:.2e}; sun vs spot {apart:.3}");
    assert!(apart > 0.01, "the two lights cast the same shadow ({apart}): the test would prove nothing");
    assert!(mad_sun <= 1e-4 && mad_spot <= 1e-4, "sun {mad_sun}, spot {mad_spot}");

    let lights: [(&[f32], &Shot); 2] = [(v_sun, &lit_sun), (v_spot, &lit_spot)];
    let errors = composite_sum_errors(&shot, &lights, &dark, |v| v < 0.95);
    let n = errors.len();
    assert!(n > 100, "only {n} shadowed pixels");
    let (mean, p99) = mean_and_p99(errors);
    println!("sun + spot vs dark + Σ V·(lit − dark): mean {mean:.4}, p99 {p99:.4} over {n} pixels");
    // Four 8-bit images: ≤ 4 steps of 0.0088 at worst.
    assert!(mean <= 0.005 && p99 <= 0.03, "mean {mean}, p99 {p99}");
}

#[test]
fn a_sun_on_another_render_layer_is_never_taken_away_from_a_view_that_does_not_see_it() {
    // The fin-shadowed sun on render layer 1, seen by a second camera on
    // layer 1; the first camera (layer 0) sees only a plain DirectionalLight
    // from another direction, without shadows. Bevy leaves the sun out of
    // the first view's list, so the composite must find nothing to take
    // away there — not the plain light in the sun's place: the first view's
    // image is the same with the sun at full and at zero illuminance.
    use bevy::prelude::*;
    let mut setup = sun_setup(SceneId::BoxOverPlane, settings());
    setup.sun_illuminance = 1500.0;
    setup.extra_cameras = vec![setup.camera];
    let mut session = shadow_fins_app::harness::Session::new(&setup);
    let world = session.app.world_mut();
    let layer_one = bevy::camera::visibility::RenderLayers::layer(1);
    let sun = world.query_filtered::<Entity, With<DirectionalLight>>().single(world).expect("one sun");
    world.entity_mut(sun).insert(layer_one.clone());
    // The meshes on both layers: drawn by the first camera, and casters for
    // the light, which (like Bevy's shadow maps) takes casters only on a
    // layer it shares.
    let meshes: Vec<Entity> = world.query_filtered::<Entity, With<Mesh3d>>().iter(world).collect();
    for mesh in meshes {
        world.entity_mut(mesh).insert(bevy::camera::visibility::RenderLayers::from_layers(&[0, 1]));
    }
    let second = world.query::<(Entity, &Camera)>().iter(world).find(|(_, c)| c.order == 1).expect("camera").0;
    world.entity_mut(second).insert(layer_one);
    world.spawn((
        DirectionalLight { illuminance: 600.0, ..default() },
        Transform::default().looking_to(Vec3::new(-0.4, -1.0, 0.3), Vec3::Y),
    ));
    let with_sun = session.settle(16).expect("render");
    let world = session.app.world_mut();
    world.get_mut::<DirectionalLight>(sun).expect("the sun").illuminance = 0.0;
    let without_sun = session.settle(16).expect("render");
    let (a, b) = (linear_rgb(&with_sun), linear_rgb(&without_sun));
    let lit = b.iter().filter(|c| c[1] > 0.05).count();
    assert!(lit > 1000, "the plain light lights only {lit} pixels: the test would prove nothing");
    assert_visibility_not_trivial(&with_sun.visibility);
    let worst = (0..a.len()).map(|i| (a[i][1] - b[i][1]).abs()).fold(0.0, f32::max);
    println!("sun on another layer: largest |with sun − without| {worst:.4} on the view that does not see it");
    // One 8-bit step.
    assert!(worst <= 0.01, "the view is changed by a sun it does not see: {worst}");
}

#[test]
fn a_still_or_slightly_moved_camera_keeps_the_suns_frame_and_a_far_move_rebuilds_it() {
    // The fitted window is quantised: frames that change nothing keep the
    // sun's frame (its generation), a camera nudged by a millimetre too; a
    // camera moved across the scene gets new maps where it now looks.
    use bevy::prelude::*;
    let setup = sun_setup(SceneId::BoxOverPlane, settings());
    let mut session = shadow_fins_app::harness::Session::new(&setup);
    session.settle(16).expect("render");
    let generation = |session: &mut shadow_fins_app::harness::Session| {
        let frames = session.app.world().resource::<bevy_shadow_fins::FinFrames>();
        frames.0.first().expect("the sun's frame").data.generation
    };
    let camera = |world: &mut World| world.query_filtered::<Entity, With<Camera3d>>().single(world).expect("camera");
    let before = generation(&mut session);
    for _ in 0..4 {
        session.update();
    }
    assert_eq!(generation(&mut session), before, "nothing moved, yet the sun's frame was rebuilt");
    let world = session.app.world_mut();
    let c = camera(world);
    world.get_mut::<Transform>(c).unwrap().translation.x += 1e-3;
    session.update();
    session.update();
    assert_eq!(generation(&mut session), before, "a 1 mm camera move rebuilt the sun's frame");
    let world = session.app.world_mut();
    world.get_mut::<Transform>(c).unwrap().translation += Vec3::new(-4.0, 0.0, -6.0);
    session.update();
    session.update();
    assert_ne!(generation(&mut session), before, "a camera moved across the scene kept maps fitted to its old view");
}

#[test]
fn cubes_under_a_sun_moved_and_turned_shadow_as_the_cpu_extraction_does() {
    // 100 cubes of one mesh under a sun, rendered by the GPU extraction and
    // by the CPU's: still, after one cube moved sideways (the GPU extracts it
    // alone, `extract_plan.wgsl`'s incremental extraction) and after another
    // turned. Same silhouettes, fins and layers; the same shadow.
    use bevy::prelude::*;
    use shadow_fins_app::{harness::Session, render_lab::scaling::spawn_cubes};
    let run = |extraction: FinExtraction, moves: &dyn Fn(&mut World, &[Entity])| {
        let mut session =
            Session::new(&sun_setup(SceneId::BoxOverPlane, FinShadowSettings { extraction, ..unfitted() }));
        let cubes = spawn_cubes(session.app.world_mut(), 100);
        // Bevy's clustering adds a light a few frames late (`render_bevy_lights`).
        session.settle(16).expect("render");
        moves(session.app.world_mut(), &cubes);
        let shot = session.settle(6).expect("render");
        (shot, fin_stats(&session))
    };
    let still = |_: &mut World, _: &[Entity]| {};
    let nudge = |world: &mut World, cubes: &[Entity]| {
        world.get_mut::<Transform>(cubes[57]).expect("a transform").translation.x += 0.1;
    };
    let turn = |world: &mut World, cubes: &[Entity]| {
        world.get_mut::<Transform>(cubes[12]).expect("a transform").rotate_y(0.6);
    };
    let cases: [(&str, &dyn Fn(&mut World, &[Entity])); 3] =
        [("still", &still), ("a cube nudged", &nudge), ("a cube turned", &turn)];
    for (what, moves) in cases {
        let (gpu, g) = run(FinExtraction::Gpu, moves);
        let (cpu, c) = run(FinExtraction::Cpu, moves);
        let (mad, far) = compare(&gpu.visibility, &cpu.visibility);
        println!(
            "{what}: extracted alone {}; GPU {} silhouettes, {} fins, {} layers; CPU {}, {}, {}; mean |gpu − cpu| {mad:.5}, share > 0.1 {:.2}%",
            g.incremental_extraction,
            g.silhouettes,
            g.fins,
            g.layers,
            c.silhouettes,
            c.fins,
            c.layers,
            far * 100.0
        );
        assert_not_trivial(&gpu);
        if what == "a cube nudged" {
            assert!(g.incremental_extraction, "a cube nudged under a sun was not extracted alone");
        }
        assert_eq!((g.silhouettes, g.fins, g.layers), (c.silhouettes, c.fins, c.layers), "{what}");
        assert!(mad <= 0.002 && far <= 0.005, "{what}: the GPU's shadow differs from the CPU's ({mad}, {far})");
    }
}
