//! Mesh input, vertex welding and edge → face adjacency.
//!
//! A [`Mesh`] is an indexed triangle list, validated on construction. Its
//! [`Topology`] welds vertices that share a position (so flat-shaded exports with
//! split vertices still have connected edges), drops degenerate faces, and lists
//! every edge with the faces around it. The topology is light-independent: it is
//! built once per mesh and reused every frame by [`crate::silhouette`].

use std::collections::HashMap;

use glam::Vec3;

use crate::error::MeshError;

/// Marks "no face" in [`Edge::faces`] (a boundary edge has one face).
pub const NO_FACE: u32 = u32::MAX;

/// Dihedral angle above which an edge is a crease (a box's edge) rather than
/// part of a tessellated smooth surface (a sphere's facet edge).
pub const CREASE_ANGLE_DEG: f32 = 40.0;

/// An indexed triangle mesh in its own object space.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    positions: Vec<Vec3>,
    indices: Vec<u32>,
}

impl Mesh {
    /// Validates and wraps a triangle list.
    ///
    /// Errors: no triangles, an index count that is not a multiple of 3, an index
    /// out of range, a non-finite position, or every triangle of zero area.
    /// Individual degenerate triangles are allowed (they are skipped later).
    pub fn new(positions: Vec<Vec3>, indices: Vec<u32>) -> Result<Self, MeshError> {
        if indices.is_empty() {
            return Err(MeshError::Empty);
        }
        if indices.len() % 3 != 0 {
            return Err(MeshError::IndexCountNotTriangles(indices.len()));
        }
        if let Some((vertex, p)) = positions.iter().enumerate().find(|(_, p)| !p.is_finite()) {
            return Err(MeshError::NonFinitePosition { vertex, position: p.to_array() });
        }
        if let Some((at, &index)) = indices.iter().enumerate().find(|&(_, &i)| i as usize >= positions.len()) {
            return Err(MeshError::IndexOutOfRange { at, index, vertex_count: positions.len() });
        }
        let mesh = Self { positions, indices };
        if mesh.triangles().all(|[a, b, c]| triangle_is_degenerate(a, b, c)) {
            return Err(MeshError::AllDegenerate);
        }
        Ok(mesh)
    }

    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The corner positions of every triangle, in index order.
    pub fn triangles(&self) -> impl Iterator<Item = [Vec3; 3]> + '_ {
        self.indices
            .chunks_exact(3)
            .map(|t| [self.positions[t[0] as usize], self.positions[t[1] as usize], self.positions[t[2] as usize]])
    }
}

/// True when the triangle has (numerically) zero area relative to its size.
pub fn triangle_is_degenerate(a: Vec3, b: Vec3, c: Vec3) -> bool {
    let cross = (b - a).cross(c - a);
    let scale = (b - a).length_squared().max((c - a).length_squared()).max((c - b).length_squared());
    // Area² below (1e-7 · edge²)² is noise for f32 positions.
    !(cross.length_squared() > scale * scale * 1e-14)
}

/// One undirected edge of the welded mesh.
///
/// `vertices[0] < vertices[1]`. `faces[i]` is a face index or [`NO_FACE`];
/// `forward[i]` says whether face `i` walks the edge from `vertices[0]` to
/// `vertices[1]` in its winding order. Edges with three or more faces are listed
/// in [`Topology::non_manifold_edges`] instead.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    pub vertices: [u32; 2],
    pub faces: [u32; 2],
    pub forward: [bool; 2],
}

/// An edge shared by three or more faces: `(face, forward)` for each.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NonManifoldEdge {
    pub vertices: [u32; 2],
    pub faces: Vec<(u32, bool)>,
}

