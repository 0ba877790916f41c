//! Settings changed at runtime take effect the next frames, with no restart.

use bevy::prelude::*;
use bevy_shadow_fins::{FinLight, FinShadowSettings};
use shadow_fins::{oracle::Method, scenes::SceneId};
use shadow_fins_app::harness;

use super::common::*;

fn run(app: &mut App, slot: &harness::Slot, frames: u32) -> Vec<f32> {
    for _ in 0..frames {
        app.update();
    }
    // GPU extraction: wait for its counts of this frame (and a redo if it
    // outgrew a buffer), then for the read-back of an image rendered after it.
    for _ in 0..60 {
        if app.world().resource::<bevy_shadow_fins::FinShadowStats>().0.up_to_date {
            break;
        }
        app.update();
    }
    for _ in 0..2 {
        app.update();
    }
    let data = slot.lock().unwrap().take().expect("read-back");
    harness::unpad(WIDTH, HEIGHT, &data).map(f32::from_le_bytes).collect()
}

/// `setup` with the box of `SceneId::BoxOverPlane` moved by `offset`.
fn with_box_moved(setup: &harness::Setup, offset: Vec3) -> harness::Setup {
    with_moved(setup, "box", offset)
}

/// The box of `SceneId::BoxOverPlane`: the mesh above the ground.
fn the_box(world: &mut World) -> Entity {
    let mut meshes = world.query::<(Entity, &Mesh3d, &GlobalTransform)>();
    meshes.iter(world).find(|(_, _, t)| t.translation().y > 1.0).expect("the box").0
}

/// The visibility a fresh app renders of `setup` with 100 cubes
/// (`spawn_cubes`), `extra` spawned, and each cube `(k, by)` moved by `by`,
/// and its fin stats: what an app updated in place must match.
fn fresh_cubes(
    setup: &harness::Setup,
    extra: impl Fn(&mut World),
    moves: &[(usize, Vec3)],
) -> (Vec<f32>, bevy_shadow_fins::FinFrameStats) {
    let mut fresh = harness::Session::new(setup);
    let cubes = shadow_fins_app::render_lab::scaling::spawn_cubes(fresh.app.world_mut(), 100);
    extra(fresh.app.world_mut());
    for &(k, by) in moves {
        fresh.app.world_mut().get_mut::<Transform>(cubes[k]).expect("a transform").translation += by;
    }
    let visibility = fresh.settle(6).expect("render").visibility;
    (visibility, fin_stats(&fresh))
}

#[test]
fn radius_layers_and_refinement_change_the_read_back() {
    let mut s = setup(SceneId::RingPlate, settings());
    let (mut app, slots) = harness::app(&s);
    let slot = &slots[0].visibility;
    app.finish();
    app.cleanup();
    let base = run(&mut app, slot, 6);

    let changed = |app: &mut App, f: &dyn Fn(&mut FinLight, &mut FinShadowSettings)| {
        let mut q = app.world_mut().query::<(&mut FinLight, &mut FinShadowSettings)>();
        for (mut l, mut st) in q.iter_mut(app.world_mut()) {
            f(&mut l, &mut st);
        }
    };
    let differs = |a: &[f32], b: &[f32]| a.iter().zip(b).filter(|(x, y)| (*x - *y).abs() > 0.05).count();

    changed(&mut app, &|l, _| l.radius *= 2.0);
    let bigger = run(&mut app, slot, 4);
    assert!(differs(&base, &bigger) > 100, "doubling the radius must widen the penumbrae");

    changed(&mut app, &|l, st| {
        l.radius /= 2.0;
        st.layers = 1;
    });
    let single = run(&mut app, slot, 4);
    assert!(differs(&base, &single) > 20, "one layer leaks light under the plate (fig. 7)");
    let layers = app.world().resource::<bevy_shadow_fins::FinShadowStats>().0.layers;
    assert_eq!(layers, 1);

    changed(&mut app, &|_, st| {
        st.layers = 16;
        st.refinement = false;
    });
    let unrefined = run(&mut app, slot, 4);
    assert!(differs(&base, &unrefined) > 20, "refinement off must change the penumbrae");

    // And the last state still agrees with the oracle for those settings.
    s.settings.refinement = false;
    let expected = oracle(&s, Method::MultiLayer);
    let (mad, _) = compare(&unrefined, &expected);
    assert!(mad <= 0.01, "after the change: mean difference {mad}");
}

