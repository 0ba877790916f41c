//! An alpha mask as a material samples it: the texture's alphas (box-filtered
//! down past [`MAX_MASK_SIDE`]), its cutoff, its wrap modes and its filter.

use glam::Vec2;

/// The largest UV coordinate taken (a texture repeated a million times).
pub const MAX_UV: f32 = 1e6;

/// The largest mask side modelled; larger masks are box-filtered down.
pub const MAX_MASK_SIDE: u32 = 256;

/// Why an alpha mask cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CutoutError {
    #[error("alpha mask of {width} x {height} texels holds {len} values: give width x height alphas")]
    Size { width: u32, height: u32, len: usize },
    #[error("alpha cutoff {0} is not a number: use a cutoff in [0, 1] (glTF's default is 0.5)")]
    Cutoff(f32),
    #[error("{uvs} UVs for {vertices} vertices: give one UV per mesh vertex")]
    Uvs { uvs: usize, vertices: usize },
    #[error("a UV is not finite or beyond ±{MAX_UV}: {0}")]
    BadUv(Vec2),
}

/// How a texture coordinate outside `[0, 1]` reads the texture (glTF's
/// sampler wrap modes, Bevy's `ImageAddressMode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Address {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

impl Address {
    /// Texel index `i` of a row or column of `n` texels read this way.
    #[inline]
    pub(super) fn texel(self, i: i64, n: u32) -> u32 {
        let n = n as i64;
        (match self {
            Address::Repeat => i.rem_euclid(n),
            Address::MirroredRepeat => {
                let k = i.rem_euclid(2 * n);
                if k < n { k } else { 2 * n - 1 - k }
            }
            Address::ClampToEdge => i.clamp(0, n - 1),
        }) as u32
    }
}

/// How the texture is read between texels (Bevy's sampler's magnification
/// filter, glTF's `magFilter`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Filter {
    /// Bilinear between texel centres (Bevy's default).
    #[default]
    Linear,
    /// The texel a UV falls in: a pixel-art mask's square texels.
    Nearest,
}

/// Ties go to opaque (Bevy's `alpha < cutoff → discard`): an alpha within
/// this of the cutoff counts as reaching it, everywhere alike, so that a
/// bilinear iso-line never runs exactly along a texel border (where a
/// texture's 0-to-255 steps interpolate to 0.5, glTF's default cutoff). A
/// nearest-filtered mask's outline runs along texel borders by design.
const TIE: f32 = 1.0 / 8192.0;

/// A material's alpha, texel by texel, and its cutoff.
#[derive(Debug, Clone, PartialEq)]
pub struct AlphaMask {
    pub(super) width: u32,
    pub(super) height: u32,
    /// Alpha per texel, row-major from the top row (`v = 0`), 0..=255.
    pub(super) alpha: Vec<u8>,
    /// The alpha below which the caster is a hole, in `[0, 1]`.
    pub(super) cutoff: f32,
    /// The material's base alpha, which multiplies every texel's.
    pub(super) base_alpha: f32,
    /// How `u` and `v` outside `[0, 1]` read the texture.
    pub(super) address: [Address; 2],
    /// How the texture is read between texels.
    pub(super) filter: Filter,
}

impl AlphaMask {
    /// A mask of `width × height` alphas (row-major, first row at `v = 0`,
    /// as glTF and Bevy address textures). `base_alpha` multiplies every
    /// texel (the material's base colour alpha; not finite counts as 1); a
    /// cutoff outside `[0, 1]` is clamped, NaN is an error. An empty mask is
    /// the texture-less material: its base alpha alone. Larger than
    /// [`MAX_MASK_SIDE`] on a side, the mask is box-filtered down.
    pub fn new(width: u32, height: u32, alpha: Vec<u8>, base_alpha: f32, cutoff: f32) -> Result<Self, CutoutError> {
        if alpha.len() as u64 != width as u64 * height as u64 {
            return Err(CutoutError::Size { width, height, len: alpha.len() });
        }
        if cutoff.is_nan() {
            return Err(CutoutError::Cutoff(cutoff));
        }
        let base_alpha = if base_alpha.is_finite() { base_alpha.clamp(0.0, 1.0) } else { 1.0 };
        let (alpha, width, height) = if alpha.is_empty() { (vec![255], 1, 1) } else { (alpha, width, height) };
        let (alpha, width, height) = box_filter(alpha, width, height);
        Ok(Self {
            width,
            height,
            alpha,
            cutoff: cutoff.clamp(0.0, 1.0),
            base_alpha,
            address: [Address::Repeat; 2],
            filter: Filter::Linear,
        })
    }

    pub fn base_alpha(&self) -> f32 {
        self.base_alpha
    }

    /// True when every texel passes the cutoff: the material casts solid.
    pub fn is_solid(&self) -> bool {
        let t = self.threshold();
        self.alpha.iter().all(|&a| a as f32 / 255.0 >= t)
    }

