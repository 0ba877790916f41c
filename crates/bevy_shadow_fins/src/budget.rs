//! What the GPU can hold: the device's limits, the user's memory budget, and
//! how fin shadows degrade when a scene asks for more — never a validation
//! error, always a reason in [`FinShadowStats`](crate::FinShadowStats).
//!
//! Every buffer the plugin binds must fit the device's
//! `max_storage_buffer_binding_size` (and `max_buffer_size`). The penumbra maps
//! are the big one (layers × resolution² × 9 words); past the budget they lose
//! resolution first, down to [`MIN_DEGRADED_RESOLUTION`] — but never so far
//! that the light's widest penumbra spans fewer than
//! [`MIN_PENUMBRA_TEXELS`] — then layers (the deepest layers merge), then
//! resolution again. The extraction's per-scene
//! buffers that cannot shrink (vertices, faces, the packed geometry) move the
//! extraction to the CPU when they do not fit; the output buffers (silhouettes,
//! fins, casters) are capped, and what does not fit is dropped.

use bevy::prelude::*;

/// The GPU memory fin shadows may use. A resource: change it at any time.
///
/// Defaults: 768 MiB of penumbra maps, and the device's own largest binding.
/// Set `max_buffer_bytes` lower to see degradation on a big GPU (the tests do).
/// A lower budget takes effect the next frame: buffers larger than it are
/// reallocated at the new size.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Eq, Hash, Reflect)]
#[reflect(Resource, Default, Debug, Clone)]
pub struct FinShadowBudget {
    /// Bytes all penumbra-map layers may take together, split between the
    /// fin-shadowed lights' frames (a point light's six faces are six) by
    /// need: a frame whose maps are known to need less than an equal share
    /// gets what it needs, the others share the rest (`shares_by_need`);
    /// convolution frames share equally.
    pub map_bytes: u64,
    /// The largest single GPU buffer, bytes: `None` is the device's
    /// `max_storage_buffer_binding_size`; a value above it is lowered to it.
    pub max_buffer_bytes: Option<u64>,
}

impl Default for FinShadowBudget {
    fn default() -> Self {
        Self { map_bytes: 768 << 20, max_buffer_bytes: None }
    }
}

/// The device's limits, as the render world found them at start (main world).
#[derive(Resource, Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FinDeviceLimits {
    /// `min(max_storage_buffer_binding_size, max_buffer_size)`.
    pub max_binding_bytes: u64,
}

impl Default for FinDeviceLimits {
    /// WebGPU's guaranteed minimum, until the device says more.
    fn default() -> Self {
        Self { max_binding_bytes: 128 << 20 }
    }
}

impl FinDeviceLimits {
    /// The largest buffer allowed under this budget.
    /// Rounded down to 256 bytes: storage bindings must be a multiple of 4,
    /// and a user's odd byte count must not become a validation error.
    pub fn max_buffer(&self, budget: &FinShadowBudget) -> u64 {
        let b = budget.max_buffer_bytes.map_or(self.max_binding_bytes, |b| b.min(self.max_binding_bytes));
        (b & !255).max(256)
    }
}

