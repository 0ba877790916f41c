//! The CPU oracle of the whole fin method (DESIGN §3).
//!
//! [`FinShadowModel`] prepares one scene under one light for one method:
//! silhouettes, fins, the layer plan and the casters in map space. It then
//! answers visibility in two ways that share every rule:
//! - [`FinShadowModel::analytic`]: each receiver's centre ray is intersected
//!   exactly with the casters and fins (no rasterization);
//! - [`RasterMaps`]: the per-layer light-space maps at a given resolution, sampled
//!   at texel centres, as a GPU renders them, looked up at the nearest texel.
//!
//! Both evaluate the same [`LayerTexel`] per layer and the same
//! [`combine_layers`], so the raster converges to the analytic answer as the map
//! resolution grows.

mod analytic;
mod map_geometry;
mod raster;

use glam::{Vec2, Vec3};

pub use analytic::AnalyticIndex;
pub use map_geometry::{MapCutout, MapTriangle};
pub use raster::{MapRegion, RASTER_MAP_LIMIT, RasterMaps};

use crate::{
    error::SettingsError,
    fins::{Fin, FinBuilder, FinSample, FinSide},
    layers::LayerPlan,
    light::LightFrame,
    refine::{Falloff, refine_weight},
    scene::{LightSpaceScene, Scene},
    silhouette::{NO_PATCH, SilhouetteEdge, SilhouetteScratch, extract_object_silhouettes},
};

/// Which soft-shadow method to evaluate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Shadow map from the light centre: visibility 0 or 1.
    Hard,
    /// Hard shadow plus outer fins only: the smoothies / penumbra-map family.
    OuterFins,
    /// Inner and outer fins in one layer (the paper's §3).
    SingleLayer,
    /// Inner and outer fins in up to `layers` layers (the paper's §4).
    MultiLayer,
}

impl Method {
    pub const ALL: [Method; 4] = [Method::Hard, Method::OuterFins, Method::SingleLayer, Method::MultiLayer];

    pub fn name(self) -> &'static str {
        match self {
            Method::Hard => "hard",
            Method::OuterFins => "outer-fins",
            Method::SingleLayer => "single-layer",
            Method::MultiLayer => "fins",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// Settings of the fin method. Defaults are the paper's: 16 layers from 1024
/// sub-layers, refinement on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FinSettings {
    /// Layer count `N` (1..=64).
    pub layers: u32,
    /// Sub-layer count `S` (1..=65536).
    pub sub_layers: u32,
    /// Refine fin weights to the real receiver depth (eq. 5).
    pub refinement: bool,
    pub falloff: Falloff,
    /// How overlapping fins and layers combine.
    pub overlap: Overlap,
}

impl Default for FinSettings {
    fn default() -> Self {
        Self {
            layers: 16,
            sub_layers: 1024,
            refinement: true,
            falloff: Falloff::default(),
            overlap: Overlap::default(),
        }
    }
}

impl FinSettings {
    /// Checks every field's range.
    pub fn validate(self) -> Result<Self, SettingsError> {
        if !(1..=64).contains(&self.layers) {
            return Err(SettingsError::Layers(self.layers));
        }
        if !(1..=65536).contains(&self.sub_layers) {
            return Err(SettingsError::SubLayers(self.sub_layers));
        }
        Ok(self)
    }
}

/// The fins of one side (inner or outer) at one texel: the lowest and highest
/// weight, each with the depth of the fin that gave it, and how many fins.
///
/// The paper keeps only the minimum (inner) or maximum (outer); keeping both
/// ends and a count lets [`Overlap::Union`] combine two overlapping fins. On a
/// GPU these are min/max blends and an additive count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideTexel {
    pub min_weight: f32,
    pub min_depth: f32,
    pub max_weight: f32,
    pub max_depth: f32,
    pub count: u32,
}

impl SideTexel {
    pub const EMPTY: Self = Self {
        min_weight: f32::INFINITY,
        min_depth: f32::INFINITY,
        max_weight: f32::NEG_INFINITY,
        max_depth: f32::INFINITY,
        count: 0,
    };

    /// Ties go to the nearer fin, so weight and depth of one winner stay together
    /// (the plateau trick).
    #[inline]
    pub fn add(&mut self, s: FinSample) {
        if s.weight < self.min_weight || (s.weight == self.min_weight && s.depth < self.min_depth) {
            self.min_weight = s.weight;
            self.min_depth = s.depth;
        }
        if s.weight > self.max_weight || (s.weight == self.max_weight && s.depth < self.max_depth) {
            self.max_weight = s.weight;
            self.max_depth = s.depth;
        }
        self.count += 1;
    }

    pub fn min(&self) -> Option<FinSample> {
        (self.count > 0).then_some(FinSample { weight: self.min_weight, depth: self.min_depth })
    }

