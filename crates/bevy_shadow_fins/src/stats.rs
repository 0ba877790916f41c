//! What the frames model, read by users and tests: per light
//! ([`FinLightStats`]), for the first light ([`FinShadowStats`]), and why a
//! mesh could not cast ([`FinSceneError`]) or a frame models less than its
//! settings ask ([`FinFrameStats::degraded`]).

use crate::budget::FinDegradations;
use bevy::prelude::*;

/// Why a mesh could not be used as a caster (logged once per mesh).
#[derive(Debug, Clone, PartialEq)]
pub enum FinSceneError {
    /// The mesh is not a triangle list (lines, points) — it casts nothing.
    NotTriangles,
    /// The mesh's data was sent to the GPU only (`RenderAssetUsages::RENDER_WORLD`).
    NoMainWorldData,
    /// Invalid geometry (NaN positions, bad indices, no area): the core's error.
    Invalid(shadow_fins::MeshError),
}

/// Counts of what the current frame models.
///
/// With GPU extraction, silhouettes, fins and layers are read back from the
/// GPU a few frames later; `up_to_date` says whether they belong to the latest
/// frame. Read them from the [`FinShadowStats`] resource.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FinFrameStats {
    pub casters: usize,
    pub triangles: usize,
    pub silhouettes: usize,
    pub fins: usize,
    pub layers: usize,
    /// Main-world CPU time of building the frame, ms: the whole extraction on
    /// the CPU path; packing instance transforms on the GPU path.
    pub extract_ms: f32,
    /// The counts describe the current frame (always true on the CPU path).
    pub up_to_date: bool,
    /// Why the frame models less than the settings ask for (a GPU limit or the
    /// [`FinShadowBudget`](crate::FinShadowBudget)): every reason, one of
    /// each kind; empty when nothing was cut.
    pub degraded: FinDegradations,
    /// The penumbra maps' resolution as allocated.
    pub map_resolution: u32,
    /// GPU memory the light's shadow data needs, bytes: for the fin methods
    /// the sparse penumbra maps as allocated (`frame::map_tiles`: a page
    /// word per 8×8 tile per layer, then the pool's tiles at 64 × 36 bytes) and the
    /// convolution method's basis; for the coverage method its depth lists
    /// (124 bytes a texel) and every record it uploads. Not counted: the fin
    /// methods' caster and fin records and the extraction's buffers, and the
    /// headroom a reused buffer keeps (the render world allocates up to half
    /// as much again, within the buffer limit, and does not shrink a buffer
    /// that still fits). A point light's faces: their sum.
    pub gpu_bytes: u64,
    /// Where the fins were extracted: the settings' choice, or the CPU when
    /// the scene's geometry did not fit a GPU buffer (see `degraded`).
    pub extraction: FinExtraction,
    /// The GPU extraction's last map update redrew only the texels under the
    /// casters that moved (their old and new footprints): a few casters of
    /// many moved, and the maps' plan (region, reference depth, layer
    /// planes) stayed. `false`: redrawn whole, or extracted on the CPU.
    pub partial_redraw: bool,
    /// Texels (all layers) of the penumbra maps the last update cleared and
    /// drew again: all of them on a full redraw (every update of the CPU
    /// extraction), a partial redraw's few; 0 for the coverage method (no
    /// penumbra maps).
    pub redrawn_texels: u64,
    /// The GPU extraction's last update extracted only the casters that
    /// moved, and kept every other caster's silhouettes, fins and map
    /// triangles from before (`extract_*.wgsl`): a few moved, and the
    /// reference depth and the silhouettes' depth range stayed. `false`:
    /// everything extracted anew, or on the CPU.
    pub incremental_extraction: bool,
    /// Skinned or morphed casters the GPU posed itself (`pose.wgsl`): a new
    /// pose of one of them is a changed instance, like a moved caster. The
    /// others posed are posed on the CPU (the CPU extraction, or a pose that
    /// changes the mesh's topology; see `casters::mesh::posed_mesh`). Counted per
    /// light frame, with those out of the light's reach (their vertices
    /// still bound the receivers' depth); a point light's faces: the most.
    pub posed_on_gpu: usize,
}

/// What the first fin-shadowed light's shadows currently model (see
/// [`FinFrameStats`]); every light's are in its [`FinLightStats`].
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq)]
pub struct FinShadowStats(pub FinFrameStats);

