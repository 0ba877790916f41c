//! A glTF opened in the editor, loaded by Bevy's own loader — materials,
//! textures, hierarchy, `KHR_lights_punctual` lights and cameras, as a Bevy
//! game gets them — and, when it brings no light or camera, a first view
//! that is readable at any scale and from inside a room.
//!
//! The ground truth and the analysis views trace what the plugin sees:
//! [`bevy_shadow_fins::scene_snapshot`] of the spawned entities, not a
//! second reading of the file.

use std::{path::Path, sync::Arc};

use bevy::{light::SunDisk, prelude::*};
use bevy_shadow_fins::{FinShadowSettings, GltfSceneLoading};
use shadow_fins::{
    default_view::{DefaultView, default_view_of},
    light::Light,
};

use crate::state::EditorSceneRoot;
use crate::{
    EditorState,
    ground::AddedGround,
    orbit::OrbitCamera,
    state::{EditorCamera, EditorLight, EditorMesh, LightKind, LightParams, LoadedScene},
};

/// The illuminance the default light gives the surface under it, lux: a white
/// surface reads mid-grey at Bevy's default exposure (EV100 9.7), as the demo's
/// 1 Mlm light 6 m above its ground does.
pub const READABLE_LUX: f32 = 2000.0;

/// Bevy's point and spot lights attenuate by `1 / max(d², 10⁻⁴)`
/// (`getDistanceAttenuation`, `pbr_lighting.wgsl`): nothing is lit as if
/// nearer than a centimetre.
pub const BEVY_MIN_DISTANCE_SQUARED: f32 = 1e-4;

/// The lumens of a light `distance` above a surface that give it
/// [`READABLE_LUX`]: Bevy spreads a point or spot light's lumens over the
/// sphere (`E = Φ / 4π·max(d², 10⁻⁴)`), so the light's power follows the
/// scene's scale squared down to Bevy's centimetre floor (a kilometre valley
/// gets 10¹⁰ lm, a millimetre box 2.5 lm).
pub fn readable_lumens(distance: f32) -> f32 {
    let d = if distance.is_finite() && distance > 0.0 { distance } else { 1.0 };
    (4.0 * std::f32::consts::PI * (d * d).max(BEVY_MIN_DISTANCE_SQUARED) * READABLE_LUX).min(f32::MAX / 2.0)
}

/// A glTF being loaded (beside the plugin's `GltfSceneLoading`); the
/// scene it replaces stays until it is spawned.
#[derive(Component)]
pub(crate) struct PendingGltf {
    name: String,
    keep_light: bool,
}

/// How long a load that neither fails nor spawns is waited for.
pub const GLTF_LOAD_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(60);

/// Starts loading `path` with Bevy's loader, in place of any load still
/// pending (the last request wins). A file that does not exist or that the
/// core's importer rejects (its errors are typed and it refuses hostile
/// sizes before reading them) is an error at once; Bevy's own errors arrive
/// later, in [`finish_gltf_loads`].
pub(crate) fn start_gltf_load(
    commands: &mut Commands,
    assets: &AssetServer,
    pending: impl Iterator<Item = Entity>,
    path: &Path,
    keep_light: bool,
) -> Result<(), String> {
    let import =
        shadow_fins::gltf_import::load_gltf(path).map_err(|e| format!("could not open {}: {e}", path.display()))?;
    if import.scene.objects.is_empty() {
        return Err(format!("could not open {}: it has no mesh", path.display()));
    }
    cancel_pending(commands, pending);
    // The scene the core read is the one Bevy must spawn.
    let root = bevy_shadow_fins::spawn_gltf_scene(commands, assets, path, import.scene_index.unwrap_or(0));
    let name = path.file_name().map_or("scene".into(), |n| n.to_string_lossy().into_owned());
    commands.entity(root).insert(PendingGltf { name, keep_light });
    Ok(())
}

/// Drops loads still pending (a newer request replaces them).
pub(crate) fn cancel_pending(commands: &mut Commands, pending: impl Iterator<Item = Entity>) {
    for e in pending {
        commands.entity(e).despawn();
    }
}