#[test]
fn a_hidden_mesh_and_one_with_bevys_not_shadow_caster_cast_no_fin_shadow_until_they_do() {
    // The box over the plane: its shadow is there; `Visibility::Hidden` (the
    // mesh is not drawn), a hidden parent, or Bevy's `NotShadowCaster` takes it away, as
    // removing the box would; undoing either brings it back exactly.
    let setup = setup(SceneId::BoxOverPlane, settings());
    let mut no_box = setup.clone();
    no_box.scene.objects.retain(|o| o.name != "box");
    let mut session = harness::Session::new(&setup);
    let shadowed = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&shadowed);
    let unshadowed = render(&no_box).visibility;
    let world = session.app.world_mut();
    let the_box = the_box(world);
    for (what, hide, show) in [
        (
            "Visibility::Hidden",
            (|e: &mut EntityWorldMut| {
                e.insert(Visibility::Hidden);
            }) as fn(&mut EntityWorldMut),
            (|e: &mut EntityWorldMut| {
                e.insert(Visibility::Inherited);
            }) as fn(&mut EntityWorldMut),
        ),
        (
            // Its own `Visibility` says inherit; `InheritedVisibility` says hidden.
            "a hidden parent",
            |e: &mut EntityWorldMut| {
                let parent = e.world_scope(|w| w.spawn((Transform::IDENTITY, Visibility::Hidden)).id());
                e.insert(ChildOf(parent));
            },
            |e: &mut EntityWorldMut| {
                let parent = e.get::<ChildOf>().map(|c| c.parent());
                e.remove::<ChildOf>();
                if let Some(parent) = parent {
                    e.world_scope(|w| w.despawn(parent));
                }
            },
        ),
        (
            "NotShadowCaster",
            |e: &mut EntityWorldMut| {
                e.insert(bevy::light::NotShadowCaster);
            },
            |e: &mut EntityWorldMut| {
                e.remove::<bevy::light::NotShadowCaster>();
            },
        ),
    ] {
        hide(&mut session.app.world_mut().entity_mut(the_box));
        let hidden = session.settle(6).expect("render").visibility;
        let (mad, _) = compare(&hidden, &unshadowed);
        println!("{what}: |V − V without the box| = {mad:.2e}");
        // A hidden box is not drawn, so it does not receive either: the
        // pixels where it stood see the ground, as without it.
        assert!(mad <= 1e-4, "{what}: the box still casts ({mad})");
        show(&mut session.app.world_mut().entity_mut(the_box));
        let back = session.settle(6).expect("render").visibility;
        let (mad, _) = compare(&back, &shadowed);
        assert!(mad <= 1e-4, "{what}: the shadow did not come back ({mad})");
    }
}

#[test]
fn a_caster_on_no_layer_of_the_lights_casts_no_fin_shadow_until_they_share_one() {
    // Bevy's shadow maps take a caster only when its `RenderLayers` meet the
    // light's; fin shadows do the same. The camera sees layers 0 and 1, so
    // the box on layer 1 is drawn (and receives) but, for a spot on layer 0,
    // casts as a `NotShadowCaster` box does; the spot on both layers brings
    // the shadow back exactly.
    use bevy::camera::visibility::RenderLayers;
    let mut setup = setup(SceneId::BoxOverPlane, settings());
    setup.spot = true;
    let mut session = harness::Session::new(&setup);
    let world = session.app.world_mut();
    let cameras: Vec<Entity> = world.query_filtered::<Entity, With<Camera3d>>().iter(world).collect();
    for camera in cameras {
        world.entity_mut(camera).insert(RenderLayers::from_layers(&[0, 1]));
    }
    let shadowed = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&shadowed);
    let world = session.app.world_mut();
    let the_box = the_box(world);
    let spot = world.query_filtered::<Entity, With<SpotLight>>().single(world).expect("one spot");
    world.entity_mut(the_box).insert(bevy::light::NotShadowCaster);
    let not_casting = session.settle(6).expect("render").visibility;
    let (gone, _) = compare(&not_casting, &shadowed);
    assert!(gone > 0.005, "the box's shadow is too small to tell ({gone})");
    let world = session.app.world_mut();
    world.entity_mut(the_box).remove::<bevy::light::NotShadowCaster>();
    world.entity_mut(the_box).insert(RenderLayers::layer(1));
    let off_layer = session.settle(6).expect("render").visibility;
    let (mad, _) = compare(&off_layer, &not_casting);
    println!("box on layer 1, spot on 0: |V − V not casting| = {mad:.2e}");
    assert!(mad <= 1e-4, "a box on no layer of the light's still casts ({mad})");
    session.app.world_mut().entity_mut(spot).insert(RenderLayers::from_layers(&[0, 1]));
    let back = session.settle(6).expect("render").visibility;
    let (mad, _) = compare(&back, &shadowed);
    assert!(mad <= 1e-4, "sharing a layer did not bring the shadow back ({mad})");
    // Removing `RenderLayers` puts a mesh back on layer 0: with the spot on
    // layer 0 alone again, the box casts once its layer-1 component goes.
    let world = session.app.world_mut();
    world.entity_mut(spot).remove::<RenderLayers>();
    assert!(compare(&session.settle(6).expect("render").visibility, &not_casting).0 <= 1e-4, "layer 1 box cast");
    session.app.world_mut().entity_mut(the_box).remove::<RenderLayers>();
    let removed = session.settle(6).expect("render").visibility;
    let (mad, _) = compare(&removed, &shadowed);
    println!("RenderLayers removed from the box: |V − V shadowed| = {mad:.2e}");
    assert!(mad <= 1e-4, "removing the box's RenderLayers did not bring its shadow back ({mad})");
}

