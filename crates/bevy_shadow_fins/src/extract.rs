//! Main world: the fin light and its casters, turned into one [`FinFrame`],
//! rebuilt only when a caster, the light or a setting changed.
//!
//! With [`FinExtraction::Gpu`] (the default) the frame holds the packed caster
//! geometry (built once per mesh) and one transform per caster instance; the
//! render world's compute passes do the rest. With [`FinExtraction::Cpu`] the
//! core crate extracts silhouettes, patches, fins and layers here and the frame
//! holds the map-space casters and fins.

use std::{
    collections::HashMap,
    hash::{Hash, Hasher},
    sync::Arc,
};

use bevy::{
    asset::AssetId,
    camera::primitives::Aabb,
    math::DVec3,
    mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues},
    prelude::*,
    render::extract_resource::ExtractResource,
};
use shadow_fins::{
    fins::{Fin, FinShape, FinSide},
    light::{DiskLight, Light, LightFrame},
    mesh::{Mesh as CoreMesh, Topology},
    oracle::{FinShadowModel, MapRegion, RasterMaps},
    scene::{LightSpaceScene, Scene, SceneObject},
};

use crate::{
    budget::{FinDegradation, FinDeviceLimits, FinShadowBudget, FinShadowsUnsupported, allocate_maps},
    coverage_frame::{CoverageFrame, coverage_frame},
    gpu_scene::{GpuCapacity, GpuMeshGeometry, GpuScene, GpuSceneBuilder},
    light::{FinExtraction, FinLight, FinMethod, FinShadowSettings, NotFinShadowCaster},
};

/// Why a mesh could not be used as a caster (logged once per mesh).
#[derive(Debug, Clone, PartialEq)]
pub enum FinSceneError {
    /// The mesh is not a triangle list (lines, points) — it casts nothing.
    NotTriangles,
    /// The mesh's data was sent to the GPU only (`RenderAssetUsages::RENDER_WORLD`).
    NoMainWorldData,
    /// Invalid geometry (NaN positions, bad indices, no area): the core's error.
    Invalid(shadow_fins::MeshError),
}

/// Counts of what the current frame models.
///
/// With GPU extraction, silhouettes, fins and layers are read back from the
/// GPU a few frames later; `up_to_date` says whether they belong to the latest
/// frame. Read them from the [`FinShadowStats`] resource.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FinFrameStats {
    pub casters: usize,
    pub triangles: usize,
    pub silhouettes: usize,
    pub fins: usize,
    pub layers: usize,
    /// Main-world CPU time of building the frame, ms: the whole extraction on
    /// the CPU path; packing instance transforms on the GPU path.
    pub extract_ms: f32,
    /// The counts describe the current frame (always true on the CPU path).
    pub up_to_date: bool,
    /// Why the frame models less than the settings ask for (a GPU limit or the
    /// [`FinShadowBudget`](crate::FinShadowBudget)); `None` when nothing was cut.
    pub degraded: Option<FinDegradation>,
    /// The penumbra maps' resolution as allocated.
    pub map_resolution: u32,
    /// Where the fins were extracted: the settings' choice, or the CPU when
    /// the scene's geometry did not fit a GPU buffer (see `degraded`).
    pub extraction: FinExtraction,
}

/// What the fin light's shadows currently model (see [`FinFrameStats`]).
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq)]
pub struct FinShadowStats(pub FinFrameStats);

/// One caster triangle in light-map space (see the core's `MapTriangle`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuCaster {
    pub corners: [f32; 6],
    pub normal: [f32; 3],
    pub offset: f32,
    pub min_depth: f32,
    pub max_depth: f32,
    pub layer: u32,
    pub _pad: u32,
}

/// One fin: `header = [kind (0 quad, 1 sector), side (0 inner, 1 outer), layer, 0]`,
/// then the shape's numbers (see `maps.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuFin {
    pub header: [u32; 4],
    pub data: [f32; 12],
}

