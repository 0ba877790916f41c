//! Convolution soft shadows (Annen, Dong, Mertens, Bekaert, Seidel, Kautz,
//! *Real-Time, All-Frequency Shadows in Dynamic Scenes*, 2008; `004_…`): a
//! shadow map from the light's centre whose shadow test is expanded in a
//! Fourier series, so that filtering the test over any rectangle is a
//! filter of basis images (convolution shadow maps, CSM), and the average
//! blocker depth over a rectangle is one too (CSM-Z).
//!
//! Per receiver at normalised depth `d` (§3–4, Figure 2):
//! 1. **search**: the cone from the receiver to the light cut at the
//!    shadow map's near plane gives the first rectangle;
//! 2. **CSM-Z** (eq. 8, 11): `z_avg = [w ∗ f̄(d, z)·z] / [w ∗ f̄(d, z)]`,
//!    with the complementary test `f̄ ≈ ½ + 2 Σ_k sin(c_k (d − z))/c_k`
//!    (eq. 10, `c_k = π(2k − 1)`) expanded into the basis images
//!    `cos(c_k z)`, `sin(c_k z)`, `z cos(c_k z)`, `z sin(c_k z)` and `z`;
//! 3. **penumbra**: `f_w = Δ/d · (d − z_avg)/z_avg · z_n` at the near plane
//!    (§4.1), which in map units is [`LightFrame::penumbra_half_width`]
//!    `(z_avg, d)` — the disk's `R (d − z_avg)/(d z_avg)`, the sun's
//!    `tan θ (d − z_avg)`;
//! 4. **CSM** (eq. 3): the filtered test `s_f = 1 − [w ∗ f̄]` over that
//!    rectangle; **ringing suppression** (§3.3, Figure 3): scaled about ½ and
//!    clamped, `clamp(α (s_f − ½) + ½, 0, 1)`; **sharpening** (eq. 9):
//!    `s_f^p`, `p = 1 + A exp(−B (d − z_avg))`.
//!
//! Prefiltering is by summed-area tables (exact box filters of the
//! piecewise-constant map at any fractional rectangle, in f64 where the paper
//! had 32-bit floats) or mipmaps (trilinear, the footprint's larger side
//! choosing the level — a rectangle light's, the side of the square of its
//! area), the paper's two options.
//!
//! What is ours, where the paper leaves a number open:
//! - `α`: the smallest that maps every oscillation outside the step onto 0
//!   or 1 ([`ringing_scale`]; 1.2–1.3, as the Gibbs overshoot is 9%);
//! - the depth **shift** that keeps a surface from shadowing itself (the
//!   series is ½ at `d = z`): the smallest for which the suppressed test is 1
//!   at the surface's own depth, found once per order ([`step_shift`]);
//! - depths are normalised over `[near, L0]` (nearest caster, deepest
//!   receiver) into `[0, depth_span]`, short of 1 because the series is
//!   periodic ([`depth_span`]); `A = 30` (their Figure 4) and `B = 20` (its
//!   tightest), in those normalised depths;
//! - receivers look the maps up after a normal offset of 1.5 texels (as the
//!   fin oracle's raster maps do);
//! - **the light's shape**: the search and filter regions are the light
//!   seen through the receiver on the map (§4.1's `f_w` per axis). The
//!   disk's is the square around it, `R` per side; a rectangle light's
//!   (`Aperture::Rect`, half sides `a`, `b`) is the rectangle itself, `a`
//!   and `b` where the bounding circle `√(a² + b²)` made both. For a
//!   rectangle the box filter is the exact penumbra of a straight edge
//!   across either axis (a linear ramp `2a` or `2b` wide, before `α`);
//!   the square of the bounding circle blurred a 4 : 1 light's short side
//!   ×4 (MAE 0.123 against 0.042 under a disk of the same area, box over
//!   plane).
//!
//! It is a filtering method: it sees one depth per texel (single-silhouette
//! artifacts, blockers flattened within a kernel, as §5 says). Being one,
//! it takes alpha-masked casters as they are: their texels alpha-tested
//! into the shadow map ([`crate::cutout`]), a hole's penumbra filtered like
//! any edge's. (So do the plateaus, whose cones and sheets come from the
//! masked outline and whose drop shadow alpha-tests its rays; single-sample's
//! shells and the wedges' silhouettes come from the triangles: they model a
//! cut-out card solid.)

