//! The tiled edge lists (C4 in [`super`]): a uniform grid over light-map
//! space whose cells list, for the receivers whose map point falls in them,
//! the potential silhouette edges that can move a light sample's count.
//!
//! - **Footprint.** An edge at depth `z` reaches a receiver at depth
//!   `z_p ≤ L0` only within map distance `R(1/z − 1/z_p) ≤ R(1/z − 1/L0)` of
//!   its own map projection (disk light), or `tanθ (z_p − z) ≤ tanθ (L0 − z)`
//!   (sun); a cell lists the edge only if that capsule around its map segment
//!   touches the cell, and [`EdgeIndex::may_reach`] applies the receiver's
//!   exact bound.
//! - **Silhouette from the cell** ([`EdgeIndex::coverage`]). The edge's σ
//!   (C2) is `0` wherever the receiver lies on opposite sides of its two
//!   faces' planes; each side is an affine function of the receiver, so if
//!   the eight corners of the cell's receiver region (its map rectangle
//!   between the edge's depth and `L0`) all lie on opposite sides, so does
//!   every receiver of the cell, and the edge — most of a smooth closed
//!   mesh's potential silhouettes under a large light — is left out.
//! - **Reference lists.** The raster reference count (C1's `D(c)` through
//!   the depth lists) corrects along a move of at most a texel and a half at
//!   the receiver; only faces and edges whose map projection comes that close
//!   can be passed, so it walks two short lists: the edges whose map segment
//!   comes within that margin of the cell, and the faces (each once, however
//!   many of its edges are listed) whose map box, widened by it, touches the
//!   cell. One list of edges standing for their faces, as before, loaded a
//!   ground plane's one big face once per boundary edge in every cell: that
//!   walk was most of the method's cost on a simple scene (BENCHMARKS.md,
//!   issue 39).
//!
//! The cells coarsen until the footprint boxes hold at most [`MAX_ENTRIES`].

use glam::{Vec2, Vec3};

use super::edges::CoverageEdge;
use crate::cell_grid::{CellGrid, cell_range};
use crate::light::{LightFrame, Projection};

/// Perspective map coordinates beyond this (about 89° off the light axis) are
/// clamped (`LightFrame::map_limit`).
const MAP_LIMIT: f32 = 64.0;

/// The most cell entries the grid keeps (4M: 16 MiB of edge ids).
pub const MAX_ENTRIES: usize = 4 << 20;

/// A cell's rectangle is widened by this share of a cell before the finer
/// tests, for the f32 rounding of the cell a receiver is looked up in.
const CELL_SLACK: f32 = 1e-3;

/// Per cell, the edges that can matter to its receivers (CSR): the sample
/// walk's, and the raster reference count's edges and faces.
#[derive(Debug, Clone)]
pub struct EdgeIndex {
    samples: CellGrid,
    /// The reference count's edges; empty unless built with a reference margin.
    reference_edges: CellGrid,
    /// The reference count's faces (ids into `faces`); empty likewise.
    reference_faces: CellGrid,
    /// Each face of the edges once, as its first edge has it: `(a, b, third)`.
    faces: Vec<[Vec3; 3]>,
    /// Per edge: its map-space segment (clipped endpoints' projections).
    segments: Vec<(Vec2, Vec2)>,
}

/// The faces of `edges`, each once (two edges share a face when its three
/// corners are the same bits), in the order their first edge lists them.
fn unique_faces(edges: &[CoverageEdge]) -> Vec<[Vec3; 3]> {
    let mut seen = std::collections::HashSet::new();
    let mut faces = Vec::new();
    for e in edges {
        for &t in &e.third[..e.faces as usize] {
            let mut key = [e.a, e.b, t].map(|p| p.to_array().map(f32::to_bits));
            key.sort_unstable();
            if seen.insert(key) {
                faces.push([e.a, e.b, t]);
            }
        }
    }
    faces
}