/// Present (main world) when the device cannot run fin shadows, with why.
#[derive(Resource, Debug, Clone, Copy)]
pub(crate) struct FinShadowsUnsupported(pub &'static str);

/// Why fin shadows are modelled with less than the settings ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FinDegradation {
    /// The maps use a lower resolution and/or fewer layers than asked.
    Maps { resolution: u32, wanted_resolution: u32, layers: u32, wanted_layers: u32, limit_bytes: u64 },
    /// An extraction output buffer is capped: what did not fit was dropped.
    Capacity { buffer: &'static str, kept: u32, wanted: u32, limit_bytes: u64 },
    /// The scene's geometry does not fit one GPU buffer: extracted on the CPU.
    ExtractedOnCpu { buffer: &'static str, bytes: u64, limit_bytes: u64 },
    /// The device cannot run fin shadows at all (no compute shaders, WebGL2,
    /// too few storage bindings); the fin lights stay dark.
    Unsupported(&'static str),
    /// A coverage cell lists more edges than one shader invocation should
    /// walk: nothing is dropped, but a GPU watchdog may stop the pass and
    /// llvmpipe stops any invocation after 65535 loop iterations, so shadows
    /// there may be wrong on such devices.
    LongCoverageCell { edges: u32, limit: u32 },
    /// More lights ask for fin shadows than [`MAX_FIN_LIGHTS`](crate::MAX_FIN_LIGHTS):
    /// this one (later by entity order) keeps Bevy's own shadow map (a
    /// `FinLight`, which only the plugin lights, is not lit).
    TooManyLights { max: u32 },
    /// The convolution method's basis images (`FinMethod::Convolution`)
    /// keep only their mip levels from `dropped` on: penumbrae narrower than
    /// two of the finest kept texels blur.
    ConvolutionLevels { dropped: u32, limit_bytes: u64 },
    /// Not even the convolution basis of the coarsest allowed level fits:
    /// the light's visibility is not computed, so it shines unshadowed (a
    /// Bevy light's own shadow map stays off; a `FinLight` is not lit).
    ConvolutionBasis { bytes: u64, limit_bytes: u64 },
    /// A plateau cell lists more sheets than one shader invocation walks
    /// (the rest are skipped there: lighter penumbrae in that cell).
    LongPlateauCell { sheets: u32, limit: u32 },
}

/// Every reason a light's frame models less than its settings ask for
/// ([`FinFrameStats::degraded`](crate::FinFrameStats::degraded)): one of each
/// kind, in the order found (a frame's own reasons first; a GPU read-back's
/// shortfalls go before the reasons of the frame they were read from). A
/// point light's faces share one list.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FinDegradations {
    reasons: [Option<FinDegradation>; Self::MAX],
}

impl FinDegradations {
    /// Reasons kept: one of every kind of [`FinDegradation`] (a new kind
    /// must raise it, or `kind_is_counted` fails).
    pub const MAX: usize = 9;

    /// The first reason, if any.
    pub fn first(&self) -> Option<FinDegradation> {
        self.reasons[0]
    }

    /// Every reason, first found first.
    pub fn iter(&self) -> impl Iterator<Item = FinDegradation> + '_ {
        self.reasons.iter().map_while(|r| *r)
    }

    /// Nothing was cut.
    pub fn is_empty(&self) -> bool {
        self.reasons[0].is_none()
    }

    /// With `why` added after the others, unless a reason of its kind is
    /// already there (the first one found of a kind says the most).
    pub(crate) fn with(mut self, why: impl Into<Option<FinDegradation>>) -> Self {
        let Some(why) = why.into() else { return self };
        if self.holds_kind_of(&why) {
            return self;
        }
        if let Some(free) = self.reasons.iter_mut().find(|r| r.is_none()) {
            *free = Some(why);
        }
        self
    }

    /// A reason of `why`'s kind is here (whatever its numbers).
    pub(crate) fn holds_kind_of(&self, why: &FinDegradation) -> bool {
        self.iter().any(|r| std::mem::discriminant(&r) == std::mem::discriminant(why))
    }

    /// These reasons, then those of `other` of kinds not here yet.
    pub(crate) fn and(self, other: Self) -> Self {
        other.iter().fold(self, Self::with)
    }
}

impl From<FinDegradation> for FinDegradations {
    fn from(why: FinDegradation) -> Self {
        Self::default().with(why)
    }
}

impl From<Option<FinDegradation>> for FinDegradations {
    fn from(why: Option<FinDegradation>) -> Self {
        Self::default().with(why)
    }
}

/// The reasons in one line, `; ` between them.
impl std::fmt::Display for FinDegradations {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, why) in self.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{why}")?;
        }
        Ok(())
    }
}

