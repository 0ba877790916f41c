//! The grid of configurations `measure` runs: which methods, with which
//! settings, at which light radius. Settings a method ignores are dropped
//! before deduplication, so no configuration is rendered twice.

use shadow_fins::{
    oracle::Method,
    peers::{PeerMethod, convolution::ConvolutionSettings},
    refine::Falloff,
};

/// What renders a configuration's shadows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Technique {
    /// The plugin, with one of the fin methods.
    Fins(Method),
    /// Bevy's point light with its cube shadow maps (PCF).
    BevyHard,
    /// Bevy's point light with PCSS (`experimental_pbr_pcss`).
    BevyPcss,
    /// The core crate's raster oracle on the CPU (multi-layer fins).
    CpuOracle,
    /// The plugin's coverage method (`FinMethod::Coverage`, 256 light samples).
    Coverage,
    /// The plugin's convolution shadow maps on the GPU
    /// (`FinMethod::Convolution`: order 4, mipmaps, on its hard shadow map).
    Convolution,
    /// The plugin's plateaus on the GPU (`FinMethod::Plateaus`: the texture
    /// on the receiver plane beside its hard shadow map).
    Plateaus,
    /// Another paper's method, on the CPU with the core crate
    /// (`shadow_fins::peers`), at the pixels the GPU shaded.
    Peer(PeerMethod),
}

impl Technique {
    pub const ALL: [Technique; 16] = [
        Technique::Fins(Method::MultiLayer),
        Technique::Fins(Method::SingleLayer),
        Technique::Fins(Method::OuterFins),
        Technique::Fins(Method::Hard),
        Technique::BevyHard,
        Technique::BevyPcss,
        Technique::CpuOracle,
        Technique::Coverage,
        Technique::Convolution,
        Technique::Plateaus,
        Technique::Peer(PeerMethod::SingleSample),
        Technique::Peer(PeerMethod::Plateaus),
        Technique::Peer(PeerMethod::PenumbraWedges),
        Technique::Peer(PeerMethod::WedgeBlending),
        Technique::Peer(PeerMethod::Convolution),
        Technique::Peer(PeerMethod::ConvolutionMipmap),
    ];

    /// The name on the command line, in tables and in plots.
    pub fn name(self) -> &'static str {
        match self {
            Technique::Fins(Method::MultiLayer) => "fins",
            Technique::Fins(Method::SingleLayer) => "single-layer",
            Technique::Fins(Method::OuterFins) => "outer-fins",
            Technique::Fins(Method::Hard) => "hard",
            Technique::BevyHard => "bevy-hard",
            Technique::BevyPcss => "bevy-pcss",
            Technique::CpuOracle => "cpu-oracle",
            Technique::Coverage => "coverage",
            Technique::Convolution => "gpu-convolution",
            Technique::Plateaus => "gpu-plateaus",
            Technique::Peer(p) => p.name(),
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == s)
    }

    /// Whether layers, refinement and falloff mean anything to it.
    fn uses_layers(self) -> bool {
        matches!(self, Technique::Fins(Method::MultiLayer) | Technique::CpuOracle)
    }

    fn uses_fins(self) -> bool {
        matches!(self, Technique::Fins(m) if m != Method::Hard) || self == Technique::CpuOracle
    }

    /// Whether it is drawn by the GPU (and so has a frame time); the others
    /// are timed on the CPU.
    pub fn is_rendered(self) -> bool {
        !matches!(self, Technique::CpuOracle | Technique::Peer(_))
    }
}

/// The coverage method's light samples at the baseline (the plugin's default).
pub const BASE_COVERAGE_SAMPLES: u32 = 256;

/// One configuration, with what its technique ignores set to `None`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    pub technique: Technique,
    /// Layers, clamped to the plugin's 1..=32.
    pub layers: Option<u32>,
    pub refinement: Option<bool>,
    pub falloff: Option<Falloff>,
    /// Light-space map (or Bevy cube face) resolution.
    pub map_resolution: u32,
    /// Light radius, world units.
    pub radius: f32,
    /// The coverage method's light samples per receiver (`None` for the others).
    pub samples: Option<u32>,
    /// The baseline of its technique (it goes into the image strip).
    pub baseline: bool,
}

