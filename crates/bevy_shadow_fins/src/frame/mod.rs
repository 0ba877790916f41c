//! Main world: the fin-shadowed lights and their casters, turned into one
//! [`FinLightFrame`] per light (six for a point light, one per cube face),
//! each rebuilt only when a caster, that light or its settings changed.
//!
//! - `update.rs`: the `PostUpdate` system that decides which frames to rebuild;
//! - `lights.rs`: Bevy's lights (and [`FinLight`](crate::FinLight)) as the core's lights;
//! - `build.rs`: one light's frame, by method;
//! - `in_frame.rs`: the light frame every path works in; `sun_fit.rs`: a sun's
//!   maps fitted to the views;
//! - `priority.rs`: which lights get fins past [`MAX_FIN_LIGHTS`];
//! - `map_casters.rs`, `coverage.rs`, `plateaus.rs`: each method's data.
//!
//! With [`FinExtraction::Gpu`](crate::FinExtraction) (the default) the frame
//! holds the packed caster geometry (built once per mesh) and one transform
//! per caster instance; the render world's compute passes do the rest. With
//! [`FinExtraction::Cpu`](crate::FinExtraction) the core crate extracts
//! silhouettes, patches, fins and layers here and the frame holds the
//! map-space casters and fins.

use crate::{
    casters::gpu_scene::GpuScene,
    gpu_layout::{GpuCaster, GpuCutout, GpuFin},
    stats::FinFrameStats,
};
use crate::{
    frame::coverage::CoverageFrame,
    settings::{FinLight, FinShadowSettings},
};
use bevy::{math::DVec3, prelude::*, render::extract_resource::ExtractResource};
use shadow_fins::{
    light::{Aperture, CubeFace, Light},
    oracle::MapRegion,
};
use std::sync::Arc;

pub(crate) mod build;
pub(crate) mod coverage;
pub(crate) mod in_frame;
pub(crate) mod lights;
pub(crate) mod map_casters;
pub(crate) mod map_tiles;
pub(crate) mod plateaus;
pub(crate) mod priority;
pub(crate) mod sun_fit;
pub(crate) mod update;

/// Everything the GPU passes need for one frame, shared with the render world.
#[derive(Debug)]
pub struct FinFrameData {
    /// Bumped whenever the content changed, so the GPU re-uploads only then.
    pub generation: u64,
    pub stats: FinFrameStats,
    pub(crate) casters: Vec<GpuCaster>,
    /// The casters' cut-outs and the alpha masks they read (`cutout.wgsl`).
    pub(crate) cutouts: Vec<GpuCutout>,
    pub(crate) mask_words: Vec<u32>,
    pub(crate) fins: Vec<GpuFin>,
    pub(crate) region: MapRegion,
    /// Map layers allocated (what fits the budget; the GPU merges the deepest
    /// layers beyond it).
    pub(crate) map_layers: u32,
    /// Tiles the sparse maps' pool holds (`map_tiles`): what the frame
    /// wants, or what fits while that is unknown.
    pub(crate) map_tiles: u32,
    /// The largest buffer this frame was built for, bytes.
    pub(crate) limit_bytes: u64,
    /// The most the penumbra maps may take, bytes (`FinShadowBudget::map_bytes`).
    pub(crate) map_limit_bytes: u64,
    /// World → light frame: origin and axes (u, v, n), in f64 so that each
    /// camera's view → light transform is composed without losing precision far
    /// from the world origin.
    pub(crate) origin: DVec3,
    pub(crate) axes: [DVec3; 3],
    /// The light's size: the disk's radius `R` (a rectangle's bounding
    /// circle's), or the sun's `tan θ`.
    pub(crate) size: f32,
    /// Where in that circle the light is: a rectangle's fins are as wide as
    /// its support function across them (`extract_common.wgsl`'s `support`).
    pub(crate) aperture: Aperture,
    /// The sun's orthographic maps (`x, y` in world units); else perspective
    /// maps from the disk's centre (`x/L, y/L`).
    pub(crate) orthographic: bool,
    pub(crate) reference_depth: f32,
    pub(crate) near: f32,
    pub(crate) scene_extent: f32,
    pub(crate) settings: FinShadowSettings,
    /// GPU extraction: geometry, instances and buffer capacities (`None` on the CPU path).
    pub(crate) gpu: Option<GpuScene>,
    /// The coverage method's edges, grid, casters and samples (`None` for fins).
    pub(crate) coverage: Option<CoverageFrame>,
    /// The plateaus method's plane, cones and sheets (`None` for other methods).
    pub(crate) plateaus: Option<crate::frame::plateaus::PlateauFrame>,
    /// The convolution method's basis chain as the budget allows it (`None`
    /// for other methods, or when it does not fit).
    pub(crate) convolution: Option<crate::budget::BasisLayout>,
    /// The maps are a window onto casters that go on past it (a sun fitted
    /// to the views), not a cover of every caster.
    pub(crate) windowed: bool,
}

