//! The frame builder's system (`PostUpdate`, [`FinFramesUpdate`]): which
//! lights have fin shadows, which of their frames changed (a caster, the
//! light, a setting, the budget), and the caster set brought up to date
//! before any frame is rebuilt (`casters/`).

use crate::{
    budget::{FinDegradation, FinDeviceLimits, FinShadowBudget, FinShadowsUnsupported},
    casters::{CasterScene, CasterSignature, FinCasterUpdates, SlotSources},
    frame::sun_fit,
    hashing::{hash_floats, hash_layers},
    settings::{FinLight, FinShadowSettings, FinShadowView, NotFinShadowCaster},
};
use crate::{
    casters::{
        gpu_geometry::GpuMeshGeometry,
        mesh::{CachedMesh, Casters, PosedCaster},
        reach::LightSees,
    },
    frame::{
        FinFrames, FinLightFrame, FrameKey, LightShading, MAX_FIN_LIGHTS,
        build::{FrameAsked, FrameLimits, LightState, light_frame},
        lights::{DirectionalLights, LightSource, OtherLights, SpotLights, faces_of, light_key, light_sources},
    },
    stats::{FinFrameStats, FinLightStats, FinShadowStats, set_stats},
};
use bevy::{
    asset::AssetId,
    camera::{primitives::Aabb, visibility::RenderLayers},
    mesh::Mesh,
    prelude::*,
};
use shadow_fins::light::{CubeFace, Light};
use std::{
    collections::{HashMap, HashSet},
    hash::{Hash, Hasher},
    sync::Arc,
};

pub(crate) fn build(app: &mut App) {
    app.init_resource::<FinFrames>()
        .init_resource::<MeshCache>()
        .init_resource::<crate::casters::cutout::CutoutCache>()
        .init_resource::<FinShadowStats>()
        .init_resource::<FinCasterScans>()
        .init_resource::<FinCasterUpdates>()
        .add_systems(
            PostUpdate,
            (update_fin_frames, mirror_first_light_stats)
                .chain()
                .in_set(FinFramesUpdate)
                .after(TransformSystems::Propagate)
                // A sun's window reads this frame's boxes and camera projections.
                .after(bevy::camera::visibility::VisibilitySystems::CalculateBounds)
                .after(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate)
                .after(bevy::camera::CameraUpdateSystems),
        );
}

/// Where every fin-shadowed light's frame is rebuilt (`PostUpdate`).
#[derive(bevy::ecs::schedule::SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct FinFramesUpdate;

#[derive(Resource, Default)]
pub(crate) struct MeshCache {
    pub(crate) meshes: HashMap<AssetId<Mesh>, CachedMesh>,
    /// Bumped for every frame built, for every light: a read-back's
    /// generation names one light's one frame.
    pub(crate) generation: u64,
    /// Posed casters (skinned, morphed), per entity with its pose's hash:
    /// rebuilt when the pose changed.
    pub(crate) posed: HashMap<Entity, PosedCaster>,
    /// Per skinned or morphed mesh, its topology at rest packed with what
    /// poses it on the GPU (`None`: it cannot be posed there).
    pub(crate) posable: HashMap<AssetId<Mesh>, Option<Arc<GpuMeshGeometry>>>,
    /// [`FinGpuPosing`](crate::FinGpuPosing) as the posed casters were posed.
    pub(crate) gpu_posing: bool,
    pub(crate) lights: HashMap<FrameKey, LightState>,
    /// The `CutoutCache` generation the frames were built with.
    pub(crate) cutout_generation: u64,
    /// The casters as the last frames were built from (`casters/mod.rs`):
    /// updated in place when only some casters changed.
    pub(crate) scene: Option<CasterScene>,
}

/// How many times the frame builder has walked every mesh to sign the
/// casters. Only what may change every caster at once walks: a mesh asset
/// loading, edited or removed, a material's cut-out changing, a skin's bind
/// poses loading, a sun starting or stopping to fit the views. A caster that
/// moved, appeared, went, was hidden or shown, or changed its layers, shadow
/// flags or material is signed alone ([`FinCasterUpdates`](crate::FinCasterUpdates)
/// counts the ones rebuilt in place), so a still scene — or one where a few
/// casters move — costs no walk however many entities it holds (Bevy's change
/// ticks are still checked per entity; issue 16's "big scenes that move"; a
/// diagnostic).
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FinCasterScans(pub u64);