impl Config {
    fn new(
        technique: Technique,
        layers: u32,
        refinement: bool,
        falloff: Falloff,
        map_resolution: u32,
        radius: f32,
    ) -> Self {
        Self {
            technique,
            layers: technique.uses_layers().then_some(layers.clamp(1, 32)),
            refinement: technique.uses_fins().then_some(refinement),
            falloff: technique.uses_fins().then_some(falloff),
            // The peers keep their own resolutions: one configuration each, whatever the sweep.
            map_resolution: match technique {
                Technique::Peer(_) => ConvolutionSettings::default().resolution,
                _ => map_resolution.clamp(16, 4096),
            },
            radius,
            samples: (technique == Technique::Coverage).then_some(BASE_COVERAGE_SAMPLES),
            baseline: false,
        }
    }

    /// The coverage method with `samples` light samples (clamped to the plugin's 1..=256).
    fn with_samples(self, samples: u32) -> Self {
        Self { samples: self.samples.map(|_| samples.clamp(1, 256)), ..self }
    }

    /// A short label: the technique and what differs from `base`.
    pub fn label(&self) -> String {
        let mut s = self.technique.name().to_string();
        if let Some(l) = self.layers {
            s += &format!(" {l}L");
        }
        if self.refinement == Some(false) {
            s += " no-refine";
        }
        if let Some(f) = self.falloff.filter(|f| *f != Falloff::DiskSegment) {
            s += &format!(" {}", f.name());
        }
        if let Some(n) = self.samples.filter(|n| *n != BASE_COVERAGE_SAMPLES) {
            s += &format!(" {n}s");
        }
        s
    }

    fn same_as(&self, other: &Config) -> bool {
        Config { baseline: false, ..*self } == Config { baseline: false, ..*other }
    }
}

/// The axes of the grid.
#[derive(Debug, Clone)]
pub struct Axes {
    pub techniques: Vec<Technique>,
    pub layers: Vec<u32>,
    pub refinement: Vec<bool>,
    pub falloffs: Vec<Falloff>,
    pub map_resolutions: Vec<u32>,
    pub radii: Vec<f32>,
    /// Light samples swept for the coverage method.
    pub coverage_samples: Vec<u32>,
    /// The baseline every one-at-a-time sweep starts from.
    pub base_layers: u32,
    pub base_map_resolution: u32,
    pub base_radius: f32,
}

impl Axes {
    /// One factor at a time around the baseline (16 layers, refinement on,
    /// the disk-segment falloff, the base map resolution and radius): every
    /// technique at the baseline, then each axis swept alone — layers,
    /// refinement and falloff for multi-layer fins, map resolution for
    /// multi-layer fins and Bevy's two, radius for every technique.
    /// `full`: the whole Cartesian product instead.
    pub fn configs(&self, full: bool) -> Vec<Config> {
        let mut out: Vec<Config> = vec![];
        let mut push = |c: Config| {
            if let Some(existing) = out.iter_mut().find(|o| o.same_as(&c)) {
                existing.baseline |= c.baseline;
            } else {
                out.push(c);
            }
        };
        let (bl, br, bm) = (self.base_layers, self.base_radius, self.base_map_resolution);
        let base_falloff = Falloff::DiskSegment;
        for &t in &self.techniques {
            push(Config { baseline: true, ..Config::new(t, bl, true, base_falloff, bm, br) });
        }
        if full {
            for &t in &self.techniques {
                for &r in &self.radii {
                    for &m in &self.map_resolutions {
                        for &l in &self.layers {
                            for &refine in &self.refinement {
                                for &f in &self.falloffs {
                                    for &n in &self.coverage_samples {
                                        push(Config::new(t, l, refine, f, m, r).with_samples(n));
                                    }
                                }
                            }
                        }
                    }
                }
            }
            return out;
        }
        let fins = Technique::Fins(Method::MultiLayer);
        if self.techniques.contains(&fins) {
            for &l in &self.layers {
                push(Config::new(fins, l, true, base_falloff, bm, br));
            }
            for &refine in &self.refinement {
                push(Config::new(fins, bl, refine, base_falloff, bm, br));
            }
            for &f in &self.falloffs {
                push(Config::new(fins, bl, true, f, bm, br));
            }
        }
        for &t in self.techniques.iter().filter(|t| {
            matches!(t, Technique::BevyHard | Technique::BevyPcss | Technique::Coverage | Technique::Convolution)
                || **t == fins
        }) {
            for &m in &self.map_resolutions {
                push(Config::new(t, bl, true, base_falloff, m, br));
            }
        }
        if self.techniques.contains(&Technique::Coverage) {
            for &n in &self.coverage_samples {
                push(Config::new(Technique::Coverage, bl, true, base_falloff, bm, br).with_samples(n));
            }
        }
        for &t in &self.techniques {
            for &r in &self.radii {
                push(Config::new(t, bl, true, base_falloff, bm, r));
            }
        }
        out
    }
}

