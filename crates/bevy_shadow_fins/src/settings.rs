//! What users put on lights and cameras: the fin light, its settings, the
//! camera opt-in and the caster/receiver markers; and the resources that
//! switch the GPU extraction's partial work off ([`FinPartialRedraw`],
//! [`FinIncrementalExtraction`]) for measuring it.

use bevy::prelude::*;
use shadow_fins::{
    oracle::{FinSettings, Method, Overlap},
    refine::Falloff,
};

use crate::stats::FinExtraction;

/// A disk light whose shadows are soft and physically sized by its radius.
///
/// The disk faces along the entity's forward direction (−Z), like a
/// `SpotLight`: point it at the scene with `Transform::looking_at`. It lights
/// the half-space in front of it.
///
/// Values outside their range are clamped, never a panic: a negative or
/// non-finite radius is 0 (hard shadows), a non-finite intensity is 0.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default, Debug, Clone)]
#[require(Transform, Visibility, FinShadowSettings)]
pub struct FinLight {
    pub color: Color,
    /// Luminous power in lumens, as for Bevy's `PointLight`.
    pub intensity: f32,
    /// Distance beyond which the light has no effect.
    pub range: f32,
    /// Radius `R` of the disk in world units: the size of the penumbrae.
    pub radius: f32,
}

impl Default for FinLight {
    fn default() -> Self {
        Self { color: Color::WHITE, intensity: 1_000_000.0, range: 20.0, radius: 0.25 }
    }
}

impl FinLight {
    /// The radius actually used: `radius` clamped to `[0, ∞)`, NaN → 0.
    pub fn effective_radius(&self) -> f32 {
        if self.radius.is_finite() && self.radius > 0.0 { self.radius } else { 0.0 }
    }
}

/// Gives a Bevy light physically sized fin shadows, like `VolumetricLight`
/// or `ContactShadows` add their effect: put it on the light's entity (it
/// adds [`FinShadowSettings`], which tune it, and
/// [`FinLightStats`](crate::FinLightStats), which report what it models).
///
/// The light keeps looking like the Bevy light it is — Bevy shades it, with
/// its colour, intensity, range, cone and BRDF — and only its shadow changes:
/// - `SpotLight { radius, .. }`: a disk of that radius facing along the spot
///   axis (`radius: 0` gives exactly the hard shadow). The cone is Bevy's;
///   casters wholly outside it (widened by what the disk subtends) cast
///   nothing for the light, so its visibility outside the cone — where Bevy
///   lights nothing — is not its shadow there.
/// - `DirectionalLight` (+ `SunDisk`): the sun, a disk at infinity of half
///   the `SunDisk::angular_size` (`SunDisk::EARTH`, 0.53°, when it has none;
///   at most 80°), through orthographic maps fitted to what the
///   [`FinShadowView`] cameras see of the scene (out to their far plane;
///   [`FinShadowSettings::fit_sun_to_views`]); `0` gives exactly the hard
///   shadow. Bevy's cascades and contact shadows for it are off (unless kept,
///   below). Two suns of the same direction and colour on different render
///   layers are not told apart by the compositing pass (it finds a sun in a
///   view's list by them); while Bevy's maps are kept, neither is a fin sun
///   and a non-fin sun of that direction and colour.
/// - `RectLight { width, height, .. }`: a rectangle of those sizes (times the
///   transform's scale along local X and Y, as Bevy scales it) facing local
///   −Z. Fins across an edge are as wide as the rectangle's support function
///   in the direction across it, the coverage method and the ground truth
///   sample the rectangle itself; `0 × 0` gives exactly the hard shadow.
///   Bevy has no shadow for a `RectLight` (and needs the `area_light_luts`
///   feature to light one at all): this is its only shadow.
/// - `PointLight { radius, .. }`: a sphere of that radius, shadowed all
///   around. Seen from a receiver its outline is a disk facing it, which the
///   ground truth and the coverage method sample; fins are made in six
///   cube-face frames (each its own extraction and maps over its frustum and
///   a margin for casters near the light; the sphere is `√(1 + |m|²)` times
///   wider along the map position `m` than across it, which sizes the fins
///   off a face's axis), whose visibility passes each shade the receivers in
///   their face and fill the light's one visibility layer between them
///   (`shadow_fins::light`). A face that sees no caster runs no
///   extraction or map pass (its visibility pass writes 1 on its pixels).
///   `radius: 0` gives exactly the hard shadow. The penumbra-map
///   budget is shared per face: a point light takes six shares.
///
/// Bevy's own shadow map and contact shadows for the light are off while
/// `FinShadows` is on (in the render world: the light's `shadow_maps_enabled`
/// is left as the user set it, and comes back when `FinShadows` is removed),
/// unless [`BevyShadowMapsKept`](crate::BevyShadowMapsKept) keeps them for
/// a camera without [`FinShadowView`] or a receiver fin shadows cannot reach.
/// Fin shadows reach the pixels of cameras with [`FinShadowView`]: deferred
/// materials through the compositing pass, forward opaque and alpha-masked
/// `StandardMaterial`s through the forward hook (on devices that bind five
/// groups); elsewhere — other cameras, alpha-blended and transmissive
/// materials (counted in [`FinReceivers`](crate::FinReceivers)), custom
/// forward materials, the diffuse-transmission lobe of deferred ones, and
/// while the light's visibility cannot be computed (its first frames while
/// pipelines compile, an MSAA camera, maps over the device's storage limit)
/// — the light gets Bevy's own shadow while the maps are kept (a `RectLight`
/// has none: it shines unshadowed there) and shines unshadowed otherwise. A
/// `VolumetricLight` loses its shafts while the maps are off (Bevy draws
/// them from its shadow map).
#[derive(Component, Debug, Clone, Copy, Default, Reflect)]
#[reflect(Component, Default, Debug, Clone)]
#[require(FinShadowSettings)]
pub struct FinShadows;

