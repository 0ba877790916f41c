//! The ground the editor adds under a glTF that has none (a helmet, a
//! character alone): a grey shadow catcher that receives fin shadows and
//! casts none, nor Bevy's, so that the soft shadow the editor exists for is
//! visible. On by default ([`EditorOptions::add_ground`](crate::EditorOptions),
//! `--no-ground`), switched in the View panel ([`AddedGround::shown`]).
//!
//! The ground truth traces it as a receiver only: whenever the loaded scene
//! is taken again (a new load, an animation at rest) it is added back, and
//! switching it bumps the scene's generation so derived views restart.

use std::sync::Arc;

use bevy::prelude::*;
use shadow_fins::{
    default_view::Ground,
    scene::{Scene, SceneObject},
};

use crate::state::{EditorGround, EditorMesh, LoadedScene};

/// The name of the added ground, in the Bevy world and in the core's scene.
pub const GROUND_NAME: &str = "ground (added by the editor)";

/// The loaded glTF has no ground of its own: where one goes, and whether it
/// is shown. Absent for a scene that has one (the demo, a room, a terrain).
#[derive(Resource, Debug, Clone, Copy, PartialEq)]
pub struct AddedGround {
    pub ground: Ground,
    pub shown: bool,
}

/// The ground as the core's scene object: a receiver, not a caster.
fn ground_object(ground: Ground) -> Option<SceneObject> {
    let mesh = shadow_fins::shapes::plane(2.0 * ground.half_size, 1);
    let at = bevy::math::Affine3A::from_translation(ground.center);
    let mut object = SceneObject::new(GROUND_NAME, mesh, at).ok()?;
    object.casts_shadows = false;
    Some(object)
}

/// `scene` with the added ground when it is shown (and not there already):
/// what the ground truth traces.
pub(crate) fn with_shown_ground(world: &World, mut scene: Scene) -> Scene {
    if let Some(added) = world.get_resource::<AddedGround>().filter(|g| g.shown)
        && !scene.objects.iter().any(|o| o.name == GROUND_NAME)
        && let Some(object) = ground_object(added.ground)
    {
        scene.objects.push(object);
    }
    scene
}

/// Spawns the ground's entity: grey, receiving, casting no shadow of either kind.
fn spawn_ground(world: &mut World, ground: Ground) -> Option<Entity> {
    let object = ground_object(ground)?;
    let mesh = world.resource_mut::<Assets<Mesh>>().add(bevy_shadow_fins::mesh_from_core(&object.mesh));
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial {
        base_color: Color::srgb(0.6, 0.6, 0.6),
        perceptual_roughness: 0.9,
        ..default()
    });
    let entity = world
        .spawn((
            Name::new(GROUND_NAME),
            EditorMesh,
            EditorGround,
            bevy_shadow_fins::NotFinShadowCaster,
            bevy::light::NotShadowCaster,
            Mesh3d(mesh),
            MeshMaterial3d(material),
            Transform::from_translation(ground.center),
        ))
        .id();
    Some(entity)
}

/// Makes the world and the loaded scene agree with [`AddedGround`]: spawns or
/// despawns the ground entity, adds or removes its object (a new generation).
/// Runs after each load and whenever the View panel switches it.
pub(crate) fn apply_added_ground(world: &mut World) {
    let shown = world.get_resource::<AddedGround>().filter(|g| g.shown).map(|g| g.ground);
    let spawned: Vec<Entity> = world.query_filtered::<Entity, With<EditorGround>>().iter(world).collect();
    if shown.is_some() == !spawned.is_empty() {
        return;
    }
    for e in spawned {
        world.despawn(e);
    }
    if let Some(ground) = shown {
        spawn_ground(world, ground);
    }
    let Some(loaded) = world.get_resource::<LoadedScene>().cloned() else { return };
    let mut scene = (*loaded.scene).clone();
    scene.objects.retain(|o| o.name != GROUND_NAME);
    let scene = with_shown_ground(world, scene);
    world.insert_resource(LoadedScene { scene: Arc::new(scene), generation: loaded.generation + 1, ..loaded });
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::math::Vec3;

    fn world_with_a_lone_box() -> World {
        let mut world = World::new();
        world.init_resource::<Assets<Mesh>>();
        world.init_resource::<Assets<StandardMaterial>>();
        let cube =
            SceneObject::new("box", shadow_fins::shapes::cuboid(Vec3::splat(0.5)), bevy::math::Affine3A::IDENTITY)
                .unwrap();
        let scene = Scene::new(vec![cube]);
        world.insert_resource(LoadedScene { name: "box".into(), scene: Arc::new(scene), generation: 7, extent: 1.7 });
        world
    }

    fn grounds(world: &mut World) -> usize {
        world.query_filtered::<Entity, With<EditorGround>>().iter(world).count()
    }

    fn scene_has_ground(world: &World) -> bool {
        world.resource::<LoadedScene>().scene.objects.iter().any(|o| o.name == GROUND_NAME && !o.casts_shadows)
    }

    #[test]
    fn switching_the_ground_spawns_it_adds_it_to_the_truth_and_takes_both_away_again() {
        let mut world = world_with_a_lone_box();
        let ground = Ground { center: Vec3::new(0.0, -0.5, 0.0), half_size: 4.0 };
        world.insert_resource(AddedGround { ground, shown: true });
        apply_added_ground(&mut world);
        assert_eq!(grounds(&mut world), 1);
        assert!(scene_has_ground(&world));
        assert_eq!(world.resource::<LoadedScene>().generation, 8, "the truth restarts");
        let objects = world.resource::<LoadedScene>().scene.objects.len();
        // Applying again changes nothing (no second ground, no new generation).
        apply_added_ground(&mut world);
        assert_eq!((grounds(&mut world), world.resource::<LoadedScene>().generation), (1, 8));
        assert_eq!(world.resource::<LoadedScene>().scene.objects.len(), objects);
        world.resource_mut::<AddedGround>().shown = false;
        apply_added_ground(&mut world);
        assert_eq!(grounds(&mut world), 0);
        assert!(!scene_has_ground(&world));
        assert_eq!(world.resource::<LoadedScene>().scene.objects.len(), objects - 1);
        assert_eq!(world.resource::<LoadedScene>().generation, 9);
        world.resource_mut::<AddedGround>().shown = true;
        apply_added_ground(&mut world);
        assert_eq!(grounds(&mut world), 1);
        assert!(scene_has_ground(&world));
        // A scene with a ground of its own: no resource, nothing added.
        world.remove_resource::<AddedGround>();
        apply_added_ground(&mut world);
        assert_eq!(grounds(&mut world), 0);
        assert!(!scene_has_ground(&world));
    }

    #[test]
    fn a_scene_taken_again_keeps_the_shown_ground_once() {
        let mut world = world_with_a_lone_box();
        let scene = (*world.resource::<LoadedScene>().scene).clone();
        assert_eq!(with_shown_ground(&world, scene.clone()).objects.len(), 1, "no ground resource");
        let ground = Ground { center: Vec3::new(0.0, -0.5, 0.0), half_size: 4.0 };
        world.insert_resource(AddedGround { ground, shown: false });
        assert_eq!(with_shown_ground(&world, scene.clone()).objects.len(), 1, "switched off");
        world.insert_resource(AddedGround { ground, shown: true });
        let again = with_shown_ground(&world, scene);
        assert_eq!(again.objects.len(), 2);
        assert_eq!(with_shown_ground(&world, again).objects.len(), 2, "never twice");
    }
}
