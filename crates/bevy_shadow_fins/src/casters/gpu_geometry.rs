//! Caster geometry packed once per mesh for `shaders/extract_*.wgsl` (and
//! posed in place by `pose.wgsl`): the word layout, and a pose's record.

use crate::casters::pose::PoseSource;
use bevy::prelude::*;
use shadow_fins::mesh::{NO_FACE, Topology};
use std::hash::{Hash, Hasher};

/// Word offsets of a packed mesh's header (`G_*` in `extract_common.wgsl` and
/// `pose.wgsl`): vertex count, face count, edge count, then where the faces,
/// vertices, edges, vertex → edge lists and non-manifold face lists start;
/// then, for a posable packing, where its pose section starts (0: none) and
/// its morph targets; then, for an outlined packing, where its faces' UVs
/// start (0: none) and its mesh's own vertices (the outline's follow).
pub(crate) const HEADER_WORDS: usize = 12;
pub(crate) const G_POSE_AT: usize = 8;
pub(crate) const G_MORPH_TARGETS: usize = 9;
pub(crate) const G_FACE_UVS_AT: usize = 10;
pub(crate) const G_MESH_VERTICES: usize = 11;
/// Words per welded vertex in a pose section: bind position, four joint
/// indices as two `u16` pairs, four weights (then, target-major, each morph
/// target's displacement of every welded vertex, three words each; then,
/// in an outlined packing, each outline vertex's face and barycentrics
/// w1, w2, three words each).
pub(crate) const POSE_VERTEX_WORDS: usize = 9;
/// A joint index no skin has: the weight on it counts for nothing.
pub(crate) const NO_JOINT: u32 = 0xFFFF;
/// Words of a pose buffer's header and of each of its jobs (`pose.wgsl`).
pub(crate) const POSES_HEADER_WORDS: usize = 8;
pub(crate) const POSE_JOB_WORDS: usize = 8;
pub(crate) const EDGE_FORWARD_FIRST: u32 = 1;
pub(crate) const EDGE_FORWARD_SECOND: u32 = 2;
pub(crate) const EDGE_CREASE: u32 = 4;
pub(crate) const EDGE_NON_MANIFOLD: u32 = 8;
/// An outlined packing's mesh edge: it joins patches, and is never a
/// silhouette (the outline's edges are).
pub(crate) const EDGE_PATCH_ONLY: u32 = 16;
/// An outlined packing's outline edge: a silhouette candidate that joins no
/// patch (its faces are mesh faces, joined across the mesh's edges).
pub(crate) const EDGE_OUTLINE: u32 = 32;

/// One mesh's light-independent topology as `u32` words (floats as bits):
/// - a header of [`HEADER_WORDS`]: the counts and where each part starts;
/// - vertices: position, area-weighted normal (6 words);
/// - faces: three vertex ids, plane normal and offset (7 words);
/// - edges (one- and two-face, then non-manifold): `v0, v1, f0, f1, flags`;
///   a non-manifold edge has the offset and length of its face list instead of
///   `f0, f1`;
/// - per vertex the edges at it (CSR), which the fin pass walks to find the
///   silhouette edges meeting at a silhouette vertex;
/// - non-manifold face lists: `face | forward << 31`;
/// - a posable packing ([`Self::pack_posable`]) then has a pose section:
///   what `pose.wgsl` poses a copy of the words before it from (an outlined
///   one's outline vertices too, by their faces);
/// - an outlined packing ([`Self::pack_outlined`]: an alpha-masked mesh)
///   then has its faces' corner UVs (6 words a face).
#[derive(Debug)]
pub(crate) struct GpuMeshGeometry {
    pub words: Vec<u32>,
    pub vertices: u32,
    pub faces: u32,
    pub edges: u32,
    pub closed: bool,
    /// Packed with the outline of a cut-out ([`Self::pack_outlined`]): its
    /// silhouettes come from the outline, its casters carry UVs.
    pub outlined: bool,
    /// Unique per packing: what the concatenated geometry is keyed by. Not the
    /// `Arc`'s address — a mesh edited in place is packed again and its new
    /// `Arc` may reuse the freed address, which kept the old triangles on the GPU.
    pub packing: u64,
}

