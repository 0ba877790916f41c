//! The CPU paths' map-space records as the GPU reads them: the core's map
//! triangles with their cut-outs and masks, and its fins (the CPU
//! extraction, `build.rs`; the coverage method's casters, `coverage.rs`).

use crate::budget::FinDegradation;
use crate::{
    casters::cutout::pack_mask,
    gpu_layout::{GpuCaster, GpuCutout, GpuFin},
};
use bevy::prelude::*;
use shadow_fins::{
    fins::{Fin, FinShape, FinSide},
    oracle::MapTriangle,
};

/// The cut-outs and masks of a frame, or none when they do not fit one GPU
/// buffer (every caster then solid, and said so): the masks a frame's
/// instances share are packed once, so only thousands of distinct masks
/// get here.
pub(crate) fn fit_cutouts(
    casters: &mut [GpuCaster],
    cutouts: &mut Vec<GpuCutout>,
    mask_words: &mut Vec<u32>,
    max_buffer: u64,
) -> Option<FinDegradation> {
    let bytes = (size_of_val(cutouts.as_slice()) as u64).max(size_of_val(mask_words.as_slice()) as u64);
    if bytes <= max_buffer {
        return None;
    }
    let wanted = cutouts.len() as u32;
    casters.iter_mut().for_each(|c| c.cutout = 0);
    cutouts.clear();
    mask_words.clear();
    Some(FinDegradation::Capacity {
        buffer: "alpha masks (casters made solid)",
        kept: 0,
        wanted,
        limit_bytes: max_buffer,
    })
}

/// Map triangles as the GPU reads them, with their cut-outs and the masks
/// those index, packed as `cutout.wgsl` reads them (`layers`: each
/// triangle's layer, or layer 0).
pub(crate) fn gpu_casters(
    triangles: &[MapTriangle],
    layers: Option<&[u32]>,
    masks: &[std::sync::Arc<shadow_fins::cutout::AlphaMask>],
) -> (Vec<GpuCaster>, Vec<GpuCutout>, Vec<u32>) {
    // Each mask once (`pack_mask`).
    let mut mask_words: Vec<u32> = Vec::new();
    let mut mask_at: Vec<Option<u32>> = vec![None; masks.len()];
    let mut cutouts = Vec::new();
    let casters = triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let cutout = match t.cutout {
                None => 0,
                Some(c) => {
                    let at = *mask_at[c.mask as usize]
                        .get_or_insert_with(|| pack_mask(&masks[c.mask as usize], &mut mask_words));
                    cutouts.push(GpuCutout {
                        uvs: [c.uvs[0].x, c.uvs[0].y, c.uvs[1].x, c.uvs[1].y, c.uvs[2].x, c.uvs[2].y],
                        depths: c.depths,
                        mask: at,
                    });
                    cutouts.len() as u32
                }
            };
            GpuCaster {
                corners: [
                    t.corners[0].x,
                    t.corners[0].y,
                    t.corners[1].x,
                    t.corners[1].y,
                    t.corners[2].x,
                    t.corners[2].y,
                ],
                normal: t.normal.to_array(),
                offset: t.offset,
                min_depth: t.min_depth,
                max_depth: t.max_depth,
                layer: layers.map_or(0, |l| l[i]),
                cutout,
                patch_id: 0,
            }
        })
        .collect();
    (casters, cutouts, mask_words)
}

pub(crate) fn gpu_fin(f: &Fin, layer: u32) -> GpuFin {
    let side = match f.side {
        FinSide::Inner => 0,
        FinSide::Outer => 1,
    };
    match f.shape {
        FinShape::Quad { m0, m1, d0, d1, w0, w1, z0, z1 } => GpuFin {
            header: [0, side, layer, 0],
            data: [m0.x, m0.y, m1.x, m1.y, d0.x, d0.y, d1.x, d1.y, w0, w1, z0, z1],
        },
        FinShape::Sector { center, radius, from, to, depth } => GpuFin {
            header: [1, side, layer, 0],
            data: [center.x, center.y, from.x, from.y, to.x, to.y, radius, depth, 0.0, 0.0, 0.0, 0.0],
        },
    }
}