use glam::{Vec2, Vec3};

use crate::{
    light::{Aperture, LightFrame},
    oracle::{MapRegion, RASTER_MAP_LIMIT},
    receiver::Receiver,
    scene::{LightSpaceScene, surface_epsilon},
};

/// How the basis images are prefiltered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Prefilter {
    SummedArea,
    Mipmap,
}

/// Settings of the convolution shadow maps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConvolutionSettings {
    /// Shadow map resolution (clamped to `16..=2048`, and lowered until the
    /// basis images fit in [`MAX_BASIS_BYTES`]).
    pub resolution: u32,
    /// Reconstruction order `M` (clamped to `1..=16`); the paper renders with 4.
    pub order: u32,
    pub prefilter: Prefilter,
    /// Sharpening `(A, B)` of eq. 9, or `None` for `p = 1`.
    pub sharpening: Option<(f32, f32)>,
    /// Mipmaps only: how many levels finer than the footprint's side the
    /// lookup reads, `log2(side) − mip_bias` (clamped to `0..=4`). 0 is the
    /// paper's choice; bilinear taps of a level-`l` texel blur as a box of
    /// side `√3 · 2^l` (equal variance), so [`VARIANCE_MATCHED_MIP_BIAS`]
    /// filters as wide as the box meant, where 0 blurs √3× wider.
    pub mip_bias: f32,
}

/// `log2 √3`: the mip bias at which a trilinear lookup has the variance of the
/// box filter it stands for (box of side `s`: `s²/12`; a level-`l` texel's
/// box under the bilinear tent: `4^l (1/12 + 1/6)`).
pub const VARIANCE_MATCHED_MIP_BIAS: f32 = 0.792_481_2;

impl Default for ConvolutionSettings {
    fn default() -> Self {
        Self {
            resolution: 512,
            order: 4,
            prefilter: Prefilter::SummedArea,
            sharpening: Some((30.0, 20.0)),
            mip_bias: 0.0,
        }
    }
}

/// Memory the basis images may take (a user asking for 2048² at order 16
/// gets a smaller map, not an allocation failure).
pub const MAX_BASIS_BYTES: usize = 512 << 20;

#[inline]
fn c(k: u32) -> f32 {
    std::f32::consts::PI * (2 * k - 1) as f32
}

/// The order-`M` series of the shadow test `f(x)`, `x = d − z`:
/// `½ − 2 Σ sin(c_k x)/c_k` (1 for `x < 0`, 0 for `0 < x < 1`, period 2).
pub fn series_step(x: f32, order: u32) -> f32 {
    0.5 - 2.0 * (1..=order).map(|k| (c(k) * x).sin() / c(k)).sum::<f32>()
}

/// Ringing suppression's scale `α` about ½ for order `M`: the smallest that
/// lifts every oscillation of the lit side past its first peak (`x < −1/2M`)
/// to at least 1 — and, by symmetry, drops the shadowed side's to 0 —, so
/// that clamping leaves no ringing (their Figure 3(c)–(d)). It narrows
/// penumbrae by `α` (1.2–1.3: "sharpens shadows slightly").
pub fn ringing_scale(order: u32) -> f32 {
    let peak = 0.5 / order as f32;
    let n = 4096;
    let lowest = (0..=n)
        .map(|i| -peak - (1.0 - 2.0 * peak) * i as f32 / n as f32)
        .map(|x| series_step(x, order))
        .fold(f32::INFINITY, f32::min);
    1.001 / (2.0 * (lowest - 0.5)).max(1e-3)
}

/// The shadow test reconstructed by the order-`M` series with ringing
/// suppression `α` ([`ringing_scale`]): `clamp(α (f(x) − ½) + ½, 0, 1)`.
pub fn suppressed_step(x: f32, order: u32, alpha: f32) -> f32 {
    (alpha * (series_step(x, order) - 0.5) + 0.5).clamp(0.0, 1.0)
}

/// The smallest shift `δ` with `suppressed_step(−δ) = 1`: reconstructing at
/// `d − δ`, a surface at the depth the map holds for it is lit.
pub fn step_shift(order: u32) -> f32 {
    let alpha = ringing_scale(order);
    let (mut lo, mut hi) = (0.0f32, 0.5f32 / order as f32);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if suppressed_step(-mid, order, alpha) >= 1.0 { hi = mid } else { lo = mid }
    }
    hi
}