/// Bytes for a person: MiB from 1 MiB on (one decimal), KiB below, bytes
/// under 1 KiB — a test's 12 KiB limit is not "0.0 MiB". The degradation
/// reasons and the editor's memory figures (`FinFrameStats::gpu_bytes`) say
/// sizes this way.
pub struct ByteSize(pub u64);

impl std::fmt::Display for ByteSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            b if b >= 1 << 20 => write!(f, "{:.1} MiB", b as f64 / (1u64 << 20) as f64),
            b if b >= 1 << 10 => write!(f, "{:.1} KiB", b as f64 / 1024.0),
            b => write!(f, "{b} bytes"),
        }
    }
}

impl std::fmt::Display for FinDegradation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let size = ByteSize;
        match *self {
            FinDegradation::Maps { resolution, wanted_resolution, layers, wanted_layers, limit_bytes } => write!(
                f,
                "penumbra maps {layers} layers at {resolution}² instead of {wanted_layers} at {wanted_resolution}²: \
                 over the {} allowed (the light's share of FinShadowBudget::map_bytes, or the GPU's buffer limit)",
                size(limit_bytes)
            ),
            FinDegradation::Capacity { buffer, kept, wanted, limit_bytes } => {
                write!(f, "{buffer}: {kept} of {wanted} kept, the rest dropped (a {} buffer limit)", size(limit_bytes))
            }
            FinDegradation::ExtractedOnCpu { buffer, bytes, limit_bytes } => write!(
                f,
                "fins extracted on the CPU: the GPU extraction's {buffer} needs {}, over the {} buffer limit",
                size(bytes),
                size(limit_bytes)
            ),
            FinDegradation::Unsupported(why) => write!(f, "fin shadows are off: {why}"),
            FinDegradation::LongCoverageCell { edges, limit } => write!(
                f,
                "a coverage cell lists {edges} potential silhouette edges (over {limit}): a GPU watchdog or \
                 llvmpipe's 65535-iteration limit may cut its pixels short"
            ),
            FinDegradation::TooManyLights { max } => {
                write!(
                    f,
                    "more than {max} fin-shadowed lights: this one keeps Bevy's own shadow map (a FinLight is not lit)"
                )
            }
            FinDegradation::ConvolutionLevels { dropped, limit_bytes } => write!(
                f,
                "convolution basis: its {dropped} finest mip level(s) dropped to fit {} (what \
                 FinShadowBudget::map_bytes leaves beside the maps, or the GPU's buffer limit)",
                size(limit_bytes)
            ),
            FinDegradation::ConvolutionBasis { bytes, limit_bytes } => write!(
                f,
                "convolution basis needs {} at its coarsest, over the {} allowed: the light casts no shadow",
                size(bytes),
                size(limit_bytes)
            ),
            FinDegradation::LongPlateauCell { sheets, limit } => {
                write!(f, "a plateau cell lists {sheets} sheets (over {limit}): the rest are skipped there")
            }
        }
    }
}

/// The convolution method's basis images: the mip chain of a map, which
/// levels are stored, and where (`shaders/convolution_types.wgsl`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct BasisLayout {
    /// Floats per texel, `1 + 4M`.
    pub channels: u32,
    /// The first stored level (0 unless the budget dropped the finest).
    pub first: u32,
    /// Levels of the full chain, from the map's resolution down to 1.
    pub chain: u32,
    /// Per stored level: (resolution, offset in floats).
    pub stored: Vec<(u32, u32)>,
}

/// Mip levels a basis chain may have (a 4096² map has 13).
pub(crate) const MAX_BASIS_LEVELS: usize = 16;
/// Finest levels the budget may drop: the first stored level averages
/// `2^k × 2^k` map texels per invocation, kept short.
pub(crate) const MAX_DROPPED_LEVELS: u32 = 4;

