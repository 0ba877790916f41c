//! Error against ground truth (DESIGN §4), over the shadowed region only: the
//! pixels where the reference or the method is below 0.999, so a big lit floor
//! cannot hide a bad penumbra.

/// Visibility below which a pixel counts as shadowed.
pub const SHADOW_THRESHOLD: f32 = 0.999;

/// Error of a method against the reference over the shadowed region.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorMetrics {
    /// Pixels in the shadowed region.
    pub count: usize,
    pub mae: f32,
    pub rmse: f32,
    /// 99th percentile of the absolute error.
    pub p99: f32,
    /// Share of the region where the method says ≤ 0.02 and the reference ≥ 0.10.
    pub umbra_over: f32,
    /// Share where the method says ≥ 0.10 and the reference ≤ 0.02 (light leaks).
    pub leak: f32,
    /// Method values that were NaN or infinite (counted as error 1).
    pub non_finite: usize,
}

impl ErrorMetrics {
    /// Compares `method` with `reference`, pixel for pixel.
    ///
    /// # Panics
    /// When the slices differ in length (a programming error, not user input).
    pub fn compute(method: &[f32], reference: &[f32]) -> Self {
        assert_eq!(method.len(), reference.len(), "method and reference must cover the same pixels");
        let mut errors = Vec::new();
        let (mut over, mut leak, mut non_finite) = (0usize, 0usize, 0usize);
        for (&m, &r) in method.iter().zip(reference) {
            if !m.is_finite() {
                non_finite += 1;
                errors.push(1.0f32);
                continue;
            }
            if !(m < SHADOW_THRESHOLD || r < SHADOW_THRESHOLD) {
                continue;
            }
            errors.push((m - r).abs());
            if m <= 0.02 && r >= 0.10 {
                over += 1;
            }
            if m >= 0.10 && r <= 0.02 {
                leak += 1;
            }
        }
        let count = errors.len();
        if count == 0 {
            return Self::default();
        }
        let n = count as f64;
        let mae = errors.iter().map(|&e| e as f64).sum::<f64>() / n;
        let rmse = (errors.iter().map(|&e| (e as f64).powi(2)).sum::<f64>() / n).sqrt();
        errors.sort_unstable_by(f32::total_cmp);
        let p99 = errors[((count as f64 * 0.99).ceil() as usize).clamp(1, count) - 1];
        Self {
            count,
            mae: mae as f32,
            rmse: rmse as f32,
            p99,
            umbra_over: over as f32 / count as f32,
            leak: leak as f32 / count as f32,
            non_finite,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lit_pixels_are_excluded_and_errors_are_exact() {
        let reference = [1.0, 1.0, 0.5, 0.0, 0.2];
        let method = [1.0, 1.0, 0.6, 0.0, 0.0];
        let m = ErrorMetrics::compute(&method, &reference);
        assert_eq!(m.count, 3);
        assert!((m.mae - 0.3 / 3.0).abs() < 1e-6);
        assert!((m.rmse - ((0.01 + 0.04) / 3.0f32).sqrt()).abs() < 1e-6);
        assert!((m.p99 - 0.2).abs() < 1e-6);
        assert!((m.umbra_over - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(m.leak, 0.0);
    }

    #[test]
    fn leaks_and_nan_are_counted() {
        let m = ErrorMetrics::compute(&[0.5, f32::NAN], &[0.0, 0.0]);
        assert_eq!(m.non_finite, 1);
        assert_eq!(m.count, 2);
        assert!((m.leak - 0.5).abs() < 1e-6);
    }

    #[test]
    fn all_lit_gives_zero_count() {
        assert_eq!(ErrorMetrics::compute(&[1.0; 4], &[1.0; 4]).count, 0);
    }
}