/// Which shadow method renders the fin light.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Reflect)]
pub enum FinMethod {
    /// A shadow map from the light's centre.
    Hard,
    /// Hard shadow plus outer fins (smoothies / penumbra maps).
    OuterFins,
    /// Inner and outer fins in one layer (the paper's §3).
    SingleLayer,
    /// Inner and outer fins in layers (the paper's §4).
    #[default]
    MultiLayer,
    /// Exact coverage with occluder fusion (beyond the paper, see
    /// `shadow_fins::coverage`): per light sample, how many casters lie
    /// between the receiver and the sample, counted from potential silhouette
    /// edges; right where fins fail, on assets of many overlapping parts.
    /// Costs more per penumbra pixel than fins; `coverage_samples` trades it.
    Coverage,
    /// Convolution soft shadow maps (Annen et al. 2008, `004_…`; the
    /// core's `shadow_fins::peers::convolution`), the filtering peer: the
    /// hard shadow map expanded in `1 + 4M` Fourier basis images
    /// (`convolution_order` `M`), mipmapped, filtered per pixel over the
    /// light's footprint at the average blocker depth (CSM-Z), the mip level
    /// chosen so the trilinear blur is as wide as that footprint (ours:
    /// `VARIANCE_MATCHED_MIP_BIAS`; the paper's level blurs √3× wider and
    /// greys the umbra, MAE 0.046 against 0.039 on box-over-plane). Cheapest
    /// per pixel and independent of the scene's complexity once the map is
    /// drawn; it sees one depth per texel, so stacked casters fuse into one
    /// and contact shadows lift (see `BENCHMARKS.md`). Mipmaps only on the GPU
    /// (f32 summed-area tables lose the small differences they subtract).
    Convolution,
    /// Plateaus (Haines 2001, `003_…`; the core's
    /// `shadow_fins::peers::plateaus`), the outer-only ancestor of fins: on
    /// one receiver plane (the largest flat receiver facing the light), the
    /// hard drop shadow widened outwards by a cone at every silhouette
    /// vertex and a sheet along every silhouette edge, darkest wins. Every
    /// receiver off that plane gets the hard shadow; the umbra never
    /// shrinks (it over-darkens where the light would wrap round, see
    /// `BENCHMARKS.md`). The silhouettes are found on the CPU when
    /// something moves.
    Plateaus,
}