/// Everything the GPU passes need for one frame, shared with the render world.
#[derive(Debug)]
pub struct FinFrameData {
    /// Bumped whenever the content changed, so the GPU re-uploads only then.
    pub generation: u64,
    pub stats: FinFrameStats,
    pub(crate) casters: Vec<GpuCaster>,
    pub(crate) fins: Vec<GpuFin>,
    pub(crate) region: MapRegion,
    /// Map layers allocated (what fits the budget; the GPU merges the deepest
    /// layers beyond it).
    pub(crate) map_layers: u32,
    /// The largest buffer this frame was built for, bytes.
    pub(crate) limit_bytes: u64,
    /// The most the penumbra maps may take, bytes (`FinShadowBudget::map_bytes`).
    pub(crate) map_limit_bytes: u64,
    /// World → light frame: origin and axes (u, v, n), in f64 so that each
    /// camera's view → light transform is composed without losing precision far
    /// from the world origin.
    pub(crate) origin: DVec3,
    pub(crate) axes: [DVec3; 3],
    pub(crate) radius: f32,
    pub(crate) reference_depth: f32,
    pub(crate) near: f32,
    pub(crate) scene_extent: f32,
    pub(crate) settings: FinShadowSettings,
    /// GPU extraction: geometry, instances and buffer capacities (`None` on the CPU path).
    pub(crate) gpu: Option<GpuScene>,
    /// The coverage method's edges, grid, casters and samples (`None` for fins).
    pub(crate) coverage: Option<CoverageFrame>,
}

/// The current fin frame (`None` without a fin light). Read `stats` for counts.
#[derive(Resource, Clone, Default, ExtractResource)]
pub struct FinFrame(pub Option<Arc<FinFrameData>>);

type CachedMesh = Result<(Arc<CoreMesh>, Arc<Topology>, Arc<GpuMeshGeometry>), FinSceneError>;

#[derive(Resource, Default)]
pub(crate) struct MeshCache {
    meshes: HashMap<AssetId<Mesh>, CachedMesh>,
    signature: u64,
    generation: u64,
    gpu: GpuSceneBuilder,
    /// GPU buffer sizes, grown when a read-back says a frame overflowed them.
    pub(crate) capacity: Option<GpuCapacity>,
    pub(crate) capacity_epoch: u64,
    /// What the latest GPU read-back said did not fit (kept into new frames).
    pub(crate) shortfall: Option<FinDegradation>,
    /// The degradation last warned about.
    pub(crate) warned: Option<FinDegradation>,
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<FinFrame>()
        .init_resource::<MeshCache>()
        .init_resource::<FinShadowStats>()
        .add_systems(PostUpdate, update_fin_frame.after(TransformSystems::Propagate));
}

