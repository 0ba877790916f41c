//! The uniform every fin pass reads ([`FinParams`], `FinParams` in
//! `fin_types.wgsl`): one frame's map region, counts, light and axes.

use crate::frame::FinFrameData;

/// The uniform every pass reads; the layout of `FinParams` in `fin_types.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct FinParams {
    pub(crate) map: [f32; 4],
    pub(crate) counts: [u32; 4],
    pub(crate) light: [f32; 4],
    pub(crate) flags: [u32; 4],
    pub(crate) origin: [f32; 4],
    pub(crate) axis_u: [f32; 4],
    pub(crate) axis_v: [f32; 4],
    pub(crate) axis_n: [f32; 4],
    /// The texels the map passes redraw, inclusive (x0, x1, y0, y1): the
    /// whole maps, but on the GPU extraction's partial redraw.
    pub(crate) redraw: [u32; 4],
    /// The sparse maps' shape (`map_tiles`): (layers in the page table,
    /// tiles in the pool, 0, 0). The CPU writes it on both paths; the GPU
    /// extraction's copy of its params stops before it ([`GPU_WRITTEN_BYTES`]).
    pub(crate) tiles: [u32; 4],
}

/// The bytes of [`FinParams`] the GPU extraction writes (its `FinParams`
/// words in `control`, `extract_*.wgsl`): all but `tiles`.
pub(crate) const GPU_WRITTEN_BYTES: u64 = std::mem::offset_of!(FinParams, tiles) as u64;

pub(crate) use crate::gpu_layout::WORKGROUP;

/// `FinParams.flags.w`: how the frame's maps project.
pub(crate) fn projection_code(f: &FinFrameData) -> u32 {
    match (f.orthographic, f.aperture) {
        (true, _) => 1,
        (false, shadow_fins::light::Aperture::Sphere { .. }) => 2,
        (false, _) => 0,
    }
}

pub(crate) fn params_of(f: &FinFrameData) -> FinParams {
    let s = f.settings;
    let falloff = match s.falloff {
        shadow_fins::refine::Falloff::Linear => 0,
        shadow_fins::refine::Falloff::Bernstein => 1,
        shadow_fins::refine::Falloff::DiskSegment => 2,
    };
    let overlap = match s.overlap {
        shadow_fins::oracle::Overlap::MinMax => 0,
        shadow_fins::oracle::Overlap::Union => 1,
    };
    let v4 = |v: bevy::math::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
    FinParams {
        map: [f.region.min.x, f.region.min.y, f.region.texel, f.reference_depth],
        counts: [f.region.resolution, f.stats.layers as u32, f.casters.len() as u32, f.fins.len() as u32],
        // The sun's near depth is −∞ (no near plane); the shaders' stand-in is
        // the most negative finite float.
        light: [f.size, f.near.max(-3.0e38), f.scene_extent * 1e-7, shadow_fins::scene::SURFACE_EPSILON],
        // Projection: 0 a disk's perspective, 1 the sun's orthographic, 2 a
        // point light's cube face (its visibility pass shades its frustum only).
        flags: [s.refinement as u32, falloff, overlap, projection_code(f)],
        origin: v4(f.origin),
        axis_u: v4(f.axes[0]),
        axis_v: v4(f.axes[1]),
        axis_n: v4(f.axes[2]),
        redraw: {
            let last = f.region.resolution.max(1) - 1;
            [0, last, 0, last]
        },
        tiles: {
            let shape = f.map_shape();
            [shape.layers, shape.tiles, 0, 0]
        },
    }
}
