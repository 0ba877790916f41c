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
    mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues},
    prelude::*,
    render::extract_resource::ExtractResource,
};
use shadow_fins::{
    fins::{Fin, FinShape, FinSide},
    light::{DiskLight, Light},
    mesh::{Mesh as CoreMesh, Topology},
    oracle::{FinShadowModel, MapRegion, RasterMaps},
    scene::{LightSpaceScene, Scene, SceneObject},
};

use crate::{
    gpu_scene::{GpuCapacity, GpuMeshGeometry, GpuScene, GpuSceneBuilder},
    light::{FinExtraction, FinLight, FinShadowSettings, NotFinShadowCaster},
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
    /// World → light frame: origin and axes (u, v, n).
    pub(crate) origin: Vec3,
    pub(crate) axes: [Vec3; 3],
    pub(crate) radius: f32,
    pub(crate) reference_depth: f32,
    pub(crate) near: f32,
    pub(crate) scene_extent: f32,
    pub(crate) settings: FinShadowSettings,
    /// GPU extraction: geometry, instances and buffer capacities (`None` on the CPU path).
    pub(crate) gpu: Option<GpuScene>,
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
    casters: Query<(Entity, &Mesh3d, &GlobalTransform, Has<NotFinShadowCaster>)>,
    meshes: Res<Assets<Mesh>>,
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
    // Signature of everything the frame depends on: skip all work when unchanged.
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    hash_floats(&mut hasher, &light_transform.to_matrix().to_cols_array());
    hash_floats(&mut hasher, &[light.effective_radius(), light.range]);
    settings.clamped().hash(&mut hasher);
    for (entity, mesh, transform, not_caster) in &casters {
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
    for (_, mesh3d, transform, not_caster) in &casters {
        let Some(mesh) = meshes.get(mesh3d.id()) else { continue };
        let entry = cache.meshes.entry(mesh3d.id()).or_insert_with(|| {
            let converted = core_mesh(mesh);
            if let Err(e) = &converted {
                warn!("fin shadows: mesh {:?} casts no fin shadow: {e:?}", mesh3d.id());
            }
            converted
        });
        let Ok((core, topology, geometry)) = entry else { continue };
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
    cache.generation += 1;
    let data = match settings.extraction {
        FinExtraction::Cpu => cpu_frame(Scene::new(objects), disk, settings, cache.generation, start),
        FinExtraction::Gpu => {
            let MeshCache { gpu, capacity, generation, .. } = &mut *cache;
            let scene = gpu.build(&objects, &gpu_meshes, &disk, capacity);
            let stats = FinFrameStats {
                casters: objects.iter().filter(|o| o.casts_shadows).count(),
                triangles: objects.iter().map(|o| o.mesh.triangle_count()).sum(),
                extract_ms: start.elapsed().as_secs_f32() * 1e3,
                // No caster face: the GPU runs no pass and there is nothing to read back.
                up_to_date: scene.totals[1] == 0,
                ..default()
            };
            FinFrameData {
                generation: *generation,
                stats,
                casters: Vec::new(),
                fins: Vec::new(),
                region: MapRegion { min: Vec2::ZERO, texel: 1.0, resolution: settings.map_resolution },
                origin: disk.center,
                axes: scene.axes,
                radius,
                reference_depth: 0.0,
                near: 0.0,
                scene_extent: scene.extent,
                settings,
                gpu: Some(scene),
            }
        }
    };
    stats.0 = data.stats;
    frame.0 = Some(Arc::new(data));
}

/// The whole extraction on the CPU with the core crate.
fn cpu_frame(
    scene: Scene,
    disk: DiskLight,
    settings: FinShadowSettings,
    generation: u64,
    start: std::time::Instant,
) -> FinFrameData {
    let radius = disk.radius;
    let ls = LightSpaceScene::new(&scene, Light::Disk(disk));
    let model = FinShadowModel::new(&scene, &ls, settings.method.into(), settings.core());
    let region = RasterMaps::covering_region(&model, settings.map_resolution);
    let casters_gpu: Vec<GpuCaster> = model
        .casters
        .iter()
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
    let fins_gpu: Vec<GpuFin> = model.fins.iter().zip(&model.fin_layers).map(|(f, &l)| gpu_fin(f, l)).collect();
    let stats = FinFrameStats {
        casters: scene.objects.iter().filter(|o| o.casts_shadows).count(),
        triangles: scene.triangle_count(),
        silhouettes: model.silhouettes.len(),
        fins: model.fins.len(),
        // Nothing casts: no layer, no map, and the passes have nothing to do.
        layers: if model.casters.is_empty() && model.fins.is_empty() { 0 } else { model.plan.len() },
        extract_ms: start.elapsed().as_secs_f32() * 1e3,
        up_to_date: true,
    };
    FinFrameData {
        generation,
        stats,
        casters: casters_gpu,
        fins: fins_gpu,
        region,
        origin: ls.frame.origin().as_vec3(),
        axes: ls.frame.axes(),
        radius,
        reference_depth: ls.reference_depth,
        near: model.near,
        scene_extent: ls.extent,
        settings,
        gpu: None,
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
