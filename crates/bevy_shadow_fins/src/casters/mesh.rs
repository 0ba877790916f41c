//! A caster's mesh: a Bevy mesh as the core's mesh, its topology and its
//! packed GPU geometry (cached per asset); a skinned or morphed caster
//! posed (`pose.rs`); what makes an entity a caster ([`CasterFlags`]).

use crate::settings::NotFinShadowCaster;
use crate::{
    casters::gpu_geometry::{GpuMeshGeometry, GpuPose},
    stats::FinSceneError,
};
use bevy::{
    asset::AssetId,
    camera::{primitives::Aabb, visibility::RenderLayers},
    mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues},
    prelude::*,
};
use shadow_fins::mesh::{Mesh as CoreMesh, Topology};
use std::{
    collections::HashMap,
    hash::{Hash, Hasher},
    sync::Arc,
};

pub(crate) type CachedMesh = Result<(Arc<CoreMesh>, Arc<Topology>, Arc<GpuMeshGeometry>), FinSceneError>;

/// A posed caster as last posed: its pose's hash (with its mesh's), the
/// posed mesh (whose packing is the posable one when the GPU poses it: its
/// words are the mesh at rest), whether its positions are in world space
/// (skinned), and — when the GPU poses it — the pose.
pub(crate) struct PosedCaster {
    pub(crate) key: u64,
    pub mesh: CachedMesh,
    pub world: bool,
    pub gpu: Option<Arc<GpuPose>>,
}

/// `entity`'s mesh (asset `mesh_id`) posed (`pose.rs`), from `posed` while
/// its mesh and pose are the same; `None` when it is not drawn posed.
///
/// The CPU poses it for the oracles, the CPU extraction and the other
/// methods, and keeps the topology at rest with the posed vertices
/// (`Topology::reposed`: planes, normals, creases and bounds recomputed, no
/// rebuild) when that is the posed mesh's topology too — the same welded
/// vertices and faces, which a pose that welds two vertices apart, or folds
/// a face flat, breaks. The GPU extraction then poses it itself
/// (`pose.wgsl`) from the topology at rest; else the topology is rebuilt
/// and the GPU gets the CPU's posed packing, a new mesh each pose. `posable`: the cache of
/// packings the GPU poses, `None` when the GPU is not to pose it.
pub(crate) fn posed_mesh<'a>(
    entity: Entity,
    mesh_id: AssetId<Mesh>,
    mesh: &Mesh,
    posed: &'a mut HashMap<Entity, PosedCaster>,
    at_rest: &mut HashMap<AssetId<Mesh>, CachedMesh>,
    posable: Option<&mut HashMap<AssetId<Mesh>, Option<Arc<GpuMeshGeometry>>>>,
    poses: &crate::casters::pose::Poses,
) -> Option<&'a PosedCaster> {
    if !poses.is_posed(entity) {
        return None;
    }
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    // A mesh swapped for another, already loaded, is posed anew at the same pose.
    mesh_id.hash(&mut hasher);
    poses.hash_pose(entity, &mut hasher);
    let key = hasher.finish();
    if posed.get(&entity).is_none_or(|p| p.key != key) {
        let pose = poses.pose(entity, mesh)?;
        let rest = at_rest.entry(mesh_id).or_insert_with(|| core_mesh(mesh)).as_ref().ok();
        // The rest topology with the posed vertices, when the pose kept it
        // (nearly always): no rebuild, and the GPU may pose it. Else this
        // pose's own topology, posed on the CPU for the GPU too.
        let reposed = rest.and_then(|(core, topology, _)| {
            let topology = topology.reposed(core.indices(), &pose.positions)?;
            Some((core.indices().to_vec(), topology))
        });
        let kept_rest_topology = reposed.is_some();
        let posed_now = match reposed {
            Some((indices, topology)) => CoreMesh::new(pose.positions, indices)
                .map(|core| (Arc::new(core), Arc::new(topology)))
                .map_err(FinSceneError::Invalid),
            None => core_topology_at(mesh, pose.positions),
        };
        // The GPU poses it when the pose kept the topology at rest (then no
        // packing of the posed mesh is made: the posable one stands for it).
        let gpu = rest.filter(|_| kept_rest_topology).zip(posable).and_then(|((_, rest, rest_packing), posable)| {
            let posable = posable.entry(mesh_id).or_insert_with(|| {
                GpuMeshGeometry::pack_posable(rest_packing, rest, &crate::casters::pose::pose_source(mesh), None)
                    .map(Arc::new)
            });
            Some((posable.clone()?, Arc::new(GpuPose::new(&pose.pose))))
        });
        let cached = posed_now.map(|(core, topology)| {
            let geometry = match &gpu {
                Some((posable, _)) => posable.clone(),
                None => Arc::new(GpuMeshGeometry::pack(&topology)),
            };
            (core, topology, geometry)
        });
        let gpu = gpu.map(|(_, pose)| pose);
        posed.insert(entity, PosedCaster { key, mesh: cached, world: pose.world, gpu });
    }
    posed.get(&entity)
}

