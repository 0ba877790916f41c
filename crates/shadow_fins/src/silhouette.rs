//! Silhouette extraction (Cai et al. §3.1, brute force over all edges).
//!
//! A face faces the light when its normal points towards the light centre (disk)
//! or against the light's travel direction (sun). An edge is a silhouette when:
//! - it has two faces and exactly one faces the light;
//! - it has one face (boundary) and that face faces the light, or the mesh
//!   is open (its back faces are in the maps too): then oriented by the back;
//! - it has three or more faces (non-manifold) and they disagree: at least one
//!   faces the light and at least one does not. The first light-facing face
//!   orients it. (All-facing non-manifold edges cast no fins, by choice: they lie
//!   inside the occluder's projection as often as on its outline.)
//!
//! Edges are *oriented*: walking `a → b` in map space, the light-facing face is
//! on the right. (A light-facing triangle projects clockwise: its projected
//! signed area is `dot(a, N) / (z_a z_b z_c) < 0`.) The fins' outward direction
//! is then the left normal of the projected edge, with no look at the third
//! vertex, so it is robust even when the face projects to a sliver.
//!
//! **Patches.** The faces that go into the light-space maps (light-facing faces,
//! plus back faces of meshes that are not closed) are grouped into *patches*:
//! connected regions joined across edges that are not silhouettes. A patch is
//! one occluder as the light sees it: its outline is exactly its silhouette
//! edges, so its fins and its hard shadow belong together. Layers are built from
//! whole patches (see [`crate::layers`]), never from parts of one.
//!
//! The facing test runs in each object's own space against the light moved into
//! that space: one dot product per face, no per-vertex transform. Only
//! silhouette endpoints are transformed to the light frame.

use glam::Vec3;

use crate::{
    mesh::{NO_FACE, Topology},
    scene::{LightInObject, ObjectToFrame},
};

/// One silhouette edge in the light frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SilhouetteEdge {
    /// Endpoints in the light frame, ordered so the light-facing face is on the right.
    pub a: Vec3,
    pub b: Vec3,
    /// Scene-wide welded vertex ids of `a` and `b` (object base + local id).
    pub vertex_a: u32,
    pub vertex_b: u32,
    /// Area-weighted vertex normals at `a` and `b`, light frame (for junctions).
    pub normal_a: Vec3,
    pub normal_b: Vec3,
    /// Scene-wide id of the patch whose outline this edge is.
    pub patch: u32,
    /// The edge is a crease (see [`crate::mesh::CREASE_ANGLE_DEG`]), not a facet
    /// edge of a smooth surface.
    pub crease: bool,
}

impl SilhouetteEdge {
    /// Light-space depth of the edge midpoint (what layer assignment histograms).
    #[inline]
    pub fn mid_depth(&self) -> f32 {
        0.5 * (self.a.z + self.b.z)
    }
}

/// Marks a face that is in no patch (a back face of a closed mesh).
pub const NO_PATCH: u32 = u32::MAX;

/// Reusable buffers for [`extract_object_silhouettes`].
#[derive(Debug, Default)]
pub struct SilhouetteScratch {
    facing: Vec<bool>,
    stack: Vec<u32>,
}

