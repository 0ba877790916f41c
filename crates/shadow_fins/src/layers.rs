//! Layer assignment (Cai et al. §4.1): `S` equal sub-layers over the depth range
//! of the silhouette edges, a histogram of edge midpoints, merged into at most `N`
//! layers that each hold about the same number of edges.
//!
//! The cumulative histogram is cut at the `k/N` quantiles; cuts that coincide, or
//! that would leave nothing behind them, are dropped, so every layer holds at
//! least one silhouette edge and empty layers cost nothing. The first layer
//! reaches up to the light and the last one down to infinity, so every depth has
//! a layer.

/// Depth planes that split light space into layers.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LayerPlan {
    /// Strictly increasing plane depths; layer `j` is `[planes[j-1], planes[j])`.
    planes: Vec<f32>,
}

impl LayerPlan {
    /// One layer holding everything (the single-layered algorithm, §3).
    pub fn single() -> Self {
        Self { planes: Vec::new() }
    }

    /// Histogram `edge_depths` into `sub_layers` bins and merge into at most
    /// `layers` layers at the quantiles. Both counts are clamped to at least 1.
    pub fn from_edge_depths(edge_depths: &[f32], sub_layers: u32, layers: u32) -> Self {
        let (sub_layers, layers) = (sub_layers.max(1) as usize, layers.max(1) as usize);
        let finite = edge_depths.iter().copied().filter(|d| d.is_finite());
        let (lo, hi) = finite.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), d| (lo.min(d), hi.max(d)));
        if layers == 1 || !(hi > lo) {
            return Self::single();
        }
        let step = (hi - lo) / sub_layers as f32;
        let mut histogram = vec![0u32; sub_layers];
        let mut total = 0u64;
        for &d in edge_depths.iter().filter(|d| d.is_finite()) {
            histogram[sub_layer_of(d, lo, step, sub_layers)] += 1;
            total += 1;
        }
        let mut planes = Vec::with_capacity(layers - 1);
        let mut cumulative = 0u64;
        let mut next_cut = 1usize;
        for (i, &count) in histogram.iter().enumerate() {
            cumulative += count as u64;
            // Cut after sub-layer i when it reaches the next quantile(s).
            let mut reached = false;
            while next_cut < layers && cumulative * layers as u64 >= next_cut as u64 * total {
                next_cut += 1;
                reached = true;
            }
            if reached && cumulative < total && i + 1 < sub_layers {
                planes.push(lo + step * (i + 1) as f32);
            }
        }
        planes.dedup();
        Self { planes }
    }

    /// Number of layers (at least 1).
    pub fn len(&self) -> usize {
        self.planes.len() + 1
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// The layer a depth falls in.
    #[inline]
    pub fn layer_of(&self, depth: f32) -> usize {
        self.planes.partition_point(|&p| p <= depth)
    }

    /// Depth interval `[near, far)` of layer `j` (infinite at the two ends).
    pub fn slab(&self, j: usize) -> (f32, f32) {
        let near = if j == 0 { f32::NEG_INFINITY } else { self.planes[j - 1] };
        let far = self.planes.get(j).copied().unwrap_or(f32::INFINITY);
        (near, far)
    }

    /// The splitting planes.
    pub fn planes(&self) -> &[f32] {
        &self.planes
    }
}

#[inline]
fn sub_layer_of(depth: f32, lo: f32, step: f32, sub_layers: usize) -> usize {
    (((depth - lo) / step) as usize).min(sub_layers - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_counts_per_layer_for_uniform_depths() {
        let depths: Vec<f32> = (0..1600).map(|i| 1.0 + i as f32 / 1600.0).collect();
        let plan = LayerPlan::from_edge_depths(&depths, 1024, 16);
        assert_eq!(plan.len(), 16);
        let mut counts = vec![0; plan.len()];
        for &d in &depths {
            counts[plan.layer_of(d)] += 1;
        }
        for c in counts {
            assert!((95..=105).contains(&c), "layer holds {c} edges, expected ~100");
        }
    }

    #[test]
    fn empty_layers_are_dropped() {
        // Two clusters: at most two non-empty layers whatever N is.
        let depths = [1.0, 1.0, 1.0, 5.0, 5.0];
        let plan = LayerPlan::from_edge_depths(&depths, 1024, 16);
        assert_eq!(plan.len(), 2);
        assert_eq!(plan.layer_of(1.0), 0);
        assert_eq!(plan.layer_of(5.0), 1);
        for j in 0..plan.len() {
            assert!(depths.iter().any(|&d| plan.layer_of(d) == j), "layer {j} is empty");
        }
    }

    #[test]
    fn one_sub_layer_or_one_depth_gives_one_layer() {
        assert_eq!(LayerPlan::from_edge_depths(&[2.0; 10], 1024, 16).len(), 1);
        assert_eq!(LayerPlan::from_edge_depths(&[1.0, 2.0, 3.0], 1, 16).len(), 1);
        assert_eq!(LayerPlan::from_edge_depths(&[], 1024, 16).len(), 1);
        assert_eq!(LayerPlan::from_edge_depths(&[1.0, 2.0], 1024, 0).len(), 1);
    }

    #[test]
    fn every_depth_has_a_layer() {
        let plan = LayerPlan::from_edge_depths(&[1.0, 2.0, 3.0, 4.0], 8, 4);
        assert_eq!(plan.layer_of(f32::NEG_INFINITY), 0);
        assert_eq!(plan.layer_of(-5.0), 0);
        assert_eq!(plan.layer_of(1e9), plan.len() - 1);
        let (n, f) = plan.slab(0);
        assert!(n.is_infinite() && f.is_finite());
    }
}