#[test]
fn a_parent_move_a_mesh_edit_and_a_despawn_are_each_seen() {
    // On every path that keeps caster state between frames: GPU extraction
    // (packed geometry), CPU extraction and the coverage method.
    use bevy_shadow_fins::{FinExtraction, FinMethod};
    let cpu = FinShadowSettings { extraction: FinExtraction::Cpu, ..settings() };
    let coverage = FinShadowSettings { method: FinMethod::Coverage, coverage_samples: 64, ..settings() };
    for (label, settings) in [("gpu extraction", settings()), ("cpu extraction", cpu), ("coverage", coverage)] {
        println!("{label}:");
        parent_move_mesh_edit_and_despawn(settings);
    }
}

/// The box under a new parent: moving the parent moves the shadow to where a
/// fresh app renders the box moved; editing the mesh asset in place (same
/// handle, its vertices shifted back) brings the first shadow back;
/// despawning the parent takes the box's shadow away entirely.
fn parent_move_mesh_edit_and_despawn(settings: FinShadowSettings) {
    use bevy::mesh::VertexAttributeValues;
    let setup = setup(SceneId::BoxOverPlane, settings);
    let offset = Vec3::new(0.4, 0.0, -0.3);
    let moved = with_box_moved(&setup, offset);
    let mut without_box = setup.clone();
    without_box.scene.objects.retain(|o| o.name != "box");
    let (expected_moved, expected_gone) = (render(&moved).visibility, render(&without_box).visibility);

    let mut session = harness::Session::new(&setup);
    let before = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&before);
    let world = session.app.world_mut();
    let the_box = the_box(world);
    let parent = world.spawn((Transform::default(), Visibility::default())).id();
    world.entity_mut(parent).add_child(the_box);
    let parented = session.settle(6).expect("render").visibility;
    assert!(compare(&parented, &before).0 <= 1e-4, "parenting under an identity moved the shadow");

    session.app.world_mut().get_mut::<Transform>(parent).expect("a transform").translation += offset;
    let parent_moved = session.settle(6).expect("render").visibility;
    let (mad, _) = compare(&parent_moved, &expected_moved);
    let (changed, _) = compare(&parent_moved, &before);
    println!("parent moved: |V − V fresh| = {mad:.2e}, |V − V before| = {changed:.3}");
    assert!(changed > 0.005, "moving the parent did not move the shadow ({changed})");
    assert!(mad <= 1e-3, "the parent-moved shadow differs from a fresh render ({mad})");

    {
        let world = session.app.world_mut();
        let handle = world.get::<Mesh3d>(the_box).expect("a mesh").0.clone();
        let mut meshes = world.resource_mut::<Assets<Mesh>>();
        let mut mesh = meshes.get_mut(&handle).expect("the box's mesh");
        let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION) else {
            panic!("positions");
        };
        for p in positions.iter_mut() {
            *p = (Vec3::from(*p) - offset).to_array();
        }
    }
    let edited = session.settle(6).expect("render").visibility;
    let (mad, _) = compare(&edited, &before);
    println!("mesh edited back: |V − V before| = {mad:.2e}");
    assert!(mad <= 1e-3, "editing the mesh in place was not seen ({mad})");

    session.app.world_mut().despawn(parent);
    let gone = session.settle(6).expect("render").visibility;
    let (mad, _) = compare(&gone, &expected_gone);
    println!("parent despawned: |V − V without the box| = {mad:.2e}");
    assert!(mad <= 1e-4, "the despawned box still casts ({mad})");
}

