//! A glTF scene as Bevy 0.19 loads it: spawned by Bevy's own loader
//! ([`spawn_gltf_scene`]), and fin shadows for its lights
//! (`KHR_lights_punctual` → `SpotLight`, `DirectionalLight`, `PointLight`).
//!
//! A punctual light has no size in glTF, and Bevy 0.19's loader makes one
//! up: a spot light's `radius` is its `range` (`bevy_gltf` `loader/mod.rs`:
//! `radius: light.range().unwrap_or(0.0)`, which gives a 20 m-range lamp a
//! 20 m disk, or a hard shadow when the file gives no range), a point
//! light's is 0. [`give_gltf_lights_fin_shadows`] sets every adopted light's
//! radius: its `extras` `"radius"` (this project's convention, written by
//! `shadow-fins-lab make-assets`), else the caller's fallback.

use std::sync::{
    Arc, OnceLock,
    atomic::{AtomicBool, Ordering},
};

use bevy::{
    asset::{LoadState, RecursiveDependencyLoadState},
    gltf::{Gltf, GltfExtras},
    prelude::*,
    world_serialization::WorldInstanceReady,
};

use crate::{FinShadowSettings, FinShadows, MAX_FIN_LIGHTS};

/// A glTF scene being spawned by [`spawn_gltf_scene`] (on its root entity).
/// Clones share the load's state.
#[derive(Component, Clone)]
pub struct GltfSceneLoading {
    /// The whole file (its scenes, animations, nodes, materials): held while
    /// this is, as Bevy drops a file's root asset that nothing holds.
    pub gltf: Handle<Gltf>,
    /// The scene of the file that is spawned (an index into `Gltf::scenes`).
    pub scene_index: usize,
    state: Arc<LoadingState>,
    /// When the load began (a load that neither fails nor spawns is given up).
    pub started: std::time::Instant,
}

#[derive(Default)]
struct LoadingState {
    /// The scene's instance has spawned.
    spawned: AtomicBool,
    /// Why the scene cannot spawn although the file loaded.
    failure: OnceLock<String>,
}

impl GltfSceneLoading {
    /// Spawned (the frame after, its transforms are propagated), from the
    /// whole file loaded (see [`spawn_gltf_scene`]).
    pub fn is_ready(&self) -> bool {
        self.state.spawned.load(Ordering::Relaxed)
    }

    /// Bevy's loader's error, once the file or one of its dependencies (an
    /// external texture, a buffer) failed, or why the loaded file has no such
    /// scene.
    ///
    /// One line: Bevy's error text appends a backtrace where one was
    /// captured (`RUST_BACKTRACE`), which is for a developer's log, not a
    /// panel (see [`first_line`]).
    pub fn failed(&self, assets: &AssetServer) -> Option<String> {
        if let LoadState::Failed(e) = assets.load_state(&self.gltf) {
            return Some(first_line(&e.to_string()));
        }
        if let RecursiveDependencyLoadState::Failed(e) = assets.recursive_dependency_load_state(&self.gltf) {
            return Some(format!("a file it needs: {}", first_line(&e.to_string())));
        }
        self.state.failure.get().cloned()
    }
}

/// The first non-empty line of an error's text, trimmed: what a status line
/// shows of a load error whose text goes on with a backtrace.
pub fn first_line(text: &str) -> String {
    text.lines().map(str::trim).find(|l| !l.is_empty()).unwrap_or("unknown error").to_string()
}

/// Spawns scene `scene_index` of the glTF at `path` with Bevy's own loader
/// and returns its root, which carries a [`GltfSceneLoading`] (a relative
/// path is made absolute, since Bevy would read it from its asset folder).
///
/// The file is loaded once, as a `Gltf` (Bevy loads a file a second time for
/// a second kind of request — the scene's label, then the file's root — and
/// that load's copies replace the first one's materials and meshes when it
/// lands, changes made to them in between lost): once it has loaded with its
/// dependencies, [`ShadowFinsPlugin`](crate::ShadowFinsPlugin) gives the root
/// the file's `Gltf::scenes[scene_index]` as its `WorldAssetRoot` (the asset
/// `GltfAssetLabel::Scene(scene_index)` names). The file's cameras are
/// turned off as the scene spawns (Bevy makes the first active, and it would
/// draw over the app's).
pub fn spawn_gltf_scene(
    commands: &mut Commands,
    assets: &AssetServer,
    path: &std::path::Path,
    scene_index: usize,
) -> Entity {
    let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let gltf = assets.load::<Gltf>(path);
    let state = Arc::new(LoadingState::default());
    let spawned = state.clone();
    let loading = GltfSceneLoading { gltf, scene_index, state, started: std::time::Instant::now() };
    commands
        .spawn(loading)
        .observe(move |ready: On<WorldInstanceReady>, children: Query<&Children>, mut cameras: Query<&mut Camera>| {
            for e in children.iter_descendants(ready.entity) {
                if let Ok(mut camera) = cameras.get_mut(e) {
                    camera.is_active = false;
                }
            }
            spawned.spawned.store(true, Ordering::Relaxed);
        })
        .id()
}