/// The normalised depth range `[0, depth_span(M)]` the map's depths are
/// scaled into. The series has period 2: it is a step only for `|d − z| < 1`,
/// and flips back at ±1, so depths keep three shifts away from that end
/// (a receiver at the far end behind a caster at the near end stays dark).
pub fn depth_span(order: u32) -> f32 {
    1.0 - 3.0 * step_shift(order)
}

/// The basis images' values at normalised depth `z` (`1 + 4M` channels):
/// `z`, then `cos(c_k z)`, `sin(c_k z)`, `z cos(c_k z)`, `z sin(c_k z)` for
/// `k = 1..=M`, each group of `M` together (the GPU's `convolution.wgsl`
/// stores them in this order).
pub fn basis(z: f32, order: u32, out: &mut [f32]) {
    let m = order as usize;
    out[0] = z;
    for k in 0..m {
        let (s, co) = (c(k as u32 + 1) * z).sin_cos();
        out[1 + k] = co;
        out[1 + m + k] = s;
        out[1 + 2 * m + k] = z * co;
        out[1 + 3 * m + k] = z * s;
    }
}

/// Half sides of the filter box of a light of size 1 (its bounding circle):
/// the square around the disk, or the rectangle itself (units of the circle).
pub fn kernel_shape(aperture: Aperture) -> Vec2 {
    match aperture {
        // A sphere's face reaches the peers as the disk in the face's plane
        // (`PeerModel::new`).
        Aperture::Disk | Aperture::Sphere { .. } => Vec2::ONE,
        Aperture::Rect { half_extents } => half_extents,
    }
}

/// What a mipmap's bilinear tap off the map reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum OffMap {
    /// The empty plane: the map covers every caster, and a kernel reaching
    /// past it (a penumbra outside the casters' footprint) must not see the
    /// casters on its edge spread outwards.
    Empty,
    /// The map's border texels: the map is a window onto casters that go on
    /// past it (`ConvolutionModel::new` and `fitted`, padded by the kernels'
    /// reach; a plugin sun fitted to the views, [`ConvolutionModel::windowed`]).
    Border,
}

/// Prefiltered basis images: box averages over any rectangle of texels.
enum Prefiltered {
    /// `(res + 1)²` corners × channels, summed from the map's origin.
    SummedArea { res: usize, channels: usize, table: Vec<f64> },
    /// Level 0 is the map; each next level halves it by 2×2 boxes.
    Mipmap { channels: usize, levels: Vec<(usize, Vec<f32>)> },
}

impl Prefiltered {
    fn summed_area(res: usize, channels: usize, texels: &[f32]) -> Self {
        let w = res + 1;
        let mut table = vec![0.0f64; w * w * channels];
        for y in 0..res {
            for x in 0..res {
                for ch in 0..channels {
                    let v = texels[(y * res + x) * channels + ch] as f64;
                    let at = |xx: usize, yy: usize| (yy * w + xx) * channels + ch;
                    table[at(x + 1, y + 1)] = v + table[at(x, y + 1)] + table[at(x + 1, y)] - table[at(x, y)];
                }
            }
        }
        Prefiltered::SummedArea { res, channels, table }
    }