#[test]
fn a_still_scene_is_not_walked_again_and_a_moved_caster_moves_its_shadow() {
    // Change detection: once settled, frames in which nothing changed do not
    // walk the meshes (`FinCasterScans` stays), and moving the box is seen
    // without a walk either: its record alone is rebuilt in place
    // (`FinCasterUpdates`, `casters/mod.rs`), and its shadow is then the one a
    // fresh app renders with the box there. Moved behind the light, it
    // stops casting (every later record renumbered): no shadow, as fresh.
    let setup = setup(SceneId::BoxOverPlane, settings());
    let offset = Vec3::new(0.4, 0.0, -0.3);
    // Above the light's plane: behind its disk, out of its reach.
    let far = Vec3::new(0.0, 10.0, 0.0);
    let expected = render(&with_box_moved(&setup, offset)).visibility;
    let expected_far = render(&with_box_moved(&setup, offset + far)).visibility;
    let mut session = harness::Session::new(&setup);
    let before = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&before);
    let scans = |session: &harness::Session| session.app.world().resource::<bevy_shadow_fins::FinCasterScans>().0;
    let updates = |session: &harness::Session| *session.app.world().resource::<bevy_shadow_fins::FinCasterUpdates>();
    let settled = scans(&session);
    let updated = updates(&session);
    for _ in 0..5 {
        session.update();
    }
    assert_eq!(scans(&session), settled, "a still scene was walked again");
    assert_eq!(updates(&session), updated, "a still scene was updated");
    // Nor is anything read back from the GPU (the counts are back already).
    let reading_back = |session: &mut harness::Session| {
        let world = session.app.world_mut();
        // The plugin's own (the harness reads its images back too).
        let mut q = world.query_filtered::<&Name, With<bevy::render::gpu_readback::Readback>>();
        q.iter(world).filter(|n| n.as_str() == "fin shadow stats read-back").count()
    };
    assert_eq!(reading_back(&mut session), 0, "a still scene runs a read-back");
    let world = session.app.world_mut();
    let the_box = the_box(world);
    world.get_mut::<Transform>(the_box).expect("a transform").translation += offset;
    session.update();
    assert_eq!(reading_back(&mut session), 1, "the moved caster's counts are not read back");
    let after = session.settle(6).expect("render").visibility;
    assert_eq!(scans(&session), settled, "moving one caster walked every mesh");
    assert_eq!(reading_back(&mut session), 0, "the read-back runs on once the counts are back");
    let now = updates(&session);
    assert_eq!((now.frames - updated.frames, now.records - updated.records), (1, 1), "the move was not one record");
    let (mad, _) = compare(&after, &expected);
    let (changed, _) = compare(&after, &before);
    println!("moved box: |V − V fresh| = {mad:.2e}, |V − V before| = {changed:.3}");
    assert!(changed > 0.005, "the shadow did not move ({changed})");
    assert!(mad <= 1e-3, "the moved shadow differs from a fresh render ({mad})");

    let world = session.app.world_mut();
    world.get_mut::<Transform>(the_box).expect("a transform").translation += far;
    let gone = session.settle(6).expect("render").visibility;
    assert_eq!(scans(&session), settled, "moving one caster walked every mesh");
    let (mad, _) = compare(&gone, &expected_far);
    let (changed, _) = compare(&gone, &after);
    println!("box moved behind the light: |V − V fresh| = {mad:.2e}, |V − V before| = {changed:.3}");
    assert!(changed > 0.005, "the shadow stayed ({changed})");
    assert!(mad <= 1e-3, "the box out of reach shadows otherwise than in a fresh render ({mad})");
}

