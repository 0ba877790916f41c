//! Bevy's own lights with fin shadows (`FinShadows` on a `SpotLight`), and
//! several fin-shadowed lights at once.
//!
//! Tolerances: colour as in `compositing.rs` (8-bit sRGB steps, ≤ 0.0088
//! linear each); a light's visibility next to other lights must be the one it
//! has alone up to float noise (1e-4: the passes are the same, the maps the
//! same size), and within the oracle bound of `oracle_agreement.rs` (0.01).

use bevy::prelude::*;
use bevy_shadow_fins::{FinShadowStats, FinShadows};
use shadow_fins::{
    light::{DiskLight, Light},
    oracle::Method,
    scenes::SceneId,
};
use shadow_fins_app::harness::{Session, Setup, Shot};

use super::common::*;

/// The box over the plane lit by a fin-shadowed Bevy spot light.
fn spot_setup() -> Setup {
    let mut s = setup(SceneId::BoxOverPlane, settings());
    s.spot = true;
    // Dim enough that nothing clips at white.
    s.intensity = 1.5e5;
    s
}

fn disk(setup: &Setup) -> DiskLight {
    match setup.light {
        Light::Disk(d) => d,
        Light::Sun(_) | Light::Rect(_) | Light::Sphere(_) => unreachable!("the built-in scenes have disk lights"),
    }
}

/// The setup with its light moved by `offset` (same size and direction).
fn moved(setup: &Setup, offset: Vec3) -> DiskLight {
    DiskLight { center: disk(setup).center + offset, ..disk(setup) }
}

#[test]
fn a_fin_shadowed_spot_light_is_bevys_light_times_the_visibility() {
    // Tonemapping off: per pixel shadowed = dark + V × (lit − dark), where
    // `lit` is the same Bevy spot light with nothing casting (V = 1: Bevy's
    // own shading, untouched) and `dark` the scene with the light at zero.
    // Bevy's own shadow map must be off: it would darken the inner penumbra
    // a second time.
    let shadowed = spot_setup();
    let mut dark = shadowed.clone();
    dark.intensity = 0.0;
    let c = SingleLightComposite::render(&shadowed, &dark, "spot");
    assert_not_trivial(&c.shadowed);
    assert!(c.lit.visibility.iter().all(|v| *v == 1.0), "nothing casts, yet V < 1 somewhere");
    let lit_pixels = c.gain.iter().filter(|g| **g > 0.05).count();
    assert!(lit_pixels > 1000, "the spot light lights only {lit_pixels} pixels");
    let penumbra = c.shadowed.visibility.iter().filter(|v| (0.05..0.95).contains(*v)).count();
    assert!(penumbra > 100, "only {penumbra} penumbra pixels");
    let n = c.errors.len();
    assert!(n > 1000, "only {n} unclipped lit pixels");
    let (mean, p99) = mean_and_p99(c.errors);
    println!("spot composite vs dark + V·(lit − dark): mean {mean:.4}, p99 {p99:.4} over {n} pixels");
    assert!(mean <= 0.005 && p99 <= 0.02, "mean {mean}, p99 {p99}");
}

#[test]
fn removing_fin_shadows_gives_the_light_its_bevy_shadow_map_back() {
    // Bevy's shadow map is turned off in the render world only (the user's
    // `shadow_maps_enabled: true` stays); without `FinShadows` Bevy extracts
    // the light again and its hard shadow map darkens the umbra.
    let setup = spot_setup();
    let mut session = Session::new(&setup);
    let fin = session.settle(16).expect("render");
    let world = session.app.world_mut();
    let spot = world.query_filtered::<Entity, With<SpotLight>>().single(world).expect("one spot light");
    assert!(world.get::<SpotLight>(spot).unwrap().shadow_maps_enabled, "the user's setting is left alone");
    world.entity_mut(spot).remove::<FinShadows>();
    let bevy = session.settle(16).expect("render");
    assert_eq!(session.app.world().resource::<FinShadowStats>().0, Default::default());
    let (fc, bc) = (linear_rgb(&fin), linear_rgb(&bevy));
    // In the fins' umbra Bevy's hard shadow is as dark: without its map back
    // the light would shine there unshadowed.
    let umbra: Vec<usize> = (0..fc.len()).filter(|&i| fin.visibility[i] < 0.02).collect();
    assert!(umbra.len() > 50, "no umbra");
    let umbra_gap = umbra.iter().map(|&i| (fc[i][1] - bc[i][1]).abs()).sum::<f32>() / umbra.len() as f32;
    println!("umbra: mean |fins − Bevy's shadow map| {umbra_gap:.4}");
    assert!(umbra_gap <= 0.01, "Bevy's shadow map is not back: umbra differs by {umbra_gap}");
}