/// Parses a comma-separated list with `parse`, naming the flag in errors.
pub fn parse_list<T>(flag: &str, s: &str, parse: impl Fn(&str) -> Option<T>) -> Result<Vec<T>, String> {
    s.split(',')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .map(|p| parse(p).ok_or_else(|| format!("--{flag}: cannot read '{p}'")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axes() -> Axes {
        Axes {
            techniques: Technique::ALL.to_vec(),
            layers: vec![1, 2, 4, 8, 16, 32, 64],
            refinement: vec![true, false],
            falloffs: Falloff::ALL.to_vec(),
            map_resolutions: vec![256, 512, 1024, 2048],
            radii: vec![0.5],
            coverage_samples: vec![16, 256, 300],
            base_layers: 16,
            base_map_resolution: 1024,
            base_radius: 0.5,
        }
    }

    #[test]
    fn the_sweep_renders_no_configuration_twice() {
        let configs = axes().configs(false);
        for (i, a) in configs.iter().enumerate() {
            for b in &configs[i + 1..] {
                assert!(!a.same_as(b), "{a:?} twice");
            }
        }
        // 64 layers clamp to 32, already in the list.
        assert!(configs.iter().all(|c| c.layers.is_none_or(|l| l <= 32)));
    }

    #[test]
    fn every_technique_has_exactly_one_baseline() {
        let configs = axes().configs(false);
        for t in Technique::ALL {
            let n = configs.iter().filter(|c| c.technique == t && c.baseline).count();
            assert_eq!(n, 1, "{}", t.name());
        }
    }

    #[test]
    fn the_sweep_covers_each_axis_for_multi_layer_fins() {
        let configs = axes().configs(false);
        let fins: Vec<&Config> =
            configs.iter().filter(|c| c.technique == Technique::Fins(Method::MultiLayer)).collect();
        // 6 layer counts + no-refine + 2 other falloffs + 3 other map sizes.
        assert_eq!(fins.len(), 6 + 1 + 2 + 3);
        let pcss = configs.iter().filter(|c| c.technique == Technique::BevyPcss).count();
        assert_eq!(pcss, 4, "PCSS at each map resolution");
        // Settings a technique ignores are not varied for it.
        assert_eq!(configs.iter().filter(|c| c.technique == Technique::Fins(Method::Hard)).count(), 1);
        assert!(configs.iter().filter(|c| c.technique != Technique::Coverage).all(|c| c.samples.is_none()));
    }

    #[test]
    fn coverage_is_swept_over_its_sample_counts_and_labelled_by_them() {
        let configs = axes().configs(false);
        let coverage: Vec<&Config> = configs.iter().filter(|c| c.technique == Technique::Coverage).collect();
        // 16 and 256 samples (300 clamps to 256, the baseline), + 3 other map sizes.
        let counts: Vec<Option<u32>> = coverage.iter().map(|c| c.samples).collect();
        assert_eq!(counts.iter().filter(|n| **n == Some(16)).count(), 1);
        assert_eq!(coverage.len(), 2 + 3);
        assert!(coverage.iter().all(|c| c.samples.is_some_and(|n| n == 16 || n == 256)));
        let labels: Vec<String> = coverage.iter().map(|c| c.label()).collect();
        assert!(labels.contains(&"coverage 16s".to_string()) && labels.contains(&"coverage".to_string()), "{labels:?}");
    }

    #[test]
    fn the_full_grid_is_the_cartesian_product_after_deduplication() {
        let mut a = axes();
        a.radii = vec![0.25, 0.5];
        let configs = a.configs(true);
        let fins = configs.iter().filter(|c| c.technique == Technique::Fins(Method::MultiLayer)).count();
        assert_eq!(fins, 2 * 4 * 6 * 2 * 3);
        let bevy_hard = configs.iter().filter(|c| c.technique == Technique::BevyHard).count();
        assert_eq!(bevy_hard, 2 * 4);
    }

    #[test]
    fn lists_parse_and_bad_items_name_the_flag() {
        assert_eq!(parse_list("layers", "1, 2,4", |s| s.parse::<u32>().ok()), Ok(vec![1, 2, 4]));
        let e = parse_list("layers", "1,x", |s| s.parse::<u32>().ok()).unwrap_err();
        assert!(e.contains("--layers") && e.contains("'x'"), "{e}");
    }
}
