//! The scene as the plugin sees it, as the core crate's [`Scene`]: what a CPU
//! oracle or a ground truth of a Bevy world (a glTF as Bevy loaded it, say)
//! must be given to judge the plugin on the same triangles.

use bevy::{ecs::system::SystemState, prelude::*};
use shadow_fins::scene::{Scene, SceneObject};

use crate::{
    NotFinShadowReceiver,
    casters::mesh::{CasterFlags, core_mesh},
    stats::FinSceneError,
};

/// A Bevy world's meshes as the core's scene, and the meshes left out.
#[derive(Debug, Clone, Default)]
pub struct FinSceneSnapshot {
    /// Every drawn mesh the plugin reads, at its `GlobalTransform`: casters
    /// as the plugin's casters (not `NotFinShadowCaster`, not Bevy's
    /// `NotShadowCaster`), receivers as its receivers.
    pub scene: Scene,
    /// Drawn meshes that are not in `scene`, and why: not loaded yet, not a
    /// triangle list, GPU-only data, invalid geometry or a degenerate transform.
    pub skipped: Vec<(Entity, FinSnapshotSkip)>,
    /// Meshes in `scene` that Bevy draws differently (see [`FinSnapshotApproximation`]).
    pub approximated: Vec<(Entity, FinSnapshotApproximation)>,
}

/// A mesh in a [`FinSceneSnapshot`] that Bevy draws otherwise than the
/// plugin (and so the snapshot) models it: the ground truth of the snapshot
/// shares the plugin's error there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FinSnapshotApproximation {
    /// Skinned or morphed but not posable yet (its skin's inverse bind poses
    /// not loaded, no joint attributes): modelled as stored. A posable one is
    /// in its current pose, as the plugin shadows it (`pose.rs`).
    Unposed,
    /// An alpha-masked material modelled solid, as the plugin models it:
    /// its texture still loading, compressed or not readable in the main
    /// world, or its mesh without the UVs it reads (`cutout.rs`). A readable
    /// one is cut out in the snapshot as in the plugin's casters.
    AlphaMasked,
}

/// Why a drawn mesh is not in a [`FinSceneSnapshot`].
#[derive(Debug, Clone, PartialEq)]
pub enum FinSnapshotSkip {
    /// Its `Mesh` asset is not loaded (or was removed).
    NotLoaded,
    /// The plugin cannot read it either (it casts no fin shadow).
    Unreadable(FinSceneError),
    /// Its `GlobalTransform` is degenerate (zero scale) or not finite.
    BadTransform,
}

/// The drawn meshes of `world` (those under `root` only, when given: the
/// entities spawned for one glTF scene, say) as the core's [`Scene`], with
/// the same triangles, transforms and caster/receiver flags the plugin's
/// extraction uses. Hidden meshes (`InheritedVisibility`) are left out, as
/// the plugin leaves them out. Skinned and morphed meshes are in their
/// current pose (joints and morph weights), as the plugin's casters are. A
/// mesh's `RenderLayers` are not applied: the snapshot is every light's
/// (the plugin drops casters a light does not share a layer with). Object
/// names are the entities' `Name`s where they have one.
pub fn scene_snapshot(world: &mut World, root: Option<Entity>) -> FinSceneSnapshot {
    #[allow(clippy::type_complexity)]
    let mut state: SystemState<(
        Query<(
            Entity,
            &Mesh3d,
            &GlobalTransform,
            CasterFlags,
            (Has<NotFinShadowReceiver>, Has<bevy::light::NotShadowReceiver>),
            Option<&Name>,
            Option<&MeshMaterial3d<StandardMaterial>>,
        )>,
        Query<&ChildOf>,
        Res<Assets<Mesh>>,
        Option<Res<Assets<StandardMaterial>>>,
        crate::casters::pose::Poses,
        crate::casters::cutout::CasterMaterials,
    )> = {
        world.init_resource::<crate::casters::cutout::CutoutCache>();
        SystemState::new(world)
    };
    // No `Assets<Mesh>` (a world without Bevy's render plugins): no meshes.
    let Ok((meshes, parents, assets, materials, poses, mut cutouts)) = state.get_mut(world) else {
        return FinSceneSnapshot::default();
    };
    cutouts.refresh();
    let mut posed = std::collections::HashMap::new();
    let under_root =
        |entity: Entity| root.is_none_or(|root| entity == root || parents.iter_ancestors(entity).any(|a| a == root));
    let mut converted = bevy::platform::collections::HashMap::new();
    let mut snapshot = FinSceneSnapshot::default();
    for (entity, mesh3d, transform, flags, not_receiver, name, material) in &meshes {
        if !flags.drawn() || !under_root(entity) {
            continue;
        }
        let Some(mesh) = assets.get(mesh3d.id()) else {
            snapshot.skipped.push((entity, FinSnapshotSkip::NotLoaded));
            continue;
        };
        // Posed as the plugin poses it (`casters::mesh::posed_mesh`), else as stored.
        // The posed triangles only: no packing for the GPU to pose.
        let posed_entry = crate::casters::mesh::posed_mesh(
            entity,
            mesh3d.id(),
            mesh,
            &mut posed,
            &mut Default::default(),
            None,
            &poses,
        )
        .map(|p| (p.mesh.clone(), p.world));
        let unposed = poses.is_posed(entity) && posed_entry.is_none();
        let is_posed = posed_entry.is_some();
        let (core, world) = match posed_entry {
            Some(posed) => posed,
            None => (converted.entry(mesh3d.id()).or_insert_with(|| core_mesh(mesh)).clone(), false),
        };
        let (core, topology, _) = match &core {
            Ok(c) => c,
            Err(e) => {
                snapshot.skipped.push((entity, FinSnapshotSkip::Unreadable(e.clone())));
                continue;
            }
        };
        let name = name.map_or_else(|| format!("{entity}"), |n| n.as_str().to_owned());
        let placed = if world { bevy::math::Affine3A::IDENTITY } else { transform.affine() };
        match SceneObject::shared(name, core.clone(), topology.clone(), placed) {
            Ok(mut object) => {
                object.casts_shadows = flags.casts();
                // Bevy's own opt-out turns fin shadows off too (`NotFinShadowReceiver` adds it).
                object.receives_shadows = !(not_receiver.0 || not_receiver.1);
                // Cut out as the plugin's casters are.
                // (Not cached for a posed mesh: its topology is this pose's.)
                object.cutout = cutouts.cutout(entity, mesh3d.id(), mesh, core, topology, is_posed);
                let masked = object.cutout.is_none()
                    && material
                        .zip(materials.as_ref())
                        .and_then(|(m, all)| all.get(&m.0))
                        .is_some_and(|m| matches!(m.alpha_mode, AlphaMode::Mask(_) | AlphaMode::AlphaToCoverage));
                snapshot.scene.objects.push(object);
                for (is, what) in
                    [(unposed, FinSnapshotApproximation::Unposed), (masked, FinSnapshotApproximation::AlphaMasked)]
                {
                    if is {
                        snapshot.approximated.push((entity, what));
                    }
                }
            }
            Err(_) => snapshot.skipped.push((entity, FinSnapshotSkip::BadTransform)),
        }
    }
    snapshot
}