    fn mipmap(res: usize, channels: usize, texels: Vec<f32>) -> Self {
        let mut levels = vec![(res, texels)];
        while levels.last().unwrap().0 > 1 {
            let (r, prev) = levels.last().unwrap();
            let (r, n) = (*r, r.div_ceil(2));
            let mut next = vec![0.0f32; n * n * channels];
            for y in 0..n {
                for x in 0..n {
                    for ch in 0..channels {
                        let mut sum = 0.0;
                        let mut count = 0.0;
                        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let (xx, yy) = (2 * x + dx, 2 * y + dy);
                            if xx < r && yy < r {
                                sum += prev[(yy * r + xx) * channels + ch];
                                count += 1.0;
                            }
                        }
                        next[(y * n + x) * channels + ch] = sum / count;
                    }
                }
            }
            levels.push((n, next));
        }
        Prefiltered::Mipmap { channels, levels }
    }

    /// Average of each channel over the texel-space rectangle `[lo, hi]`,
    /// into `out`; what lies outside the map counts as `empty` texels
    /// (summed-area tables), or as `off_map` says (a mipmap's bilinear taps
    /// off its level). A mipmap's level is that of the square of side
    /// `side`, or of the footprint's larger side when `None`.
    #[allow(clippy::too_many_arguments)]
    fn average(
        &self,
        lo: Vec2,
        hi: Vec2,
        side: Option<f32>,
        bias: f32,
        empty: &[f64],
        off_map: OffMap,
        out: &mut [f64],
    ) {
        match self {
            Prefiltered::SummedArea { res, channels, table } => {
                let r = *res as f32;
                let full = ((hi.x - lo.x) as f64 * (hi.y - lo.y) as f64).max(1e-12);
                let (lo, hi) = (lo.clamp(Vec2::ZERO, Vec2::splat(r)), hi.clamp(Vec2::ZERO, Vec2::splat(r)));
                let (lo, hi) = (lo.as_dvec2(), hi.as_dvec2().max(lo.as_dvec2() + 1e-6));
                let w = res + 1;
                // The table's bilinear interpolation is the exact integral of
                // the piecewise-constant map up to a fractional corner.
                let corner = |u: f64, v: f64, ch: usize| -> f64 {
                    let (i, j) = ((u.floor() as usize).min(*res - 1), (v.floor() as usize).min(*res - 1));
                    let (a, b) = (u - i as f64, v - j as f64);
                    let t = |x: usize, y: usize| table[(y * w + x) * channels + ch];
                    t(i, j) * (1.0 - a) * (1.0 - b)
                        + t(i + 1, j) * a * (1.0 - b)
                        + t(i, j + 1) * (1.0 - a) * b
                        + t(i + 1, j + 1) * a * b
                };
                let inside = ((hi.x - lo.x) * (hi.y - lo.y)).min(full);
                for (ch, o) in out.iter_mut().enumerate().take(*channels) {
                    let sum = corner(hi.x, hi.y, ch) - corner(lo.x, hi.y, ch) - corner(hi.x, lo.y, ch)
                        + corner(lo.x, lo.y, ch);
                    *o = (sum + (full - inside) * empty[ch]) / full;
                }
            }
            Prefiltered::Mipmap { channels, levels } => {
                let size = side.unwrap_or_else(|| (hi - lo).max_element()).max(1.0);
                let level = (size.log2() - bias).clamp(0.0, (levels.len() - 1) as f32);
                let (l0, t) = (level.floor() as usize, level.fract());
                let l1 = (l0 + 1).min(levels.len() - 1);
                let centre = 0.5 * (lo + hi);
                out[..*channels].fill(0.0);
                for (l, weight) in [(l0, 1.0 - t), (l1, t)] {
                    if weight == 0.0 {
                        continue;
                    }
                    let (r, data) = (levels[l].0 as i64, &levels[l].1);
                    // Bilinear between the level's texel centres; a tap off
                    // the level reads an empty texel, or the border's.
                    let q = centre / (1u32 << l) as f32 - 0.5;
                    let q = match off_map {
                        OffMap::Empty => q.clamp(Vec2::splat(-1.0), Vec2::splat(r as f32)),
                        OffMap::Border => q.clamp(Vec2::ZERO, Vec2::splat((r - 1) as f32)),
                    };
                    let (i, j) = (q.x.floor() as i64, q.y.floor() as i64);
                    let (a, b) = ((q.x - i as f32) as f64, (q.y - j as f32) as f64);
                    for (ch, o) in out.iter_mut().enumerate().take(*channels) {
                        let t = |x: i64, y: i64| {
                            if (0..r).contains(&x) && (0..r).contains(&y) {
                                data[((y * r + x) as usize) * channels + ch] as f64
                            } else if off_map == OffMap::Border {
                                data[((y.clamp(0, r - 1) * r + x.clamp(0, r - 1)) as usize) * channels + ch] as f64
                            } else {
                                empty[ch]
                            }
                        };
                        let v = t(i, j) * (1.0 - a) * (1.0 - b)
                            + t(i + 1, j) * a * (1.0 - b)
                            + t(i, j + 1) * (1.0 - a) * b
                            + t(i + 1, j + 1) * a * b;
                        *o += weight as f64 * v;
                    }
                }
            }
        }
    }
}