/// Rebuilds the fin frame when the light, a setting or a caster changed.
#[allow(clippy::type_complexity)]
fn update_fin_frame(
    lights: Query<(&FinLight, &FinShadowSettings, &GlobalTransform)>,
    casters: Query<(Entity, &Mesh3d, &GlobalTransform, Has<NotFinShadowCaster>, Option<&Aabb>)>,
    meshes: Res<Assets<Mesh>>,
    budget: Res<FinShadowBudget>,
    device: Res<FinDeviceLimits>,
    unsupported: Option<Res<FinShadowsUnsupported>>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    mut cache: ResMut<MeshCache>,
    mut frame: ResMut<FinFrame>,
    mut stats: ResMut<FinShadowStats>,
) {
    for event in mesh_events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            cache.meshes.remove(id);
            cache.signature = 0;
        }
    }
    let Some((light, settings, light_transform)) = lights.iter().next() else {
        if frame.0.is_some() {
            frame.0 = None;
            stats.0 = FinFrameStats::default();
        }
        return;
    };
    if let Some(why) = unsupported {
        let off = FinFrameStats { degraded: Some(FinDegradation::Unsupported(why.0)), up_to_date: true, ..default() };
        if stats.0 != off {
            stats.0 = off;
        }
        return;
    }
    // Signature of everything the frame depends on: skip all work when unchanged.
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    hash_floats(&mut hasher, &light_transform.to_matrix().to_cols_array());
    hash_floats(&mut hasher, &[light.effective_radius(), light.range]);
    settings.clamped().hash(&mut hasher);
    budget.hash(&mut hasher);
    for (entity, mesh, transform, not_caster, _) in &casters {
        entity.hash(&mut hasher);
        not_caster.hash(&mut hasher);
        mesh.id().hash(&mut hasher);
        // A mesh that finishes loading changes the frame too.
        meshes.contains(mesh.id()).hash(&mut hasher);
        hash_floats(&mut hasher, &transform.to_matrix().to_cols_array());
    }
    // A read-back that grew the GPU buffers asks for the frame again.
    cache.capacity_epoch.hash(&mut hasher);
    let signature = hasher.finish();
    if signature == cache.signature && frame.0.is_some() {
        return;
    }
    cache.signature = signature;

    let start = std::time::Instant::now();
    let (mut objects, mut gpu_meshes) = (Vec::new(), Vec::new());
    // World bounds of meshes drawn but unreadable here (render-world only,
    // invalid): receivers all the same, so the reference plane must cover them.
    let mut unread_bounds = Vec::new();
    for (_, mesh3d, transform, not_caster, aabb) in &casters {
        let Some(mesh) = meshes.get(mesh3d.id()) else {
            unread_bounds.extend(aabb.map(|b| world_corners(b, transform)));
            continue;
        };
        let entry = cache.meshes.entry(mesh3d.id()).or_insert_with(|| {
            let converted = core_mesh(mesh);
            if let Err(e) = &converted {
                warn!("fin shadows: mesh {:?} casts no fin shadow: {e:?}", mesh3d.id());
            }
            converted
        });
        let Ok((core, topology, geometry)) = entry else {
            unread_bounds.extend(aabb.map(|b| world_corners(b, transform)));
            continue;
        };
        let affine = transform.affine();
        if let Ok(mut o) = SceneObject::shared("mesh", core.clone(), topology.clone(), affine) {
            // Meshes that do not cast still receive: they count for the reference plane.
            o.casts_shadows = !not_caster;
            objects.push(o);
            gpu_meshes.push(geometry.clone());
        }
    }
    let center = light_transform.translation();
    let normal = light_transform.forward().as_vec3();
    let radius = light.effective_radius();
    let Ok(disk) = DiskLight::new(center, normal, radius) else {
        frame.0 = None;
        stats.0 = FinFrameStats::default();
        return;
    };
    let settings = settings.clamped();
    let max_buffer = device.max_buffer(&budget);
    let limits = FrameLimits { max_buffer, map_bytes: budget.map_bytes.min(max_buffer) };
    cache.generation += 1;
    if settings.method == FinMethod::Coverage {
        let data = coverage_data(&objects, disk, settings, cache.generation, start, unread_bounds, limits);
        warn_degradation(&mut cache.warned, data.stats.degraded);
        stats.0 = data.stats;
        frame.0 = Some(Arc::new(data));
        return;
    }
    let mut extraction = settings.extraction;
    let mut gpu_scene = None;
    if extraction == FinExtraction::Gpu {
        let MeshCache { gpu, capacity, .. } = &mut *cache;
        let scene = gpu.build(&objects, &gpu_meshes, &disk, capacity, GpuCapacity::max_for(max_buffer));
        // Buffers sized by the scene itself cannot shrink: past the limit the
        // core crate extracts on the CPU instead.
        match scene.input_bytes().into_iter().find(|(_, bytes)| *bytes > max_buffer) {
            Some((buffer, bytes)) => {
                warn_once!(
                    "fin shadows: the GPU extraction's {buffer} ({bytes} bytes) exceeds the buffer limit; extracting on the CPU"
                );
                extraction = FinExtraction::Cpu;
                gpu_scene = Some(Err(FinDegradation::ExtractedOnCpu { buffer, bytes, limit_bytes: max_buffer }));
            }
            None => gpu_scene = Some(Ok(scene)),
        }
    }
    let receiver_bound = unread_bounds.into_iter().flatten();
    let mut data = match (extraction, gpu_scene) {
        (FinExtraction::Gpu, Some(Ok(scene))) => {
            // Layers are known to the GPU only (a read-back grows them): the
            // maps hold what the GPU last wanted, at the best resolution that
            // fits, and may grow to the most layers that fit at all.
            let asked = if settings.method == FinMethod::MultiLayer { settings.layers } else { 1 };
            let most = allocate_maps(settings.map_resolution, asked, MAP_TEXEL_BYTES, limits.map_bytes).layers;
            let mut scene = scene;
            let wanted = scene.capacity.layers.min(most);
            let alloc = allocate_maps(settings.map_resolution, wanted, MAP_TEXEL_BYTES, limits.map_bytes);
            scene.capacity.layers = alloc.layers;
            scene.max_capacity.layers = most;
            let frame = LightFrame::disk(&disk);
            scene.receiver_depth = receiver_bound.map(|p| frame.to_frame(p).z).fold(0.0, f32::max);
            let stats = FinFrameStats {
                casters: objects.iter().filter(|o| o.casts_shadows).count(),
                triangles: objects.iter().map(|o| o.mesh.triangle_count()).sum(),
                extract_ms: start.elapsed().as_secs_f32() * 1e3,
                // No caster face: the GPU runs no pass and there is nothing to read back.
                up_to_date: scene.totals[1] == 0,
                degraded: alloc.degradation,
                map_resolution: alloc.resolution,
                ..default()
            };
            FinFrameData {
                generation: cache.generation,
                stats,
                casters: Vec::new(),
                fins: Vec::new(),
                region: MapRegion { min: Vec2::ZERO, texel: 1.0, resolution: alloc.resolution },
                map_layers: alloc.layers,
                limit_bytes: limits.max_buffer,
                map_limit_bytes: limits.map_bytes,
                origin: disk.center.as_dvec3(),
                axes: scene.axes,
                radius,
                reference_depth: 0.0,
                near: 0.0,
                scene_extent: scene.extent,
                settings,
                gpu: Some(scene),
                coverage: None,
            }
        }
        (_, fallback) => {
            let mut data =
                cpu_frame(Scene::new(objects), disk, settings, cache.generation, start, receiver_bound, limits);
            if let Some(Err(why)) = fallback {
                // What the CPU path had to cut (maps, dropped casters) shows first.
                data.stats.degraded = data.stats.degraded.or(Some(why));
            }
            data
        }
    };
    data.stats.map_resolution = data.region.resolution;
    data.stats.extraction = if data.gpu.is_some() { FinExtraction::Gpu } else { FinExtraction::Cpu };
    // What the last read-back said the GPU had to drop still holds until a
    // read-back says otherwise (no flicker between re-extractions).
    data.stats.degraded = data.stats.degraded.or(cache.shortfall);
    warn_degradation(&mut cache.warned, data.stats.degraded);
    stats.0 = data.stats;
    frame.0 = Some(Arc::new(data));
}

