//! Refinement of fin weights to the real receiver (eq. 5) and the falloff curves.

use crate::light::LightFrame;

/// Refines a fin weight `s0`, built for the reference plane `L0`, to a receiver
/// at depth `L_r` behind a fin at depth `L_b` (Cai et al. eq. 5):
///
/// `s_r = 1/2 + (B0/Br)(s0 − 1/2)`, clamped to `[0, 1/2]`,
///
/// with `B0/Br` the ratio of the fin's penumbra half-width at `L0` to the one at
/// `L_r`. As `Br → 0` (receiver in contact with the edge) the ratio is capped at
/// 1e12, so the weight collapses to a hard edge (`0`, or `1/2` exactly on the
/// edge) with no NaN or infinity. Returns `None` when the fin is not in front of
/// the receiver (`L_b >= L_r`): it cannot shadow it.
#[inline]
pub fn refine_weight(
    frame: &LightFrame,
    s0: f32,
    fin_depth: f32,
    receiver_depth: f32,
    reference_depth: f32,
) -> Option<f32> {
    if !(fin_depth < receiver_depth) {
        return None;
    }
    let b0 = frame.penumbra_half_width(fin_depth, reference_depth);
    let br = frame.penumbra_half_width(fin_depth, receiver_depth);
    let ratio = if br > b0 * 1e-12 { b0 / br } else { 1e12 };
    Some((0.5 + ratio * (s0 - 0.5)).clamp(0.0, 0.5))
}

/// How the combined illuminance `I ∈ [0, 1]` becomes visibility `V`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Falloff {
    /// `V = I`.
    Linear,
    /// `V = 3I² − 2I³` (Parker et al.; Haines' plateaus).
    Bernstein,
    /// `V = 1/2 + (x√(1 − x²) + asin x)/π`, `x = 2I − 1`: the visible fraction of a
    /// disk cut by a straight line at offset `x·R`, so a straight edge is exact.
    #[default]
    DiskSegment,
}

impl Falloff {
    pub const ALL: [Falloff; 3] = [Falloff::Linear, Falloff::Bernstein, Falloff::DiskSegment];

    /// Applies the curve; the input is clamped to `[0, 1]` and NaN maps to 0.
    #[inline]
    pub fn apply(self, illuminance: f32) -> f32 {
        let i = if illuminance > 0.0 { illuminance.min(1.0) } else { 0.0 };
        match self {
            Falloff::Linear => i,
            Falloff::Bernstein => i * i * (3.0 - 2.0 * i),
            Falloff::DiskSegment => {
                let x = 2.0 * i - 1.0;
                (0.5 + (x * (1.0 - x * x).max(0.0).sqrt() + x.asin()) / std::f32::consts::PI).clamp(0.0, 1.0)
            }
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Falloff::Linear => "linear",
            Falloff::Bernstein => "bernstein",
            Falloff::DiskSegment => "disk-segment",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::DiskLight;
    use glam::Vec3;

    fn frame(r: f32) -> LightFrame {
        LightFrame::disk(&DiskLight::new(Vec3::ZERO, Vec3::Z, r).unwrap())
    }

    #[test]
    fn falloffs_are_monotone_with_fixed_ends_and_midpoint() {
        for f in Falloff::ALL {
            assert_eq!(f.apply(0.0), 0.0);
            assert!((f.apply(1.0) - 1.0).abs() < 1e-6);
            assert!((f.apply(0.5) - 0.5).abs() < 1e-6, "{f:?}");
            assert_eq!(f.apply(f32::NAN), 0.0);
            let mut prev = 0.0;
            for k in 0..=100 {
                let v = f.apply(k as f32 / 100.0);
                assert!(v >= prev - 1e-6, "{f:?} not monotone");
                prev = v;
            }
        }
    }

    #[test]
    fn refinement_on_the_reference_plane_is_identity() {
        let f = frame(0.7);
        for s0 in [0.0, 0.1, 0.25, 0.5] {
            let r = refine_weight(&f, s0, 2.0, 5.0, 5.0).unwrap();
            assert!((r - s0).abs() < 1e-6);
        }
    }

    #[test]
    fn refinement_collapses_to_hard_edge_at_contact_without_nan() {
        let f = frame(1.0);
        for gap in [1e-3, 1e-6, 1e-9, 0.0] {
            let lr = 2.0 + gap;
            match refine_weight(&f, 0.3, 2.0, lr, 5.0) {
                Some(s) => assert!(s.is_finite() && (0.0..=0.5).contains(&s)),
                None => assert!(lr <= 2.0, "only a receiver not behind the fin is skipped"),
            }
        }
        assert_eq!(refine_weight(&f, 0.3, 2.0, 2.0 + 1e-6, 5.0), Some(0.0));
        assert_eq!(refine_weight(&f, 0.5, 2.0, 2.0 + 1e-6, 5.0), Some(0.5));
    }

    #[test]
    fn refinement_rescales_t_to_the_receiver_width() {
        // t0 = 0.5 on the reference plane; a nearer receiver has a narrower
        // penumbra, so the same map point is further out: t_r = t0 · w0/wr.
        let f = frame(1.0);
        let (lb, lr, l0) = (1.0, 2.0, 4.0);
        let w0 = f.penumbra_half_width(lb, l0);
        let wr = f.penumbra_half_width(lb, lr);
        let s = refine_weight(&f, 0.25, lb, lr, l0).unwrap();
        let expected = (0.5 * (1.0 - 0.5 * w0 / wr)).clamp(0.0, 0.5);
        assert!((s - expected).abs() < 1e-6);
    }
}