/// One scene under one light as convolution shadow maps.
pub struct ConvolutionModel {
    pub settings: ConvolutionSettings,
    pub region: MapRegion,
    maps: Prefiltered,
    off_map: OffMap,
    /// The basis of an empty texel (the far plane).
    empty: Vec<f64>,
    frame: LightFrame,
    /// Depth normalisation: `span · (z − near) / (far − near)`.
    near: f32,
    far: f32,
    span: f32,
    shift: f32,
    ringing_scale: f32,
    extent: f32,
    reference_depth: f32,
}

impl ConvolutionModel {
    /// The map covering every caster (a whole-scene shadow map).
    pub fn new(light_space: &LightSpaceScene, settings: ConvolutionSettings) -> Self {
        Self::within(light_space, settings, None)
    }

    /// The map fitted to what `receivers` can see of it: their map points,
    /// widened by each one's search rectangle — what a renderer fits to its
    /// view (a 60-unit ground under a 0.2-unit penumbra would otherwise get
    /// 0.1-unit texels).
    pub fn fitted(light_space: &LightSpaceScene, settings: ConvolutionSettings, receivers: &[Receiver]) -> Self {
        let frame = &light_space.frame;
        let near = light_space
            .casters
            .iter()
            .flatten()
            .map(|p| p.z)
            .filter(|z| *z > light_space.reference_depth * 1e-5 || !frame.is_perspective())
            .fold(f32::INFINITY, f32::min);
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for r in receivers {
            let p = r.position;
            if !p.is_finite() || (frame.is_perspective() && !(p.z > 0.0)) {
                continue;
            }
            let q = frame.map(p);
            let reach = if near.is_finite() { frame.penumbra_half_width(near, p.z) } else { 0.0 };
            let reach = kernel_shape(frame.aperture) * reach;
            if q.is_finite() && reach.is_finite() {
                lo = lo.min(q - reach);
                hi = hi.max(q + reach);
            }
        }
        let window = (lo.x <= hi.x && lo.y <= hi.y).then_some((lo, hi));
        Self::within(light_space, settings, window)
    }