/// An edge's map segment and footprint radius, or `None` when it lies wholly
/// at or behind the light plane.
fn footprint(e: &CoverageEdge, frame: &LightFrame, reference_depth: f32) -> Option<(Vec2, Vec2, f32)> {
    match frame.projection {
        Projection::Perspective { radius } => {
            // Receivers lie no deeper than L0, so R(1/z − 1/L0) bounds the reach.
            let near = reference_depth * 1e-5;
            let (a, b) = e.clipped(near, f32::INFINITY)?;
            let z = a.z.min(b.z).max(near);
            Some((frame.map(a), frame.map(b), (radius * ((reference_depth - z) / z) / reference_depth).max(0.0)))
        }
        Projection::Orthographic { tan_angle } => {
            Some((frame.map(e.a), frame.map(e.b), tan_angle * (reference_depth - e.min_depth()).max(0.0)))
        }
    }
}

/// Distance from `q` to the segment `a b`.
#[inline]
fn segment_distance(q: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 { ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
    (a + ab * t - q).length()
}

/// Distance from the rectangle `lo..hi` to the segment `a b` (0 where they meet).
fn rect_segment_distance(lo: Vec2, hi: Vec2, a: Vec2, b: Vec2) -> f32 {
    let inside = |p: Vec2| p.cmpge(lo).all() && p.cmple(hi).all();
    if inside(a) || inside(b) {
        return 0.0;
    }
    let corners = [lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)];
    let cross = |u: Vec2, v: Vec2| u.x * v.y - u.y * v.x;
    let mut best = f32::INFINITY;
    for k in 0..4 {
        let (c, d) = (corners[k], corners[(k + 1) % 4]);
        // A proper crossing of a side: the segment passes through the rectangle.
        let (s1, s2) = (cross(d - c, a - c), cross(d - c, b - c));
        let (s3, s4) = (cross(b - a, c - a), cross(b - a, d - a));
        if (s1 > 0.0) != (s2 > 0.0) && (s3 > 0.0) != (s4 > 0.0) {
            return 0.0;
        }
        best = best.min(segment_distance(c, a, b)).min(segment_distance(a, c, d)).min(segment_distance(b, c, d));
    }
    best
}

/// The receivers a cell's edges are culled for: the map rectangle `lo..hi`
/// between depths `z0` and `z1`, as its eight corners in the light frame
/// (a frustum's slice under a perspective light, a box under the sun).
fn region_corners(perspective: bool, lo: Vec2, hi: Vec2, z0: f32, z1: f32) -> [Vec3; 8] {
    let m = [lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)];
    let at = |m: Vec2, z: f32| if perspective { (m * z).extend(z) } else { m.extend(z) };
    std::array::from_fn(|k| at(m[k % 4], if k < 4 { z0 } else { z1 }))
}

/// The nearest depth at which a receiver `distance` map units from an edge
/// at depth `z` can have it within reach (`EdgeIndex::may_reach`, inverted
/// with its tolerance and a little more): `R(1/z − 1/z_p) ≥ d` (disk) or
/// `tanθ (z_p − z) ≥ d` (sun); `None` where no depth can.
fn nearest_reached_depth(projection: Projection, z: f32, distance: f32) -> Option<f32> {
    let d = (distance - 1e-12).max(0.0) / (1.0 + 1e-4) * (1.0 - 1e-3);
    match projection {
        Projection::Perspective { radius } if radius > 0.0 && d > 0.0 => {
            let inverse = 1.0 / z - d / radius;
            (inverse > 0.0).then(|| z.max(1.0 / inverse * (1.0 - 1e-4)))
        }
        Projection::Orthographic { tan_angle } if tan_angle > 0.0 && d > 0.0 => {
            let depth = z + d / tan_angle;
            Some(z.max(depth - 1e-4 * (depth - z)))
        }
        _ => Some(z),
    }
}