/// Light-independent connectivity of a mesh, built once and reused every frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Topology {
    /// Positions after welding: one per distinct position.
    pub positions: Vec<Vec3>,
    /// Per input vertex, its welded vertex (an index into `positions`).
    pub welded_from: Vec<u32>,
    /// Non-degenerate faces, as welded vertex indices in the input winding.
    pub faces: Vec<[u32; 3]>,
    /// Per face, the input triangle it is (its index in the mesh's triangles).
    pub source_triangles: Vec<u32>,
    /// Unnormalised face normal `(b − a) × (c − a)` and `dot(normal, a)`, so that
    /// "faces a point `x`" is `dot(normal, x) > offset` with no per-frame work.
    pub face_planes: Vec<(Vec3, f32)>,
    /// Area-weighted vertex normals (unnormalised), used at silhouette junctions.
    pub vertex_normals: Vec<Vec3>,
    /// Per face, the face across each of its edges `(v0,v1)`, `(v1,v2)`, `(v2,v0)`
    /// when that edge has exactly two faces; [`NO_FACE`] otherwise.
    pub face_neighbors: Vec<[u32; 3]>,
    /// Edges with one or two faces.
    pub edges: Vec<Edge>,
    /// Per edge in `edges`: true when it is a crease — its faces meet at more
    /// than [`CREASE_ANGLE_DEG`], or it has one face. Fins of smooth edges bend
    /// with the surface's vertex normals; fins of creases stay straight.
    pub crease: Vec<bool>,
    /// Edges with three or more faces.
    pub non_manifold_edges: Vec<NonManifoldEdge>,
    /// Input triangles dropped for zero area (or for repeating a welded vertex).
    pub degenerate_faces: usize,
    /// Two-face edges whose faces walk them in the same direction (flipped winding).
    pub inconsistent_edges: usize,
    /// Object-space bounds of the welded positions.
    pub bounds: (Vec3, Vec3),
}

impl Topology {
    /// Welds vertices by exact position and builds edge → face adjacency.
    pub fn build(mesh: &Mesh) -> Self {
        let (positions, remap) = weld_positions(mesh.positions());
        let mut faces = Vec::with_capacity(mesh.triangle_count());
        let mut source_triangles = Vec::with_capacity(mesh.triangle_count());
        let mut degenerate_faces = 0;
        for (t, tri) in mesh.indices().chunks_exact(3).enumerate() {
            let f = [remap[tri[0] as usize], remap[tri[1] as usize], remap[tri[2] as usize]];
            let [a, b, c] = f.map(|i| positions[i as usize]);
            if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] || triangle_is_degenerate(a, b, c) {
                degenerate_faces += 1;
            } else {
                faces.push(f);
                source_triangles.push(t as u32);
            }
        }
        let face_planes = planes_of(&faces, &positions);
        let vertex_normals = vertex_normals_of(&faces, &face_planes, positions.len());