/// The coverage method's frame: edges and lists from the core crate.
fn coverage_data(
    objects: &[SceneObject],
    disk: DiskLight,
    settings: FinShadowSettings,
    generation: u64,
    start: std::time::Instant,
    unread_bounds: Vec<[Vec3; 8]>,
    limits: FrameLimits,
) -> FinFrameData {
    let scene = Scene::new(objects.to_vec());
    let (coverage, degraded, potential_silhouettes) = coverage_frame(
        &scene,
        disk,
        settings.map_resolution,
        settings.coverage_samples,
        unread_bounds.into_iter().flatten(),
        limits.map_bytes,
        limits.max_buffer,
    );
    let stats = FinFrameStats {
        casters: scene.objects.iter().filter(|o| o.casts_shadows).count(),
        triangles: scene.triangle_count(),
        silhouettes: potential_silhouettes,
        fins: 0,
        layers: if coverage.casters.is_empty() { 0 } else { 1 },
        extract_ms: start.elapsed().as_secs_f32() * 1e3,
        up_to_date: true,
        degraded,
        map_resolution: coverage.region.resolution,
        extraction: FinExtraction::Cpu,
    };
    let axes = shadow_fins::light::LightFrame::disk(&disk).axes_f64();
    FinFrameData {
        generation,
        stats,
        casters: Vec::new(),
        fins: Vec::new(),
        region: coverage.region,
        map_layers: 1,
        limit_bytes: limits.max_buffer,
        map_limit_bytes: limits.map_bytes,
        origin: disk.center.as_dvec3(),
        axes,
        radius: disk.radius,
        reference_depth: 0.0,
        near: coverage.near,
        scene_extent: coverage.extent,
        settings,
        gpu: None,
        coverage: Some(coverage),
    }
}