/// Whether edge `e` has σ = 0 (C2) for every receiver among `corners`'
/// convex hull. σ sums, per face `(a, b, t)`, the sign of
/// `det(a − p, b − p, t − p) = −(p − a)·((b − a) × (t − a))`: the side of the
/// face's plane `p` lies on. Two faces cancel where `p` is on opposite sides
/// of their planes; both sides are affine in `p`, so the corners decide. A
/// margin keeps out receivers the GPU's f32 determinant could put on the
/// other side (its rounding: `ε` times the vectors' lengths and coordinates).
fn never_a_silhouette(e: &CoverageEdge, corners: &[Vec3; 8]) -> bool {
    if e.faces != 2 {
        return false;
    }
    let reach = corners.iter().fold(0.0f32, |r, c| r.max((*c - e.a).length())) + (e.b - e.a).length();
    let scale = corners.iter().fold(e.a.length().max(e.b.length()), |s, c| s.max(c.length())).max(reach);
    let side = |t: Vec3| {
        let n = (e.b - e.a).cross(t - e.a);
        let margin = 1e-5 * scale * reach * (reach + (t - e.a).length());
        let values = corners.map(|c| (c - e.a).dot(n));
        if values.iter().all(|v| *v > margin) {
            1
        } else if values.iter().all(|v| *v < -margin) {
            -1
        } else {
            0
        }
    };
    let (s1, s2) = (side(e.third[0]), side(e.third[1]));
    s1 != 0 && s1 == -s2
}

impl EdgeIndex {
    /// Bins `edges` by footprint alone (every cell lists each edge whose
    /// footprint capsule touches it): for the penumbra-wedges peer, whose
    /// edges are outlines, not σ-counted silhouettes.
    pub fn new(edges: &[CoverageEdge], frame: &LightFrame, reference_depth: f32) -> Self {
        Self::build(edges, frame, reference_depth, false, None)
    }

    /// The coverage method's lists: by footprint and silhouette from the
    /// cell, and with `reference_margin` (map units) the raster reference
    /// count's two: the faces whose map box, and the edges whose map
    /// segment, come within it of the cell.
    pub fn coverage(
        edges: &[CoverageEdge],
        frame: &LightFrame,
        reference_depth: f32,
        reference_margin: Option<f32>,
    ) -> Self {
        Self::build(edges, frame, reference_depth, true, reference_margin)
    }