/// Gives each [`spawn_gltf_scene`] root whose file has loaded (with its
/// dependencies) its scene to spawn, or says why there is none.
pub(crate) fn spawn_loaded_gltf_scenes(
    mut commands: Commands,
    assets: Res<AssetServer>,
    gltfs: Res<Assets<Gltf>>,
    roots: Query<(Entity, &GltfSceneLoading), Without<WorldAssetRoot>>,
) {
    for (root, loading) in &roots {
        // A root that failed stays (its caller reads why) and is not looked at again.
        if loading.state.failure.get().is_some() || !assets.is_loaded_with_dependencies(&loading.gltf) {
            continue;
        }
        let Some(gltf) = gltfs.get(&loading.gltf) else { continue };
        match gltf.scenes.get(loading.scene_index) {
            Some(scene) => {
                commands.entity(root).insert(WorldAssetRoot(scene.clone()));
            }
            None => {
                let n = gltf.scenes.len();
                let failure = format!("the file has {n} scene(s); scene {} was asked for", loading.scene_index);
                let _ = loading.state.failure.set(failure);
            }
        }
    }
}

/// `root`'s descendants with a `T`, in the order the scene spawned them
/// (depth first, the file's order).
pub fn descendants_with<T: Component>(world: &mut World, root: Entity) -> Vec<Entity> {
    let mut children = world.query::<&Children>();
    let (mut out, mut stack) = (vec![], vec![root]);
    while let Some(e) = stack.pop() {
        if e != root && world.get::<T>(e).is_some() {
            out.push(e);
        }
        if let Ok(c) = children.get(world, e) {
            stack.extend(c.iter().rev());
        }
    }
    out
}

/// The physical radius a glTF light's `extras` JSON declares (`{"radius": r}`),
/// if it is a finite number ≥ 0.
pub fn gltf_light_radius(extras: &str) -> Option<f32> {
    let value: serde_json::Value = serde_json::from_str(extras).ok()?;
    let radius = value.get("radius")?.as_f64()? as f32;
    (radius.is_finite() && radius >= 0.0).then_some(radius)
}

/// A glTF light entity's radius: its extras' ([`gltf_light_radius`]), else
/// `fallback` (what Bevy's loader put there is never a size).
pub fn gltf_light_radius_or(world: &World, light: Entity, fallback: f32) -> f32 {
    world.get::<GltfExtras>(light).and_then(|e| gltf_light_radius(&e.value)).unwrap_or(fallback)
}

/// What [`give_gltf_lights_fin_shadows`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GltfLightsAdopted {
    /// Spot, point and directional lights that now have [`FinShadows`].
    pub lights: Vec<Entity>,
}