/// What tells the frame builder that a caster changed since the last frame.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct CasterChanges<'w, 's> {
    #[allow(clippy::type_complexity)]
    pub(crate) changed: Query<
        'w,
        's,
        Entity,
        (
            With<Mesh3d>,
            Or<(
                Changed<GlobalTransform>,
                Changed<Mesh3d>,
                Changed<InheritedVisibility>,
                Changed<RenderLayers>,
                // Bevy rewrites a skinned mesh's box every frame; its pose
                // (`poses`) says whether the caster changed.
                (Changed<Aabb>, Without<bevy::camera::visibility::DynamicSkinnedMeshBounds>),
                Added<bevy::light::NotShadowCaster>,
                Added<NotFinShadowCaster>,
                // What poses it (a skin or morph weights arriving or swapped).
                Changed<bevy::mesh::skinning::SkinnedMesh>,
                Changed<bevy::mesh::morph::MeshMorphWeights>,
                // What it casts with (its material id is in its signature).
                Changed<MeshMaterial3d<StandardMaterial>>,
            )>,
        ),
    >,
    pub(crate) removed_meshes: RemovedComponents<'w, 's, Mesh3d>,
    pub(crate) removed_not_shadow: RemovedComponents<'w, 's, bevy::light::NotShadowCaster>,
    pub(crate) removed_not_fin: RemovedComponents<'w, 's, NotFinShadowCaster>,
    pub(crate) removed_layers: RemovedComponents<'w, 's, RenderLayers>,
    pub(crate) removed_boxes: RemovedComponents<'w, 's, Aabb>,
    pub(crate) removed_transforms: RemovedComponents<'w, 's, GlobalTransform>,
    pub(crate) removed_visibility: RemovedComponents<'w, 's, InheritedVisibility>,
    pub(crate) removed_materials: RemovedComponents<'w, 's, MeshMaterial3d<StandardMaterial>>,
    pub(crate) scans: ResMut<'w, FinCasterScans>,
    pub(crate) updates: ResMut<'w, FinCasterUpdates>,
    pub(crate) kept: Local<'s, CasterSignature>,
    /// Skinned and morphed casters, posed as Bevy draws them.
    pub(crate) poses: crate::casters::pose::Poses<'w, 's>,
}

impl CasterChanges<'_, '_> {
    /// The mesh entities that changed since the last call: changed or
    /// removed components, and the posed casters whose pose may have changed
    /// (the removal readers are drained either way).
    fn take_changed(&mut self) -> HashSet<Entity> {
        let mut changed: HashSet<Entity> = self.changed.iter().collect();
        changed.extend(self.removed_meshes.read());
        changed.extend(self.removed_not_shadow.read());
        changed.extend(self.removed_not_fin.read());
        changed.extend(self.removed_layers.read());
        changed.extend(self.removed_boxes.read());
        changed.extend(self.removed_transforms.read());
        changed.extend(self.removed_visibility.read());
        changed.extend(self.removed_materials.read());
        changed.extend(self.poses.changed_poses());
        changed
    }
}

/// The casters' meshes and materials, and what changed of them.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct CasterAssets<'w, 's> {
    pub(crate) meshes: Res<'w, Assets<Mesh>>,
    pub(crate) mesh_events: MessageReader<'w, 's, AssetEvent<Mesh>>,
    /// A skin's inverse bind poses loading or changing re-poses its casters
    /// (optional: a world without Bevy's skinning has none).
    pub(crate) bindpose_events:
        Option<MessageReader<'w, 's, AssetEvent<bevy::mesh::skinning::SkinnedMeshInverseBindposes>>>,
    pub(crate) gpu_posing: Option<Res<'w, crate::casters::pose::FinGpuPosing>>,
    pub(crate) materials: crate::casters::cutout::CasterMaterials<'w, 's>,
}