impl FinMethod {
    /// Whether the fins' visibility pass (`visibility.wgsl`) shades this
    /// method's pixels; coverage, convolution and plateaus have their own.
    pub(crate) fn shaded_by_fin_pass(self) -> bool {
        matches!(self, FinMethod::Hard | FinMethod::OuterFins | FinMethod::SingleLayer | FinMethod::MultiLayer)
    }
}

impl From<FinMethod> for Method {
    /// The core's fin method. `Coverage`, `Convolution` and `Plateaus` have
    /// no fins: they map to the hard shadow map (the one convolution filters
    /// and plateaus widen, and what the fin-map views of the editor show).
    fn from(m: FinMethod) -> Self {
        match m {
            FinMethod::Hard | FinMethod::Coverage | FinMethod::Convolution | FinMethod::Plateaus => Method::Hard,
            FinMethod::OuterFins => Method::OuterFins,
            FinMethod::SingleLayer => Method::SingleLayer,
            FinMethod::MultiLayer => Method::MultiLayer,
        }
    }
}

/// The most layers a light's maps may have.
pub const MAX_LAYERS: u32 = 32;

/// Settings of the fin light's shadows, on the [`FinLight`] entity. Every field
/// can change at runtime and takes effect the next frame.
///
/// Out-of-range values are clamped (see [`FinShadowSettings::clamped`]).
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Hash, Reflect)]
#[reflect(Component, Default, Debug, Clone)]
#[require(crate::FinLightStats)]
pub struct FinShadowSettings {
    pub method: FinMethod,
    /// Layers `N`, 1..=32 (default 16). Empty layers cost nothing.
    pub layers: u32,
    /// Sub-layers `S` of the depth histogram, 1..=65536 (default 1024).
    pub sub_layers: u32,
    /// Light-space map resolution (square), 16..=4096 (default 1024).
    pub map_resolution: u32,
    /// Refine fin weights to the receiver's depth (eq. 5).
    pub refinement: bool,
    #[reflect(ignore)]
    pub falloff: Falloff,
    #[reflect(ignore)]
    pub overlap: Overlap,
    /// GPU (default) or CPU fin extraction and layer assignment. (The
    /// coverage method's edges are extracted on the CPU for now.)
    pub extraction: FinExtraction,
    /// Light samples per receiver of [`FinMethod::Coverage`], 1..=256
    /// (default 256: MAE about 0.003 against the truth; 64: about 0.01).
    pub coverage_samples: u32,
    /// A sun's maps cover only what the [`FinShadowView`] cameras see of the
    /// scene (default), not all of it: the texels go where someone looks. The
    /// maps follow the cameras in steps: a camera moving a sixteenth of its
    /// view re-extracts the sun's shadows. Off: maps over everything drawn,
    /// rebuilt only when the scene or the sun changes. Disk lights ignore it.
    pub fit_sun_to_views: bool,
    /// Reconstruction order `M` of [`FinMethod::Convolution`], 1..=16
    /// (default 4, the paper's): higher is closer to the hard test with less
    /// ringing to suppress, at `4M + 1` basis images of memory and lookups.
    pub convolution_order: u32,
}

impl Default for FinShadowSettings {
    fn default() -> Self {
        let core = FinSettings::default();
        Self {
            method: FinMethod::MultiLayer,
            layers: core.layers,
            sub_layers: core.sub_layers,
            map_resolution: 1024,
            refinement: core.refinement,
            falloff: core.falloff,
            overlap: core.overlap,
            extraction: FinExtraction::Gpu,
            coverage_samples: 256,
            fit_sun_to_views: true,
            convolution_order: 4,
        }
    }
}