/// A Bevy mesh's triangles as the core's mesh, with its topology and its
/// packed GPU geometry.
pub(crate) fn core_mesh(mesh: &Mesh) -> CachedMesh {
    let positions = match mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION) {
        Ok(Some(VertexAttributeValues::Float32x3(p))) => p.iter().map(|p| Vec3::from_array(*p)).collect::<Vec<_>>(),
        Ok(_) => return Err(FinSceneError::NotTriangles),
        Err(_) => return Err(FinSceneError::NoMainWorldData),
    };
    core_mesh_at(mesh, positions)
}

/// [`core_mesh`] with the vertices at `positions` (a pose of the mesh).
pub(crate) fn core_mesh_at(mesh: &Mesh, positions: Vec<Vec3>) -> CachedMesh {
    let (core, topology) = core_topology_at(mesh, positions)?;
    let geometry = GpuMeshGeometry::pack(&topology);
    Ok((core, topology, Arc::new(geometry)))
}

/// [`core_mesh_at`] without the GPU packing.
pub(crate) fn core_topology_at(
    mesh: &Mesh,
    positions: Vec<Vec3>,
) -> Result<(Arc<CoreMesh>, Arc<Topology>), FinSceneError> {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(FinSceneError::NotTriangles);
    }
    let indices: Vec<u32> = match mesh.try_indices_option() {
        Ok(Some(Indices::U16(i))) => i.iter().map(|&i| i as u32).collect(),
        Ok(Some(Indices::U32(i))) => i.clone(),
        Ok(None) => (0..positions.len() as u32).collect(),
        Err(_) => return Err(FinSceneError::NoMainWorldData),
    };
    let core = CoreMesh::new(positions, indices).map_err(FinSceneError::Invalid)?;
    let topology = Topology::build(&core);
    Ok((Arc::new(core), Arc::new(topology)))
}

/// What makes a mesh a caster: drawn (`InheritedVisibility`; a mesh hidden
/// by it or a parent casts no shadow, as in Bevy's own maps), and neither
/// `NotFinShadowCaster` nor Bevy's `NotShadowCaster`.
#[derive(bevy::ecs::query::QueryData)]
pub(crate) struct CasterFlags {
    pub(crate) not_fin_caster: Has<NotFinShadowCaster>,
    pub(crate) not_bevy_caster: Has<bevy::light::NotShadowCaster>,
    pub(crate) visibility: Option<&'static InheritedVisibility>,
    pub(crate) aabb: Option<&'static Aabb>,
    pub(crate) layers: Option<&'static RenderLayers>,
}

impl CasterFlagsItem<'_, '_> {
    pub(crate) fn drawn(&self) -> bool {
        self.visibility.is_none_or(|v| v.get())
    }

    pub(crate) fn casts(&self) -> bool {
        !self.not_fin_caster && !self.not_bevy_caster
    }

    /// The mesh's `RenderLayers` (layer 0 without the component, as in Bevy).
    pub(crate) fn layers(&self) -> RenderLayers {
        self.layers.cloned().unwrap_or_default()
    }
}

/// Every mesh that may cast or receive.
pub(crate) type Casters<'w, 's> = Query<'w, 's, (Entity, &'static Mesh3d, &'static GlobalTransform, CasterFlags)>;