#[test]
fn two_spot_lights_each_match_their_shadow_alone() {
    let a = spot_setup();
    let b = moved(&a, Vec3::new(1.5, 0.0, 0.5));
    let mut both = a.clone();
    both.extra_lights = vec![Light::Disk(b)];
    let mut b_alone = a.clone();
    b_alone.light = Light::Disk(b);
    let (shot, alone_a, alone_b) = (render_bevy_lights(&both), render_bevy_lights(&a), render_bevy_lights(&b_alone));
    // Slot order is entity order, not spawn order: read each light's own layer.
    let (together_a, together_b) = (&shot.light_visibility[0], &shot.light_visibility[1]);
    assert_not_trivial(&alone_a);
    assert_visibility_not_trivial(&alone_b.visibility);
    let (mad_a, _) = compare(together_a, &alone_a.visibility);
    let (mad_b, _) = compare(together_b, &alone_b.visibility);
    let (apart, _) = compare(&alone_a.visibility, &alone_b.visibility);
    println!("together vs alone: A {mad_a:.2e}, B {mad_b:.2e}; A vs B {apart:.3}");
    assert!(apart > 0.01, "the two lights cast the same shadow ({apart}): the test would prove nothing");
    assert!(mad_a <= 1e-4 && mad_b <= 1e-4, "A {mad_a}, B {mad_b}");
}

#[test]
fn eight_spot_lights_each_match_the_oracle() {
    let base = spot_setup();
    let offsets: Vec<Vec3> = (0..8)
        .map(|k| {
            let a = k as f32 * std::f32::consts::TAU / 8.0;
            Vec3::new(a.cos(), 0.0, a.sin()) * 1.2
        })
        .collect();
    let mut all = base.clone();
    all.extra_lights = offsets.iter().map(|o| Light::Disk(moved(&base, *o))).collect();
    let shot = render_bevy_lights(&all);
    assert_eq!(shot.light_visibility.len(), 9, "the setup's light and eight more");
    let mut worst: f32 = 0.0;
    for (k, light) in all.extra_lights.iter().enumerate() {
        let mut alone = base.clone();
        alone.light = *light;
        let expected = oracle(&alone, Method::MultiLayer);
        let (mad, far) = compare(&shot.light_visibility[k + 1], &expected);
        assert_visibility_not_trivial(&shot.light_visibility[k + 1]);
        println!("light {k}: mean |GPU − oracle| {mad:.2e}, {:.1}% off by > 0.1", far * 100.0);
        assert!(mad <= 0.01 && far <= 0.03, "light {k}: {mad} / {far}");
        worst = worst.max(mad);
    }
    println!("worst of eight lights: {worst:.2e}");
}