    pub fn max(&self) -> Option<FinSample> {
        (self.count > 0).then_some(FinSample { weight: self.max_weight, depth: self.max_depth })
    }
}

/// One layer's light-map contents at one map point: the nearest caster and the
/// inner and outer fins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerTexel {
    /// Nearest caster depth in the layer; `+∞` when none.
    pub slab_depth: f32,
    pub inner: SideTexel,
    pub outer: SideTexel,
}

impl LayerTexel {
    pub const EMPTY: Self = Self { slab_depth: f32::INFINITY, inner: SideTexel::EMPTY, outer: SideTexel::EMPTY };

    /// Keeps the nearest caster.
    #[inline]
    pub fn add_caster(&mut self, depth: f32) {
        if depth < self.slab_depth {
            self.slab_depth = depth;
        }
    }

    #[inline]
    pub fn add_fin(&mut self, side: FinSide, s: FinSample) {
        match side {
            FinSide::Inner => self.inner.add(s),
            FinSide::Outer => self.outer.add(s),
        }
    }
}

/// How overlapping fins and layers combine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Overlap {
    /// The paper (§3.3, §4.2): minimum inner weight, maximum outer weight in a
    /// layer; the minimum illuminance over layers. Too dark where penumbrae of
    /// one occluder overlap (§7.2: `min` where `+` is right), too bright where
    /// penumbrae of different occluders overlap.
    MinMax,
    /// Ours: overlapping fins reveal (inner) or hide (outer) different parts of
    /// the disk, so two fins of a side combine as a union `1 − (1 − a)(1 − b)`
    /// (exact for a thin strip's two edges up to their overlap, and for a
    /// corner of a square light), and layers — different occluders — multiply,
    /// as independent blockers do.
    #[default]
    Union,
}

impl Overlap {
    pub const ALL: [Overlap; 2] = [Overlap::MinMax, Overlap::Union];

    pub fn name(self) -> &'static str {
        match self {
            Overlap::MinMax => "min-max",
            Overlap::Union => "union",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.name() == s)
    }
}

/// What the per-pixel combination needs to know about the receiver and light.
#[derive(Debug, Clone, Copy)]
pub struct CombineParams<'a> {
    pub frame: &'a LightFrame,
    pub reference_depth: f32,
    pub refinement: bool,
    pub overlap: Overlap,
}

/// The per-pixel combination of DESIGN §3 over every layer. Returns the
/// illuminance `I ∈ [0, 1]` before the falloff.
///
/// For each layer: `base = 0` when the layer's nearest caster blocks the centre
/// ray nearer than `blocking_limit`, else 1; `u = clamp(base + inner − outer, 0, 1)`
/// with refined weights of fins in front of the receiver; penumbra (a fin
/// applies): `I = min(I, u)`; umbra: `I = 0`; lit: keep. The result is the
/// minimum over layers, so their order does not matter; casters and fins behind
/// the receiver drop out by their depth.
pub fn combine_layers(texels: &[LayerTexel], receiver_depth: f32, blocking_limit: f32, p: CombineParams) -> f32 {
    let refine = |s: FinSample| {
        if p.refinement {
            refine_weight(p.frame, s.weight, s.depth, receiver_depth, p.reference_depth)
        } else {
            (s.depth < receiver_depth).then_some(s.weight)
        }
    };
    // One side's refined weight at this texel, or None when no fin applies.
    let side = |t: &SideTexel, paper_pick_min: bool| -> Option<f32> {
        match p.overlap {
            Overlap::MinMax => (if paper_pick_min { t.min() } else { t.max() }).and_then(refine),
            Overlap::Union => {
                let lo = t.min().and_then(refine);
                let hi = if t.count >= 2 { t.max().and_then(refine) } else { None };
                match (lo, hi) {
                    (Some(a), Some(b)) => Some(1.0 - (1.0 - a) * (1.0 - b)),
                    (a, b) => a.or(b),
                }
            }
        }
    };
    let mut illuminance = 1.0f32;
    for t in texels {
        let base = if t.slab_depth < blocking_limit { 0.0 } else { 1.0 };
        let inner = side(&t.inner, true);
        let outer = side(&t.outer, false);
        if inner.is_some() || outer.is_some() {
            let u = (base + inner.unwrap_or(0.0) - outer.unwrap_or(0.0)).clamp(0.0, 1.0);
            illuminance = match p.overlap {
                Overlap::MinMax => illuminance.min(u),
                Overlap::Union => illuminance * u,
            };
        } else if base == 0.0 {
            illuminance = 0.0;
        }
    }
    illuminance
}

/// A receiver point in the light frame, with its unit normal (zero if unknown).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Receiver {
    pub position: Vec3,
    pub normal: Vec3,
}