/// Logs a degradation once per distinct reason (a moving light re-extracts
/// every frame; the same reason is said once, not sixty times a second).
pub(crate) fn warn_degradation(warned: &mut Option<FinDegradation>, now: Option<FinDegradation>) {
    if let Some(why) = now
        && *warned != now
    {
        warn!("fin shadows: {why}");
        *warned = now;
    }
}

/// Bytes per penumbra-map texel (nine 32-bit channels, `fin_types.wgsl`).
pub(crate) const MAP_TEXEL_BYTES: u64 = 9 * 4;

/// The buffer limits one frame is built under.
#[derive(Debug, Clone, Copy)]
struct FrameLimits {
    /// The largest buffer, bytes.
    max_buffer: u64,
    /// All map layers together, bytes.
    map_bytes: u64,
}

/// The eight world-space corners of an entity's bounding box.
fn world_corners(aabb: &Aabb, transform: &GlobalTransform) -> [Vec3; 8] {
    let (c, h) = (Vec3::from(aabb.center), Vec3::from(aabb.half_extents));
    std::array::from_fn(|k| {
        let s = Vec3::new(
            if k & 1 == 0 { -1.0 } else { 1.0 },
            if k & 2 == 0 { -1.0 } else { 1.0 },
            if k & 4 == 0 { -1.0 } else { 1.0 },
        );
        transform.transform_point(c + h * s)
    })
}

