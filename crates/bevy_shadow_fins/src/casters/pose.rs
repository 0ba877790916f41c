//! Casters as Bevy draws them: a skinned mesh in its current pose, a mesh
//! with morph targets at its current weights (issue 16, item 2).
//!
//! Bevy poses these on the GPU, in the vertex shader (`skinning.wgsl`,
//! `morph.wgsl`), and keeps no posed copy. The plugin poses them twice, the
//! same way — each vertex displaced by the weighted morph targets
//! (`Mesh::morph_targets`, target-major), then moved by `Σ wᵢ (Jᵢ · IBPᵢ)`
//! over its four joints (`Jᵢ` the joint entity's `GlobalTransform`, `IBPᵢ`
//! its inverse bind pose), which gives world positions (Bevy's skinning
//! ignores the mesh entity's own transform):
//!
//! - on the CPU, the main-world copy when the pose changes ([`Poses::pose`]),
//!   for the CPU extraction, the other methods, and
//!   [`scene_snapshot`](crate::scene_snapshot), so that oracles and ground
//!   truths judge the pose the plugin shadowed;
//! - on the GPU, for the GPU extraction (`shaders/pose.wgsl`): each posed
//!   instance has its own copy of its mesh's geometry at rest with a pose
//!   section ([`pose_source`], `GpuMeshGeometry::pack_posable`), posed in
//!   place from the [`Pose`] (joint matrices, morph weights) before the
//!   extraction runs. A new pose is then a changed instance record, not new
//!   geometry: nothing is repacked or uploaded but the pose, and the maps
//!   are redrawn only under the caster (`extract_plan.wgsl`'s partial redraw).
//!
//! The GPU poses the topology at rest (welded vertices, faces, edges); a pose
//! whose own topology differs (it welds two vertices apart, or folds a face
//! to nothing) is posed on the CPU for the GPU too (`casters::mesh::posed_mesh`).
//!
//! Cost: the CPU still poses its copy of a posed mesh in every frame in which
//! its pose changed (its time is in the main world's); the topology is
//! rebuilt only for a pose that changed it (`Topology::reposed`).

use std::hash::{Hash, Hasher};

use bevy::{
    mesh::{
        VertexAttributeValues,
        morph::{MeshMorphWeights, MorphWeights},
        skinning::{SkinnedMesh, SkinnedMeshInverseBindposes},
    },
    prelude::*,
};

/// Whether the GPU extraction poses skinned and morphed casters itself
/// (`shaders/pose.wgsl`; see [`FinFrameStats::posed_on_gpu`](crate::FinFrameStats)).
/// On by default. Off, it gets the CPU's posed mesh as new geometry every
/// pose (repacked, uploaded, the maps redrawn whole) — for measuring what
/// posing on the GPU saves (`shadow-fins-render-lab scaling`).
#[derive(Resource, Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Resource)]
pub struct FinGpuPosing(pub bool);

impl Default for FinGpuPosing {
    fn default() -> Self {
        Self(true)
    }
}

/// What poses meshes: skins, morph weights, joints, inverse bind poses.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct Poses<'w, 's> {
    skins: Query<'w, 's, (Entity, &'static SkinnedMesh)>,
    morphs: Query<'w, 's, (Entity, Ref<'static, MeshMorphWeights>)>,
    weights: Query<'w, 's, Ref<'static, MorphWeights>>,
    joints: Query<'w, 's, Ref<'static, GlobalTransform>>,
    bindposes: Res<'w, Assets<SkinnedMeshInverseBindposes>>,
}

/// A posed mesh's vertex positions.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Posed {
    pub positions: Vec<Vec3>,
    /// The positions are in world space (skinned), not the entity's own.
    pub world: bool,
    /// What posed them, for the GPU to pose the same way (`pose.wgsl`).
    pub pose: Pose,
}

/// What a pose is made of, as the GPU's posing pass reads it: the morph
/// weights applied (non-finite ones as 0, one per target the mesh has), then
/// the skin's `Jᵢ · IBPᵢ` (`None`: not skinned; a joint not finite stays
/// NaN, which the pass counts for nothing, as [`skinned`] does).
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct Pose {
    pub morph_weights: Vec<f32>,
    pub joints: Option<Vec<Mat4>>,
}

impl Poses<'_, '_> {
    /// True when `entity` is drawn posed (skinned or with morph weights).
    pub(crate) fn is_posed(&self, entity: Entity) -> bool {
        self.skins.contains(entity) || self.morphs.contains(entity)
    }