#[test]
fn one_cube_of_many_moving_redraws_only_its_part_of_the_maps_and_shadows_as_a_fresh_app() {
    // Partial redraw (`extract_*.wgsl`): 100 cubes over the ground under the
    // spot; one moved sideways leaves the maps' region, reference depth and
    // layer planes as they were, so the update clears and redraws only the
    // texels under its old and new footprints — and the visibility is the
    // one a fresh app renders with the cube already there.
    use shadow_fins_app::render_lab::scaling::spawn_cubes;
    let setup = setup(SceneId::BoxOverPlane, settings());
    let (mover, offset) = (66, Vec3::new(0.12, 0.0, 0.05));
    let mut session = harness::Session::new(&setup);
    let cubes = spawn_cubes(session.app.world_mut(), 100);
    let before = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&before);
    let full = fin_stats(&session);
    assert!(!full.partial_redraw, "the first update must draw the maps whole");
    let whole = full.map_texels();
    assert_eq!(full.redrawn_texels, whole, "a full redraw clears every texel of every layer");
    session.app.world_mut().get_mut::<Transform>(cubes[mover]).expect("a transform").translation += offset;
    let after = session.settle(6).expect("render").visibility;
    let partial = fin_stats(&session);
    println!(
        "one cube of 100 moved: extracted alone {}, partial {}, {} of {whole} texels redrawn",
        partial.incremental_extraction, partial.partial_redraw, partial.redrawn_texels
    );
    assert!(!full.incremental_extraction, "the first update must extract every caster");
    assert!(partial.incremental_extraction, "one cube of 100 moved sideways was not extracted alone");
    assert!(partial.partial_redraw, "one cube of 100 moved sideways redrew the maps whole");
    assert_eq!(
        (partial.silhouettes, partial.fins),
        (full.silhouettes, full.fins),
        "a cube moved sideways keeps its silhouettes and fins: the retired ones must not count"
    );
    assert!(
        partial.redrawn_texels > 0 && partial.redrawn_texels * 20 < whole,
        "a partial redraw of one small cube redrew {} of {whole} texels",
        partial.redrawn_texels
    );

    let (expected, _) = fresh_cubes(&setup, |_| {}, &[(mover, offset)]);
    let (mad, _) = compare(&after, &expected);
    let worst = max_difference(&after, &expected);
    let (changed, _) = compare(&after, &before);
    println!("partial redraw: |V − V fresh| mean {mad:.2e}, max {worst:.2e}; |V − V before| {changed:.4}");
    assert!(changed > 1e-4, "the moved cube's shadow did not move ({changed})");
    assert!(worst <= 1e-4, "the partial redraw differs from a fresh app's maps (max {worst})");

    // Again, the same cube back over where it was and its neighbour onto its
    // old place: footprints kept from a partial update are as good as a full one's.
    let (neighbour, second) = (mover + 1, Vec3::new(-0.3, 0.0, 0.0));
    let world = session.app.world_mut();
    world.get_mut::<Transform>(cubes[mover]).expect("a transform").translation -= offset * 0.5;
    world.get_mut::<Transform>(cubes[neighbour]).expect("a transform").translation += second;
    let again = session.settle(6).expect("render").visibility;
    let twice = fin_stats(&session);
    assert!(twice.partial_redraw, "two cubes of 100 moved redrew the maps whole");
    assert!(twice.incremental_extraction, "two cubes of 100 moved were not extracted alone");
    let (expected, _) = fresh_cubes(&setup, |_| {}, &[(mover, offset * 0.5), (neighbour, second)]);
    let worst = max_difference(&again, &expected);
    let (changed, _) = compare(&again, &after);
    println!("second partial redraw: |V − V fresh| max {worst:.2e}; |V − V before| {changed:.4}");
    assert!(changed > 1e-4, "the second move changed no shadow ({changed})");
    assert!(worst <= 1e-4, "the second partial redraw differs from a fresh app's maps (max {worst})");

    // A cube lifted above every other caster (and out of the scene's box:
    // the CPU asks for a full update) is extracted anew with all the
    // others, from incremental updates' leftovers — exactly a fresh app's
    // shadow.
    let lift = Vec3::new(0.0, 2.5, 0.0);
    session.app.world_mut().get_mut::<Transform>(cubes[neighbour]).expect("a transform").translation += lift;
    let lifted = session.settle(6).expect("render").visibility;
    let stats = fin_stats(&session);
    println!("a cube lifted: extracted alone {}, partial {}", stats.incremental_extraction, stats.partial_redraw);
    assert!(!stats.incremental_extraction, "a cube lifted out of the scene's box was extracted alone");
    let (expected, _) = fresh_cubes(&setup, |_| {}, &[(mover, offset * 0.5), (neighbour, second + lift)]);
    let worst = max_difference(&lifted, &expected);
    let (changed, _) = compare(&lifted, &again);
    println!("lifted cube: |V − V fresh| max {worst:.2e}; |V − V before| {changed:.4}");
    assert!(changed > 1e-4, "lifting a cube changed no shadow ({changed})");
    assert!(worst <= 1e-4, "a full extraction after incremental ones differs from a fresh app's (max {worst})");
}