impl Receiver {
    /// True when the light's centre is in front of the surface (or the normal is
    /// unknown). Elsewhere the light's shading is zero, so visibility there is
    /// never seen: error metrics skip such receivers.
    pub fn faces_light(&self, frame: &LightFrame) -> bool {
        if self.normal == Vec3::ZERO {
            return true;
        }
        if frame.is_perspective() { self.normal.dot(-self.position) > 0.0 } else { self.normal.z < 0.0 }
    }
}

/// Per-frame fin extraction: silhouettes, patches, fins and the layer plan.
/// Buffers are reused between calls; this is the stage the paper runs on the CPU.
#[derive(Debug, Default)]
pub struct FinExtractor {
    scratch: SilhouetteScratch,
    builder: FinBuilder,
    depths: Vec<f32>,
    patch_depth: Vec<(f32, u32)>,
    /// Face patches found by the last [`FinExtractor::extract_silhouettes`].
    patch_count: u32,
    pub silhouettes: Vec<SilhouetteEdge>,
    /// Per caster triangle (the order of [`LightSpaceScene::casters`]): its patch,
    /// or [`NO_PATCH`] when it is not drawn into the maps.
    pub face_patches: Vec<u32>,
    /// Layer of each patch.
    pub patch_layers: Vec<u32>,
    pub fins: Vec<Fin>,
    /// Layer of each fin (same order as `fins`).
    pub fin_layers: Vec<u32>,
    pub plan: LayerPlan,
}

impl FinExtractor {
    /// Extracts silhouettes, patches and fins of every casting object and
    /// assigns layers. `layers == 1` gives the single-layered plan.
    ///
    /// Layers (§4.1): the sub-layer histogram of silhouette-edge midpoints is cut
    /// at its quantiles into depth planes; each patch goes, whole, to the layer of
    /// the mean depth of its silhouette edges, and its fins with it. (The paper
    /// clips casters into depth slabs instead; measured against ground truth,
    /// that turns the inner penumbra of any occluder deeper than its own
    /// silhouette — a box's sides, a wall standing on the floor — into umbra.)
    pub fn extract(&mut self, scene: &Scene, light_space: &LightSpaceScene, layers: u32, sub_layers: u32) {
        self.extract_silhouettes(scene, light_space);
        self.build_fins(light_space);
        self.assign_layers(layers, sub_layers);
    }

    /// Stage 1: silhouette edges (and face patches) of every casting object.
    pub fn extract_silhouettes(&mut self, scene: &Scene, light_space: &LightSpaceScene) {
        self.silhouettes.clear();
        self.face_patches.clear();
        let frame = &light_space.frame;
        let (mut vertex_base, mut patches) = (0u32, 0u32);
        for (object, to_frame) in scene.objects.iter().zip(&light_space.object_frames) {
            let outline = object.fitting_cutout().map(|c| &*c.outline);
            if object.casts_shadows {
                let light = to_frame.light_in_object(frame);
                patches += extract_object_silhouettes(
                    &object.topology,
                    to_frame,
                    light,
                    vertex_base,
                    patches,
                    &mut self.scratch,
                    &mut self.face_patches,
                    &mut self.silhouettes,
                    outline,
                );
            }
            vertex_base += object.topology.positions.len() as u32 + outline.map_or(0, |o| o.positions.len() as u32);
        }
        self.patch_count = patches;
        // A sphere light's face keeps the silhouettes that can shade it.
        self.silhouettes.retain(|e| !frame.outside_face_window(&[e.a, e.b]));
    }

    /// Stage 2: fins and fans of the silhouettes of stage 1 (eq. 3 widths).
    pub fn build_fins(&mut self, light_space: &LightSpaceScene) {
        let near = near_depth(light_space);
        self.builder.build(&self.silhouettes, &light_space.frame, light_space.reference_depth, near, &mut self.fins);
    }

    /// Stage 3: the sub-layer histogram cut into `layers` planes, and every
    /// patch and fin of stages 1–2 given its layer.
    pub fn assign_layers(&mut self, layers: u32, sub_layers: u32) {
        let patches = self.patch_count;
        self.depths.clear();
        self.depths.extend(self.silhouettes.iter().map(SilhouetteEdge::mid_depth));
        self.plan = LayerPlan::from_edge_depths(&self.depths, sub_layers, layers);

        // Patch layer: mean silhouette-edge depth; patches with no silhouette
        // (a closed mesh seen from inside) go to the last layer.
        self.patch_depth.clear();
        self.patch_depth.resize(patches as usize, (0.0, 0));
        for e in &self.silhouettes {
            let (sum, n) = &mut self.patch_depth[e.patch as usize];
            *sum += e.mid_depth();
            *n += 1;
        }
        let last = self.plan.len() as u32 - 1;
        self.patch_layers.clear();
        self.patch_layers.extend(
            self.patch_depth.iter().map(
                |&(sum, n)| {
                    if n == 0 { last } else { self.plan.layer_of(sum / n as f32) as u32 }
                },
            ),
        );
        self.fin_layers.clear();
        self.fin_layers.extend(self.fins.iter().map(|f| self.patch_layers[f.patch as usize]));
    }
}

