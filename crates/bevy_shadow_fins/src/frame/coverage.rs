//! Main world: the coverage method's frame (see `shadow_fins::coverage`),
//! built with the core crate when a caster, the light or a setting changed:
//! the potential silhouette edges and their footprint grid, every caster
//! triangle in light-map space for the depth lists, and the light samples.
//! The render world uploads them and runs `shaders/coverage_lists.wgsl` and
//! `shaders/coverage.wgsl`.

use bevy::prelude::*;
use shadow_fins::{
    coverage::{DEPTH_LIST_LENGTH, EdgeIndex, far_list_length, potential_silhouette_edges, reference},
    oracle::{MapRegion, near_depth},
    scene::Scene,
};

use crate::{
    budget::{FinDegradation, FinDegradations, allocate_maps},
    gpu_layout::GpuCaster,
};

/// Caster depths each texel's near list keeps, as the core's
/// `shadow_fins::coverage::DepthLists` at [`DEPTH_LIST_LENGTH`].
pub(crate) const NEAR_DEPTHS: u32 = DEPTH_LIST_LENGTH;
/// And its far list.
pub(crate) const FAR_DEPTHS: u32 = far_list_length(NEAR_DEPTHS);
/// Words per texel of the depth lists: near, far, total.
pub(crate) const LIST_WORDS: u64 = (NEAR_DEPTHS + FAR_DEPTHS + 1) as u64;

/// Texels of a caster's bounding box one workgroup of `raster_lists` covers:
/// a big triangle is split over several, so that no invocation runs long (a
/// GPU's watchdog; llvmpipe stops a shader after 65535 loop iterations).
pub(crate) const LIST_BLOCK_TEXELS: u32 = 4096;

/// Entries one coverage cell's list may hold before the frame reports it: a
/// pixel walks its cell's sample list and its two reference lists (edges,
/// faces), and llvmpipe stops an invocation after 65535 loop iterations in
/// all (3 × 16 384 stays below).
pub(crate) const LONG_CELL_EDGES: u32 = 16_384;

/// The longest cell of `starts` (cell `i` is `starts[i]..starts[i + 1]`), as
/// a report when it is over `limit`.
fn long_cell(starts: &[u32], limit: u32) -> Option<FinDegradation> {
    let longest = starts.windows(2).map(|w| w[1].saturating_sub(w[0])).max()?;
    (longest > limit).then_some(FinDegradation::LongCoverageCell { edges: longest, limit })
}

/// One potential silhouette edge (`Edge` in `coverage.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuCoverageEdge {
    /// `a.w`: the number of faces.
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub third0: [f32; 4],
    pub third1: [f32; 4],
    /// The map segment of the near-clipped ends.
    pub segment: [f32; 4],
}

/// One face the raster reference count tests its move against (`Face` in
/// `coverage_types.wgsl`): corners `a`, `b`, `c` (`EdgeIndex::faces`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuCoverageFace {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
}

/// Everything the coverage passes need for one frame.
#[derive(Debug)]
pub(crate) struct CoverageFrame {
    pub edges: Vec<GpuCoverageEdge>,
    pub faces: Vec<GpuCoverageFace>,
    /// Each cell's three lists (`EdgeIndex::gpu_lists`): `3 · cells + 1`
    /// starts, the sample lists' first, then the reference edges', then the
    /// reference faces' (ids into `faces`).
    pub cell_starts: Vec<u32>,
    pub cell_items: Vec<u32>,
    /// Grid origin (xy) and cells per map unit (zw); cells in x and y.
    pub grid: [f32; 4],
    pub dims: [u32; 2],
    pub casters: Vec<GpuCaster>,
    /// The casters' cut-outs and the alpha masks they read (`cutout.wgsl`).
    pub cutouts: Vec<crate::gpu_layout::GpuCutout>,
    pub mask_words: Vec<u32>,
    /// `raster_lists` work: (caster, block of `LIST_BLOCK_TEXELS` texels of
    /// its bounding box), one workgroup each.
    pub raster_work: Vec<[u32; 2]>,
    pub region: MapRegion,
    pub samples: Vec<[f32; 2]>,
    pub near: f32,
    pub extent: f32,
}