/// What one light's fin shadows currently model: on every light with
/// [`FinShadowSettings`](crate::FinShadowSettings) (the first light's is also the [`FinShadowStats`]
/// resource).
#[derive(Component, Debug, Clone, Copy, Default, PartialEq)]
pub struct FinLightStats(pub FinFrameStats);

impl FinFrameStats {
    /// Texels of the penumbra maps, all layers: what a full redraw clears
    /// and draws again ([`Self::redrawn_texels`]).
    pub fn map_texels(&self) -> u64 {
        self.layers as u64 * (self.map_resolution as u64).pow(2)
    }

    /// One light's stats from its frames' (a point light's six faces): the
    /// work summed (silhouettes, fins, extraction time), the casters and
    /// triangles of the face that sees the most (faces share them), the most
    /// layers, the least resolution, up to date when every face is, the
    /// first reason any face was cut.
    pub(crate) fn combined(frames: impl Iterator<Item = FinFrameStats>) -> Option<Self> {
        frames.reduce(|a, b| FinFrameStats {
            casters: a.casters.max(b.casters),
            triangles: a.triangles.max(b.triangles),
            silhouettes: a.silhouettes + b.silhouettes,
            fins: a.fins + b.fins,
            layers: a.layers.max(b.layers),
            extract_ms: a.extract_ms + b.extract_ms,
            up_to_date: a.up_to_date && b.up_to_date,
            degraded: a.degraded.and(b.degraded),
            map_resolution: a.map_resolution.min(b.map_resolution),
            gpu_bytes: a.gpu_bytes + b.gpu_bytes,
            extraction: a.extraction,
            partial_redraw: a.partial_redraw && b.partial_redraw,
            incremental_extraction: a.incremental_extraction && b.incremental_extraction,
            redrawn_texels: a.redrawn_texels + b.redrawn_texels,
            posed_on_gpu: a.posed_on_gpu.max(b.posed_on_gpu),
        })
    }
}

/// Sets a light's [`FinLightStats`] when they changed.
pub(crate) fn set_stats(light_stats: &mut Query<&mut FinLightStats>, light: Entity, now: FinFrameStats) {
    if let Ok(mut s) = light_stats.get_mut(light)
        && s.0 != now
    {
        s.0 = now;
    }
}

/// Logs a light's reasons when a kind of reason appears that was not there
/// (a moving light re-extracts every frame; the same reasons are said once,
/// not sixty times a second).
pub(crate) fn warn_degradation(warned: &mut FinDegradations, now: FinDegradations) {
    // By kind: a buffer's count that changes as a light moves, or the order
    // a read-back merges in, is not news.
    if now.iter().any(|r| !warned.holds_kind_of(&r)) {
        warn!("fin shadows: {now}");
    }
    *warned = now;
}

/// Where fins are extracted and layers assigned: asked for by
/// [`FinShadowSettings::extraction`](crate::FinShadowSettings), and what a
/// frame did ([`FinFrameStats::extraction`]: the CPU where the scene did not
/// fit a GPU buffer). Here, with the stats, so that the settings can require
/// [`FinLightStats`] without the two files needing each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Reflect)]
pub enum FinExtraction {
    /// Compute passes (`shaders/extract_*.wgsl`): caster geometry is uploaded once
    /// per mesh and only instance transforms when something moves; silhouettes,
    /// patches, fins, the depth histogram and the layer cut all run on the GPU.
    #[default]
    Gpu,
    /// The core crate on the CPU (the paper's split), uploading map-space
    /// casters and fins. The reference the GPU path is tested against.
    Cpu,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::FinDegradation;

    #[test]
    fn a_point_lights_faces_sum_their_bytes_and_keep_every_reason() {
        let maps = FinDegradation::Maps {
            resolution: 512,
            wanted_resolution: 1024,
            layers: 4,
            wanted_layers: 4,
            limit_bytes: 128 << 20,
        };
        let cut = FinDegradation::Capacity { buffer: "fins", kept: 10, wanted: 20, limit_bytes: 1 << 20 };
        let face =
            |bytes, why: Option<FinDegradation>| FinFrameStats { gpu_bytes: bytes, degraded: why.into(), ..default() };
        let light =
            FinFrameStats::combined([face(3 << 20, Some(maps)), face(1 << 20, None), face(5, Some(cut))].into_iter())
                .expect("three faces");
        assert_eq!(light.gpu_bytes, (4 << 20) + 5);
        assert_eq!(light.degraded.iter().collect::<Vec<_>>(), vec![maps, cut]);
    }
}