/// Rebuilds each light's frame when it, a setting or a caster changed.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
pub(crate) fn update_fin_frames(
    fin_lights: Query<(Entity, &FinLight, &FinShadowSettings, &GlobalTransform)>,
    mut spot_lights: SpotLights,
    mut directional_lights: DirectionalLights,
    mut lights: OtherLights,
    casters: Casters,
    mut changes: CasterChanges,
    light_layers: Query<&RenderLayers>,
    views: Query<(&GlobalTransform, &Projection), With<FinShadowView>>,
    mut light_stats: Query<&mut FinLightStats>,
    mut assets: CasterAssets,
    budget: Res<FinShadowBudget>,
    device: Res<FinDeviceLimits>,
    unsupported: Option<Res<FinShadowsUnsupported>>,
    mut cache: ResMut<MeshCache>,
    mut frames: ResMut<FinFrames>,
) {
    let meshes = &assets.meshes;
    // Bumps the casters' epoch: the same entities, new triangles or cut-outs.
    let mut meshes_changed = false;
    // Any mesh event (one finishing loading, too) changes what casts; so
    // does a change of what an alpha-masked material cuts out.
    let mut mesh_event = false;
    assets.materials.refresh();
    let cutouts = assets.materials.cache.generation();
    if cutouts != cache.cutout_generation {
        cache.cutout_generation = cutouts;
        meshes_changed = true;
        mesh_event = true;
    }
    if let Some(events) = assets.bindpose_events.as_mut()
        && events.read().count() > 0
    {
        // Rare (a skin loading): every posed caster is posed again.
        mesh_event = true;
        cache.posed.clear();
    }
    // Compared with the last frame's, not by change detection: a mutable
    // borrow (an editor's checkbox) is a change, and a removal is none.
    let gpu_posing = assets.gpu_posing.as_ref().is_none_or(|g| g.0);
    if gpu_posing != cache.gpu_posing {
        cache.gpu_posing = gpu_posing;
        // Posed anew, for the GPU or not: new geometry for the GPU's frames.
        meshes_changed = true;
        mesh_event = true;
        cache.posed.clear();
    }
    for event in assets.mesh_events.read() {
        mesh_event = true;
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            cache.meshes.remove(id);
            cache.posable.remove(id);
            assets.materials.cache.forget_mesh(*id);
            // A posed mesh of that asset is posed again (rare: clear them all).
            cache.posed.clear();
            meshes_changed = true;
        }
    }
    let changed_casters = changes.take_changed();
    let (mut sources, invalid) = light_sources(&fin_lights, &spot_lights, &directional_lights, &lights);
    for source in &mut sources {
        if let Ok(layers) = light_layers.get(source.entity) {
            source.layers = layers.clone();
        }
    }
    // A light with no finite position or direction shadows nothing and takes
    // no share of the budget.
    for entity in invalid {
        set_stats(&mut light_stats, entity, FinFrameStats { up_to_date: true, ..default() });
    }
    // Past the limit, the lights that matter most to the views keep their slots.
    let viewers: Vec<super::priority::Viewer> =
        views.iter().filter_map(|(t, p)| super::priority::Viewer::new(t, p)).collect();
    let had_fins = |entity| {
        cache.lights.contains_key(&(entity, None)) || cache.lights.contains_key(&(entity, Some(CubeFace::ALL[0])))
    };
    for cut in super::priority::keep_most_important(&mut sources, &viewers, MAX_FIN_LIGHTS, had_fins) {
        warn_once!(
            "fin shadows: more than {MAX_FIN_LIGHTS} fin-shadowed lights; the rest keep Bevy's shadows \
             (a FinLight past the limit is not lit)"
        );
        let over = FinFrameStats {
            degraded: FinDegradation::TooManyLights { max: MAX_FIN_LIGHTS as u32 }.into(),
            up_to_date: true,
            ..default()
        };
        set_stats(&mut light_stats, cut.entity, over);
    }
    if let Some(why) = unsupported {
        let off = FinFrameStats { degraded: FinDegradation::Unsupported(why.0).into(), up_to_date: true, ..default() };
        for s in &sources {
            set_stats(&mut light_stats, s.entity, off);
        }
        return;
    }
    // The boxes only matter to suns fitted to the views.
    let fitting = sources.iter().any(|s| matches!(s.light, Light::Sun(_)) && s.settings.fit_sun_to_views);
    let kept = &mut *changes.kept;
    if meshes_changed {
        kept.mesh_epoch += 1;
    }
    // The casters' part of every frame's signature: the changed casters
    // signed again (change detection), every caster only when something
    // changed them all (`casters/mod.rs`).
    if mesh_event || kept.signature.is_none() || kept.fitting != fitting || !changed_casters.is_empty() {
        let some = if mesh_event { None } else { Some(&changed_casters) };
        let materials = &assets.materials;
        if kept.update(some, &casters, meshes, |e| materials.material_of(e), &changes.poses, fitting) {
            changes.scans.0 += 1;
        }
    }
    let (scene_box, every_mesh_boxed) = (kept.scene_box, kept.every_mesh_boxed);
    let casters_signature = kept.signature;
    // Suns fit their maps to the cameras' view of the scene's box.
    if fitting && every_mesh_boxed && scene_box.0.x <= scene_box.1.x {
        let volumes = sun_fit::view_volumes(views.iter(), scene_box);
        for source in &mut sources {
            if let (Light::Sun(sun), Some(volumes), true) = (&source.light, &volumes, source.settings.fit_sun_to_views)
            {
                let previous = cache.lights.get(&(source.entity, None)).and_then(|s| s.window);
                source.window = sun_fit::sun_window(volumes, scene_box, sun, previous);
            }
        }
    }
    // One frame per light, six per point light (its cube faces).
    let sources: Vec<(usize, &LightSource, Option<CubeFace>)> = sources
        .iter()
        .enumerate()
        .flat_map(|(layer, source)| faces_of(&source.light).into_iter().map(move |face| (layer, source, face)))
        .collect();
    cache.lights.retain(|key, _| sources.iter().any(|(_, s, face)| (s.entity, *face) == *key));

    // The maps' budget is split between the frames by need: what each
    // one's sparse maps last wanted (a face that sees nothing: its page
    // table), the rest equally.
    let max_buffer = device.max_buffer(&budget);
    let needs: Vec<Option<u64>> = sources
        .iter()
        .map(|(_, source, face)| {
            // The convolution basis shares the budget too: its frames split equally.
            if source.settings.method == crate::settings::FinMethod::Convolution {
                return None;
            }
            let demand = cache.lights.get(&(source.entity, *face))?.tile_demand?;
            // The single-layer methods build one layer's page table.
            let multi = source.settings.method == crate::settings::FinMethod::MultiLayer;
            let layers = if multi { source.settings.layers } else { 1 };
            let resolution = source.settings.map_resolution;
            Some(crate::frame::map_tiles::bytes_needed(Some(demand), resolution, layers))
        })
        .collect();
    let shares = crate::budget::shares_by_need(budget.map_bytes, &needs, max_buffer);
    let mut scene_caught_up = false;
    let mut next = Vec::with_capacity(sources.len());
    let mut changed = frames.0.len() != sources.len();
    for (&(layer, source, face), &map_bytes) in sources.iter().zip(&shares) {
        let key = (source.entity, face);
        // The light's own part of its frame's signature: it, its settings,
        // the budget and how many lights share it.
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        budget.hash(&mut hasher);
        sources.len().hash(&mut hasher);
        map_bytes.hash(&mut hasher);
        let state = cache.lights.entry(key).or_default();
        state.window = source.window;
        state.capacity_epoch.hash(&mut hasher);
        source.settings.hash(&mut hasher);
        hash_floats(&mut hasher, &light_key(&source.light));
        hash_floats(&mut hasher, &source.window.unwrap_or([f32::NAN; 4]));
        hash_floats(&mut hasher, &[source.reach.range, source.reach.cone.unwrap_or(-1.0)]);
        hash_layers(&source.layers, &mut hasher);
        let light_part = hasher.finish();
        let signature = {
            let mut hasher = std::collections::hash_map::DefaultHasher::new();
            (light_part, casters_signature).hash(&mut hasher);
            hasher.finish()
        };
        let previous = frames.0.iter().find(|f| f.key() == key);
        if let Some(previous) = previous
            && state.signature == signature
        {
            // Only the shading may have moved (colour, intensity): keep the maps.
            next.push(FinLightFrame { shading: source.shading, layer, ..previous.clone() });
            changed |= previous.shading != source.shading || previous.layer != layer;
            continue;
        }
        state.signature = signature;
        changed = true;
        let light = source.light;
        if !scene_caught_up {
            let MeshCache { meshes: cached, posed, posable, scene, .. } = &mut *cache;
            let mut sources = SlotSources {
                casters: &casters,
                meshes: &assets.meshes,
                cache: cached,
                posed,
                posable,
                gpu_posing,
                poses: &changes.poses,
                materials: &mut assets.materials,
            };
            catch_up(scene, &mut changes.kept.pending, &mut sources, &mut changes.updates);
            scene_caught_up = true;
        }
        let limits = FrameLimits { max_buffer, map_bytes };
        cache.generation += 1;
        let generation = cache.generation;
        let MeshCache { scene, lights: states, .. } = &mut *cache;
        let (scene, state) = (scene.as_ref().expect("caught up above"), states.get_mut(&key).expect("inserted above"));
        let sees = LightSees { reach: source.reach, layers: &source.layers };
        let asked = FrameAsked { light, face, window: source.window, sees, settings: source.settings, light_part };
        let data = light_frame(scene, asked, generation, limits, state);
        state.stats = data.stats;
        next.push(FinLightFrame {
            light: source.entity,
            face,
            layer,
            shape: light,
            shading: source.shading,
            data: Arc::new(data),
        });
    }
    if !changed {
        return;
    }
    publish_light_stats(&next, &cache, &mut light_stats);
    // A Bevy light no longer fin-shadowed gets its own shadow map back: marked
    // changed, Bevy extracts it again with the user's `shadow_maps_enabled`
    // (`render/bevy_lights.rs` turned it off in the render world).
    // A light no longer fin-shadowed reports nothing any more.
    for gone in frames.0.iter().filter(|f| !next.iter().any(|n| n.light == f.light)) {
        if matches!(gone.shading, LightShading::Bevy { .. }) {
            if let Ok((_, mut spot, ..)) = spot_lights.get_mut(gone.light) {
                spot.set_changed();
            }
            if let Ok((_, mut sun, ..)) = directional_lights.get_mut(gone.light) {
                sun.set_changed();
            }
            if let Ok((_, mut point, ..)) = lights.points.get_mut(gone.light) {
                point.set_changed();
            }
        }
        set_stats(&mut light_stats, gone.light, FinFrameStats::default());
    }
    frames.0 = next;
}