#[test]
fn a_cube_lifted_out_of_the_kept_silhouette_depth_range_is_extracted_with_every_other_in_the_same_update() {
    // Incremental extraction (`extract_plan.wgsl`'s `decide`): the moved cube's
    // new silhouettes are the nearest to the light, so the histogram's depth
    // range — and with it every silhouette's sub-layer — is not last
    // frame's. The update must throw away its incremental attempt and
    // extract every caster anew before it plans the layers. A tall pole that
    // casts nothing keeps the scene's box (and so the light's parameters)
    // as they were: only the GPU can see the range moved.
    use shadow_fins_app::render_lab::scaling::spawn_cubes;
    let setup = setup(SceneId::BoxOverPlane, settings());
    let spawn_pole = |world: &mut World| {
        let mesh = world.resource_mut::<Assets<Mesh>>().add(Cuboid::new(0.1, 3.6, 0.1));
        let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
        let at = Transform::from_xyz(4.5, 1.8, -4.5);
        world.spawn((Mesh3d(mesh), MeshMaterial3d(material), at, bevy::light::NotShadowCaster));
    };
    let (sideways, lifted) = ((21, Vec3::new(0.1, 0.0, 0.0)), (44, Vec3::new(0.0, 2.5, 0.0)));
    let mut session = harness::Session::new(&setup);
    let cubes = spawn_cubes(session.app.world_mut(), 100);
    spawn_pole(session.app.world_mut());
    let before = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&before);
    let world = session.app.world_mut();
    world.get_mut::<Transform>(cubes[sideways.0]).expect("a transform").translation += sideways.1;
    session.settle(6).expect("render");
    assert!(fin_stats(&session).incremental_extraction, "a cube moved sideways was not extracted alone");
    session.app.world_mut().get_mut::<Transform>(cubes[lifted.0]).expect("a transform").translation += lifted.1;
    let lifted_shot = session.settle(6).expect("render");
    save(&lifted_shot, "incremental_cube_lifted");
    let after = lifted_shot.visibility;
    let stats = fin_stats(&session);
    println!("a cube lifted within the scene's box: extracted alone {}", stats.incremental_extraction);
    assert!(!stats.incremental_extraction, "a cube holding the nearest silhouette now was extracted alone");

    let (expected, fresh_stats) = fresh_cubes(&setup, spawn_pole, &[sideways, lifted]);
    let worst = max_difference(&after, &expected);
    let (changed, _) = compare(&after, &before);
    println!("lifted cube: |V − V fresh| max {worst:.2e}; |V − V before| {changed:.4}");
    assert!(changed > 1e-4, "lifting a cube changed no shadow ({changed})");
    assert_eq!(
        (stats.silhouettes, stats.fins, stats.layers),
        (fresh_stats.silhouettes, fresh_stats.fins, fresh_stats.layers),
        "the update extracted otherwise than a fresh app"
    );
    assert!(worst <= 1e-4, "the update that fell back differs from a fresh app's (max {worst})");

    // With `FinIncrementalExtraction` off every caster is extracted, and the
    // maps are still redrawn only under the moved cube's old and new
    // footprints: its old shadow must go.
    session.app.insert_resource(bevy_shadow_fins::FinIncrementalExtraction(false));
    let back = Vec3::new(-0.4, 0.0, 0.0);
    session.app.world_mut().get_mut::<Transform>(cubes[sideways.0]).expect("a transform").translation += back;
    let moved_back_shot = session.settle(6).expect("render");
    save(&moved_back_shot, "incremental_off_cube_moved_back");
    let moved_back = moved_back_shot.visibility;
    let stats = fin_stats(&session);
    assert!(!stats.incremental_extraction, "FinIncrementalExtraction(false) extracted the moved cube alone");
    assert!(stats.partial_redraw, "a cube moved sideways redrew the maps whole");
    let (expected, _) = fresh_cubes(&setup, spawn_pole, &[(sideways.0, sideways.1 + back), lifted]);
    let worst = max_difference(&moved_back, &expected);
    println!("every caster extracted, maps redrawn in part: |V − V fresh| max {worst:.2e}");
    assert!(worst <= 1e-4, "the partial redraw after a full extraction differs from a fresh app's (max {worst})");
}