impl BasisLayout {
    /// The chain of a `resolution`² map at order `order`, without as many of
    /// its finest levels as it takes to fit in `limit_bytes` (each dropped
    /// level quarters the memory and blurs penumbrae narrower than two of
    /// its texels); `Err(bytes)`, what the coarsest allowed chain needs, when
    /// even that does not fit.
    pub fn new(resolution: u32, order: u32, limit_bytes: u64) -> Result<Self, u64> {
        let channels = 1 + 4 * order.clamp(1, 16);
        let mut sizes = vec![resolution.max(1)];
        while *sizes.last().expect("one level") > 1 && sizes.len() < MAX_BASIS_LEVELS {
            sizes.push(sizes.last().expect("one level").div_ceil(2));
        }
        let bytes_from =
            |first: usize| -> u64 { sizes[first..].iter().map(|r| *r as u64 * *r as u64 * channels as u64 * 4).sum() };
        let most = (MAX_DROPPED_LEVELS as usize).min(sizes.len() - 1);
        let first = (0..=most).find(|f| bytes_from(*f) <= limit_bytes).ok_or(bytes_from(most))?;
        let mut offset = 0u64;
        let stored = sizes[first..]
            .iter()
            .map(|r| {
                let at = offset;
                offset += *r as u64 * *r as u64 * channels as u64;
                (*r, at as u32)
            })
            .collect();
        Ok(Self { channels, first: first as u32, chain: sizes.len() as u32, stored })
    }

    pub fn bytes(&self) -> u64 {
        self.stored.iter().map(|(r, _)| *r as u64 * *r as u64 * self.channels as u64 * 4).sum()
    }
}

/// Each frame's share of `total` map bytes, split by need: a frame whose
/// maps are known to need less than an equal share of what is left gets what
/// it needs, the others split the rest equally (water-filling). `None`: not
/// known yet (a first frame, the coverage method's dense lists). No share is
/// above `cap`, the device's buffer limit.
pub(crate) fn shares_by_need(total: u64, needs: &[Option<u64>], cap: u64) -> Vec<u64> {
    let mut known: Vec<(u64, usize)> = needs.iter().enumerate().filter_map(|(i, n)| n.map(|n| (n, i))).collect();
    known.sort_unstable();
    let mut given = vec![None; needs.len()];
    let (mut left, mut frames) = (total, needs.len() as u64);
    for (need, i) in known {
        if need > left / frames.max(1) {
            break;
        }
        given[i] = Some(need.min(cap));
        left -= need;
        frames -= 1;
    }
    let rest = (left / frames.max(1)).min(cap);
    given.into_iter().map(|share| share.unwrap_or(rest)).collect()
}

/// Resolution the maps degrade to before they lose layers.
pub const MIN_DEGRADED_RESOLUTION: u32 = 256;
/// Resolution below which the maps never go.
pub const MIN_RESOLUTION: u32 = 16;

/// How the penumbra maps are allocated: the resolution and layers that fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct MapAllocation {
    pub resolution: u32,
    pub layers: u32,
    pub degradation: Option<FinDegradation>,
}

/// The fewest texels the widest penumbra (half-width) may span before the
/// budget takes layers rather than resolution. Layers separate fins of
/// casters at different depths; a penumbra of a few texels has almost no fin
/// to separate, and its shadow's error is the texel size. Measured on the
/// real sun (θ = 4.65 mrad) over the built-in scenes, 128 MiB of maps: 16
/// layers at 256² gave MAE 0.04–0.11 against the truth, one layer at 1024²
/// 0.011–0.028 (`shadow-fins-render-lab sun --layers`, BENCHMARKS.md).
pub const MIN_PENUMBRA_TEXELS: f32 = 4.0;