    fn within(light_space: &LightSpaceScene, settings: ConvolutionSettings, window: Option<(Vec2, Vec2)>) -> Self {
        let order = settings.order.clamp(1, 16);
        let channels = 1 + 4 * order as usize;
        let mut resolution = settings.resolution.clamp(16, 2048);
        while resolution > 16 && (resolution as usize + 1).pow(2) * channels * 8 > MAX_BASIS_BYTES {
            resolution /= 2;
        }
        let settings = ConvolutionSettings { resolution, order, ..settings };
        let frame = light_space.frame;
        let perspective = frame.is_perspective();
        let min_near = light_space.reference_depth * 1e-5;
        let near_clip = if perspective { min_near } else { f32::NEG_INFINITY };
        // Alpha-masked casters cut out of the shadow map, as the fins' maps do.
        let triangles = crate::coverage::reference::map_triangles(light_space, near_clip);
        let limit = frame.map_limit(RASTER_MAP_LIMIT);
        // Padded by the widest search rectangle, so that a receiver's
        // kernel beyond the casters sees empty texels, not the map's edge.
        let nearest = triangles.iter().map(|t| t.min_depth).filter(|z| *z > near_clip).fold(f32::INFINITY, f32::min);
        let pad =
            if nearest.is_finite() { frame.penumbra_half_width(nearest, light_space.reference_depth) } else { 0.0 };
        let pad = if pad.is_finite() { pad.min(limit) } else { 0.0 };
        let pad = kernel_shape(frame.aperture) * pad;
        let bounds = triangles.iter().map(|t| {
            let [a, b, c] = t.corners;
            (a.min(b).min(c) - pad, a.max(b).max(c) + pad)
        });
        let (lo, hi) = window.map_or((Vec2::splat(-limit), Vec2::splat(limit)), |(lo, hi)| {
            (lo.max(Vec2::splat(-limit)), hi.min(Vec2::splat(limit)))
        });
        let region = MapRegion::covering_within(bounds, resolution, (lo, hi));
        // The nearest depth per texel centre: the shadow map.
        let res = resolution as usize;
        let mut depth = vec![f32::INFINITY; res * res];
        for t in &triangles {
            let [a, b, c] = t.corners;
            let Some((x0, x1, y0, y1)) = region.texel_range(a.min(b).min(c), a.max(b).max(c)) else { continue };
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let q = region.texel_center(x, y);
                    if t.contains(q) && t.opaque_at(q, &light_space.masks) {
                        let d = t.depth_at(q);
                        let cell = &mut depth[y as usize * res + x as usize];
                        if d > near_clip && d < *cell {
                            *cell = d;
                        }
                    }
                }
            }
        }
        Self { off_map: OffMap::Border, ..Self::on_depth_map(light_space, settings, region, &depth) }
    }

    /// Convolution shadow maps of a shadow map made elsewhere: `depth` holds
    /// the nearest caster depth (light frame, `+∞` where none) at each texel
    /// centre of `region`, row by row, a region that covers every caster
    /// (past it lies the empty plane). What the plugin's GPU method does with
    /// its hard shadow map (`FinMethod::Convolution`), and what it is tested
    /// against, with the mipmap prefilter.
    pub fn on_depth_map(
        light_space: &LightSpaceScene,
        settings: ConvolutionSettings,
        region: MapRegion,
        depth: &[f32],
    ) -> Self {
        let order = settings.order.clamp(1, 16);
        let channels = 1 + 4 * order as usize;
        let res = region.resolution as usize;
        assert_eq!(depth.len(), res * res, "one depth per texel of the region");
        let settings = ConvolutionSettings { resolution: region.resolution, order, ..settings };
        let frame = light_space.frame;
        let near = depth.iter().copied().filter(|d| d.is_finite()).fold(f32::INFINITY, f32::min);
        let far = light_space.reference_depth * (1.0 + 1e-4);
        let near = if near.is_finite() && near < far { near } else { far * 0.5 };
        let span = depth_span(order);
        // An empty range (L0 at 0) reads 1, not NaN.
        let normalise = |z: f32| ((z - near) / (far - near).max(1e-30)).clamp(0.0, 1.0) * span;
        let mut texels = vec![0.0f32; res * res * channels];
        for (i, &d) in depth.iter().enumerate() {
            // Empty texels hold the far plane: nothing in front of any receiver.
            basis(
                if d.is_finite() { normalise(d) } else { span },
                order,
                &mut texels[i * channels..(i + 1) * channels],
            );
        }
        let mut empty = vec![0.0f32; channels];
        basis(span, order, &mut empty);
        let maps = match settings.prefilter {
            Prefilter::SummedArea => Prefiltered::summed_area(res, channels, &texels),
            Prefilter::Mipmap => Prefiltered::mipmap(res, channels, texels),
        };
        Self {
            settings,
            region,
            maps,
            off_map: OffMap::Empty,
            empty: empty.iter().map(|v| *v as f64).collect(),
            frame,
            near,
            far,
            span,
            shift: step_shift(order),
            ringing_scale: ringing_scale(order),
            extent: light_space.extent,
            reference_depth: light_space.reference_depth,
        }
    }

    /// The same model on a map that is a window onto casters going on past
    /// it (the plugin's sun fitted to its views): a tap off the map reads its
    /// border, not the empty plane.
    pub fn windowed(self) -> Self {
        Self { off_map: OffMap::Border, ..self }
    }

    /// `(f̄, numerator of z_avg)` over the map-space rectangle `q ± half`
    /// (half sides per axis), at normalised receiver depth `d`; `None` when
    /// it misses the map.
    fn filtered(&self, q: Vec2, half: Vec2, d: f32, scratch: &mut [f64]) -> Option<(f64, f64)> {
        let texel = self.region.texel;
        let r = self.region.resolution as f32;
        let centre = (q - self.region.min) / texel;
        let h = (half / texel).max(Vec2::splat(0.5));
        let (lo, hi) = (centre - h, centre + h);
        if !(hi.x > 0.0 && hi.y > 0.0 && lo.x < r && lo.y < r) {
            return None;
        }
        // A mipmap is isotropic: the disk's square takes its side; a
        // rectangle, the square of its area — a departure from Annen et al.
        // §4 (rectangular lights), who filter anisotropically: here a 4 : 1
        // light's short side is blurred ×2 and its long side ×0.5; the
        // summed-area variant filters the exact a × b box.
        let side = match self.frame.aperture {
            Aperture::Disk | Aperture::Sphere { .. } => None,
            Aperture::Rect { .. } => Some(2.0 * (h.x * h.y).sqrt()),
        };
        let bias = self.settings.mip_bias.clamp(0.0, 4.0);
        self.maps.average(lo, hi, side, bias, &self.empty, self.off_map, scratch);
        let m = self.settings.order as usize;
        let d = (d - self.shift) as f64;
        let (mut complement, mut numerator) = (0.5, 0.5 * scratch[0]);
        for k in 0..m {
            let ck = c(k as u32 + 1) as f64;
            let (s, co) = (ck * d).sin_cos();
            complement += 2.0 / ck * (s * scratch[1 + k] - co * scratch[1 + m + k]);
            numerator += 2.0 / ck * (s * scratch[1 + 2 * m + k] - co * scratch[1 + 3 * m + k]);
        }
        Some((complement, numerator))
    }

    /// Visibility of the light from a receiver (light frame), in `[0, 1]`.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let eps = surface_epsilon(receiver.position, self.extent);
        let perspective = self.frame.is_perspective();
        let texel_world = if perspective { self.region.texel * receiver.position.z } else { self.region.texel };
        let p: Vec3 = receiver.position + receiver.normal * (eps + 1.5 * texel_world);
        if !p.is_finite() || (perspective && !(p.z > self.reference_depth * 1e-5)) {
            return 0.0;
        }
        let q = self.frame.map(p);
        let d = ((p.z - self.near) / (self.far - self.near).max(1e-30)).clamp(0.0, 1.0) * self.span;
        let mut scratch = [0.0f64; 1 + 4 * 16];
        // 1. The search rectangle: the cone to the light at the near plane,
        // the light's shape (a rectangle's sides, the disk's square).
        let shape = kernel_shape(self.frame.aperture);
        let search = self.frame.penumbra_half_width(self.near, p.z);
        // 2. The average blocker depth (CSM-Z).
        let Some((complement, numerator)) = self.filtered(q, shape * search, d, &mut scratch) else { return 1.0 };
        let z_avg = if complement > 1e-3 { (numerator / complement).clamp(0.0, d as f64) as f32 } else { d };
        let z_avg_frame = self.near + z_avg / self.span * (self.far - self.near);
        // 3. The penumbra's half-width at that depth; 4. the filtered test.
        let half = self.frame.penumbra_half_width(z_avg_frame.max(self.near), p.z);
        let half = if half.is_finite() { half } else { search };
        let Some((complement, _)) = self.filtered(q, shape * half, d, &mut scratch) else { return 1.0 };
        let s = (self.ringing_scale as f64 * (0.5 - complement) + 0.5).clamp(0.0, 1.0) as f32;
        let s = match self.settings.sharpening {
            Some((a, b)) => s.powf(1.0 + a * (-b * (d - z_avg).max(0.0)).exp()),
            None => s,
        };
        // Radius 0 keeps the point lookup's test.
        if self.frame.size() == 0.0 {
            return if s >= 0.5 { 1.0 } else { 0.0 };
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_suppressed_series_has_no_ringing_and_its_step_narrows_with_the_order() {
        let mut widths = vec![];
        for order in [2, 4, 8, 16] {
            let (shift, alpha) = (step_shift(order), ringing_scale(order));
            assert!((1.1..1.4).contains(&alpha), "order {order}: α = {alpha}");
            // Outside the transition the test is exactly 0 or 1 (Figure 3(d)),
            // over every `d − z` the normalised depths can make.
            let span = depth_span(order);
            let xs: Vec<f32> = (0..=4000).map(|i| (i as f32 / 4000.0 * 2.0 - 1.0) * span - shift).collect();
            let band = xs.iter().filter(|x| {
                let v = suppressed_step(**x, order, alpha);
                v > 0.0 && v < 1.0
            });
            let (lo, hi) = band.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
            assert!(lo >= -shift - 1e-3 && hi <= shift + 1e-3, "order {order}: band [{lo}, {hi}], shift {shift}");
            assert!(suppressed_step(-shift, order, alpha) == 1.0 && suppressed_step(shift, order, alpha) < 1e-6);
            widths.push(hi - lo);
        }
        // Converges to the hard test: the band shrinks about as 1/M.
        for w in widths.windows(2) {
            assert!(w[1] < 0.7 * w[0], "widths {widths:?}");
        }
    }

    #[test]
    fn a_mipmaps_taps_off_the_map_read_empty_texels_not_its_border() {
        // A map of ones in an empty (zero) plane: a box centred on its right
        // border reads half map, half plane — clamping to the border texels
        // would read all ones and spread a caster on the edge outwards.
        let res = 8;
        let maps = Prefiltered::mipmap(res, 1, vec![1.0; res * res]);
        let mut out = [0.0f64];
        maps.average(Vec2::new(7.0, 3.0), Vec2::new(9.0, 5.0), None, 0.0, &[0.0], OffMap::Empty, &mut out);
        assert!((out[0] - 0.5).abs() < 1e-6, "{}", out[0]);
        // A window onto casters that go on reads its border there.
        maps.average(Vec2::new(7.0, 3.0), Vec2::new(9.0, 5.0), None, 0.0, &[0.0], OffMap::Border, &mut out);
        assert!((out[0] - 1.0).abs() < 1e-6, "{}", out[0]);
        // Inside, the same box reads the map alone.
        maps.average(Vec2::new(3.0, 3.0), Vec2::new(5.0, 5.0), None, 0.0, &[0.0], OffMap::Empty, &mut out);
        assert!((out[0] - 1.0).abs() < 1e-6, "{}", out[0]);
    }

    #[test]
    fn the_variance_matched_mip_bias_filters_a_step_closer_to_the_box_than_the_papers_level() {
        // Vertical steps at every offset from the level grid (ones left of
        // x = 32 + k), each filtered by a 16-texel box swept across it: the
        // summed-area table is the exact box, each mip bias a trilinear
        // approximation (exact at the paper's level only where the step
        // lies on a level-4 texel boundary).
        let res = 64;
        let error = |bias: f32| {
            let mut sum = 0.0;
            for k in 0..16 {
                let texels: Vec<f32> = (0..res * res).map(|i| if i % res < 32 + k { 1.0 } else { 0.0 }).collect();
                let exact = Prefiltered::summed_area(res, 1, &texels);
                let mip = Prefiltered::mipmap(res, 1, texels);
                for i in 0..40 {
                    let c = Vec2::new(14.0 + k as f32 + i as f32 * 0.9, 32.0);
                    let (lo, hi) = (c - Vec2::splat(8.0), c + Vec2::splat(8.0));
                    let (mut a, mut b) = ([0.0f64], [0.0f64]);
                    exact.average(lo, hi, None, 0.0, &[0.0], OffMap::Empty, &mut a);
                    mip.average(lo, hi, None, bias, &[0.0], OffMap::Empty, &mut b);
                    sum += (a[0] - b[0]).abs();
                }
            }
            sum / (16.0 * 40.0)
        };
        let (paper, matched) = (error(0.0), error(VARIANCE_MATCHED_MIP_BIAS));
        println!("mean |mip − box|: paper's level {paper:.4}, variance-matched {matched:.4}");
        assert!(matched < 0.8 * paper, "variance-matched {matched} vs paper's level {paper}");
    }

    #[test]
    fn summed_area_averages_are_exact_box_filters() {
        let res = 8;
        let texels: Vec<f32> = (0..res * res).map(|i| ((i * 37) % 11) as f32).collect();
        let maps = Prefiltered::summed_area(res, 1, &texels);
        let mut out = [0.0f64];
        // A fractional rectangle, integrated by fine sampling.
        let (lo, hi) = (Vec2::new(1.3, 2.6), Vec2::new(5.1, 6.9));
        maps.average(lo, hi, None, 0.0, &[0.0], OffMap::Empty, &mut out);
        let n = 400;
        let mut sum = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let u = lo.x + (hi.x - lo.x) * (i as f32 + 0.5) / n as f32;
                let v = lo.y + (hi.y - lo.y) * (j as f32 + 0.5) / n as f32;
                sum += texels[v as usize * res + u as usize] as f64;
            }
        }
        let expected = sum / (n * n) as f64;
        assert!((out[0] - expected).abs() < 0.02, "{} vs {expected}", out[0]);
    }
}