impl CoverageFrame {
    /// GPU bytes of the frame's buffers (`render/coverage.rs` sizes them so):
    /// the per-texel depth lists, the edge and face records, the cell lists,
    /// the casters with their cut-outs and masks, and the raster work.
    pub(crate) fn gpu_bytes(&self) -> u64 {
        let texels = (self.region.resolution as u64).pow(2);
        let bytes = |n: usize, each: usize| (n * each) as u64;
        texels * LIST_WORDS * 4
            + bytes(self.edges.len(), size_of::<GpuCoverageEdge>())
            + bytes(self.faces.len(), size_of::<GpuCoverageFace>())
            + bytes(self.cell_starts.len() + self.cell_items.len() + self.mask_words.len(), 4)
            + bytes(self.casters.len(), size_of::<GpuCaster>())
            + bytes(self.cutouts.len(), size_of::<crate::gpu_layout::GpuCutout>())
            + bytes(self.raster_work.len(), 8)
            + bytes(self.samples.len(), 8)
    }

    /// The samples as `coverage.wgsl` reads them: per quad of four samples
    /// their x then their y, padded with zeros to whole 32-sample words
    /// (padding lanes are never counted: they are not above the horizon).
    pub(crate) fn sample_planes(&self) -> Vec<[f32; 4]> {
        let n = self.samples.len().div_ceil(32) * 32;
        let at = |k: usize| self.samples.get(k).copied().unwrap_or([0.0, 0.0]);
        (0..n / 4)
            .flat_map(|quad| {
                let q = [at(quad * 4), at(quad * 4 + 1), at(quad * 4 + 2), at(quad * 4 + 3)];
                [[q[0][0], q[1][0], q[2][0], q[3][0]], [q[0][1], q[1][1], q[2][1], q[3][1]]]
            })
            .collect()
    }
}

/// The blocks of texels of a map triangle's bounding box (one texel wider on
/// each side than `texel_range` in `coverage_lists.wgsl`, so rounding never
/// drops one: a block past the range's end does nothing).
fn raster_blocks(corners: &[Vec2; 3], region: &MapRegion) -> u32 {
    let lo = corners[0].min(corners[1]).min(corners[2]);
    let hi = corners[0].max(corners[1]).max(corners[2]);
    let res = region.resolution as f32;
    let to_texel = |v: f32, min: f32| (v - min) / region.texel - 0.5;
    let span = |lo: f32, hi: f32, min: f32| {
        let a = (to_texel(lo, min).ceil() - 1.0).max(0.0);
        let b = (to_texel(hi, min).floor() + 1.0).min(res - 1.0);
        if b >= a && a.is_finite() && b.is_finite() { (b - a + 1.0) as u64 } else { 0 }
    };
    let texels = span(lo.x, hi.x, region.min.x) * span(lo.y, hi.y, region.min.y);
    texels.div_ceil(LIST_BLOCK_TEXELS as u64).min(u32::MAX as u64) as u32
}