/// Descendants of `root` with a `T`, in the file's order.
fn under<T: Component>(world: &mut World, root: Entity) -> Vec<Entity> {
    bevy_shadow_fins::descendants_with::<T>(world, root)
}

/// Replaces the scene with a glTF once Bevy has spawned it (the frame after,
/// so its transforms and visibility are propagated): its first light becomes
/// the editor's light, its first camera the editor's view, unless the user's
/// light is kept; without them the default view is used.
pub(crate) fn finish_gltf_loads(world: &mut World) {
    let mut pending = world.query::<(Entity, &PendingGltf, &GltfSceneLoading)>();
    let loads: Vec<(Entity, String, bool, GltfSceneLoading)> =
        pending.iter(world).map(|(e, p, l)| (e, p.name.clone(), p.keep_light, l.clone())).collect();
    for (root, name, keep_light, loading) in loads {
        let failed = loading.failed(world.resource::<AssetServer>()).or_else(|| {
            (!loading.is_ready() && loading.started.elapsed() > GLTF_LOAD_TIMEOUT)
                .then(|| format!("Bevy had not spawned it after {} s", GLTF_LOAD_TIMEOUT.as_secs()))
        });
        if let Some(e) = failed {
            world.resource_mut::<EditorState>().error = Some(format!("could not open {name}: {e}"));
            world.despawn(root);
            continue;
        }
        if !loading.is_ready() {
            continue;
        }
        let snapshot = bevy_shadow_fins::scene_snapshot(world, Some(root));
        let Some(view) = default_view_of(&snapshot.scene) else {
            world.resource_mut::<EditorState>().error =
                Some(format!("could not open {name}: no mesh Bevy drew is readable"));
            world.despawn(root);
            continue;
        };
        // The new scene replaces the old one.
        let old: Vec<Entity> =
            world.query_filtered::<Entity, Or<(With<EditorMesh>, With<EditorSceneRoot>)>>().iter(world).collect();
        for e in old {
            world.despawn(e);
        }
        world.entity_mut(root).remove::<(PendingGltf, GltfSceneLoading)>().insert(EditorSceneRoot);
        let scene = snapshot.scene;
        let (objects, triangles) = (scene.objects.len(), scene.triangle_count());
        // A ground to catch the shadow, when the file has none (a helmet, a
        // character alone): spawned below, once the scene is the loaded one.
        let add_ground = world.get_resource::<crate::EditorOptions>().is_none_or(|o| o.add_ground);
        match view.missing_ground {
            Some(ground) => world.insert_resource(AddedGround { ground, shown: add_ground }),
            None => _ = world.remove_resource::<AddedGround>(),
        }
        let ground = view.missing_ground.is_some() && add_ground;
        let extent = scene.diagonal().unwrap_or(1.0).max(1e-6);
        let lights = adopt_lights(world, root, keep_light, &view, extent);
        let camera = adopt_camera(world, root, &view, extent);
        // `--animation-time` is for the glTF the editor opens with; later ones start at 0.
        let start = world.get_resource_mut::<crate::EditorOptions>().and_then(|mut o| o.animation_time.take());
        let start = start.unwrap_or(0.0);
        let animations = crate::animation::adopt_animations(world, root, Some(&loading.gltf), start);
        let generation = world.get_resource::<LoadedScene>().map_or(1, |l| l.generation + 1);
        world.insert_resource(LoadedScene { name: name.clone(), scene: Arc::new(scene), generation, extent });
        crate::ground::apply_added_ground(world);
        let mut skipped = match snapshot.skipped.len() {
            0 => String::new(),
            n => format!("; {n} meshes unreadable (not in the ground truth, no fin shadow)"),
        };
        if !snapshot.approximated.is_empty() {
            skipped += &format!(
                "; {} alpha-masked meshes whose mask is unreadable (modelled solid), or posed \
                 meshes not posable yet (the ground truth shares that)",
                snapshot.approximated.len()
            );
        }
        let inside = if view.inside { ", seen from inside" } else { "" };
        if !animations.is_empty() {
            skipped += &format!("; {animations}");
        }
        if ground {
            skipped += "; a ground added under it (the file has none; switch it in View)";
        }
        world.resource_mut::<EditorState>().status = Some(format!(
            "loaded {name}: {objects} meshes, {triangles} triangles, {lights}, {camera}{inside}{skipped}"
        ));
    }
}