#[test]
fn lights_past_the_budget_degrade_with_the_reason_in_their_stats() {
    // Four lights share 8 MiB of maps (2 MiB each, under one 256² layer of
    // 2.25 MiB): every light's maps shrink, each says why, nothing fails.
    let base = spot_setup();
    let mut setup = base.clone();
    setup.extra_lights = (1..4).map(|k| Light::Disk(moved(&base, Vec3::new(k as f32 * 0.5, 0.0, 0.0)))).collect();
    let mut session = Session::new(&setup);
    session.app.world_mut().insert_resource(bevy_shadow_fins::FinShadowBudget { map_bytes: 8 << 20, ..default() });
    let shot = session.settle(16).expect("render");
    let world = session.app.world_mut();
    let stats: Vec<_> = world.query::<&bevy_shadow_fins::FinLightStats>().iter(world).map(|s| s.0).collect();
    assert_eq!(stats.len(), 4);
    for s in &stats {
        println!("{:?} at {}²: {}", s.layers, s.map_resolution, s.degraded);
        let Some(bevy_shadow_fins::FinDegradation::Maps { resolution, layers, limit_bytes, .. }) = s.degraded.first()
        else {
            panic!("no degradation reason: {s:?}");
        };
        assert_eq!(limit_bytes, 2 << 20, "the reason names the light's share");
        // Sparse maps (`map_tiles`): a header and a page word per 8×8 tile
        // per layer, then whole tiles of 64 texels × 36 B, never more than
        // every tile.
        let all_tiles = layers as u64 * (resolution as u64).div_ceil(8).pow(2);
        let pool = s.gpu_bytes.checked_sub((4 + all_tiles) * 4).expect("the page table is allocated");
        assert_eq!(pool % (64 * 36), 0, "the pool holds whole tiles: {} bytes", s.gpu_bytes);
        assert!(pool / (64 * 36) <= all_tiles, "no more tiles than {layers} layers at {resolution}² have");
        assert!(s.gpu_bytes <= 2 << 20, "{} bytes exceed the light's share", s.gpu_bytes);
    }
    for v in &shot.light_visibility {
        assert_visibility_not_trivial(v);
        assert!(v.iter().all(|v| (0.0..=1.0).contains(v)));
    }
}

#[test]
fn two_lights_composite_to_the_sum_of_their_shadowed_contributions() {
    // Linear output: image(A + B) = dark + V_A·(lit_A − dark) + V_B·(lit_B − dark),
    // with lit_X the light X alone over casters that do not cast. This pins the
    // composite's slot ≥ 1 (its Bevy light index and its visibility layer).
    let a = spot_setup();
    let b = moved(&a, Vec3::new(1.5, 0.0, 0.5));
    let mut both = a.clone();
    both.extra_lights = vec![Light::Disk(b)];
    let unshadowed = |light: DiskLight| {
        let mut s = a.clone();
        s.light = Light::Disk(light);
        for o in &mut s.scene.objects {
            o.casts_shadows = false;
        }
        s
    };
    let mut dark = a.clone();
    dark.intensity = 0.0;
    let (shot, lit_a, lit_b, dark) = (
        render_bevy_lights(&both),
        render_bevy_lights(&unshadowed(disk(&a))),
        render_bevy_lights(&unshadowed(b)),
        render_bevy_lights(&dark),
    );
    let (va, vb) = (&shot.light_visibility[0], &shot.light_visibility[1]);
    let lights: [(&[f32], &Shot); 2] = [(va, &lit_a), (vb, &lit_b)];
    let errors = composite_sum_errors(&shot, &lights, &dark, |v| (0.05..0.95).contains(&v));
    let n = errors.len();
    assert!(n > 100, "only {n} penumbra pixels");
    let (mean, p99) = mean_and_p99(errors);
    println!("two lights vs dark + Σ V·(lit − dark): mean {mean:.4}, p99 {p99:.4} over {n} pixels");
    // Four 8-bit images: ≤ 4 steps of 0.0088 at worst.
    assert!(mean <= 0.005 && p99 <= 0.03, "mean {mean}, p99 {p99}");
}