/// The next [`GpuMeshGeometry::packing`].
pub(crate) static NEXT_PACKING: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

pub(crate) fn next_packing() -> u64 {
    NEXT_PACKING.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl GpuMeshGeometry {
    pub fn pack(t: &Topology) -> Self {
        Self::pack_with(t, None)
    }

    /// An alpha-masked mesh's packing (`cutout` fits `t`: one UV triple per
    /// face): its vertices then its outline's (numbered after the mesh's, as
    /// the core's `extract_object_silhouettes` numbers them); its edges
    /// (`EDGE_PATCH_ONLY`) then the outline's (`EDGE_OUTLINE`); its faces'
    /// UVs after the rest. Never closed: light through a hole meets the back.
    pub fn pack_outlined(t: &Topology, cutout: &shadow_fins::cutout::Cutout) -> Self {
        Self::pack_with(t, Some(cutout))
    }

    fn pack_with(t: &Topology, cutout: Option<&shadow_fins::cutout::Cutout>) -> Self {
        let outline = cutout.map(|c| &*c.outline);
        let extra_vertices = outline.map_or(0, |o| o.positions.len());
        let extra_edges = outline.map_or(0, |o| o.edges.len());
        let mesh_edge_flags = if outline.is_some() { EDGE_PATCH_ONLY } else { 0 };
        let (v, f) = (t.positions.len() + extra_vertices, t.faces.len());
        let e = t.edges.len() + t.non_manifold_edges.len() + extra_edges;
        let mut w = vec![0u32; HEADER_WORDS];
        let bits = |x: f32| x.to_bits();

        let faces_at = w.len();
        for (face, (n, d)) in t.faces.iter().zip(&t.face_planes) {
            w.extend_from_slice(face);
            w.extend([bits(n.x), bits(n.y), bits(n.z), bits(*d)]);
        }
        let vertices_at = w.len();
        let outline_vertices = outline.into_iter().flat_map(|o| o.positions.iter().zip(&o.normals));
        for (p, n) in t.positions.iter().zip(&t.vertex_normals).chain(outline_vertices) {
            w.extend([p.x, p.y, p.z, n.x, n.y, n.z].map(bits));
        }
        let edges_at = w.len();
        let mut non_manifold = Vec::new();
        let first_outline_vertex = t.positions.len() as u32;
        let outline_edges = outline.into_iter().flat_map(|o| {
            o.edges.iter().zip(&o.crease).map(move |(edge, &crease)| {
                let vertices = edge.vertices.map(|x| x + first_outline_vertex);
                (shadow_fins::mesh::Edge { vertices, ..*edge }, crease, EDGE_OUTLINE)
            })
        });
        let mesh_edges = t.edges.iter().zip(&t.crease).map(|(edge, &crease)| (*edge, crease, mesh_edge_flags));
        for (edge, crease, kind) in mesh_edges.chain(outline_edges) {
            let flags = if edge.forward[0] { EDGE_FORWARD_FIRST } else { 0 }
                | if edge.forward[1] { EDGE_FORWARD_SECOND } else { 0 }
                | if crease { EDGE_CREASE } else { 0 }
                | kind;
            let f1 = if edge.faces[1] == NO_FACE { u32::MAX } else { edge.faces[1] };
            w.extend([edge.vertices[0], edge.vertices[1], edge.faces[0], f1, flags]);
        }
        // (An outlined packing's non-manifold mesh edges go after its outline
        // edges: they are patch-only like its other mesh edges.)
        for edge in &t.non_manifold_edges {
            w.extend([
                edge.vertices[0],
                edge.vertices[1],
                non_manifold.len() as u32,
                edge.faces.len() as u32,
                EDGE_NON_MANIFOLD | EDGE_CREASE | mesh_edge_flags,
            ]);
            non_manifold.extend(edge.faces.iter().map(|&(face, forward)| face | (forward as u32) << 31));
        }
        // Vertex → edge lists (CSR): starts (v + 1 words), then the edge ids.
        let csr_at = w.len();
        let mut degree = vec![0u32; v + 1];
        let endpoints: Vec<[u32; 2]> = t
            .edges
            .iter()
            .map(|e| e.vertices)
            .chain(
                outline.into_iter().flat_map(|o| o.edges.iter().map(|e| e.vertices.map(|x| x + first_outline_vertex))),
            )
            .chain(t.non_manifold_edges.iter().map(|e| e.vertices))
            .collect();
        for ends in &endpoints {
            for &x in ends {
                degree[x as usize + 1] += 1;
            }
        }
        for i in 0..v {
            degree[i + 1] += degree[i];
        }
        let mut fill = degree.clone();
        let mut list = vec![0u32; endpoints.len() * 2];
        for (edge, ends) in endpoints.iter().enumerate() {
            for &x in ends {
                list[fill[x as usize] as usize] = edge as u32;
                fill[x as usize] += 1;
            }
        }
        w.extend(&degree);
        w.extend(&list);
        let non_manifold_at = w.len();
        w.extend(&non_manifold);
        w[..G_POSE_AT].copy_from_slice(&[
            v as u32,
            f as u32,
            e as u32,
            faces_at as u32,
            vertices_at as u32,
            edges_at as u32,
            csr_at as u32,
            non_manifold_at as u32,
        ]);
        if let Some(c) = cutout {
            w[G_MESH_VERTICES] = t.positions.len() as u32;
            w[G_FACE_UVS_AT] = w.len() as u32;
            w.extend(c.face_uvs.iter().flat_map(|uvs| uvs.iter().flat_map(|uv| [bits(uv.x), bits(uv.y)])));
        }
        let (vertices, faces, edges) = (v as u32, f as u32, e as u32);
        let closed = t.is_closed_manifold() && outline.is_none();
        Self { words: w, vertices, faces, edges, closed, outlined: outline.is_some(), packing: next_packing() }
    }
}

impl GpuMeshGeometry {
    /// `rest` (the packing of `t`, the topology of the mesh at its bind
    /// positions `source.positions`) with a pose section, for `pose.wgsl` to
    /// pose each instance's copy on the GPU. Each welded vertex is posed as
    /// its first input vertex (the one welding kept). An outlined `rest`
    /// (`outline`: the one it was packed with) also gets each outline
    /// vertex's face and barycentrics there, which carry it with the pose.
    /// `None` when `t` is not that mesh's topology, or `outline` not `rest`'s.
    pub fn pack_posable(
        rest: &Self,
        t: &Topology,
        source: &PoseSource,
        outline: Option<&shadow_fins::cutout::Outline>,
    ) -> Option<Self> {
        let outline_vertices = outline.map_or(0, |o| o.positions.len());
        if rest.outlined != outline.is_some()
            || rest.vertices as usize != t.positions.len() + outline_vertices
            || outline.is_some_and(|o| {
                o.faces.len() != outline_vertices || o.faces.iter().any(|&f| f >= t.faces.len() as u32)
            })
        {
            return None;
        }
        let (welded, remap) = shadow_fins::mesh::weld_positions(&source.positions);
        if welded != t.positions {
            return None;
        }
        let mut first = vec![u32::MAX; welded.len()];
        for (input, &w) in remap.iter().enumerate().rev() {
            first[w as usize] = input as u32;
        }
        let mut g = Self { words: rest.words.clone(), packing: next_packing(), ..*rest };
        let pose_at = g.words.len();
        let bits = |x: f32| x.to_bits();
        let skinned = source.joints.len() == source.positions.len() && source.weights.len() == source.positions.len();
        for (&input, p) in first.iter().zip(&welded) {
            let (mut joints, mut weights) = ([0u32; 4], [0.0f32; 4]);
            if skinned {
                let (j, w) = (source.joints[input as usize], source.weights[input as usize]);
                for k in 0..4 {
                    // A weight not finite counts for nothing and renormalises
                    // the others (`pose::skinned`): as on a joint no skin has.
                    (joints[k], weights[k]) = if w[k].is_finite() { (j[k] as u32, w[k]) } else { (NO_JOINT, 1.0) };
                }
            }
            g.words.extend([p.x, p.y, p.z].map(bits));
            g.words.extend([joints[0] | joints[1] << 16, joints[2] | joints[3] << 16]);
            g.words.extend(weights.map(bits));
        }
        debug_assert_eq!(g.words.len() - pose_at, POSE_VERTEX_WORDS * welded.len());
        let n = source.positions.len();
        let targets: Vec<&Vec<Vec3>> = source.morph_targets.iter().filter(|d| d.len() == n).collect();
        for deltas in &targets {
            for &input in &first {
                let d = deltas[input as usize];
                // A displacement not finite would make a NaN even at weight 0.
                let d = if d.is_finite() { d } else { Vec3::ZERO };
                g.words.extend([d.x, d.y, d.z].map(bits));
            }
        }
        for (p, &face) in outline.into_iter().flat_map(|o| o.positions.iter().zip(&o.faces)) {
            let corners = t.faces[face as usize].map(|v| t.positions[v as usize]);
            let b = barycentrics(corners, *p);
            g.words.extend([face, b.y.to_bits(), b.z.to_bits()]);
        }
        g.words[G_POSE_AT] = pose_at as u32;
        g.words[G_MORPH_TARGETS] = targets.len() as u32;
        Some(g)
    }

    /// True for a packing with a pose section ([`Self::pack_posable`]).
    pub fn posable(&self) -> bool {
        self.words[G_POSE_AT] != 0
    }

    /// The words a posed instance's own copy needs: all but the pose
    /// section, which the instances of a mesh share.
    pub(crate) fn posed_part(&self) -> &[u32] {
        match self.words[G_POSE_AT] as usize {
            0 => &self.words,
            at => &self.words[..at],
        }
    }
}

/// `p`'s barycentrics in the triangle `c` (the first corner's of a
/// degenerate one): `p = c₀ + b.y (c₁ − c₀) + b.z (c₂ − c₀)` for a point on it.
/// In f64: the normal equations' determinant cancels as sin² of the
/// triangle's sharpest angle, and a sliver's barycentrics in f32 would be
/// right at rest but not once a pose changes its shape.
pub(crate) fn barycentrics(c: [Vec3; 3], p: Vec3) -> Vec3 {
    let [c0, c1, c2, p] = [c[0], c[1], c[2], p].map(|x| x.as_dvec3());
    let (e1, e2, ep) = (c1 - c0, c2 - c0, p - c0);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if !(det.abs() > 0.0) {
        return Vec3::X;
    }
    let v = (d22 * ep.dot(e1) - d12 * ep.dot(e2)) / det;
    let w = (d11 * ep.dot(e2) - d12 * ep.dot(e1)) / det;
    bevy::math::DVec3::new(1.0 - v - w, v, w).as_vec3()
}

/// One caster's pose as `pose.wgsl` reads it: each joint's `Jᵢ · IBPᵢ` as
/// four columns, the last one's `w` 1 when the matrix is finite and 0 when
/// the pass must skip it; the morph weights.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GpuPose {
    pub joints: Vec<[f32; 16]>,
    pub morph_weights: Vec<f32>,
    pub skinned: bool,
    /// Changes with the pose: the instance record carries it, so that a new
    /// pose is a changed record (uploaded, and redrawn in part).
    pub hash: u64,
}

impl GpuPose {
    pub fn new(pose: &crate::casters::pose::Pose) -> Self {
        let joints: Vec<[f32; 16]> = pose
            .joints
            .iter()
            .flatten()
            .map(|m| {
                let mut c = if m.is_finite() { m.to_cols_array() } else { [0.0; 16] };
                // `transform_point3` ignores the bottom row: its last word is the flag.
                c[15] = m.is_finite() as u32 as f32;
                c
            })
            .collect();
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        crate::hashing::hash_floats(&mut hasher, joints.as_flattened());
        crate::hashing::hash_floats(&mut hasher, &pose.morph_weights);
        pose.joints.is_some().hash(&mut hasher);
        Self {
            joints,
            morph_weights: pose.morph_weights.clone(),
            skinned: pose.joints.is_some(),
            hash: hasher.finish(),
        }
    }
}