/// The glTF's lights: the first spot, directional or point light becomes the
/// editor's light (its position, direction, colour, power; a point light
/// becomes the editor's disk facing down, as fins do not model spheres yet)
/// and is despawned; the others keep shining with fin shadows
/// (`give_gltf_lights_fin_shadows`). Without any, the default view's light,
/// with [`readable_lumens`]. Returns what it did, for the status line.
fn adopt_lights(world: &mut World, root: Entity, keep_light: bool, view: &DefaultView, extent: f32) -> String {
    let spots = under::<SpotLight>(world, root);
    let suns = under::<DirectionalLight>(world, root);
    let points = under::<PointLight>(world, root);
    // The file's first light (its order) whose place is finite.
    let usable = |world: &World, e: Entity| {
        world.get::<GlobalTransform>(e).is_some_and(|t| {
            t.translation().is_finite() && Vec3::from(t.affine().matrix3 * bevy::math::Vec3A::NEG_Z).length() > 0.0
        })
    };
    let mut all: Vec<Entity> = spots.iter().chain(&suns).chain(&points).copied().collect();
    let order = under::<ChildOf>(world, root);
    all.sort_by_key(|e| order.iter().position(|x| x == e));
    let first = all.into_iter().find(|&e| usable(world, e));
    let fallback_radius = match view.light {
        Light::Disk(d) => d.radius,
        _ => extent * 0.05,
    };
    let settings =
        world.query_filtered::<&FinShadowSettings, With<EditorLight>>().iter(world).next().copied().unwrap_or_default();
    let count = spots.len() + suns.len() + points.len();
    if !keep_light {
        let mut params = *world.resource::<LightParams>();
        match first {
            Some(light) => {
                let radius = bevy_shadow_fins::gltf_light_radius_or(world, light, fallback_radius);
                let transform = world.get::<GlobalTransform>(light).copied().unwrap_or_default();
                params.position = transform.translation();
                params.direction = (transform.affine().matrix3 * bevy::math::Vec3A::NEG_Z).into();
                params.radius = radius;
                let e = world.entity(light);
                if let Some(spot) = e.get::<SpotLight>() {
                    (params.kind, params.intensity) = (LightKind::Spot, spot.intensity);
                    params.color = spot.color.to_linear().to_f32_array_no_alpha();
                } else if let Some(sun) = e.get::<DirectionalLight>() {
                    (params.kind, params.illuminance) = (LightKind::Sun, sun.illuminance);
                    params.color = sun.color.to_linear().to_f32_array_no_alpha();
                    params.sun_angle = e.get::<SunDisk>().map_or(SunDisk::EARTH.angular_size, |d| d.angular_size);
                } else if let Some(point) = e.get::<PointLight>() {
                    (params.kind, params.intensity) = (LightKind::Point, point.intensity);
                    params.color = point.color.to_linear().to_f32_array_no_alpha();
                    params.direction = Vec3::NEG_Y;
                }
                world.despawn(light);
            }
            None => {
                if let Light::Disk(d) = view.light {
                    (params.position, params.direction, params.radius) = (d.center, d.normal, d.radius);
                }
                params.intensity = readable_lumens(view.light_distance);
                if params.kind == LightKind::Sun {
                    // A sun has no distance: the editor's own (the glTF set none).
                    params.kind = LightKind::FinLight;
                }
            }
        }
        world.insert_resource(params);
    }
    let adopted = bevy_shadow_fins::give_gltf_lights_fin_shadows(world, root, settings, fallback_radius);
    match (count, keep_light) {
        (0, false) => "no light in the file (default light)".into(),
        (0, true) => "the kept light (none in the file)".into(),
        (n, false) => {
            format!("{n} lights from the file (the first is the editor's, {} more fin-shadowed)", adopted.lights.len())
        }
        (n, true) => format!("{n} lights from the file beside the kept light"),
    }
}