    /// The mask read with these wrap modes for `u` and `v` (default: repeat).
    pub fn with_address(mut self, address: [Address; 2]) -> Self {
        self.address = address;
        self
    }

    pub fn address(&self) -> [Address; 2] {
        self.address
    }

    /// The mask read with this filter (default: linear). A mask box-filtered
    /// down from a larger texture ([`MAX_MASK_SIDE`]) is read nearest from
    /// the filtered texels.
    pub fn with_filter(mut self, filter: Filter) -> Self {
        self.filter = filter;
        self
    }

    pub fn filter(&self) -> Filter {
        self.filter
    }

    /// How close to a face's edge an iso-line counts as on it, in UV: a
    /// thousandth of a texel (the iso-lines [`TIE`] moves off a texel
    /// border are a tenth of that from it).
    #[inline]
    pub(super) fn hair(&self) -> f32 {
        1e-3 / self.width.max(self.height) as f32 + 1e-6
    }

    /// What the texture's own alpha (before the base alpha) is compared
    /// with: `alpha · base ≥ cutoff` as `alpha ≥ cutoff / base`, less
    /// [`TIE`] (no rounding of `alpha · base` into 8 bits, which Bevy does
    /// not do either). A base of 0 passes nothing but a cutoff of 0.
    #[inline]
    pub fn threshold(&self) -> f32 {
        if self.base_alpha > 0.0 {
            self.cutoff / self.base_alpha - TIE
        } else if self.cutoff <= 0.0 {
            -TIE
        } else {
            f32::INFINITY
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texture's alphas, row-major, before the base alpha (what a GPU
    /// copy uploads, with [`AlphaMask::threshold`]).
    pub fn alpha(&self) -> &[u8] {
        &self.alpha
    }

    pub fn cutoff(&self) -> f32 {
        self.cutoff
    }

    /// The alpha at texel `(x, y)` of the texture read by its wrap modes, in `[0, 1]`.
    #[inline]
    pub(super) fn texel(&self, x: i64, y: i64) -> f32 {
        let (x, y) = (self.address[0].texel(x, self.width), self.address[1].texel(y, self.height));
        self.alpha[(y * self.width + x) as usize] as f32 * (1.0 / 255.0)
    }

    /// The texture's alpha at `uv` (before the base alpha): bilinear between
    /// texel centres, or the texel's own under [`Filter::Nearest`], read by
    /// the wrap modes.
    #[inline]
    pub fn alpha_at(&self, uv: Vec2) -> f32 {
        if self.filter == Filter::Nearest {
            let (i, j) = self.texel_of(uv);
            return self.texel(i, j);
        }
        let x = uv.x as f64 * self.width as f64 - 0.5;
        let y = uv.y as f64 * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (i, j) = (x0 as i64, y0 as i64);
        let top = self.texel(i, j) * (1.0 - fx) + self.texel(i + 1, j) * fx;
        let bottom = self.texel(i, j + 1) * (1.0 - fx) + self.texel(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The texel `uv` falls in (before wrapping): texel `i` spans
    /// `[i/w, (i+1)/w)`.
    #[inline]
    pub(super) fn texel_of(&self, uv: Vec2) -> (i64, i64) {
        ((uv.x as f64 * self.width as f64).floor() as i64, (uv.y as f64 * self.height as f64).floor() as i64)
    }

    /// True when the caster blocks light at `uv`: the alpha there is at
    /// least the cutoff. A non-finite UV blocks.
    #[inline]
    pub fn opaque(&self, uv: Vec2) -> bool {
        !uv.is_finite() || self.alpha_at(uv) >= self.threshold()
    }
}

/// `alpha` box-filtered down to at most [`MAX_MASK_SIDE`] a side, each new
/// texel the mean of the source texels under it (source ranges split in
/// proportion, so the filtered mask stays aligned with the texture).
fn box_filter(alpha: Vec<u8>, width: u32, height: u32) -> (Vec<u8>, u32, u32) {
    if width <= MAX_MASK_SIDE && height <= MAX_MASK_SIDE {
        return (alpha, width, height);
    }
    let factor = width.max(height).div_ceil(MAX_MASK_SIDE);
    let (w, h) = (width.div_ceil(factor), height.div_ceil(factor));
    let span = |i: u32, n: u32, to: u32| {
        let (a, b) = ((i as u64 * n as u64 / to as u64) as u32, ((i as u64 + 1) * n as u64 / to as u64) as u32);
        a..b.max(a + 1).min(n)
    };
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (mut sum, mut n) = (0u32, 0u32);
            for sy in span(y, height, h) {
                for sx in span(x, width, w) {
                    sum += alpha[(sy * width + sx) as usize] as u32;
                    n += 1;
                }
            }
            out.push((sum as f32 / n.max(1) as f32).round() as u8);
        }
    }
    (out, w, h)
}