#[test]
fn a_skinned_bar_bending_among_many_cubes_is_posed_on_the_gpu_and_redraws_only_its_part() {
    // Posing on the GPU (`pose.wgsl`): a new pose of a skinned caster is a
    // changed instance record — joint matrices up, no new geometry — so the
    // maps are redrawn only under the bar's old and new footprints, and the
    // visibility is the one a fresh app renders with the bar already bent.
    use shadow_fins_app::render_lab::scaling::{spawn_cubes, spawn_skinned_bar};
    let setup = setup(SceneId::BoxOverPlane, settings());
    let at = Vec3::new(1.2, 0.9, 1.2);
    let bend = |world: &mut World, joint: Entity| {
        world.get_mut::<Transform>(joint).expect("a transform").rotate_z(0.3);
    };
    let mut session = harness::Session::new(&setup);
    spawn_cubes(session.app.world_mut(), 100);
    let joint = spawn_skinned_bar(session.app.world_mut(), at);
    let straight = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&straight);
    assert_eq!(fin_stats(&session).posed_on_gpu, 1, "the bar was not posed on the GPU");
    bend(session.app.world_mut(), joint);
    let bent = session.settle(6).expect("render").visibility;
    let partial = fin_stats(&session);
    let whole = partial.map_texels();
    println!(
        "bar bent among 100 cubes: posed on the GPU {}, partial {}, {} of {whole} texels redrawn",
        partial.posed_on_gpu, partial.partial_redraw, partial.redrawn_texels
    );
    assert_eq!(partial.posed_on_gpu, 1, "the bent bar was not posed on the GPU");
    assert!(partial.partial_redraw, "a new pose of one caster of 101 redrew the maps whole");
    assert!(partial.incremental_extraction, "a new pose of one caster of 101 was not extracted alone");
    assert!(partial.redrawn_texels * 10 < whole, "the bend redrew {} of {whole} texels", partial.redrawn_texels);

    let (expected, _) = fresh_cubes(
        &setup,
        |world| {
            let joint = spawn_skinned_bar(world, at);
            bend(world, joint);
        },
        &[],
    );
    let worst = max_difference(&bent, &expected);
    let (changed, _) = compare(&bent, &straight);
    println!("bent bar: |V − V fresh| max {worst:.2e}; |V − V straight| {changed:.4}");
    assert!(changed > 1e-4, "the bar's shadow did not bend ({changed})");
    assert!(worst <= 1e-4, "the partial redraw of a new pose differs from a fresh app's (max {worst})");

    // Posed on the CPU instead (`FinGpuPosing` off): the same shadow, up to
    // rounding (the GPU's arithmetic is its own), the maps redrawn whole.
    session.app.insert_resource(bevy_shadow_fins::FinGpuPosing(false));
    let on_cpu = session.settle(6).expect("render").visibility;
    let cpu = fin_stats(&session);
    assert_eq!(cpu.posed_on_gpu, 0, "FinGpuPosing off still posed on the GPU");
    let (mad, far) = compare(&on_cpu, &bent);
    println!("posed on the CPU vs on the GPU: mean {mad:.2e}, {:.3}% of pixels by > 0.1", far * 100.0);
    assert!(mad <= 1e-4 && far <= 5e-4, "posing on the CPU and on the GPU disagree: {mad} / {far}");
}

#[test]
fn a_pose_that_tears_welded_vertices_apart_is_posed_on_the_cpu_and_still_shadows_as_a_fresh_app() {
    // The GPU poses the topology at rest (`pose.wgsl`). A skin whose three
    // copies of a cuboid corner (one per face) carry different weights
    // welds them at rest but pulls them apart when bent: the posed mesh's
    // topology is another, so that pose falls back to the CPU's posed mesh
    // (`casters::mesh::posed_mesh`) — and shadows as a fresh app does.
    use shadow_fins_app::render_lab::scaling::spawn_skinned_bar_weighted;
    let setup = setup(SceneId::BoxOverPlane, settings());
    let at = Vec3::new(1.2, 0.9, 1.2);
    // Each face's four vertices: the end faces' and side faces' copies differ.
    let torn = |i: usize, p: Vec3| (0.5 + p.x / 1.2 + if (i / 4) % 2 == 0 { 0.0 } else { 0.2 }).clamp(0.0, 1.0);
    let bend = |world: &mut World, joint: Entity| {
        world.get_mut::<Transform>(joint).expect("a transform").rotate_z(0.5);
    };
    let mut session = harness::Session::new(&setup);
    let joint = spawn_skinned_bar_weighted(session.app.world_mut(), at, torn);
    let straight = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&straight);
    assert_eq!(fin_stats(&session).posed_on_gpu, 1, "at rest the torn bar's topology is its own: the GPU poses it");
    bend(session.app.world_mut(), joint);
    let bent = session.settle(6).expect("render").visibility;
    assert_eq!(fin_stats(&session).posed_on_gpu, 0, "a pose that tore the welded corners apart was posed on the GPU");

    let mut fresh = harness::Session::new(&setup);
    let fresh_joint = spawn_skinned_bar_weighted(fresh.app.world_mut(), at, torn);
    bend(fresh.app.world_mut(), fresh_joint);
    let expected = fresh.settle(6).expect("render").visibility;
    let worst = max_difference(&bent, &expected);
    let (changed, _) = compare(&bent, &straight);
    println!("torn bar: |V − V fresh| max {worst:.2e}; |V − V straight| {changed:.4}");
    assert!(changed > 1e-4, "the torn bar's shadow did not bend ({changed})");
    assert!(worst <= 1e-4, "the torn bar shadows otherwise than in a fresh app (max {worst})");
}