/// Brings the kept scene up to the casters: the `pending` changed entities
/// rebuilt in place, or the scene collected anew (first frame, after a walk,
/// or a change no slot can take).
pub(crate) fn catch_up(
    scene: &mut Option<CasterScene>,
    pending: &mut Option<HashSet<Entity>>,
    sources: &mut SlotSources<'_, '_, '_, '_, '_, '_, '_>,
    updates: &mut FinCasterUpdates,
) {
    let version = scene.as_ref().map_or(0, |s| s.version) + 1;
    let updated = match (scene.as_mut(), pending.take()) {
        (Some(_), Some(changed)) if changed.is_empty() => true,
        (Some(kept), Some(changed)) => {
            let updated = kept.update(&changed, sources);
            if updated {
                updates.frames += 1;
                updates.records += kept.dirty.as_ref().map_or(0, |d| d.len() as u64);
            }
            updated
        }
        _ => false,
    };
    if !updated {
        *scene = Some(CasterScene::collect(sources, version));
    }
    *pending = Some(HashSet::new());
}

/// Every light's [`FinLightStats`] from its frames' latest stats.
pub(crate) fn publish_light_stats(
    frames: &[FinLightFrame],
    cache: &MeshCache,
    light_stats: &mut Query<&mut FinLightStats>,
) {
    let mut start = 0;
    while start < frames.len() {
        let light = frames[start].light;
        let end = start + frames[start..].iter().take_while(|f| f.light == light).count();
        let stats = frames[start..end].iter().filter_map(|f| cache.lights.get(&f.key()).map(|s| s.stats));
        if let Some(combined) = FinFrameStats::combined(stats) {
            set_stats(light_stats, light, combined);
        }
        start = end;
    }
}

/// [`FinShadowStats`] is the first light's [`FinLightStats`]: the first
/// light with a frame, else (no frame: the device is unsupported, or every
/// light is invalid) the first light asking for fin shadows, by entity order.
/// One place keeps the mirror, whoever wrote the light's stats (the frame
/// builder or the GPU read-back).
pub(crate) fn mirror_first_light_stats(
    frames: Res<FinFrames>,
    lights: Query<(Entity, &FinLightStats)>,
    mut stats: ResMut<FinShadowStats>,
) {
    let first = match frames.0.first() {
        Some(f) => lights.get(f.light).ok().map(|(_, s)| s.0),
        None => lights.iter().min_by_key(|(e, _)| *e).map(|(_, s)| s.0),
    };
    let now = first.unwrap_or_default();
    if stats.0 != now {
        stats.0 = now;
    }
}