/// Depth below which geometry is treated as at or behind the light plane.
pub fn near_depth(light_space: &LightSpaceScene) -> f32 {
    if light_space.frame.is_perspective() { light_space.reference_depth * 1e-5 } else { f32::NEG_INFINITY }
}

/// One scene under one light, prepared for one method.
pub struct FinShadowModel<'a> {
    pub light_space: &'a LightSpaceScene,
    pub method: Method,
    pub settings: FinSettings,
    pub silhouettes: Vec<SilhouetteEdge>,
    pub fins: Vec<Fin>,
    pub fin_layers: Vec<u32>,
    pub plan: LayerPlan,
    pub casters: Vec<MapTriangle>,
    /// Layer of each map caster.
    pub caster_layers: Vec<u32>,
    pub near: f32,
}

impl<'a> FinShadowModel<'a> {
    /// Extracts silhouettes and fins and plans layers as `method` asks.
    pub fn new(scene: &Scene, light_space: &'a LightSpaceScene, method: Method, settings: FinSettings) -> Self {
        let mut ex = FinExtractor::default();
        let layers = if method == Method::MultiLayer { settings.layers } else { 1 };
        ex.extract(scene, light_space, layers, settings.sub_layers);
        let keep = |f: &Fin| match method {
            Method::Hard => false,
            Method::OuterFins => f.side == FinSide::Outer,
            Method::SingleLayer | Method::MultiLayer => true,
        };
        let (fins, fin_layers): (Vec<Fin>, Vec<u32>) =
            ex.fins.iter().zip(&ex.fin_layers).filter(|(f, _)| keep(f)).map(|(f, l)| (*f, *l)).unzip();
        let near = near_depth(light_space);
        let perspective = light_space.frame.is_perspective();
        let (mut casters, mut caster_layers) = (Vec::new(), Vec::new());
        for (k, (tri, &patch)) in light_space.casters.iter().zip(&ex.face_patches).enumerate() {
            if patch != NO_PATCH {
                let cutout = light_space.cutout(k);
                for t in MapTriangle::clipped_with_cutout(tri, cutout, &light_space.frame, near, perspective) {
                    casters.push(t);
                    caster_layers.push(ex.patch_layers[patch as usize]);
                }
            }
        }
        Self {
            light_space,
            method,
            settings,
            silhouettes: ex.silhouettes,
            fins,
            fin_layers,
            plan: ex.plan,
            casters,
            caster_layers,
            near,
        }
    }

    pub fn frame(&self) -> &LightFrame {
        &self.light_space.frame
    }

    fn combine_params(&self) -> CombineParams<'_> {
        CombineParams {
            frame: &self.light_space.frame,
            reference_depth: self.light_space.reference_depth,
            refinement: self.settings.refinement,
            overlap: self.settings.overlap,
        }
    }

    /// Receiver moved off its surface by `offset` along its normal.
    fn lifted(&self, r: Receiver, offset: f32) -> Vec3 {
        r.position + r.normal * offset
    }

    /// Epsilon for self-shadowing at a receiver ([`crate::scene::surface_epsilon`]).
    pub fn surface_epsilon(&self, receiver: Receiver) -> f32 {
        crate::scene::surface_epsilon(receiver.position, self.light_space.extent)
    }

    /// Visibility from the layer texels at a receiver: `falloff(I)`.
    fn visibility_from(&self, texels: &[LayerTexel], depth: f32, blocking_limit: f32) -> f32 {
        let i = combine_layers(texels, depth, blocking_limit, self.combine_params());
        self.settings.falloff.apply(i)
    }

    /// Builds the map-space index for exact evaluation.
    pub fn analytic(&self) -> AnalyticIndex<'_, 'a> {
        AnalyticIndex::new(self)
    }

    /// Renders the per-layer light-space maps at `resolution²`, as the GPU does.
    pub fn raster(&self, resolution: u32) -> RasterMaps<'_, 'a> {
        RasterMaps::new(self, resolution)
    }

    /// Shared tail of both evaluations: a receiver at or behind the light plane
    /// sees nothing of a one-sided disk.
    fn behind_light(&self, p: Vec3) -> bool {
        !(p.z > self.near) || !p.is_finite()
    }

    /// Map coordinate of a frame point.
    #[inline]
    fn map(&self, p: Vec3) -> Vec2 {
        self.light_space.frame.map(p)
    }
}