    /// The posed entities whose pose may have changed since the last frame:
    /// a joint of its skin moved, or its morph weights changed.
    pub(crate) fn changed_poses(&self) -> impl Iterator<Item = Entity> + '_ {
        let moved = |joints: &[Entity]| joints.iter().any(|j| self.joints.get(*j).is_ok_and(|t| t.is_changed()));
        let skinned = self.skins.iter().filter(move |(_, s)| moved(&s.joints)).map(|(e, _)| e);
        let morphed = self.morphs.iter().filter_map(|(e, m)| {
            let changed = m.is_changed()
                || matches!(&*m, MeshMorphWeights::Reference(source) if self.weights.get(*source).is_ok_and(|w| w.is_changed()));
            changed.then_some(e)
        });
        skinned.chain(morphed)
    }

    /// Hashes `entity`'s pose (its joints' matrices and morph weights) into
    /// `hasher`: what a frame's signature must change with.
    pub(crate) fn hash_pose(&self, entity: Entity, hasher: &mut impl Hasher) {
        if let Ok((_, skin)) = self.skins.get(entity) {
            skin.inverse_bindposes.id().hash(hasher);
            for joint in &skin.joints {
                let m = self.joints.get(*joint).map_or([f32::NAN; 16], |t| t.to_matrix().to_cols_array());
                m.iter().for_each(|x| x.to_bits().hash(hasher));
            }
        }
        if let Some(w) = self.morph_weights(entity) {
            w.iter().for_each(|x| x.to_bits().hash(hasher));
        }
    }

    /// The weights `entity`'s morph targets are drawn at.
    fn morph_weights(&self, entity: Entity) -> Option<&[f32]> {
        match self.morphs.get(entity).ok()?.1.into_inner() {
            MeshMorphWeights::Value { weights } => Some(weights),
            MeshMorphWeights::Reference(source) => self.weights.get(*source).ok().map(|w| w.into_inner().weights()),
        }
    }

    /// `entity`'s mesh in its current pose, or `None` when it is drawn as
    /// stored (neither skinned nor morphed, or what poses it is missing: an
    /// unloaded skin, a mesh without joint attributes — then Bevy draws it
    /// unposed too, or not at all).
    pub(crate) fn pose(&self, entity: Entity, mesh: &Mesh) -> Option<Posed> {
        let mut positions = bind_positions(mesh)?;
        // Morph targets (`Mesh::morph_targets`, target-major) at their weights.
        let morph = self.morph_weights(entity).zip(mesh.try_morph_targets().ok());
        let mut pose = Pose::default();
        if let Some((weights, targets)) = morph {
            let n = positions.len();
            // The weights of the targets the mesh has; a weight the GPU would
            // read as a NaN is no displacement.
            let count = targets.len().checked_div(n).unwrap_or(0);
            pose.morph_weights = weights.iter().take(count).map(|w| if w.is_finite() { *w } else { 0.0 }).collect();
            for (target, w) in targets.chunks_exact(n.max(1)).zip(&pose.morph_weights).filter(|(_, w)| **w != 0.0) {
                for (p, d) in positions.iter_mut().zip(target) {
                    *p += d.position * *w;
                }
            }
        }
        // Skinned when the skin, its matrices and the mesh's joint attributes
        // are all there; else morphed only (in the entity's space), or unposed.
        let skin =
            self.skins.get(entity).ok().and_then(|(_, skin)| self.joint_matrices(skin)).zip(skin_attributes(mesh));
        let Some((matrices, (joints, weights))) = skin else {
            return morph.is_some().then_some(Posed { positions, world: false, pose });
        };
        for ((p, j), w) in positions.iter_mut().zip(joints).zip(weights) {
            *p = skinned(*p, j, w, &matrices);
        }
        pose.joints = Some(matrices);
        Some(Posed { positions, world: true, pose })
    }

    /// Each joint's `Jᵢ · IBPᵢ`, or `None` before the skin has loaded.
    fn joint_matrices(&self, skin: &SkinnedMesh) -> Option<Vec<Mat4>> {
        let bindposes = self.bindposes.get(&skin.inverse_bindposes)?;
        Some(
            skin.joints
                .iter()
                .zip(bindposes.iter())
                .map(|(joint, ibp)| self.joints.get(*joint).map_or(Mat4::NAN, |t| t.to_matrix() * *ibp))
                .collect(),
        )
    }
}