#[test]
fn a_part_of_the_kitbash_moved_is_extracted_again_and_shadows_as_a_fresh_app() {
    // Content not made for this test: the kitbash of interpenetrating open
    // and closed parts (`SceneId::Kitbash`). Its ball moved a little: the
    // update (extracting the ball alone, or everything when the ball held
    // the kept depth range) must leave the visibility a fresh app renders
    // with the ball already there.
    let setup = setup(SceneId::Kitbash, settings());
    let MovedInPlace { before, shot, stats, fresh: expected } =
        moved_in_place(&setup, "ball", Vec3::new(0.06, -0.02, 0.04), "kitbash_ball_moved");
    let worst = max_difference(&shot.visibility, &expected);
    let (changed, _) = compare(&shot.visibility, &before);
    println!(
        "kitbash ball moved: extracted alone {}, partial {}, {} texels; |V − V fresh| max {worst:.2e}; |V − V before| {changed:.4}",
        stats.incremental_extraction, stats.partial_redraw, stats.redrawn_texels
    );
    assert!(changed > 1e-4, "moving the ball changed no shadow ({changed})");
    assert!(worst <= 1e-4, "the kitbash updated in place differs from a fresh app's (max {worst})");
}

#[test]
fn a_cube_moving_every_frame_across_the_map_keeps_every_tile_of_its_shadow() {
    // Sparse maps (`map_tiles`): a partial redraw never frees a tile, and
    // while a caster moves every frame the read-back lags behind the
    // newest frame. The tiles its trail leaves must neither run the pool
    // out (the extraction redraws whole when it fills, `tiles_to_spare`)
    // nor stay dropped (a lagging read-back still sizes the pool): after
    // 24 one-frame moves the shadow is a fresh app's, nothing degraded.
    use shadow_fins_app::render_lab::scaling::spawn_cubes;
    // At 1024² the cubes' layer fills a small part of its tiles: the pool is
    // sized to them, well under every tile.
    let setup = setup(SceneId::BoxOverPlane, FinShadowSettings { map_resolution: 1024, ..settings() });
    let (mover, step, steps) = (66, Vec3::new(0.05, 0.0, 0.02), 24);
    let mut session = harness::Session::new(&setup);
    let cubes = spawn_cubes(session.app.world_mut(), 100);
    assert_visibility_not_trivial(&session.settle(6).expect("render").visibility);
    for _ in 0..steps {
        session.app.world_mut().get_mut::<Transform>(cubes[mover]).expect("a transform").translation += step;
        session.app.update();
    }
    let moved = session.settle(8).expect("render").visibility;
    let stats = fin_stats(&session);
    let all_tiles = stats.layers as u64 * 128 * 128;
    let pool = (stats.gpu_bytes - (4 + all_tiles) * 4) / (64 * 36);
    println!("{} layers, a pool of {pool} of {all_tiles} tiles", stats.layers);
    assert!(pool * 2 < all_tiles, "the pool is sized to the tiles drawn, not every tile ({pool} of {all_tiles})");
    let mut fresh = harness::Session::new(&setup);
    let fresh_cubes = spawn_cubes(fresh.app.world_mut(), 100);
    fresh.app.world_mut().get_mut::<Transform>(fresh_cubes[mover]).expect("a transform").translation +=
        step * steps as f32;
    let expected = fresh.settle(6).expect("render").visibility;
    let (mad, far) = compare(&moved, &expected);
    println!(
        "after {steps} one-frame moves: |V − V fresh| = {mad:.2e}, {:.2}% off by > 0.1; {}",
        far * 100.0,
        stats.degraded
    );
    assert!(stats.degraded.is_empty(), "{}", stats.degraded);
    assert!(mad <= 1e-3 && far <= 1e-3, "the moved cube's shadow differs from a fresh app's: {mad} / {far}");
}