        // (min, max) → list of (face, walks min→max)
        let mut by_key: HashMap<(u32, u32), Vec<(u32, bool)>> = HashMap::with_capacity(faces.len() * 3 / 2);
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                by_key.entry(key).or_default().push((fi as u32, a < b));
            }
        }
        let mut face_neighbors = vec![[NO_FACE; 3]; faces.len()];
        for list in by_key.values() {
            if let [(f0, _), (f1, _)] = list.as_slice() {
                for (a, b) in [(*f0, *f1), (*f1, *f0)] {
                    let f = faces[a as usize];
                    // Which of a's edges is shared with b?
                    let k = (0..3)
                        .find(|&k| faces[b as usize].contains(&f[k]) && faces[b as usize].contains(&f[(k + 1) % 3]));
                    if let Some(k) = k {
                        face_neighbors[a as usize][k] = b;
                    }
                }
            }
        }
        let mut keys: Vec<_> = by_key.into_iter().collect();
        // Deterministic order (HashMap iteration is not): sort by vertex pair.
        keys.sort_unstable_by_key(|(k, _)| *k);
        let mut edges = Vec::with_capacity(keys.len());
        let mut non_manifold_edges = Vec::new();
        let mut inconsistent_edges = 0;
        for ((v0, v1), list) in keys {
            match list.as_slice() {
                [(f, fw)] => edges.push(Edge { vertices: [v0, v1], faces: [*f, NO_FACE], forward: [*fw, false] }),
                [(f0, fw0), (f1, fw1)] => {
                    if fw0 == fw1 {
                        inconsistent_edges += 1;
                    }
                    edges.push(Edge { vertices: [v0, v1], faces: [*f0, *f1], forward: [*fw0, *fw1] })
                }
                _ => non_manifold_edges.push(NonManifoldEdge { vertices: [v0, v1], faces: list }),
            }
        }
        let crease = creases(&edges, &face_planes);
        let bounds = bounds_of(&positions);
        Self {
            crease,
            bounds,
            positions,
            welded_from: remap,
            faces,
            source_triangles,
            face_planes,
            vertex_normals,
            face_neighbors,
            edges,
            non_manifold_edges,
            degenerate_faces,
            inconsistent_edges,
        }
    }

    /// This topology with the vertices moved: `posed` holds the mesh's input
    /// vertices (as many as it was built from) in a new pose. `Some` exactly
    /// when [`Topology::build`] of the posed mesh would give the same welds and
    /// faces — then it equals that build, field for field, at a fraction of
    /// its cost (no hashing of edges, no sort): the planes, vertex normals,
    /// creases and bounds are recomputed, the rest kept.
    ///
    /// `None` when the pose changed the topology: two vertices welded at rest
    /// moved apart, two vertices apart at rest met, a face folded to zero
    /// area, or a triangle dropped at rest for its area unfolded; or when
    /// `posed` is not this mesh's vertex count or holds a non-finite position.
    /// Why: a skinned or morphed mesh is posed every frame, and its poses
    /// nearly always keep the rest topology (welded vertices share their
    /// joints, weights and morph deltas).
    pub fn reposed(&self, indices: &[u32], posed: &[Vec3]) -> Option<Topology> {
        if posed.len() != self.welded_from.len() || posed.iter().any(|p| !p.is_finite()) {
            return None;
        }
        let key = |p: Vec3| (p + Vec3::ZERO).to_array().map(f32::to_bits);
        // Welds kept: every input vertex at its welded vertex's first input's
        // position (welded vertices are numbered in first-seen order).
        let mut positions = Vec::with_capacity(self.positions.len());
        for (&w, &p) in self.welded_from.iter().zip(posed) {
            match positions.get(w as usize) {
                Some(&first) if key(first) == key(p) => {}
                Some(_) => return None,
                None if w as usize == positions.len() => positions.push(p),
                None => return None,
            }
        }
        if positions.len() != self.positions.len() {
            return None;
        }
        // No two welded vertices met.
        let mut seen = std::collections::HashSet::with_capacity(positions.len());
        if !positions.iter().all(|&p| seen.insert(key(p))) {
            return None;
        }
        // The same triangles dropped for their area, and no others.
        let mut kept = self.source_triangles.iter().peekable();
        for (t, tri) in indices.chunks_exact(3).enumerate() {
            let f = [0, 1, 2].map(|k| self.welded_from.get(tri[k] as usize).copied());
            let [Some(a), Some(b), Some(c)] = f else { return None };
            let was_kept = kept.next_if_eq(&&(t as u32)).is_some();
            let repeats = a == b || b == c || a == c;
            let flat =
                repeats || triangle_is_degenerate(positions[a as usize], positions[b as usize], positions[c as usize]);
            if flat == was_kept {
                return None;
            }
        }
        if kept.next().is_some() {
            return None;
        }
        let face_planes = planes_of(&self.faces, &positions);
        Some(Topology {
            vertex_normals: vertex_normals_of(&self.faces, &face_planes, positions.len()),
            crease: creases(&self.edges, &face_planes),
            bounds: bounds_of(&positions),
            face_planes,
            positions,
            welded_from: self.welded_from.clone(),
            faces: self.faces.clone(),
            source_triangles: self.source_triangles.clone(),
            face_neighbors: self.face_neighbors.clone(),
            edges: self.edges.clone(),
            non_manifold_edges: self.non_manifold_edges.clone(),
            degenerate_faces: self.degenerate_faces,
            inconsistent_edges: self.inconsistent_edges,
        })
    }

    /// Edges with exactly one face.
    pub fn boundary_edge_count(&self) -> usize {
        self.edges.iter().filter(|e| e.faces[1] == NO_FACE).count()
    }

    /// True when every edge has exactly two consistently wound faces.
    pub fn is_closed_manifold(&self) -> bool {
        self.non_manifold_edges.is_empty()
            && self.inconsistent_edges == 0
            && self.edges.iter().all(|e| e.faces[1] != NO_FACE)
    }

    /// True when `p` (object space) lies inside this closed mesh, by the parity
    /// of a ray's crossings. Always false for a mesh that is not closed (it has
    /// no inside) and outside the bounds (the common case costs one box test).
    ///
    /// Robustness: the crossings are counted in f64 along a direction no
    /// modelled axis or diagonal follows; a ray that passes within a relative
    /// 1e-9 of an edge or vertex, or starts on a face, is ambiguous and the next
    /// of three directions is tried; if all three are ambiguous the majority of
    /// their parities decides.
    pub fn contains_point(&self, p: Vec3) -> bool {
        let (lo, hi) = self.bounds;
        if !self.is_closed_manifold() || !(p.cmpge(lo).all() && p.cmple(hi).all()) {
            return false;
        }
        const DIRECTIONS: [[f64; 3]; 3] =
            [[0.3112, 0.8597, 0.4049], [-0.2672, 0.8018, -0.5346], [0.8944, -0.1234, 0.4297]];
        let p = p.as_dvec3();
        let mut votes = 0;
        for (k, d) in DIRECTIONS.iter().enumerate() {
            let d = glam::DVec3::from_array(*d).normalize();
            match self.ray_crossings(p, d) {
                Some(n) => return n % 2 == 1,
                None => votes += self.ray_crossings_lenient(p, d) % 2,
            }
            if k == DIRECTIONS.len() - 1 {
                return votes >= 2;
            }
        }
        false
    }

    /// Faces crossed by the ray `p + t d, t > 0`; `None` when a hit is too close
    /// to an edge or to the origin to count reliably.
    fn ray_crossings(&self, p: glam::DVec3, d: glam::DVec3) -> Option<usize> {
        let mut n = 0;
        for f in &self.faces {
            match ray_triangle(p, d, f.map(|i| self.positions[i as usize].as_dvec3())) {
                RayTriangle::Miss => {}
                RayTriangle::Hit => n += 1,
                RayTriangle::Ambiguous => return None,
            }
        }
        Some(n)
    }

    fn ray_crossings_lenient(&self, p: glam::DVec3, d: glam::DVec3) -> usize {
        let faces = self.faces.iter().map(|f| ray_triangle(p, d, f.map(|i| self.positions[i as usize].as_dvec3())));
        faces.filter(|r| *r != RayTriangle::Miss).count()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RayTriangle {
    Miss,
    Hit,
    Ambiguous,
}

/// Möller–Trumbore in f64 with a margin: barycentrics within 1e-9 of an edge,
/// or a hit within 1e-9 (relative) of the origin, are ambiguous.
fn ray_triangle(p: glam::DVec3, d: glam::DVec3, [a, b, c]: [glam::DVec3; 3]) -> RayTriangle {
    const MARGIN: f64 = 1e-9;
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(e2);
    let det = e1.dot(h);
    let scale = e1.length() * e2.length();
    if det.abs() <= 1e-14 * scale {
        // The ray runs in the triangle's plane: counts only if it could touch it.
        return if (p - a).dot(e1.cross(e2)).abs() <= MARGIN * scale * (p - a).length().max(1.0) {
            RayTriangle::Ambiguous
        } else {
            RayTriangle::Miss
        };
    }
    let s = p - a;
    let u = s.dot(h) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let t = e2.dot(q) / det;
    let (w, size) = (1.0 - u - v, scale.sqrt());
    if u < -MARGIN || v < -MARGIN || w < -MARGIN || t < -MARGIN * size {
        return RayTriangle::Miss;
    }
    if u < MARGIN || v < MARGIN || w < MARGIN || t < MARGIN * size {
        return RayTriangle::Ambiguous;
    }
    RayTriangle::Hit
}

/// Each face's unnormalised normal `(b − a) × (c − a)` and `dot(normal, a)`.
fn planes_of(faces: &[[u32; 3]], positions: &[Vec3]) -> Vec<(Vec3, f32)> {
    faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| positions[i as usize]);
            let n = (b - a).cross(c - a);
            (n, n.dot(a))
        })
        .collect()
}