impl FinShadowSettings {
    /// Every field clamped into its documented range.
    pub fn clamped(self) -> Self {
        Self {
            layers: self.layers.clamp(1, MAX_LAYERS),
            sub_layers: self.sub_layers.clamp(1, 65536),
            map_resolution: self.map_resolution.clamp(16, 4096),
            coverage_samples: self.coverage_samples.clamp(1, 256),
            convolution_order: self.convolution_order.clamp(1, 16),
            ..self
        }
    }

    /// The core crate's settings for these.
    pub fn core(self) -> FinSettings {
        let s = self.clamped();
        FinSettings {
            layers: s.layers,
            sub_layers: s.sub_layers,
            refinement: s.refinement,
            falloff: s.falloff,
            overlap: s.overlap,
        }
    }
}

/// Put on a `Camera3d` to render the fin light (its light and its soft
/// shadows) for it.
///
/// What the camera needs, added by this component and the plugin:
/// - the depth and normal prepasses (the visibility pass reads them) and the
///   deferred prepass (the compositing pass lights the G-buffer with Bevy's
///   own PBR functions and adds the fin light, in place of Bevy's deferred
///   lighting pass);
/// - `Msaa::Off`: deferred rendering has no MSAA; the plugin turns it off on
///   such cameras, with a warning, instead of failing.
///
/// HDR on or off both work: the fin light is added before tonemapping.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default, Debug, Clone)]
#[require(
    bevy::core_pipeline::prepass::DepthPrepass,
    bevy::core_pipeline::prepass::NormalPrepass,
    bevy::core_pipeline::prepass::DeferredPrepass
)]
pub struct FinShadowView {
    /// When set, the camera's visibility (illuminance) buffer of the first
    /// fin-shadowed light (by entity order), `R32Float` at the camera's size,
    /// is copied into this image every frame: read it back with
    /// `Readback::texture`, or show it.
    pub visibility_target: Option<Handle<Image>>,
    /// The same for any light: (light entity, image), each light's own
    /// visibility copied into its image.
    pub light_visibility_targets: Vec<(Entity, Handle<Image>)>,
}

/// Keeps a mesh from casting fin shadows while Bevy's own shadow maps still
/// see it. Bevy's `NotShadowCaster` keeps it from casting both.
#[derive(Component, Debug, Clone, Copy, Default, Reflect)]
#[reflect(Component, Default, Debug, Clone)]
pub struct NotFinShadowCaster;

/// Keeps a mesh from receiving fin shadows: the fin light reaches it unshadowed.
///
/// The compositing pass reads the G-buffer's shadow-receiver flag, which is
/// Bevy's `NotShadowReceiver`; so this marker adds `NotShadowReceiver` (the
/// mesh also receives no Bevy shadow-map shadows) and removing it removes that.
/// Bevy's `NotShadowReceiver` alone has the same effect on fin shadows.
#[derive(Component, Debug, Clone, Copy, Default, Reflect)]
#[reflect(Component, Default, Debug, Clone)]
pub struct NotFinShadowReceiver;

/// Whether the GPU extraction may redraw the penumbra maps in part when a few
/// casters of many moved (only the texels under their old and new
/// footprints; see `FinFrameStats::partial_redraw`). On by default: the
/// result is texel for texel a full redraw's. Off, every update redraws the
/// maps whole — for measuring what the partial redraw saves
/// (`shadow-fins-render-lab scaling`).
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq, bevy::render::extract_resource::ExtractResource)]
pub struct FinPartialRedraw(pub bool);

impl Default for FinPartialRedraw {
    fn default() -> Self {
        Self(true)
    }
}

/// Whether the GPU extraction may extract only the casters that moved, when
/// a few of many moved, and keep every other caster's silhouettes, fins and
/// map triangles from the update before (see
/// `FinFrameStats::incremental_extraction`). On by default: the result is
/// record for record a full extraction's. Off, every update extracts every
/// caster — for measuring what it saves (`shadow-fins-render-lab scaling`).
/// It applies where a partial redraw may ([`FinPartialRedraw`]).
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq, bevy::render::extract_resource::ExtractResource)]
pub struct FinIncrementalExtraction(pub bool);

impl Default for FinIncrementalExtraction {
    fn default() -> Self {
        Self(true)
    }
}