/// Appends the silhouette edges of one object to `out` and the patch of each of
/// its faces to `face_patches` (in face order; [`NO_PATCH`] for faces outside
/// the maps). Patch ids start at `patch_base`; returns how many were made.
///
/// `vertex_base` makes vertex ids unique across objects. An alpha-masked
/// object's silhouettes are drawn from its `outline` ([`crate::cutout`])
/// instead of its mesh edges: the outline's vertex ids follow the mesh's.
#[allow(clippy::too_many_arguments)]
pub fn extract_object_silhouettes(
    topology: &Topology,
    to_frame: &ObjectToFrame,
    light: LightInObject,
    vertex_base: u32,
    patch_base: u32,
    scratch: &mut SilhouetteScratch,
    face_patches: &mut Vec<u32>,
    out: &mut Vec<SilhouetteEdge>,
    outline: Option<&crate::cutout::Outline>,
) -> u32 {
    let SilhouetteScratch { facing, stack } = scratch;
    facing.clear();
    let flip = to_frame.mirrors;
    match light {
        LightInObject::Point(c) => facing.extend(topology.face_planes.iter().map(|&(n, d)| (n.dot(c) > d) != flip)),
        LightInObject::Direction(dir) => {
            facing.extend(topology.face_planes.iter().map(|&(n, _)| (n.dot(dir) < 0.0) != flip))
        }
    }

    // Patches: flood fill over map faces across non-silhouette edges.
    // An alpha-masked closed mesh keeps its back faces: light through a hole
    // in its front meets them.
    let closed = to_frame.culls_back_faces(topology) && outline.is_none();
    let first = face_patches.len();
    face_patches.resize(first + facing.len(), NO_PATCH);
    let labels = &mut face_patches[first..];
    let mut patches = 0u32;
    for seed in 0..facing.len() {
        if labels[seed] != NO_PATCH || !(facing[seed] || !closed) {
            continue;
        }
        let id = patch_base + patches;
        patches += 1;
        labels[seed] = id;
        stack.clear();
        stack.push(seed as u32);
        while let Some(f) = stack.pop() {
            let side = facing[f as usize];
            for n in topology.face_neighbors[f as usize] {
                if n != NO_FACE && labels[n as usize] == NO_PATCH && facing[n as usize] == side {
                    labels[n as usize] = id;
                    stack.push(n);
                }
            }
        }
    }
    let face_patches = &face_patches[first..];

    // Vertex ids, light-frame points and normals of the edges' ends: the
    // mesh's own, or for an alpha-masked mesh its outline's, numbered after
    // the mesh's.
    let (positions, normals, id_base) = match outline {
        Some(o) => (&o.positions, &o.normals, vertex_base + topology.positions.len() as u32),
        None => (&topology.positions, &topology.vertex_normals, vertex_base),
    };
    let mut emit = |v0: u32, v1: u32, forward: bool, face: u32, crease: bool| {
        // Orient along the light-facing face's winding.
        let (va, vb) = if forward { (v0, v1) } else { (v1, v0) };
        out.push(SilhouetteEdge {
            a: to_frame.point(positions[va as usize]),
            b: to_frame.point(positions[vb as usize]),
            vertex_a: id_base + va,
            vertex_b: id_base + vb,
            normal_a: to_frame.normal(normals[va as usize]),
            normal_b: to_frame.normal(normals[vb as usize]),
            patch: face_patches[face as usize],
            crease,
        });
    };
    let (edges, creases) = match outline {
        Some(o) => (&o.edges, &o.crease),
        None => (&topology.edges, &topology.crease),
    };
    for (e, &crease) in edges.iter().zip(creases) {
        let f0 = facing[e.faces[0] as usize];
        if e.faces[1] == NO_FACE {
            // A boundary is the outline of its face's side towards the light:
            // the face's own when it faces the light, the back's when an open
            // mesh's back face is in the maps.
            if f0 {
                emit(e.vertices[0], e.vertices[1], e.forward[0], e.faces[0], true);
            } else if !closed {
                emit(e.vertices[0], e.vertices[1], !e.forward[0], e.faces[0], true);
            }
            continue;
        }
        let f1 = facing[e.faces[1] as usize];
        if f0 != f1 {
            let k = if f0 { 0 } else { 1 };
            emit(e.vertices[0], e.vertices[1], e.forward[k], e.faces[k], crease);
        }
    }
    // An outline has its non-manifold edges' stretches among its edges.
    if outline.is_none() {
        for e in &topology.non_manifold_edges {
            let first_facing = e.faces.iter().find(|(f, _)| facing[*f as usize]);
            let any_back = e.faces.iter().any(|(f, _)| !facing[*f as usize]);
            if let (Some(&(face, forward)), true) = (first_facing, any_back) {
                emit(e.vertices[0], e.vertices[1], forward, face, true);
            }
        }
    }
    patches
}

/// Groups oriented silhouette edges into closed loops by following `b → a`.
///
/// Returns the loops (as edge indices) and the edges left over that do not close
/// (open chains from boundaries or non-manifold edges). At a vertex with several
/// outgoing edges the first unused one is taken.
pub fn trace_loops(edges: &[SilhouetteEdge]) -> (Vec<Vec<usize>>, Vec<usize>) {
    use std::collections::HashMap;
    let mut outgoing: HashMap<u32, Vec<usize>> = HashMap::new();
    for (i, e) in edges.iter().enumerate() {
        outgoing.entry(e.vertex_a).or_default().push(i);
    }
    let mut used = vec![false; edges.len()];
    let mut loops = Vec::new();
    let mut open = Vec::new();
    for start in 0..edges.len() {
        if used[start] {
            continue;
        }
        let mut chain = vec![start];
        used[start] = true;
        let mut at = edges[start].vertex_b;
        let closed = loop {
            if at == edges[start].vertex_a {
                break true;
            }
            let next = outgoing.get(&at).and_then(|l| l.iter().copied().find(|&i| !used[i]));
            match next {
                Some(n) => {
                    used[n] = true;
                    chain.push(n);
                    at = edges[n].vertex_b;
                }
                None => break false,
            }
        };
        if closed { loops.push(chain) } else { open.extend(chain) }
    }
    (loops, open)
}