/// The coverage frame of a scene under a disk or sun light; the maps' budget caps
/// the depth lists (resolution first), the buffer limit the edge lists.
pub(crate) fn coverage_frame(
    scene: &Scene,
    in_frame: crate::frame::in_frame::InFrame,
    resolution: u32,
    samples: u32,
    receiver_bound: impl Iterator<Item = Vec3>,
    map_bytes: u64,
    max_buffer: u64,
) -> (CoverageFrame, FinDegradations, usize) {
    let ls = in_frame.light_space(scene, receiver_bound);
    let near = near_depth(&ls);
    // One list per texel, no layers to trade: resolution is what goes.
    let alloc = allocate_maps(resolution, 1, LIST_WORDS * 4, map_bytes, f32::INFINITY);
    let mut degraded = FinDegradations::from(alloc.degradation);
    let triangles = reference::map_triangles(&ls, near);
    let region = in_frame.covering(triangles.iter().map(|t| t.bounds()), alloc.resolution.clamp(1, 8192));
    let edges = potential_silhouette_edges(scene, &ls, near);
    // The raster reference count moves up to a texel and a half from the receiver.
    let index = EdgeIndex::coverage(&edges, &ls.frame, ls.reference_depth, Some(1.5 * region.texel));
    let (min, inv_cell, dims) = index.grid();
    let (starts, items) = index.gpu_lists();
    let mut keep = |what: &'static str, n: usize, bytes: u64| {
        let fit = (max_buffer / bytes) as usize;
        if n > fit {
            degraded = degraded.with(FinDegradation::Capacity {
                buffer: what,
                kept: fit as u32,
                wanted: n as u32,
                limit_bytes: max_buffer,
            });
        }
        n.min(fit)
    };
    let n_casters = keep("map casters", triangles.len(), size_of::<GpuCaster>() as u64);
    let n_items = keep("edge lists", items.len(), 4);
    let n_edges = keep("potential silhouette edges", edges.len(), size_of::<GpuCoverageEdge>() as u64);
    let n_faces = keep("reference faces", index.faces().len(), size_of::<GpuCoverageFace>() as u64);
    let v4 = |v: Vec3, w: f32| [v.x, v.y, v.z, w];
    let gpu_faces = index.faces()[..n_faces]
        .iter()
        .map(|[a, b, c]| GpuCoverageFace { a: v4(*a, 0.0), b: v4(*b, 0.0), c: v4(*c, 0.0) })
        .collect();
    let gpu_edges = edges
        .iter()
        .enumerate()
        .take(n_edges)
        .map(|(id, e)| {
            let (ma, mb) = index.segment(id as u32);
            GpuCoverageEdge {
                a: v4(e.a, e.faces as f32),
                b: v4(e.b, 0.0),
                third0: v4(e.third[0], 0.0),
                third1: v4(e.third[1], 0.0),
                segment: [ma.x, ma.y, mb.x, mb.y],
            }
        })
        .collect();
    // The cell lists without the edges and faces that did not fit, and no
    // longer than fits (the last lists, the reference faces', go first).
    let cells = dims[0] * dims[1];
    let (mut cell_starts, mut cell_items) = (Vec::with_capacity(starts.len()), Vec::with_capacity(n_items));
    cell_starts.push(0u32);
    for (list, w) in starts.windows(2).enumerate() {
        let kept = if list < 2 * cells { n_edges } else { n_faces };
        for &i in &items[w[0] as usize..w[1] as usize] {
            if (i as usize) < kept && cell_items.len() < n_items {
                cell_items.push(i);
            }
        }
        cell_starts.push(cell_items.len() as u32);
    }
    let (mut casters, mut cutouts, mut mask_words) =
        crate::frame::map_casters::gpu_casters(&triangles[..n_casters], None, &ls.masks);
    let mut raster_work: Vec<[u32; 2]> = triangles
        .iter()
        .take(n_casters)
        .enumerate()
        .flat_map(|(i, t)| (0..raster_blocks(&t.corners, &region)).map(move |b| [i as u32, b]))
        .collect();
    // Blocks past the buffer limit are dropped (their texels miss casters).
    let n_work = keep("depth-list raster work", raster_work.len(), size_of::<[u32; 2]>() as u64);
    raster_work.truncate(n_work);
    if let Some(why) = crate::frame::map_casters::fit_cutouts(&mut casters, &mut cutouts, &mut mask_words, max_buffer) {
        degraded = degraded.with(why);
    }
    degraded = degraded.with(long_cell(&cell_starts, LONG_CELL_EDGES));
    let frame = CoverageFrame {
        edges: gpu_edges,
        faces: gpu_faces,
        cell_starts,
        cell_items,
        grid: [min.x, min.y, inv_cell.x, inv_cell.y],
        dims: [dims[0] as u32, dims[1] as u32],
        casters,
        cutouts,
        mask_words,
        raster_work,
        region,
        samples: ls.frame.aperture.samples(samples.clamp(1, 256)).iter().map(|q| q.to_array()).collect(),
        near,
        extent: ls.extent,
    };
    (frame, degraded, edges.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cell_over_the_limit_is_reported_with_its_length() {
        // Cells of 3, 0 and 40 000 edges.
        let starts = [0, 3, 3, 40_003];
        assert_eq!(
            long_cell(&starts, LONG_CELL_EDGES),
            Some(FinDegradation::LongCoverageCell { edges: 40_000, limit: 16_384 })
        );
        assert_eq!(long_cell(&starts[..3], LONG_CELL_EDGES), None);
        assert_eq!(long_cell(&[], LONG_CELL_EDGES), None);
        let text = long_cell(&starts, 100).unwrap().to_string();
        assert!(text.contains("40000") && text.contains("65535"), "{text}");
    }
}