/// Area-weighted vertex normals: the sum of each vertex's faces' normals.
fn vertex_normals_of(faces: &[[u32; 3]], face_planes: &[(Vec3, f32)], vertex_count: usize) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; vertex_count];
    for (f, (n, _)) in faces.iter().zip(face_planes) {
        for &v in f {
            normals[v as usize] += *n;
        }
    }
    normals
}

/// Per edge, whether it is a crease ([`Topology::crease`]).
fn creases(edges: &[Edge], face_planes: &[(Vec3, f32)]) -> Vec<bool> {
    let cos_crease = CREASE_ANGLE_DEG.to_radians().cos();
    edges
        .iter()
        .map(|e| {
            e.faces[1] == NO_FACE || {
                let (a, b) = (face_planes[e.faces[0] as usize].0, face_planes[e.faces[1] as usize].0);
                a.normalize_or_zero().dot(b.normalize_or_zero()) < cos_crease
            }
        })
        .collect()
}

fn bounds_of(positions: &[Vec3]) -> (Vec3, Vec3) {
    positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)))
}

/// Merges vertices with bit-identical positions (`-0.0` and `0.0` are one).
///
/// Returns the distinct positions, in first-seen order, and the map from input
/// vertex to welded vertex.
pub fn weld_positions(positions: &[Vec3]) -> (Vec<Vec3>, Vec<u32>) {
    let key = |p: Vec3| (p + Vec3::ZERO).to_array().map(f32::to_bits);
    let mut index: HashMap<[u32; 3], u32> = HashMap::with_capacity(positions.len());
    let mut welded = Vec::with_capacity(positions.len());
    let remap = positions
        .iter()
        .map(|&p| {
            *index.entry(key(p)).or_insert_with(|| {
                welded.push(p);
                (welded.len() - 1) as u32
            })
        })
        .collect();
    (welded, remap)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_meshes_with_typed_errors() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        assert_eq!(Mesh::new(p.clone(), vec![]), Err(MeshError::Empty));
        assert_eq!(Mesh::new(p.clone(), vec![0, 1]), Err(MeshError::IndexCountNotTriangles(2)));
        assert!(matches!(Mesh::new(p.clone(), vec![0, 1, 3]), Err(MeshError::IndexOutOfRange { index: 3, .. })));
        let nan = vec![Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0), Vec3::Y];
        assert!(matches!(Mesh::new(nan, vec![0, 1, 2]), Err(MeshError::NonFinitePosition { vertex: 1, .. })));
        let flat = vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert_eq!(Mesh::new(flat, vec![0, 1, 2]), Err(MeshError::AllDegenerate));
    }

    #[test]
    fn welding_merges_split_vertices_and_signed_zero() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(-0.0, 0.0, 0.0), Vec3::X];
        let (w, remap) = weld_positions(&p);
        assert_eq!(w.len(), 2);
        assert_eq!(remap, vec![0, 1, 0, 1]);
    }

    #[test]
    fn quad_has_one_interior_edge_and_four_boundary_edges() {
        // Split vertices (as a flat-shaded export would have them) still weld.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let t = Topology::build(&Mesh::new(p, vec![0, 1, 2, 3, 4, 5]).unwrap());
        assert_eq!(t.positions.len(), 4);
        assert_eq!(t.edges.len(), 5);
        assert_eq!(t.boundary_edge_count(), 4);
        assert_eq!(t.inconsistent_edges, 0);
        assert!(!t.is_closed_manifold());
    }

    #[test]
    fn three_faces_on_one_edge_are_non_manifold() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.0, -1.0, 0.0)];
        let t = Topology::build(&Mesh::new(p, vec![0, 1, 2, 1, 0, 3, 0, 1, 4]).unwrap());
        assert_eq!(t.non_manifold_edges.len(), 1);
        assert_eq!(t.non_manifold_edges[0].faces.len(), 3);
    }

    #[test]
    fn degenerate_faces_are_counted_and_dropped() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0];
        let t = Topology::build(&Mesh::new(p, vec![0, 1, 2, 0, 1, 3]).unwrap());
        assert_eq!(t.faces.len(), 1);
        assert_eq!(t.degenerate_faces, 1);
    }

    /// A sphere exported flat-shaded (three vertices per triangle, so every
    /// vertex is welded from several), with one sliver triangle that the
    /// rest pose drops for its area.
    fn split_sphere() -> Mesh {
        // An octahedron split twice (8 × 4 faces), built here: `shapes` builds on this module.
        let mut triangles = vec![];
        for (sx, sy, sz) in
            (0..8).map(|i| [i & 1, i & 2, i & 4].map(|b| if b == 0 { 1.0f32 } else { -1.0 })).map(|[a, b, c]| (a, b, c))
        {
            let (x, y, z) = (Vec3::X * sx, Vec3::Y * sy, Vec3::Z * sz);
            let outward = sx * sy * sz > 0.0;
            let (a, b, c) = if outward { (x, y, z) } else { (x, z, y) };
            let (ab, bc, ca) = ((a + b).normalize(), (b + c).normalize(), (c + a).normalize());
            triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        let mut positions: Vec<Vec3> = triangles.into_iter().flatten().collect();
        positions.extend([Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0)]);
        Mesh::new(positions.clone(), (0..positions.len() as u32).collect()).unwrap()
    }

    fn posed(mesh: &Mesh, f: impl Fn(Vec3) -> Vec3) -> Vec<Vec3> {
        mesh.positions().iter().map(|&p| f(p)).collect()
    }

    #[test]
    fn a_pose_that_changes_the_topology_is_refused() {
        let mesh = split_sphere();
        let rest = Topology::build(&mesh);
        assert!(rest.reposed(mesh.indices(), mesh.positions()).is_some_and(|t| t == rest));
        // Two vertices welded at rest moved apart (one split copy of a corner).
        let mut apart = mesh.positions().to_vec();
        apart[0] += Vec3::splat(1e-3);
        assert_eq!(rest.reposed(mesh.indices(), &apart), None);
        // Two vertices apart at rest met: a corner of the sphere onto another.
        let (a, b) = (rest.positions[rest.faces[0][0] as usize], rest.positions[rest.faces[0][1] as usize]);
        let met = posed(&mesh, |p| if p == b { a } else { p });
        assert_eq!(rest.reposed(mesh.indices(), &met), None);
        // The sliver dropped at rest unfolded into a triangle.
        let n = mesh.positions().len();
        let mut unfolded = mesh.positions().to_vec();
        unfolded[n - 2].y = 1.0;
        assert_eq!(rest.reposed(mesh.indices(), &unfolded), None);
        // A face folded flat: one corner moved onto the line through the other two.
        let [a, b, c] = rest.faces[10].map(|i| rest.positions[i as usize]);
        let flat = posed(&mesh, |p| if p == c { (a + b) * 0.5 } else { p });
        assert_eq!(rest.reposed(mesh.indices(), &flat), None);
        // Not this mesh's vertices, or not finite.
        assert_eq!(rest.reposed(mesh.indices(), &mesh.positions()[1..]), None);
        let mut nan = mesh.positions().to_vec();
        nan[3] = Vec3::NAN;
        assert_eq!(rest.reposed(mesh.indices(), &nan), None);
        // In each case a rebuild gives another topology, so refusing was right
        // (the NaN and the short list build no mesh at all).
        for changed in [apart, met, unfolded, flat] {
            let built = Topology::build(&Mesh::new(changed, mesh.indices().to_vec()).unwrap());
            assert!(built.positions.len() != rest.positions.len() || built.faces != rest.faces);
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 256, ..Default::default() })]

        /// Any pose that moves welded vertices as one (a function of the rest
        /// position: a bend, a twist, a stretch) and keeps the faces gives, by
        /// `reposed`, the topology a rebuild gives, field for field.
        #[test]
        fn a_pose_that_keeps_the_welds_reposes_to_the_rebuilt_topology(
            twist in -3.0f32..3.0, bend in -1.0f32..1.0, stretch in 0.2f32..3.0, shift in -1e3f32..1e3,
        ) {
            let mesh = split_sphere();
            let rest = Topology::build(&mesh);
            let pose = |p: Vec3| {
                let (s, c) = (twist * p.y).sin_cos();
                let q = Vec3::new(c * p.x - s * p.z, p.y * stretch, s * p.x + c * p.z);
                q + Vec3::new(bend * q.y * q.y, 0.0, shift)
            };
            let positions = posed(&mesh, pose);
            let built = Topology::build(&Mesh::new(positions.clone(), mesh.indices().to_vec()).unwrap());
            let same = built.positions.len() == rest.positions.len() && built.faces == rest.faces;
            let reposed = rest.reposed(mesh.indices(), &positions);
            proptest::prop_assert_eq!(reposed.is_some(), same);
            if let Some(reposed) = reposed {
                proptest::prop_assert_eq!(reposed, built);
            }
        }
    }
}