    fn build(
        edges: &[CoverageEdge],
        frame: &LightFrame,
        reference_depth: f32,
        cull_silhouettes: bool,
        reference_margin: Option<f32>,
    ) -> Self {
        let feet: Vec<Option<(Vec2, Vec2, f32)>> = edges.iter().map(|e| footprint(e, frame, reference_depth)).collect();
        // Only finite footprints are binned.
        let binned: Vec<Option<(Vec2, Vec2, f32)>> =
            feet.iter().map(|f| f.filter(|(a, b, r)| a.is_finite() && b.is_finite() && r.is_finite())).collect();
        let limit = frame.map_limit(MAP_LIMIT);
        let clamp = |v: Vec2| v.clamp(Vec2::splat(-limit), Vec2::splat(limit));
        let bounds: Vec<Option<(Vec2, Vec2)>> = binned
            .iter()
            .map(|f| f.map(|(a, b, r)| (clamp(a.min(b) - Vec2::splat(r)), clamp(a.max(b) + Vec2::splat(r)))))
            .collect();
        let z_near = if frame.is_perspective() { reference_depth * 1e-5 } else { f32::NEG_INFINITY };
        // The reference lists' bounds, widened by the margin: a face's map
        // box, an edge's map segment's; `None` inside for one reaching the
        // light plane, which projects without bound (listed in every cell).
        let margin = reference_margin.unwrap_or(0.0);
        let beyond_near = |p: &Vec3| !frame.is_perspective() || p.z > z_near;
        let widened_box = |maps: &[Vec2]| {
            let (lo, hi) =
                maps.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), m| (lo.min(*m), hi.max(*m)));
            (lo.is_finite() && hi.is_finite())
                .then(|| (clamp(lo - Vec2::splat(margin)), clamp(hi + Vec2::splat(margin))))
        };
        let faces = if reference_margin.is_some() { unique_faces(edges) } else { Vec::new() };
        let face_bounds: Vec<Option<Option<(Vec2, Vec2)>>> =
            faces
                .iter()
                .map(|f| {
                    if f.iter().all(beyond_near) { widened_box(&f.map(|p| frame.map(p))).map(Some) } else { Some(None) }
                })
                .collect();
        // Each edge's map segment, once (`None`: it reaches the light plane).
        let edge_segments: Vec<Option<(Vec2, Vec2)>> = match reference_margin {
            Some(_) => edges
                .iter()
                .map(|e| (beyond_near(&e.a) && beyond_near(&e.b)).then(|| (frame.map(e.a), frame.map(e.b))))
                .collect(),
            None => Vec::new(),
        };
        let edge_bounds: Vec<Option<Option<(Vec2, Vec2)>>> = edge_segments
            .iter()
            .map(|s| match s {
                Some((a, b)) => widened_box(&[*a, *b]).map(Some),
                None => Some(None),
            })
            .collect();
        // The grid spans both lists' boxes: a receiver just outside every
        // footprint can still need a reference correction.
        let (mut min, mut max) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        // (An edge's band need not lie in its faces' boxes: a face reaching
        // the light plane has none.)
        let reference_boxes = face_bounds.iter().chain(&edge_bounds).flatten().flatten();
        for (lo, hi) in bounds.iter().flatten().chain(reference_boxes) {
            min = min.min(*lo);
            max = max.max(*hi);
        }
        if !(min.x <= max.x && min.y <= max.y) {
            (min, max) = (Vec2::ZERO, Vec2::ONE);
        }
        let size = (max - min).max(Vec2::splat(1e-12));
        let n = (edges.len() as f32).sqrt().clamp(1.0, 256.0);
        let aspect = (size.x / size.y).clamp(1e-3, 1e3).sqrt();
        let mut dims = [((n * aspect).ceil() as usize).clamp(1, 512), ((n / aspect).ceil() as usize).clamp(1, 512)];
        // Edges of a large light reach far: coarser cells, until the lists
        // hold at most `MAX_ENTRIES` (what a GPU buffer of them can take).
        loop {
            let entries: usize = bounds
                .iter()
                .flatten()
                .map(|(lo, hi)| {
                    let (x0, x1, y0, y1) = cell_range(min, size, dims, *lo, *hi);
                    (x1 - x0 + 1) * (y1 - y0 + 1)
                })
                .sum();
            if entries <= MAX_ENTRIES || dims == [1, 1] {
                break;
            }
            dims = [(dims[0] / 2).max(1), (dims[1] / 2).max(1)];
        }
        let slack = size / Vec2::new(dims[0] as f32, dims[1] as f32) * CELL_SLACK;
        // Receivers lie no deeper than L0; a hair deeper for their lift.
        let z_far = reference_depth + 1e-3 * reference_depth.abs().max(1e-30);
        let samples = CellGrid::build_where(min, size, dims, &bounds, |id, lo, hi| {
            let (lo, hi) = (lo - slack, hi + slack);
            let Some((a, b, r)) = binned[id as usize] else { return false };
            // `may_reach`'s bound, with its tolerance, at the cell's nearest point.
            let distance = rect_segment_distance(lo, hi, a, b);
            if distance > r * (1.0 + 1e-3) + 1e-12 {
                return false;
            }
            if !cull_silhouettes {
                return true;
            }
            let e = &edges[id as usize];
            // Only receivers deep enough to have the edge within reach count.
            // `may_reach` takes an edge at least a millionth of the receiver's
            // depth from the light (receivers lie behind the near plane).
            let z_edge = if frame.is_perspective() { e.min_depth().max(z_near * 1e-6) } else { e.min_depth() };
            let Some(z0) = nearest_reached_depth(frame.projection, z_edge, distance) else { return false };
            let z0 = z0.max(z_near);
            if !(z0 < z_far) {
                return false;
            }
            !never_a_silhouette(e, &region_corners(frame.is_perspective(), lo, hi, z0, z_far))
        });
        let every_cell = |b: Vec<Option<Option<(Vec2, Vec2)>>>| -> Vec<Option<(Vec2, Vec2)>> {
            b.into_iter().map(|b| b.map(|b| b.unwrap_or((min, max)))).collect()
        };
        let reference_faces = CellGrid::build(min, size, dims, &every_cell(face_bounds));
        // An edge's move test needs its map segment within the margin of the
        // receiver (`raster_reference_count`: the move's map segment crosses it).
        let reach = margin * (1.0 + 1e-3) + 1e-12;
        let reference_edges = CellGrid::build_where(min, size, dims, &every_cell(edge_bounds), |id, lo, hi| {
            edge_segments[id as usize].is_none_or(|(a, b)| rect_segment_distance(lo - slack, hi + slack, a, b) <= reach)
        });
        let segments = feet.iter().map(|f| f.map_or((Vec2::NAN, Vec2::NAN), |(a, b, _)| (a, b))).collect();
        Self { samples, reference_edges, reference_faces, faces, segments }
    }

    /// The edges the sample walk visits for a receiver at map point `q` (none outside the grid).
    pub fn cell(&self, q: Vec2) -> &[u32] {
        self.samples.cell(q)
    }

    /// The edges the raster reference count corrects with at map point `q`.
    pub fn reference_edges(&self, q: Vec2) -> &[u32] {
        self.reference_edges.cell(q)
    }

    /// The faces (ids into [`Self::faces`]) the raster reference count tests
    /// the move against at map point `q`.
    pub fn reference_faces(&self, q: Vec2) -> &[u32] {
        self.reference_faces.cell(q)
    }

    /// Each face of the edges once, `(a, b, third)` as its first edge has it.
    pub fn faces(&self) -> &[[Vec3; 3]] {
        &self.faces
    }

    /// Whether edge `id` (`e`) can cross the cone from the receiver `p`
    /// (light frame) to the light: its map segment within the receiver's
    /// footprint bound (C4), taken at the edge's nearest depth (conservative).
    #[inline]
    pub fn may_reach(&self, id: u32, e: &CoverageEdge, p: Vec3, frame: &LightFrame) -> bool {
        let z = e.min_depth();
        if !(z < p.z) {
            return false;
        }
        let reach = match frame.projection {
            Projection::Perspective { radius } => {
                let z = z.max(p.z * 1e-6);
                radius * ((p.z - z) / z) / p.z
            }
            Projection::Orthographic { tan_angle } => tan_angle * (p.z - z),
        };
        let (a, b) = self.segments[id as usize];
        !(segment_distance(frame.map(p), a, b) > reach * (1.0 + 1e-4) + 1e-12)
    }

    /// The grid's origin, cells per map unit and size in cells (for a GPU copy).
    pub fn grid(&self) -> (Vec2, Vec2, [usize; 2]) {
        self.samples.grid()
    }

    /// The three lists as one CSR for a GPU copy: `starts` has `3 · cells + 1`
    /// entries; cell `c`'s sample edges are `items[starts[c]..starts[c + 1]]`,
    /// its reference edges `items[starts[cells + c]..starts[cells + c + 1]]`
    /// and its reference faces (ids into [`Self::faces`])
    /// `items[starts[2 · cells + c]..starts[2 · cells + c + 1]]`.
    pub fn gpu_lists(&self) -> (Vec<u32>, Vec<u32>) {
        let mut starts = vec![0u32];
        let mut items = Vec::with_capacity(self.entries());
        for grid in [&self.samples, &self.reference_edges, &self.reference_faces] {
            let (s, i) = grid.lists();
            let offset = items.len() as u32;
            starts.extend(s[1..].iter().map(|s| s + offset));
            items.extend_from_slice(i);
        }
        (starts, items)
    }

    /// Total cell entries of the three lists (the index's size).
    pub fn entries(&self) -> usize {
        [&self.samples, &self.reference_edges, &self.reference_faces].iter().map(|g| g.lists().1.len()).sum()
    }

    /// The map segment of edge `id`.
    pub fn segment(&self, id: u32) -> (Vec2, Vec2) {
        self.segments[id as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_rectangle_and_a_segment_are_apart_by_their_nearest_points() {
        let (lo, hi) = (Vec2::ZERO, Vec2::ONE);
        // Through the middle, ends outside: they meet.
        assert_eq!(rect_segment_distance(lo, hi, Vec2::new(-1.0, 0.5), Vec2::new(2.0, 0.5)), 0.0);
        // Beside the right side.
        assert!((rect_segment_distance(lo, hi, Vec2::new(3.0, -5.0), Vec2::new(3.0, 5.0)) - 2.0).abs() < 1e-6);
        // Diagonal past a corner: the corner is the nearest point.
        let d = rect_segment_distance(lo, hi, Vec2::new(2.0, 1.0), Vec2::new(1.0, 2.0));
        assert!((d - 0.5f32.sqrt()).abs() < 1e-6, "{d}");
    }

    /// A roof ridge along x at depth 1, its faces sloping away from the
    /// light (deeper): seen from below it is a crease, from beside it a
    /// silhouette.
    fn ridge() -> CoverageEdge {
        CoverageEdge {
            a: Vec3::new(-1.0, 0.0, 1.0),
            b: Vec3::new(1.0, 0.0, 1.0),
            third: [Vec3::new(0.0, 1.0, 1.2), Vec3::new(0.0, -1.0, 1.2)],
            faces: 2,
        }
    }

    #[test]
    fn a_ridge_is_culled_for_receivers_below_it_and_kept_for_those_beside_it() {
        let below = region_corners(true, Vec2::splat(-0.05), Vec2::splat(0.05), 2.0, 3.0);
        assert!(never_a_silhouette(&ridge(), &below));
        // Beside it at about its depth: the plane through p and the ridge
        // is near z = 1, both faces below it.
        let beside = region_corners(true, Vec2::new(1.0, 3.0), Vec2::new(1.1, 3.1), 1.0, 1.2);
        assert!(!never_a_silhouette(&ridge(), &beside));
        // A boundary edge (one face) counts ±1 from everywhere.
        assert!(!never_a_silhouette(&CoverageEdge { faces: 1, ..ridge() }, &below));
    }

    #[test]
    fn a_receiver_beside_every_footprint_still_gets_its_reference_faces() {
        // A boundary edge at the receivers' depth reaches nothing (footprint
        // radius 0, a segment on y = 0), but its face spans map y 0..0.25:
        // a receiver at y = 0.1 is outside every footprint yet may pass the
        // face within the raster reference count's move.
        let frame = LightFrame::disk(&crate::light::DiskLight::new(Vec3::ZERO, Vec3::Z, 0.1).unwrap());
        let edge = CoverageEdge {
            a: Vec3::new(-1.0, 0.0, 2.0),
            b: Vec3::new(1.0, 0.0, 2.0),
            third: [Vec3::new(0.0, 0.5, 2.0), Vec3::ZERO],
            faces: 1,
        };
        let q = frame.map(Vec3::new(0.0, 0.2, 2.0));
        let index = EdgeIndex::coverage(&[edge], &frame, 2.0, Some(0.01));
        // Outside the edge's footprint box (radius 0 about y = 0) …
        assert_eq!(footprint(&edge, &frame, 2.0).map(|f| f.2), Some(0.0));
        assert!(q.y > 0.05);
        // … yet inside the grid, with the edge's face in its reference list.
        assert_eq!(index.reference_faces(q), &[0]);
        assert_eq!(index.faces(), &[[edge.a, edge.b, edge.third[0]]]);
    }

    #[test]
    fn a_face_shared_by_edges_is_listed_once_whatever_its_corners_order() {
        let (a, b, c, d) =
            (Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0), Vec3::Z * 2.0);
        let edge = |a, b, t0, t1, faces| CoverageEdge { a, b, third: [t0, t1], faces };
        // Triangle abc's three boundary edges, each naming it in another
        // order, then edge bc shared with a second face bcd.
        let edges = [edge(a, b, c, Vec3::ZERO, 1), edge(c, a, b, Vec3::ZERO, 1), edge(b, c, a, d, 2)];
        assert_eq!(unique_faces(&edges), vec![[a, b, c], [b, c, d]]);
        assert!(unique_faces(&[]).is_empty());
    }

    #[test]
    fn receivers_far_from_an_edge_reach_it_only_deep_enough() {
        let disk = Projection::Perspective { radius: 0.5 };
        // At map distance 0 every depth behind the edge can.
        assert_eq!(nearest_reached_depth(disk, 1.0, 0.0), Some(1.0));
        // R (1/1 − 1/z) ≥ 0.25 → z ≥ 2.
        let z = nearest_reached_depth(disk, 1.0, 0.25).unwrap();
        assert!(z < 2.0 && z > 1.99, "{z}");
        // Beyond R / z no depth can.
        assert_eq!(nearest_reached_depth(disk, 1.0, 0.6), None);
        let sun = Projection::Orthographic { tan_angle: 0.1 };
        let z = nearest_reached_depth(sun, 1.0, 0.05).unwrap();
        assert!(z < 1.5 && z > 1.49, "{z}");
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

        /// The rectangle–segment distance is the smallest distance from the
        /// segment to any point of the rectangle (sampled densely).
        #[test]
        fn rect_segment_distance_bounds_every_point_of_the_rectangle(
            ax in -3.0f32..3.0, ay in -3.0f32..3.0, bx in -3.0f32..3.0, by in -3.0f32..3.0,
        ) {
            let (lo, hi) = (Vec2::new(-0.5, -0.25), Vec2::new(0.75, 0.5));
            let (a, b) = (Vec2::new(ax, ay), Vec2::new(bx, by));
            let d = rect_segment_distance(lo, hi, a, b);
            let mut nearest = f32::INFINITY;
            for i in 0..=40 {
                for j in 0..=40 {
                    let q = lo + (hi - lo) * Vec2::new(i as f32 / 40.0, j as f32 / 40.0);
                    nearest = nearest.min(segment_distance(q, a, b));
                }
            }
            prop_assert!(d <= nearest + 1e-5, "{d} > {nearest}");
            prop_assert!(nearest - d <= 0.05, "{d} far below {nearest}");
        }

        /// An edge culled for a region has σ = 0 (its two faces' third
        /// vertices on opposite sides of the plane through p and the edge) at
        /// every receiver p inside it.
        #[test]
        fn an_edge_culled_for_a_region_is_a_silhouette_from_none_of_its_points(
            a in prop::array::uniform3(-1.0f32..1.0), b in prop::array::uniform3(-1.0f32..1.0),
            t0 in prop::array::uniform3(-1.0f32..1.0), t1 in prop::array::uniform3(-1.0f32..1.0),
            cx in -1.0f32..1.0, cy in -1.0f32..1.0, w in 0.01f32..0.5, z0 in 1.0f32..2.0, dz in 0.1f32..2.0,
            u in prop::array::uniform3(0.0f32..1.0),
        ) {
            let shift = Vec3::new(0.0, 0.0, 0.5);
            let e = CoverageEdge {
                a: Vec3::from(a) * 0.3 + shift,
                b: Vec3::from(b) * 0.3 + shift,
                third: [Vec3::from(t0) * 0.3 + shift, Vec3::from(t1) * 0.3 + shift],
                faces: 2,
            };
            let (lo, hi) = (Vec2::new(cx, cy), Vec2::new(cx + w, cy + w));
            let corners = region_corners(true, lo, hi, z0, z0 + dz);
            if never_a_silhouette(&e, &corners) {
                let z = z0 + dz * u[2];
                let m = lo + (hi - lo) * Vec2::new(u[0], u[1]);
                let p = (m * z).extend(z);
                let n = (e.a - p).cross(e.b - p);
                let sides = e.third.map(|t| n.dot(t - p) >= 0.0);
                prop_assert!(sides[0] != sides[1], "σ ≠ 0 at {p:?}");
            }
        }
    }
}
