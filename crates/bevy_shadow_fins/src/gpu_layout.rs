//! The records and buffer sizes the main world hands the GPU passes:
//! map-space casters ([`GpuCaster`]), their cut-outs ([`GpuCutout`]) and fins
//! ([`GpuFin`]) of the CPU extraction, and the sizes of the GPU extraction's
//! buffers. Their WGSL twins: `fin_types.wgsl`, `cutout.wgsl`, `maps.wgsl`,
//! `extract_*.wgsl`.

/// One caster triangle in light-map space (see the core's `MapTriangle`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuCaster {
    pub corners: [f32; 6],
    pub normal: [f32; 3],
    pub offset: f32,
    pub min_depth: f32,
    pub max_depth: f32,
    pub layer: u32,
    /// 0: solid; else 1 + its index in the frame's [`GpuCutout`]s.
    pub cutout: u32,
    /// The GPU extraction's patch of the caster (`extract_*.wgsl`); 0 here.
    pub patch_id: u32,
}

/// An alpha-masked map triangle's cut-out (the core's `MapCutout`;
/// `cutout.wgsl`): UVs at its corners, the corners' depths, and where its
/// mask starts in the frame's mask words.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuCutout {
    pub uvs: [f32; 6],
    pub depths: [f32; 3],
    pub mask: u32,
}

/// One fin: `header = [kind (0 quad, 1 sector), side (0 inner, 1 outer), layer,
/// the GPU extraction's patch (0 here)]`,
/// then the shape's numbers (see `maps.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuFin {
    pub header: [u32; 4],
    pub data: [f32; 12],
}

/// Invocations per workgroup of every compute pass (`WORKGROUP` in
/// `extract_common.wgsl`, `maps.wgsl`, `coverage_types.wgsl`, `pose.wgsl`).
pub(crate) const WORKGROUP: u32 = 64;

/// Bytes per penumbra-map texel (nine 32-bit channels, `fin_types.wgsl`).
pub(crate) const MAP_TEXEL_BYTES: u64 = 9 * 4;

/// Bytes per record of the extraction's outputs (`extract_*.wgsl`).
pub(crate) const SILHOUETTE_BYTES: u64 = 7 * 16;
pub(crate) const FIN_BYTES: u64 = 64;
pub(crate) const CASTER_BYTES: u64 = size_of::<crate::gpu_layout::GpuCaster>() as u64;
/// `state` words per caster face (`FACE_WORDS` in `extract_common.wgsl`).
pub(crate) const FACE_STATE_WORDS: u64 = 5;
/// `state` words per instance vertex: its light-frame position (`VERTEX_WORDS`).
pub(crate) const VERTEX_STATE_WORDS: u64 = 3;
/// Bytes per caster cut-out the extraction writes (`CasterCutout`, `cutout.wgsl`).
pub(crate) const CUTOUT_BYTES: u64 = size_of::<crate::gpu_layout::GpuCutout>() as u64;
