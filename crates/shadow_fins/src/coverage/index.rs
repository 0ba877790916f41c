//! The tiled edge list (C4 in [`super`]): a uniform grid over light-map
//! space whose cells list the potential silhouette edges whose penumbra
//! footprint touches them. An edge at depth `z` reaches a receiver at depth
//! `z_p ≤ L0` only within map distance `R(1/z − 1/z_p) ≤ R(1/z − 1/L0)` of
//! its own map projection (disk light), or `tanθ (z_p − z) ≤ tanθ (L0 − z)`
//! (sun); the edge is binned with that radius, and [`EdgeIndex::may_reach`]
//! applies the receiver's exact bound. The cells coarsen until the lists
//! hold at most [`MAX_ENTRIES`].

use glam::{Vec2, Vec3};

use super::edges::CoverageEdge;
use crate::cell_grid::{CellGrid, cell_range};
use crate::light::{LightFrame, Projection};

/// Perspective map coordinates beyond this (about 89° off the light axis) are
/// clamped (`LightFrame::map_limit`).
const MAP_LIMIT: f32 = 64.0;

/// The most cell entries the grid keeps (4M: 16 MiB of edge ids).
pub const MAX_ENTRIES: usize = 4 << 20;

/// Per cell, the edges whose footprint touches it (CSR).
#[derive(Debug, Clone)]
pub struct EdgeIndex {
    grid: CellGrid,
    /// Per edge: its map-space segment (clipped endpoints' projections).
    segments: Vec<(Vec2, Vec2)>,
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

impl EdgeIndex {
    /// Bins `edges` by footprint, each widened by `margin` map units (the
    /// raster reference count corrects over up to a texel).
    pub fn new(edges: &[CoverageEdge], frame: &LightFrame, reference_depth: f32, margin: f32) -> Self {
        let feet: Vec<Option<(Vec2, Vec2, f32)>> = edges.iter().map(|e| footprint(e, frame, reference_depth)).collect();
        let limit = frame.map_limit(MAP_LIMIT);
        let clamp = |v: Vec2| v.clamp(Vec2::splat(-limit), Vec2::splat(limit));
        let bounds: Vec<Option<(Vec2, Vec2)>> = feet
            .iter()
            .map(|f| f.filter(|(a, b, r)| a.is_finite() && b.is_finite() && r.is_finite()))
            .map(|f| {
                f.map(|(a, b, r)| {
                    (clamp(a.min(b) - Vec2::splat(r + margin)), clamp(a.max(b) + Vec2::splat(r + margin)))
                })
            })
            .collect();
        let (mut min, mut max) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for (lo, hi) in bounds.iter().flatten() {
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
        let grid = CellGrid::build(min, size, dims, &bounds);
        let segments = feet.iter().map(|f| f.map_or((Vec2::NAN, Vec2::NAN), |(a, b, _)| (a, b))).collect();
        Self { grid, segments }
    }

    /// The edges binned in the cell of map point `q` (none outside the grid).
    pub fn cell(&self, q: Vec2) -> &[u32] {
        self.grid.cell(q)
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
        self.grid.grid()
    }

    /// The CSR arrays: where each cell's edges start in `items`, and the edge ids.
    pub fn lists(&self) -> (&[u32], &[u32]) {
        self.grid.lists()
    }

    /// Total cell entries (the index's size).
    pub fn entries(&self) -> usize {
        self.grid.lists().1.len()
    }

    /// The map segment of edge `id`.
    pub fn segment(&self, id: u32) -> (Vec2, Vec2) {
        self.segments[id as usize]
    }
}