/// Gives every `SpotLight`, `PointLight` and `DirectionalLight` under
/// `root` (the entity a glTF scene was spawned on) [`FinShadows`] with
/// `settings` — at most `MAX_FIN_LIGHTS − 1`, so the app's own light keeps
/// its slot; the rest keep Bevy's shadows, said once — and sets each spot or
/// point light's radius to its `extras` radius, else to `fallback_radius`
/// (clamped ≥ 0).
/// A directional light keeps its `SunDisk` if it has one (else fins use the
/// Earth's sun, as Bevy draws it).
pub fn give_gltf_lights_fin_shadows(
    world: &mut World,
    root: Entity,
    settings: FinShadowSettings,
    fallback_radius: f32,
) -> GltfLightsAdopted {
    let fallback_radius = if fallback_radius.is_finite() { fallback_radius.max(0.0) } else { 0.0 };
    let mut adopted = GltfLightsAdopted::default();
    for entity in descendants_with::<ChildOf>(world, root) {
        let radius = gltf_light_radius_or(world, entity, fallback_radius);
        let full = adopted.lights.len() + 1 >= MAX_FIN_LIGHTS;
        let mut e = world.entity_mut(entity);
        let spot = e.get_mut::<SpotLight>().map(|mut spot| spot.radius = radius).is_some();
        let point = e.get_mut::<PointLight>().map(|mut point| point.radius = radius).is_some();
        if spot || point || e.contains::<DirectionalLight>() {
            if full {
                warn_once!(
                    "fin shadows: a glTF with more than {} lights; the rest keep Bevy's shadows",
                    MAX_FIN_LIGHTS - 1
                );
                continue;
            }
            e.insert((FinShadows, settings));
            adopted.lights.push(entity);
        }
    }
    adopted
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_load_error_is_shown_as_its_first_line_without_the_backtrace() {
        let text = "Failed to load asset 'x.gltf': invalid image mime type image/webp\n\nStack backtrace:\n   0: bevy_ecs::error";
        assert_eq!(first_line(text), "Failed to load asset 'x.gltf': invalid image mime type image/webp");
        assert_eq!(first_line("\n  \n  reason  \n"), "reason");
        assert_eq!(first_line(""), "unknown error");
    }

    #[test]
    fn a_lights_radius_is_read_from_its_extras_and_nonsense_is_none() {
        assert_eq!(gltf_light_radius(r#"{"radius": 0.4}"#), Some(0.4));
        assert_eq!(gltf_light_radius(r#"{"radius": 0}"#), Some(0.0));
        for bad in [r#"{"radius": -1}"#, r#"{"radius": "big"}"#, r#"{"size": 1}"#, "not json", r#"{"radius": 1e400}"#] {
            assert_eq!(gltf_light_radius(bad), None, "{bad}");
        }
    }

    #[test]
    fn descendants_come_in_the_order_the_scene_spawned_them() {
        let mut world = World::new();
        let root = world.spawn_empty().id();
        let a = world.spawn((Name::new("a"), ChildOf(root))).id();
        let a1 = world.spawn((Name::new("a1"), ChildOf(a))).id();
        let b = world.spawn((Name::new("b"), ChildOf(root))).id();
        world.spawn(Name::new("outside"));
        assert_eq!(descendants_with::<Name>(&mut world, root), vec![a, a1, b]);
    }

    #[test]
    fn no_more_than_all_but_one_fin_light_slot_goes_to_the_file() {
        let mut world = World::new();
        let root = world.spawn_empty().id();
        for _ in 0..MAX_FIN_LIGHTS + 3 {
            world.spawn((SpotLight::default(), ChildOf(root)));
        }
        let adopted = give_gltf_lights_fin_shadows(&mut world, root, FinShadowSettings::default(), 0.1);
        assert_eq!(adopted.lights.len(), MAX_FIN_LIGHTS - 1);
    }

    #[test]
    fn lights_under_the_root_get_fin_shadows_and_a_radius_that_is_not_their_range() {
        let mut world = World::new();
        let root = world.spawn_empty().id();
        // As Bevy's loader spawns them: a spot's radius is its range (or 0
        // with no range given, range 20), a point light's 0.
        let spot = world.spawn((SpotLight { range: 20.0, radius: 20.0, ..default() }, ChildOf(root))).id();
        let rangeless = world.spawn((SpotLight { range: 20.0, radius: 0.0, ..default() }, ChildOf(root))).id();
        let named = world
            .spawn((
                SpotLight { range: 20.0, radius: 20.0, ..default() },
                GltfExtras { value: r#"{"radius":0.4}"#.into() },
                ChildOf(root),
            ))
            .id();
        let sun = world.spawn((DirectionalLight::default(), ChildOf(spot))).id();
        let point = world.spawn((PointLight { range: 5.0, radius: 0.0, ..default() }, ChildOf(root))).id();
        let outside = world.spawn(SpotLight { range: 20.0, radius: 20.0, ..default() }).id();
        let adopted = give_gltf_lights_fin_shadows(&mut world, root, FinShadowSettings::default(), 0.25);
        assert_eq!(world.get::<SpotLight>(spot).unwrap().radius, 0.25);
        assert_eq!(world.get::<SpotLight>(rangeless).unwrap().radius, 0.25);
        assert_eq!(world.get::<SpotLight>(named).unwrap().radius, 0.4);
        assert_eq!(world.get::<PointLight>(point).unwrap().radius, 0.25);
        for e in [spot, rangeless, named, sun, point] {
            assert!(world.get::<FinShadows>(e).is_some() && adopted.lights.contains(&e));
        }
        assert!(world.get::<FinShadows>(outside).is_none());
        assert_eq!(world.get::<SpotLight>(outside).unwrap().radius, 20.0);
    }
}