#[test]
fn a_light_on_another_render_layer_is_shadowed_where_bevy_lights_it_and_never_taken_away_elsewhere() {
    // A fin-shadowed spot light on render layer 1, seen by a second camera on
    // layer 1 (so Bevy extracts it), the first camera on layer 0. Whether
    // Bevy lights the first view with it depends on its clustering (CPU
    // clustering checks layers, 0.19's GPU clustering does not); either way
    // the first view's umbra must be the dark image (shadowed if lit, not lit
    // at all otherwise) and no pixel may be darker than the dark image
    // (taking away light Bevy never added).
    let mut setup = spot_setup();
    setup.extra_cameras = vec![setup.camera];
    let mut session = Session::new(&setup);
    let world = session.app.world_mut();
    let layer_one = bevy::camera::visibility::RenderLayers::layer(1);
    let spot = world.query_filtered::<Entity, With<SpotLight>>().single(world).expect("one spot light");
    world.entity_mut(spot).insert(layer_one.clone());
    // The meshes on both layers: drawn by the first camera, and casters for
    // the light, which (like Bevy's shadow maps) takes casters only on a
    // layer it shares.
    let meshes: Vec<Entity> = world.query_filtered::<Entity, With<Mesh3d>>().iter(world).collect();
    for mesh in meshes {
        world.entity_mut(mesh).insert(bevy::camera::visibility::RenderLayers::from_layers(&[0, 1]));
    }
    let second = world.query::<(Entity, &Camera)>().iter(world).find(|(_, c)| c.order == 1).expect("second camera").0;
    world.entity_mut(second).insert(layer_one);
    let hidden = session.settle(16).expect("render");
    let mut dark = setup.clone();
    dark.intensity = 0.0;
    let dark = render_bevy_lights(&dark);
    assert_not_trivial(&hidden);
    let (hc, dc) = (linear_rgb(&hidden), linear_rgb(&dark));
    let umbra: Vec<usize> = (0..hc.len()).filter(|&i| hidden.visibility[i] < 0.02).collect();
    assert!(umbra.len() > 50, "no umbra");
    let gap = umbra.iter().map(|&i| (hc[i][1] - dc[i][1]).abs()).sum::<f32>() / umbra.len() as f32;
    let below = (0..hc.len()).map(|i| dc[i][1] - hc[i][1]).fold(0.0, f32::max);
    println!("light on another layer: umbra vs dark {gap:.4}, darkest below dark {below:.4}");
    assert!(gap <= 0.005, "the umbra is lit: {gap}");
    assert!(below <= 0.02, "light Bevy never added was taken away: {below}");
}

#[test]
fn receivers_fin_shadows_cannot_reach_are_counted() {
    let setup = spot_setup();
    let mut session = Session::new(&setup);
    let world = session.app.world_mut();
    let mut material = |m: StandardMaterial| world.resource_mut::<Assets<StandardMaterial>>().add(m);
    let forward =
        material(StandardMaterial { opaque_render_method: bevy::material::OpaqueRendererMethod::Forward, ..default() });
    let blended = material(StandardMaterial { alpha_mode: AlphaMode::Blend, ..default() });
    let cube = world.resource_mut::<Assets<Mesh>>().add(Cuboid::new(0.2, 0.2, 0.2));
    for (m, x) in [(forward.clone(), -1.5), (blended, 1.5)] {
        world.spawn((Mesh3d(cube.clone()), MeshMaterial3d(m), Transform::from_xyz(x, 0.1, 1.5)));
    }
    // Not counted, since they receive no shadow either way (they would keep
    // Bevy's maps on for nothing): unlit, opted out, hidden.
    let unlit = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial {
        unlit: true,
        opaque_render_method: bevy::material::OpaqueRendererMethod::Forward,
        ..default()
    });
    let at = Transform::from_xyz(0.0, 0.1, 2.5);
    world.spawn((Mesh3d(cube.clone()), MeshMaterial3d(unlit), at));
    world.spawn((Mesh3d(cube.clone()), MeshMaterial3d(forward.clone()), at, bevy::light::NotShadowReceiver));
    world.spawn((Mesh3d(cube.clone()), MeshMaterial3d(forward), at, Visibility::Hidden));
    session.settle(16).expect("render");
    let counted = *session.app.world().resource::<bevy_shadow_fins::FinReceivers>();
    assert_eq!(counted, bevy_shadow_fins::FinReceivers { forward: 1, blended: 1 });
    // The forward hook reaches the forward cube; the blended one (drawn over
    // the surface the visibility pass shaded) keeps Bevy's maps on for it.
    assert!(session.app.world().resource::<bevy_shadow_fins::FinForwardShading>().0, "lavapipe binds 8 groups");
    assert_eq!(session.app.world().resource::<bevy_shadow_fins::BevyShadowMapsKept>().unreached_receivers, 1);
}