/// The whole extraction on the CPU with the core crate.
fn cpu_frame(
    scene: Scene,
    disk: DiskLight,
    settings: FinShadowSettings,
    generation: u64,
    start: std::time::Instant,
    receiver_bound: impl Iterator<Item = Vec3>,
    limits: FrameLimits,
) -> FinFrameData {
    let radius = disk.radius;
    let mut ls = LightSpaceScene::new(&scene, Light::Disk(disk));
    let frame = ls.frame;
    ls.cover_receivers(receiver_bound.map(|p| frame.to_frame(p)));
    let mut core = settings.core();
    let mut model = FinShadowModel::new(&scene, &ls, settings.method.into(), core);
    let mut alloc = allocate_maps(settings.map_resolution, model.plan.len() as u32, MAP_TEXEL_BYTES, limits.map_bytes);
    if (alloc.layers as usize) < model.plan.len() {
        // Fewer layers fit than the plan made: plan again with that many.
        core.layers = alloc.layers;
        model = FinShadowModel::new(&scene, &ls, settings.method.into(), core);
        alloc.layers = alloc.layers.max(model.plan.len() as u32);
    }
    let region = RasterMaps::covering_region(&model, alloc.resolution);
    let mut degraded = alloc.degradation;
    // What does not fit one buffer is dropped (and said so).
    let mut capped = |buffer: &'static str, n: usize, bytes: u64| {
        let keep = (limits.max_buffer / bytes) as usize;
        if n > keep && degraded.is_none() {
            degraded = Some(FinDegradation::Capacity {
                buffer,
                kept: keep as u32,
                wanted: n as u32,
                limit_bytes: limits.max_buffer,
            });
        }
        n.min(keep)
    };
    let n_casters = capped("map casters", model.casters.len(), size_of::<GpuCaster>() as u64);
    let n_fins = capped("fins", model.fins.len(), size_of::<GpuFin>() as u64);
    let casters_gpu: Vec<GpuCaster> = model
        .casters
        .iter()
        .take(n_casters)
        .zip(&model.caster_layers)
        .map(|(t, &layer)| GpuCaster {
            corners: [t.corners[0].x, t.corners[0].y, t.corners[1].x, t.corners[1].y, t.corners[2].x, t.corners[2].y],
            normal: t.normal.to_array(),
            offset: t.offset,
            min_depth: t.min_depth,
            max_depth: t.max_depth,
            layer,
            _pad: 0,
        })
        .collect();
    let fins_gpu: Vec<GpuFin> =
        model.fins.iter().take(n_fins).zip(&model.fin_layers).map(|(f, &l)| gpu_fin(f, l)).collect();
    let stats = FinFrameStats {
        casters: scene.objects.iter().filter(|o| o.casts_shadows).count(),
        triangles: scene.triangle_count(),
        silhouettes: model.silhouettes.len(),
        fins: model.fins.len(),
        // Nothing casts: no layer, no map, and the passes have nothing to do.
        layers: if model.casters.is_empty() && model.fins.is_empty() { 0 } else { model.plan.len() },
        extract_ms: start.elapsed().as_secs_f32() * 1e3,
        up_to_date: true,
        degraded,
        map_resolution: region.resolution,
        extraction: FinExtraction::Cpu,
    };
    FinFrameData {
        generation,
        stats,
        casters: casters_gpu,
        fins: fins_gpu,
        region,
        map_layers: alloc.layers,
        limit_bytes: limits.max_buffer,
        map_limit_bytes: limits.map_bytes,
        origin: ls.frame.origin(),
        axes: ls.frame.axes_f64(),
        radius,
        reference_depth: ls.reference_depth,
        near: model.near,
        scene_extent: ls.extent,
        settings,
        gpu: None,
        coverage: None,
    }
}

fn hash_floats(h: &mut impl Hasher, v: &[f32]) {
    for x in v {
        x.to_bits().hash(h);
    }
}

fn gpu_fin(f: &Fin, layer: u32) -> GpuFin {
    let side = match f.side {
        FinSide::Inner => 0,
        FinSide::Outer => 1,
    };
    match f.shape {
        FinShape::Quad { m0, m1, d0, d1, w0, w1, z0, z1 } => GpuFin {
            header: [0, side, layer, 0],
            data: [m0.x, m0.y, m1.x, m1.y, d0.x, d0.y, d1.x, d1.y, w0, w1, z0, z1],
        },
        FinShape::Sector { center, radius, from, to, depth } => GpuFin {
            header: [1, side, layer, 0],
            data: [center.x, center.y, from.x, from.y, to.x, to.y, radius, depth, 0.0, 0.0, 0.0, 0.0],
        },
    }
}

/// A Bevy mesh's triangles as the core's mesh, with its topology and its
/// packed GPU geometry.
fn core_mesh(mesh: &Mesh) -> CachedMesh {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(FinSceneError::NotTriangles);
    }
    let positions = match mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION) {
        Ok(Some(VertexAttributeValues::Float32x3(p))) => p.iter().map(|p| Vec3::from_array(*p)).collect::<Vec<_>>(),
        Ok(_) => return Err(FinSceneError::NotTriangles),
        Err(_) => return Err(FinSceneError::NoMainWorldData),
    };
    let indices: Vec<u32> = match mesh.try_indices_option() {
        Ok(Some(Indices::U16(i))) => i.iter().map(|&i| i as u32).collect(),
        Ok(Some(Indices::U32(i))) => i.clone(),
        Ok(None) => (0..positions.len() as u32).collect(),
        Err(_) => return Err(FinSceneError::NoMainWorldData),
    };
    let core = CoreMesh::new(positions, indices).map_err(FinSceneError::Invalid)?;
    let topology = Topology::build(&core);
    let geometry = GpuMeshGeometry::pack(&topology);
    Ok((Arc::new(core), Arc::new(topology), Arc::new(geometry)))
}