/// The maps for `layers` layers at `resolution²`, each texel `texel_bytes`,
/// within `limit` bytes: resolution halves first (not below
/// [`MIN_DEGRADED_RESOLUTION`], nor below where the widest penumbra —
/// `penumbra_texels` at `resolution`, `INFINITY` when unknown — would span
/// fewer than [`MIN_PENUMBRA_TEXELS`]), then layers go, then resolution again.
pub(crate) fn allocate_maps(
    resolution: u32,
    layers: u32,
    texel_bytes: u64,
    limit: u64,
    penumbra_texels: f32,
) -> MapAllocation {
    let dense = |r: u32, l: u32| l.max(1) as u64 * (r as u64).pow(2) * texel_bytes;
    allocate_maps_by(resolution, layers, limit, penumbra_texels, dense)
}

/// [`allocate_maps`] for maps whose `bytes(resolution, layers)` is not one
/// size per texel: the fin methods' sparse maps (`frame::map_tiles`).
pub(crate) fn allocate_maps_by(
    resolution: u32,
    layers: u32,
    limit: u64,
    penumbra_texels: f32,
    bytes: impl Fn(u32, u32) -> u64,
) -> MapAllocation {
    let (mut r, mut l) = (resolution.max(MIN_RESOLUTION), layers.max(1));
    let penumbra_at = |r: u32| penumbra_texels * r as f32 / resolution.max(1) as f32;
    while bytes(r, l) > limit
        && r / 2 >= MIN_DEGRADED_RESOLUTION.min(resolution)
        && !(penumbra_at(r / 2) < MIN_PENUMBRA_TEXELS)
    {
        r /= 2;
    }
    while bytes(r, l) > limit && l > 1 {
        // As many layers as fit when a layer's bytes are its share (exact
        // for dense maps, a first guess for sparse ones: then one less).
        let fit = (limit / bytes(r, 1).max(1)).clamp(1, l as u64 - 1) as u32;
        l = if fit < l && bytes(r, fit) <= limit { fit } else { l - 1 };
    }
    while bytes(r, l) > limit && r / 2 >= MIN_RESOLUTION {
        r /= 2;
    }
    let degraded = (r, l) != (resolution.max(MIN_RESOLUTION), layers.max(1));
    MapAllocation {
        resolution: r,
        layers: l,
        degradation: degraded.then_some(FinDegradation::Maps {
            resolution: r,
            wanted_resolution: resolution,
            layers: l,
            wanted_layers: layers,
            limit_bytes: limit,
        }),
    }
}