/// `mesh`'s positions as stored: its bind pose.
fn bind_positions(mesh: &Mesh) -> Option<Vec<Vec3>> {
    match mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION) {
        Ok(Some(VertexAttributeValues::Float32x3(p))) => Some(p.iter().map(|p| Vec3::from_array(*p)).collect()),
        _ => None,
    }
}

/// `mesh`'s joint indices and weights, when it has both in Bevy's formats.
fn skin_attributes(mesh: &Mesh) -> Option<(&[[u16; 4]], &[[f32; 4]])> {
    match (
        mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_INDEX),
        mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_WEIGHT),
    ) {
        (Ok(Some(VertexAttributeValues::Uint16x4(j))), Ok(Some(VertexAttributeValues::Float32x4(w)))) => Some((j, w)),
        _ => None,
    }
}

/// What poses `mesh` on the GPU ([`PoseSource`]): its bind
/// positions, its joints and weights (none when either attribute is missing
/// or of another format: then it is not skinned, as [`Poses::pose`] finds),
/// its morph targets' position displacements, target-major.
pub(crate) fn pose_source(mesh: &Mesh) -> crate::casters::pose::PoseSource {
    let mut source =
        crate::casters::pose::PoseSource { positions: bind_positions(mesh).unwrap_or_default(), ..default() };
    if let Some((j, w)) = skin_attributes(mesh) {
        (source.joints, source.weights) = (j.to_vec(), w.to_vec());
    }
    let n = source.positions.len();
    if let Ok(targets) = mesh.try_morph_targets()
        && n > 0
    {
        source.morph_targets = targets.chunks_exact(n).map(|t| t.iter().map(|d| d.position).collect()).collect();
    }
    source
}

/// One vertex skinned by up to four joints (`skinning.wgsl`'s
/// `skin_model`): `Σ wᵢ Mᵢ p`. A joint out of range or not finite, or a
/// weight not finite, counts for nothing and the others are renormalised; a
/// vertex left with no weight stays where it is (never a NaN).
fn skinned(p: Vec3, joints: &[u16; 4], weights: &[f32; 4], matrices: &[Mat4]) -> Vec3 {
    let mut sum = Mat4::ZERO;
    let (mut total, mut skipped) = (0.0, false);
    for (j, w) in joints.iter().zip(weights) {
        if *w == 0.0 {
            continue;
        }
        match matrices.get(*j as usize).filter(|m| m.is_finite() && w.is_finite()) {
            Some(m) => {
                sum += *m * *w;
                total += w;
            }
            None => skipped = true,
        }
    }
    if !(total.abs() > 0.0) {
        return p;
    }
    if skipped {
        sum *= 1.0 / total;
    }
    sum.transform_point3(p)
}

/// What a posable packing poses (`pose.rs`' inputs, per input vertex of the
/// Bevy mesh): bind positions, the skin's joints and weights (empty when the
/// mesh has none), and the morph targets' displacements, target-major.
#[derive(Debug, Default)]
pub(crate) struct PoseSource {
    pub positions: Vec<Vec3>,
    pub joints: Vec<[u16; 4]>,
    pub weights: Vec<[f32; 4]>,
    pub morph_targets: Vec<Vec<Vec3>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vertex_is_skinned_by_its_weighted_joints_and_bad_joints_count_for_nothing() {
        let matrices = [Mat4::from_translation(Vec3::X), Mat4::from_translation(Vec3::Y * 2.0), Mat4::NAN];
        let p = Vec3::new(1.0, 1.0, 1.0);
        assert_eq!(skinned(p, &[0, 1, 0, 0], &[0.5, 0.5, 0.0, 0.0], &matrices), p + Vec3::new(0.5, 1.0, 0.0));
        // A NaN joint matrix and an out-of-range joint are skipped, not a NaN position.
        assert_eq!(skinned(p, &[2, 9, 0, 0], &[0.5, 0.5, 0.0, 0.0], &matrices), p);
        // One good joint of two: it moves the vertex alone, as if its weight were 1.
        assert_eq!(skinned(p, &[1, 2, 0, 0], &[0.5, 0.5, 0.0, 0.0], &matrices), p + Vec3::Y * 2.0);
        assert_eq!(skinned(p, &[0, 0, 0, 0], &[0.0; 4], &matrices), p);
    }
}
