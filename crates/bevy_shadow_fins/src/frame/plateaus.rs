//! Main world: the plateaus method's frame (`FinMethod::Plateaus`, Haines
//! 2001; `shadow_fins::peers::plateaus`): the receiver plane and the cones
//! and sheets of the casters' silhouette edges on it, binned by footprint,
//! built with the core crate when a caster, the light or a setting changed.
//! The render world uploads them and `shaders/plateaus.wgsl` evaluates the
//! texture at each camera pixel on the plane, beside the light's hard
//! shadow map (the drop shadow, and the whole shadow of every receiver off
//! the plane: the method's receiver-plane restriction).

use shadow_fins::{
    peers::{PlateauTexture, ReceiverPlane},
    scene::{LightSpaceScene, Scene},
};

/// Sheets one cell's pixels walk (`MAX_CELL_SHEETS` in `plateaus.wgsl`):
/// llvmpipe stops an invocation after 65535 loop iterations, and a GPU's
/// watchdog stops long ones. The core's grid coarsens its cells until all
/// lists fit `MAX_ENTRIES` in total, so one cell may list more: the frame
/// says so (`FinDegradation::LongPlateauCell`).
pub(crate) const MAX_CELL_SHEETS: u32 = 16384;

/// One sheet (`Sheet` in `plateaus.wgsl`; the core's `SheetRecord`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuSheet {
    pub ends: [f32; 4],
    pub radii: [f32; 4],
    pub to_axes: [f32; 4],
}

/// `PlateauParams` in `plateaus.wgsl`: the plane (light frame), its axes,
/// the sheets' grid (origin, cells per unit) and its size in cells.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PlateauUniform {
    pub point: [f32; 4],
    pub normal: [f32; 4],
    pub axis_u: [f32; 4],
    pub axis_v: [f32; 4],
    pub grid: [f32; 4],
    /// (cells in x, cells in y, sheets, 0)
    pub dims: [u32; 4],
}

/// Everything the plateau pass needs for one frame.
#[derive(Debug)]
pub(crate) struct PlateauFrame {
    pub uniform: PlateauUniform,
    pub sheets: Vec<GpuSheet>,
    pub cell_starts: Vec<u32>,
    pub cell_items: Vec<u32>,
}

/// The plateau texture of `scene` under the light of `light_space`, on
/// the largest flat receiver facing it (`ReceiverPlane::largest_flat`).
pub(crate) fn plateau_frame(scene: &Scene, light_space: &LightSpaceScene) -> PlateauFrame {
    let texture = PlateauTexture::on_plane(scene, light_space, ReceiverPlane::largest_flat(scene, light_space));
    let v4 = |v: shadow_fins::glam::Vec3| [v.x, v.y, v.z, 0.0];
    let (u, v) = texture.axes();
    let (min, inv_cell, dims) = texture.grid().grid();
    let (starts, items) = texture.grid().lists();
    let sheets: Vec<GpuSheet> = texture
        .sheet_records()
        .into_iter()
        .map(|s| GpuSheet { ends: s.ends, radii: s.radii, to_axes: s.to_axes })
        .collect();
    PlateauFrame {
        uniform: PlateauUniform {
            point: v4(texture.plane.point),
            normal: v4(texture.plane.normal),
            axis_u: v4(u),
            axis_v: v4(v),
            grid: [min.x, min.y, inv_cell.x, inv_cell.y],
            dims: [dims[0] as u32, dims[1] as u32, sheets.len() as u32, 0],
        },
        sheets,
        cell_starts: starts.to_vec(),
        cell_items: items.to_vec(),
    }
}