/// What the device can do, checked once at start. `Err` says why fin shadows
/// cannot run on it.
pub(crate) fn check_device(
    limits: &bevy::render::settings::WgpuLimits,
    compute: bool,
) -> Result<FinDeviceLimits, &'static str> {
    if !compute {
        return Err("this GPU or backend has no compute shaders (WebGL2?): fin shadows need them");
    }
    if limits.max_storage_buffers_per_shader_stage < 8 {
        return Err("this GPU allows fewer than 8 storage buffers per shader stage; fin shadows need 8");
    }
    if limits.max_storage_textures_per_shader_stage < 1 {
        return Err("this GPU has no storage textures in compute shaders; the visibility pass needs one");
    }
    if limits.max_compute_workgroup_size_x < 64 || limits.max_compute_invocations_per_workgroup < 64 {
        return Err("this GPU's compute workgroups hold fewer than 64 invocations");
    }
    Ok(FinDeviceLimits { max_binding_bytes: limits.max_storage_buffer_binding_size.min(limits.max_buffer_size) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degradations_say_their_sizes_in_units_a_person_reads() {
        assert_eq!(ByteSize(12 << 10).to_string(), "12.0 KiB");
        assert_eq!(ByteSize(128 << 20).to_string(), "128.0 MiB");
        assert_eq!(ByteSize(1000).to_string(), "1000 bytes");
        let capped = FinDegradation::Capacity { buffer: "fins", kept: 1, wanted: 2, limit_bytes: 12 << 10 };
        assert!(capped.to_string().ends_with("(a 12.0 KiB buffer limit)"), "{capped}");
    }

    #[test]
    fn the_basis_chain_runs_down_to_one_texel_and_drops_its_finest_levels_to_fit() {
        let full = BasisLayout::new(1000, 4, u64::MAX).expect("fits");
        // 1000, 500, 250, 125, 63, 32, 16, 8, 4, 2, 1.
        assert_eq!(full.chain, 11);
        assert_eq!(full.stored.iter().map(|s| s.0).collect::<Vec<_>>(), [1000, 500, 250, 125, 63, 32, 16, 8, 4, 2, 1]);
        assert_eq!(full.channels, 17);
        assert_eq!(full.stored[1].1, 1000 * 1000 * 17, "level 1 starts after level 0");
        assert_eq!(full.first, 0);
        // Under a third of that, the finest level goes (and only it).
        let fitted = BasisLayout::new(1000, 4, full.bytes() / 3).expect("fits");
        assert_eq!((fitted.first, fitted.stored[0].0, fitted.chain), (1, 500, 11));
        assert!(fitted.bytes() <= full.bytes() / 3);
        assert_eq!(fitted.stored[0].1, 0);
        // At most MAX_DROPPED_LEVELS go: past that, the bytes the coarsest
        // allowed chain needs.
        let coarsest = BasisLayout::new(1000, 4, 1).expect_err("does not fit");
        let allowed = BasisLayout::new(1000, 4, coarsest).expect("fits at its own size");
        assert_eq!(allowed.first, MAX_DROPPED_LEVELS);
        assert_eq!(allowed.bytes(), coarsest);
        // The order is clamped to 1..=16 (65 channels at most), a 0² map is 1².
        assert_eq!(BasisLayout::new(16, 99, u64::MAX).expect("fits").channels, 65);
        assert_eq!(BasisLayout::new(0, 0, u64::MAX).expect("fits").stored, [(1, 0)]);
    }

    #[test]
    fn degradations_keep_one_reason_of_each_kind_in_the_order_found() {
        let maps = |resolution| FinDegradation::Maps {
            resolution,
            wanted_resolution: 1024,
            layers: 4,
            wanted_layers: 16,
            limit_bytes: 128 << 20,
        };
        let long = FinDegradation::LongCoverageCell { edges: 9000, limit: 4096 };
        let all = FinDegradations::from(maps(512)).with(None).with(long).with(maps(256));
        assert_eq!(all.iter().collect::<Vec<_>>(), vec![maps(512), long]);
        assert_eq!(all.first(), Some(maps(512)));
        let too_many = FinDegradation::TooManyLights { max: 16 };
        let merged = FinDegradations::from(too_many).and(all);
        assert_eq!(merged.iter().collect::<Vec<_>>(), vec![too_many, maps(512), long]);
        assert_eq!(merged.to_string().matches("; ").count(), 2, "{merged}");
        assert!(FinDegradations::default().is_empty() && FinDegradations::from(None).first().is_none());
    }

    #[test]
    fn kind_is_counted() {
        // Exhaustive: a new kind of reason fails to compile here, and the
        // count below reminds that `FinDegradations::MAX` holds every kind.
        let index = |d: &FinDegradation| match d {
            FinDegradation::Maps { .. } => 0,
            FinDegradation::Capacity { .. } => 1,
            FinDegradation::ExtractedOnCpu { .. } => 2,
            FinDegradation::Unsupported(_) => 3,
            FinDegradation::LongCoverageCell { .. } => 4,
            FinDegradation::TooManyLights { .. } => 5,
            FinDegradation::ConvolutionLevels { .. } => 6,
            FinDegradation::ConvolutionBasis { .. } => 7,
            FinDegradation::LongPlateauCell { .. } => 8,
        };
        assert_eq!(index(&FinDegradation::LongPlateauCell { sheets: 0, limit: 0 }) + 1, FinDegradations::MAX);
    }

    #[test]
    fn shares_follow_need_and_what_is_left_is_split_equally() {
        // 90 for three: the small need gets 10, the others split 80.
        assert_eq!(shares_by_need(90, &[Some(10), None, Some(70)], u64::MAX), vec![10, 40, 40]);
        // Everyone fits: each gets what it needs, no more.
        assert_eq!(shares_by_need(90, &[Some(10), Some(20)], u64::MAX), vec![10, 20]);
        // Nothing known: equal shares, never above the cap.
        assert_eq!(shares_by_need(90, &[None, None, None], 20), vec![20, 20, 20]);
        // A frame that needs nothing takes nothing.
        assert_eq!(shares_by_need(90, &[Some(0), None], u64::MAX), vec![0, 90]);
        assert!(shares_by_need(90, &[], 5).is_empty());
    }

    #[test]
    fn maps_that_fit_are_not_degraded() {
        let a = allocate_maps(1024, 4, 36, 1 << 30, f32::INFINITY);
        assert_eq!((a.resolution, a.layers, a.degradation), (1024, 4, None));
    }

    #[test]
    fn maps_lose_resolution_first_then_layers() {
        // 16 layers at 1024² of 36-byte texels = 576 MiB; at 256², 36 MiB.
        let limit = 16 << 20;
        let a = allocate_maps(1024, 16, 36, limit, f32::INFINITY);
        assert_eq!(a.resolution, 256, "resolution goes down to 256 first");
        assert!(a.layers < 16 && a.layers >= 1);
        assert!(a.layers as u64 * 256 * 256 * 36 <= limit);
        assert!(matches!(a.degradation, Some(FinDegradation::Maps { wanted_layers: 16, .. })));
        // A tiny limit: one layer, and resolution keeps going down, never below 16.
        let b = allocate_maps(1024, 16, 36, 4096, f32::INFINITY);
        assert_eq!(b.layers, 1);
        assert_eq!(b.resolution, 16);
    }

    #[test]
    fn a_low_resolution_ask_is_not_raised() {
        let a = allocate_maps(128, 2, 36, 1 << 30, f32::INFINITY);
        assert_eq!((a.resolution, a.layers), (128, 2));
    }

    #[test]
    fn narrow_penumbrae_keep_their_resolution_and_give_up_layers() {
        // 16 layers at 1024² do not fit 128 MiB. Penumbrae of 5 texels at
        // 1024² would span 2.5 at 512²: layers go instead (3 fit at 1024²).
        let limit = 128 << 20;
        let narrow = allocate_maps(1024, 16, 36, limit, 5.0);
        assert_eq!((narrow.resolution, narrow.layers), (1024, 3));
        // Penumbrae of 20 texels still span 5 at 256²: resolution goes first.
        let wide = allocate_maps(1024, 16, 36, limit, 20.0);
        assert_eq!((wide.resolution, wide.layers), (256, 16));
        // 10 texels: down to 512² (5 texels), then layers (14 of 9 MiB fit).
        let middle = allocate_maps(1024, 16, 36, limit, 10.0);
        assert_eq!((middle.resolution, middle.layers), (512, 14));
        // A hard shadow (no penumbra): resolution is all that matters.
        assert_eq!(allocate_maps(1024, 16, 36, limit, 0.0).resolution, 1024);
        // NaN is no estimate: as unknown (INFINITY), resolution goes first.
        assert_eq!(allocate_maps(1024, 16, 36, limit, f32::NAN).resolution, 256);
    }

    #[test]
    fn devices_without_compute_or_bindings_are_refused_with_a_reason() {
        let mut limits = bevy::render::settings::WgpuLimits::default();
        assert!(check_device(&limits, true).is_ok());
        assert!(check_device(&limits, false).unwrap_err().contains("compute"));
        limits.max_storage_buffers_per_shader_stage = 4;
        assert!(check_device(&limits, true).unwrap_err().contains("storage buffers"));
        let downlevel = bevy::render::settings::WgpuLimits::downlevel_webgl2_defaults();
        assert!(check_device(&downlevel, false).is_err());
    }
}