impl FinFrameData {
    /// The sparse maps' layout as allocated (at least one layer, which the
    /// GPU extraction may fill).
    pub(crate) fn map_shape(&self) -> map_tiles::MapShape {
        map_tiles::MapShape {
            resolution: self.region.resolution,
            layers: self.map_layers.max(1),
            tiles: self.map_tiles,
        }
    }

    /// Bytes of the penumbra maps as allocated.
    pub(crate) fn map_bytes(&self) -> u64 {
        self.map_shape().bytes()
    }

    /// A point light's sphere radius (the frame's `size` is the circle
    /// around its outline over the face, `stretch` times it); `None` for
    /// any other light.
    pub(crate) fn sphere_radius(&self) -> Option<f32> {
        match self.aperture {
            Aperture::Sphere { stretch, .. } => Some(self.size / stretch),
            _ => None,
        }
    }
}

/// The most lights with fin shadows at once. Lights past it (by entity
/// order) keep Bevy's own shadow map, with
/// [`FinDegradation::TooManyLights`](crate::FinDegradation::TooManyLights) in
/// their [`FinLightStats`](crate::FinLightStats).
pub const MAX_FIN_LIGHTS: usize = 16;

/// The most frames (map sets) at once: a `PointLight` has one per cube face.
pub(crate) const MAX_FIN_FRAMES: usize = 6 * MAX_FIN_LIGHTS;

/// How a fin-shadowed light is shaded by the compositing pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum LightShading {
    /// The plugin's own [`FinLight`]: shaded by the compositing pass (Bevy's
    /// point-light BRDF in the half-space the disk faces), times `V`.
    Own { light: FinLight, transform: GlobalTransform },
    /// A Bevy light: Bevy shades it (its shadow map is off, see
    /// `render/bevy_lights.rs`); the compositing pass takes `(1 − V)` of
    /// Bevy's own contribution of it away again. The render-world entity
    /// finds its index in Bevy's clustered light list.
    Bevy { render_entity: Entity },
}

/// One frame of a fin-shadowed light: a light's maps, extraction and
/// visibility pass. A `PointLight` has six, one per cube face, which shade
/// the receivers in their own frusta into the light's one visibility layer.
#[derive(Debug, Clone)]
pub struct FinLightFrame {
    /// The light's (main-world) entity.
    pub light: Entity,
    /// The cube face of a point light's frame (`None` for any other light).
    pub face: Option<CubeFace>,
    /// The light's visibility layer in every camera's illuminance buffer
    /// (its index among the fin-shadowed lights, by entity order).
    pub layer: usize,
    /// The light as the core crate models it (its disk, rectangle, sun or
    /// sphere): what an oracle or a ground truth of this light should be given.
    pub shape: Light,
    pub(crate) shading: LightShading,
    pub data: Arc<FinFrameData>,
}

impl FinLightFrame {
    pub(crate) fn key(&self) -> FrameKey {
        (self.light, self.face)
    }
}

/// A frame's identity: its light, and its cube face for a point light.
pub(crate) type FrameKey = (Entity, Option<CubeFace>);

/// Every fin-shadowed light's frames, by entity order (at most
/// [`MAX_FIN_LIGHTS`] lights; a point light's six faces one after another).
/// Each frame has its own maps and layers, each light its own visibility
/// layer; the penumbra-map budget is split between the frames by need.
#[derive(Resource, Clone, Default, ExtractResource)]
pub struct FinFrames(pub Vec<FinLightFrame>);

impl FinFrames {
    /// How many visibility layers the frames fill: one per light.
    pub fn light_count(&self) -> usize {
        self.0.last().map_or(0, |f| f.layer + 1)
    }

    /// The frames of visibility layer `layer`.
    pub(crate) fn of_layer(&self, layer: usize) -> impl Iterator<Item = (usize, &FinLightFrame)> {
        self.0.iter().enumerate().filter(move |(_, f)| f.layer == layer)
    }

    /// True when `slot` is the last frame of its light (its layer is complete
    /// once that frame's visibility pass ran).
    pub(crate) fn ends_layer(&self, slot: usize) -> bool {
        self.0.get(slot).is_some_and(|f| self.0.get(slot + 1).is_none_or(|n| n.layer != f.layer))
    }

    /// The lights on the coverage method (`true`) or on a fin method (`false`):
    /// each set has its own GPU resources (`render/coverage.rs`, `render/maps.rs`).
    pub(crate) fn on_coverage(&self, coverage: bool) -> impl Iterator<Item = &FinLightFrame> {
        self.0.iter().filter(move |f| f.data.coverage.is_some() == coverage)
    }
}
