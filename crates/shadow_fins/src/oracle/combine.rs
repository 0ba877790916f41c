//! One map texel per layer ([`LayerTexel`]: slab depth, inner and outer fin
//! weights), and the per-pixel combination of the layers (DESIGN §3
//! "Per-pixel combination", [`combine_layers`]) both evaluations share.

use crate::{
    fins::{FinSample, FinSide},
    light::LightFrame,
    refine::refine_weight,
};

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
