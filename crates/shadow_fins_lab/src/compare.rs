//! Side-by-side comparison of methods against the ground truth on one view.

use shadow_fins::{
    coverage::CoverageSettings,
    metrics::ErrorMetrics,
    oracle::{FinSettings, Method, Overlap, Receiver},
    peers::PeerMethod,
    scene::LightSpaceScene,
};

use crate::{
    eval::{Evaluation, camera_receivers, evaluate},
    setup::{Loaded, Measured},
};

/// One configuration to measure.
#[derive(Debug, Clone)]
pub struct Config {
    pub label: String,
    pub measured: Measured,
    pub settings: FinSettings,
}

impl Config {
    pub fn new(method: Method, settings: FinSettings) -> Self {
        let label = match method {
            Method::MultiLayer => format!(
                "fins {}L{}{}",
                settings.layers,
                if settings.overlap == Overlap::MinMax { " paper" } else { "" },
                if settings.refinement { "" } else { " no-refine" }
            ),
            m => m.name().to_string(),
        };
        Self { label, measured: Measured::Method(method), settings }
    }

    /// The coverage method with `samples` light samples.
    pub fn coverage(samples: u32) -> Self {
        Self {
            label: format!("coverage {samples}"),
            measured: Measured::Coverage(CoverageSettings { samples, ..Default::default() }),
            settings: FinSettings::default(),
        }
    }

    /// Another paper's method, labelled by its lab name.
    pub fn peer(method: PeerMethod) -> Self {
        Self { label: method.name().to_string(), measured: Measured::Peer(method), settings: FinSettings::default() }
    }

    pub fn labelled(mut self, label: impl Into<String>) -> Self {
        self.label = label.into();
        self
    }
}

/// The methods the paper compares, with `base` settings for the fin ones.
/// The paper's own combination rule is used for its methods (hard, outer fins,
/// single layer, and the paper's 16 layers); the last row is ours.
pub fn standard_configs(base: FinSettings, coverage_samples: u32) -> Vec<Config> {
    let paper = FinSettings { overlap: Overlap::MinMax, ..base };
    vec![
        Config::new(Method::Hard, paper),
        Config::new(Method::OuterFins, paper),
        Config::new(Method::SingleLayer, paper),
        Config::new(Method::MultiLayer, FinSettings { refinement: false, ..paper }),
        Config::new(Method::MultiLayer, paper),
        Config::new(Method::MultiLayer, base),
        Config::coverage(coverage_samples),
    ]
    .into_iter()
    .chain(PeerMethod::ALL.map(Config::peer))
    .collect()
}

/// A measured configuration.
pub struct Row {
    pub config: Config,
    pub evaluation: Evaluation,
    pub metrics: ErrorMetrics,
}

/// Everything measured on one view.
pub struct Comparison {
    pub width: u32,
    pub height: u32,
    /// Per pixel: the receiver seen, if any.
    pub receivers: Vec<Option<Receiver>>,
    /// Per hit receiver: does the light's centre face it (only those are scored)?
    pub lit_side: Vec<bool>,
    pub reference: Evaluation,
    pub rows: Vec<Row>,
}

impl Comparison {
    /// Per-pixel values of evaluation values over hit pixels: `None` for the
    /// background, `Some(None)` for surfaces facing away from the light.
    pub fn pixels(&self, values: &[f32]) -> Vec<Option<Option<f32>>> {
        let mut it = values.iter().zip(&self.lit_side);
        self.receivers.iter().map(|r| r.and_then(|_| it.next().map(|(v, lit)| lit.then_some(*v)))).collect()
    }
}

/// Renders the view once per configuration and once for the ground truth.
pub fn compare(
    loaded: &Loaded,
    width: u32,
    height: u32,
    configs: &[Config],
    map_resolution: Option<u32>,
    samples: u32,
) -> Comparison {
    let ls = LightSpaceScene::new(&loaded.scene, loaded.light);
    let receivers = camera_receivers(&loaded.camera, width, height, &ls);
    let hits: Vec<Receiver> = receivers.iter().flatten().copied().collect();
    let reference = evaluate(&loaded.scene, &ls, Measured::GroundTruth, FinSettings::default(), None, samples, &hits);
    let lit_side: Vec<bool> = hits.iter().map(|r| r.faces_light(&ls.frame)).collect();
    let scored = |values: &[f32]| -> Vec<f32> {
        values.iter().zip(&lit_side).filter(|(_, lit)| **lit).map(|(v, _)| *v).collect()
    };
    let reference_scored = scored(&reference.values);
    let rows = configs
        .iter()
        .map(|c| {
            let evaluation = evaluate(&loaded.scene, &ls, c.measured, c.settings, map_resolution, samples, &hits);
            let metrics = ErrorMetrics::compute(&scored(&evaluation.values), &reference_scored);
            Row { config: c.clone(), evaluation, metrics }
        })
        .collect();
    Comparison { width, height, receivers, lit_side, reference, rows }
}

/// A markdown table of the rows.
pub fn markdown_table(c: &Comparison) -> String {
    let mut s = String::from(
        "| method | MAE | RMSE | p99 | umbra over | leak | silhouettes | fins | layers | prepare ms | evaluate ms |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in &c.rows {
        let (m, e) = (&r.metrics, &r.evaluation);
        s += &format!(
            "| {} | {:.4} | {:.4} | {:.3} | {:.2}% | {:.2}% | {} | {} | {} | {:.1} | {:.1} |\n",
            r.config.label,
            m.mae,
            m.rmse,
            m.p99,
            m.umbra_over * 100.0,
            m.leak * 100.0,
            e.silhouettes,
            e.fins,
            e.layers,
            e.prepare_ms,
            e.evaluate_ms
        );
    }
    s += &format!(
        "| ground truth ({} px in shadow) | | | | | | | | | {:.1} | {:.1} |\n",
        c.rows.first().map_or(0, |r| r.metrics.count),
        c.reference.prepare_ms,
        c.reference.evaluate_ms
    );
    s
}