/// Near and far planes that hold a scene `extent` across from anywhere the
/// orbit may go (the default view's, widened).
pub(crate) fn fit_clip_planes(projection: &mut Projection, view: Option<&DefaultView>, extent: f32) {
    if let Projection::Perspective(p) = projection {
        let near = view.map_or(p.near, |v| v.near).min(extent * 1e-3);
        p.near = near.max(f32::MIN_POSITIVE);
        p.far = view.map_or(p.far, |v| v.far).max(extent * 100.0);
    }
}

/// The glTF's cameras are turned off (they would draw over the editor's
/// view); the first gives the editor its view, else the default view does
/// (also when the user's light is kept: no setting holds a camera). Near plane and zoom follow the scene's size.
fn adopt_camera(world: &mut World, root: Entity, view: &DefaultView, extent: f32) -> String {
    // Already off (`spawn_gltf_scene` turns them off as they spawn).
    let cameras = under::<Camera3d>(world, root);
    let finite =
        |world: &World, c: Entity| world.get::<GlobalTransform>(c).is_some_and(|t| t.translation().is_finite());
    let from_file = cameras.iter().copied().find(|&c| finite(world, c)).map(|c| {
        let transform = world.get::<GlobalTransform>(c).copied().unwrap_or_default();
        let fov = match world.get::<Projection>(c) {
            Some(Projection::Perspective(p)) => Some(p.fov),
            _ => None,
        };
        (transform, fov)
    });
    let mut editor = world.query_filtered::<(&mut OrbitCamera, &mut Projection), With<EditorCamera>>();
    let Ok((mut orbit, mut projection)) = editor.single_mut(world) else { return "no editor camera".into() };
    fit_clip_planes(&mut projection, Some(view), extent);
    orbit.scale = extent;
    // Always, kept light or not: settings hold no camera, and the view
    // before (the demo's, another file's) is fitted to another scene.
    match from_file {
        Some((transform, fov)) => {
            let position = transform.translation();
            let forward = Vec3::from(transform.affine().matrix3 * bevy::math::Vec3A::NEG_Z).normalize_or(Vec3::NEG_Z);
            // Orbit about the point ahead of it nearest to the subject.
            let ahead = (view.camera.target - position).dot(forward).max(extent * 0.05);
            *orbit = OrbitCamera { scale: extent, ..OrbitCamera::looking_at(position, position + forward * ahead) };
            if let (Projection::Perspective(p), Some(fov)) = (&mut *projection, fov) {
                p.fov = fov;
            }
            format!("the file's camera ({} in it)", cameras.len())
        }
        None => {
            *orbit = OrbitCamera { scale: extent, ..OrbitCamera::looking_at(view.camera.position, view.camera.target) };
            if let Projection::Perspective(p) = &mut *projection {
                p.fov = view.camera.vertical_fov.to_radians();
            }
            "the default view".into()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readable_lumens_give_the_same_illuminance_at_any_scale_down_to_bevys_floor() {
        let lux = |d: f32| readable_lumens(d) / (4.0 * std::f32::consts::PI * (d * d).max(BEVY_MIN_DISTANCE_SQUARED));
        for d in [1e-4_f32, 1e-3, 0.5, 6.0, 500.0, 5e4] {
            assert!((lux(d) / READABLE_LUX - 1.0).abs() < 1e-4, "{d}: {} lux", lux(d));
        }
        // The demo's 1 Mlm light ~6 m above its ground is about this readable.
        assert!((readable_lumens(6.0) / 1e6 - 0.9).abs() < 0.1);
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(readable_lumens(bad).is_finite() && readable_lumens(bad) > 0.0);
        }
    }
}
