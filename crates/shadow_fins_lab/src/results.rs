//! Rows of a `measure` run and their outputs: CSV, JSON, markdown tables,
//! and the targets checked against them.

use std::fmt::Write;

use shadow_fins::{
    metrics::ErrorMetrics,
    peers::{PeerMethod, convolution::ConvolutionSettings},
};

use crate::grid::{Config, Technique};

/// Median and spread of repeated timings.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Spread {
    pub median: f64,
    /// 10th and 90th percentiles.
    pub p10: f64,
    pub p90: f64,
    pub samples: usize,
}

impl Spread {
    /// Of the finite samples (all-NaN or empty gives NaN, never a panic).
    pub fn of(samples: &[f64]) -> Self {
        let mut v: Vec<f64> = samples.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return Self { median: f64::NAN, p10: f64::NAN, p90: f64::NAN, samples: 0 };
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| {
            // Linear interpolation between closest ranks.
            let x = q * (v.len() - 1) as f64;
            let (i, f) = (x.floor() as usize, x.fract());
            v[i] + (v[(i + 1).min(v.len() - 1)] - v[i]) * f
        };
        Self { median: at(0.5), p10: at(0.1), p90: at(0.9), samples: v.len() }
    }
}

/// One measured configuration.
#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    pub triangles: usize,
    pub config: Config,
    /// Against the ground truth over the scored pixels; `None` when the run
    /// had no ground truth (`--no-truth`).
    pub metrics: Option<ErrorMetrics>,
    /// Wall time per frame (GPU techniques) or CPU time of the oracle, ms.
    pub frame_ms: Spread,
    /// Per pass (`render/fin_shadows/…`), ms.
    pub passes: Vec<(String, Spread)>,
    /// Fins only: mean |visibility buffer − colour ratio| over the scored
    /// pixels, a check that the compositing applies what the buffer says.
    pub color_check: Option<f32>,
    /// NaN or infinite visibility values over the whole view.
    pub non_finite: usize,
    /// Visibility outside [0, 1] by more than 1e-3 over the whole view.
    pub out_of_range: usize,
    /// Silhouettes, fins and layers the plugin modelled (fins only).
    pub modelled: Option<(usize, usize, usize)>,
    /// The plugin's GPU bytes for the light's shadow data
    /// (`FinFrameStats::gpu_bytes`) and why it modelled less than asked, if
    /// it did (every reason, ` | ` between them); the plugin's methods only.
    pub memory: Option<(u64, Option<String>)>,
}

const HEADER: &str = "scene,triangles,method,label,layers,refinement,falloff,map_resolution,radius,pixels,mae,rmse,p99,umbra_over,leak,frame_ms,frame_p10_ms,frame_p90_ms,frames,non_finite,out_of_range,color_check,silhouettes,fins,used_layers,passes,gpu_mib,degraded";

fn opt<T: ToString>(v: Option<T>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// One line per row; per-pass medians in the last column as `name=ms;…`.
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(HEADER);
    s.push('\n');
    for r in rows {
        let c = &r.config;
        let m = r.metrics;
        let passes: Vec<String> = r.passes.iter().map(|(n, t)| format!("{n}={:.4}", t.median)).collect();
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.4},{:.4},{:.4},{},{},{},{},{},{},{},{},{},{}",
            r.scene,
            r.triangles,
            c.technique.name(),
            c.label(),
            opt(c.layers),
            opt(c.refinement),
            opt(c.falloff.map(|f| f.name())),
            c.map_resolution,
            c.radius,
            opt(m.map(|m| m.count)),
            opt(m.map(|m| m.mae)),
            opt(m.map(|m| m.rmse)),
            opt(m.map(|m| m.p99)),
            opt(m.map(|m| m.umbra_over)),
            opt(m.map(|m| m.leak)),
            r.frame_ms.median,
            r.frame_ms.p10,
            r.frame_ms.p90,
            r.frame_ms.samples,
            r.non_finite,
            r.out_of_range,
            opt(r.color_check),
            opt(r.modelled.map(|m| m.0)),
            opt(r.modelled.map(|m| m.1)),
            opt(r.modelled.map(|m| m.2)),
            passes.join(";"),
            opt(r.memory.as_ref().map(|m| format!("{:.2}", m.0 as f64 / (1u64 << 20) as f64))),
            // One CSV field: the reason's commas become semicolons.
            opt(r.memory.as_ref().and_then(|m| m.1.as_ref()).map(|why| why.replace(',', ";"))),
        );
    }
    s
}

/// A JSON number, or `null` for what JSON cannot hold (NaN, infinities).
fn num(v: f64) -> String {
    if v.is_finite() { format!("{v}") } else { "null".into() }
}

fn string(s: &str) -> String {
    let mut out = String::from("\"");
    for ch in s.chars() {
        match ch {
            '"' => out += "\\\"",
            '\\' => out += "\\\\",
            c if (c as u32) < 0x20 => out += &format!("\\u{:04x}", c as u32),
            c => out.push(c),
        }
    }
    out + "\""
}

fn json_opt<T>(v: Option<T>, f: impl Fn(T) -> String) -> String {
    v.map(f).unwrap_or_else(|| "null".into())
}

fn spread_json(s: &Spread) -> String {
    format!(
        "{{\"median\": {}, \"p10\": {}, \"p90\": {}, \"samples\": {}}}",
        num(s.median),
        num(s.p10),
        num(s.p90),
        s.samples
    )
}

/// An array of objects, one per row.
pub fn json(rows: &[Row]) -> String {
    let mut s = String::from("[\n");
    for (i, r) in rows.iter().enumerate() {
        let c = &r.config;
        let m = r.metrics;
        let metric = |f: fn(&ErrorMetrics) -> f64| json_opt(m.as_ref(), |m| num(f(m)));
        let passes: Vec<String> = r.passes.iter().map(|(n, t)| format!("{}: {}", string(n), spread_json(t))).collect();
        let _ = write!(
            s,
            "  {{\"scene\": {}, \"triangles\": {}, \"method\": {}, \"label\": {}, \"layers\": {}, \"refinement\": {}, \
             \"falloff\": {}, \"map_resolution\": {}, \"radius\": {}, \"pixels\": {}, \"mae\": {}, \"rmse\": {}, \
             \"p99\": {}, \"umbra_over\": {}, \"leak\": {}, \"frame_ms\": {}, \"non_finite\": {}, \"out_of_range\": {}, \
             \"color_check\": {}, \"passes_ms\": {{{}}}}}",
            string(&r.scene),
            r.triangles,
            string(c.technique.name()),
            string(&c.label()),
            json_opt(c.layers, |l| l.to_string()),
            json_opt(c.refinement, |b| b.to_string()),
            json_opt(c.falloff, |f| string(f.name())),
            c.map_resolution,
            num(c.radius as f64),
            json_opt(m, |m| m.count.to_string()),
            metric(|m| m.mae as f64),
            metric(|m| m.rmse as f64),
            metric(|m| m.p99 as f64),
            metric(|m| m.umbra_over as f64),
            metric(|m| m.leak as f64),
            spread_json(&r.frame_ms),
            r.non_finite,
            r.out_of_range,
            json_opt(r.color_check, |v| num(v as f64)),
            passes.join(", "),
        );
        s += if i + 1 < rows.len() { ",\n" } else { "\n" };
    }
    s + "]\n"
}

/// A table cell: the value to `digits` decimals, or "–" when absent.
pub fn cell(v: Option<f32>, digits: usize) -> String {
    v.map_or("–".to_string(), |v| format!("{v:.digits$}"))
}

/// A table cell for a share: percent to 2 decimals, or "–" when absent.
pub fn percent(v: Option<f32>) -> String {
    v.map_or("–".to_string(), |v| format!("{:.2}%", v * 100.0))
}

/// A markdown table of the rows of one scene.
pub fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| configuration | map | radius | MAE | RMSE | p99 | umbra over | leak | frame ms (p10–p90) | colour check | NaN |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let m = r.metrics;
        let time = if r.config.technique.is_rendered() {
            format!("{:.1} ({:.1}–{:.1})", r.frame_ms.median, r.frame_ms.p10, r.frame_ms.p90)
        } else {
            format!("{:.1} CPU", r.frame_ms.median)
        };
        // The peers keep their own resolutions (convolution: 512² basis maps).
        let map = match r.config.technique {
            Technique::Peer(PeerMethod::Convolution | PeerMethod::ConvolutionMipmap) => {
                format!("{} (own)", ConvolutionSettings::default().resolution)
            }
            Technique::Peer(_) => "–".to_string(),
            _ => r.config.map_resolution.to_string(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.config.label(),
            map,
            r.config.radius,
            cell(m.map(|m| m.mae), 4),
            cell(m.map(|m| m.rmse), 4),
            cell(m.map(|m| m.p99), 3),
            percent(m.map(|m| m.umbra_over)),
            percent(m.map(|m| m.leak)),
            time,
            cell(r.color_check, 5),
            r.non_finite,
        );
    }
    s
}

/// The targets on one scene's baselines: fins 16L frame time ≤ 3×
/// Bevy's hard shadows', fins 16L MAE ≤ ½ of Bevy PCSS's and of outer fins';
/// the coverage method's (issue 13): MAE ≥ 3× better than Bevy PCSS's and
/// outer fins', MAE ≤ 0.01, p99 ≤ 0.08, umbra over ≤ 0.1%, and its frame time
/// beside fins'. One markdown line per check, with the measured ratio.
pub fn targets(scene: &str, rows: &[Row]) -> Vec<String> {
    let base = |t: Technique| rows.iter().find(|r| r.scene == scene && r.config.baseline && r.config.technique == t);
    let fins = base(Technique::Fins(shadow_fins::oracle::Method::MultiLayer));
    let mut out = vec![];
    let Some(fins) = fins else { return out };
    let verdict = |ok: bool| if ok { "met" } else { "**missed**" };
    if let Some(hard) = base(Technique::BevyHard) {
        let ratio = fins.frame_ms.median / hard.frame_ms.median;
        out.push(format!(
            "| {scene} | fins {}L frame ≤ 3× bevy-hard | {:.1} ms vs {:.1} ms = {ratio:.2}× | {} |",
            fins.config.layers.unwrap_or(0),
            fins.frame_ms.median,
            hard.frame_ms.median,
            verdict(ratio <= 3.0)
        ));
    }
    for peer in [Technique::BevyPcss, Technique::Fins(shadow_fins::oracle::Method::OuterFins)] {
        if let (Some(p), Some(fm), Some(pm)) = (base(peer), fins.metrics, base(peer).and_then(|p| p.metrics)) {
            let ratio = fm.mae / pm.mae;
            out.push(format!(
                "| {scene} | fins MAE ≤ ½ {} | {:.4} vs {:.4} = {ratio:.2}× | {} |",
                p.config.technique.name(),
                fm.mae,
                pm.mae,
                verdict(ratio <= 0.5)
            ));
        }
    }
    if let Some(coverage) = base(Technique::Coverage) {
        out.push(format!(
            "| {scene} | coverage frame (its cost; no target) | {:.1} ms vs fins {:.1} ms = {:.2}× | — |",
            coverage.frame_ms.median,
            fins.frame_ms.median,
            coverage.frame_ms.median / fins.frame_ms.median
        ));
        for peer in [Technique::BevyPcss, Technique::Fins(shadow_fins::oracle::Method::OuterFins)] {
            if let (Some(p), Some(cm), Some(pm)) = (base(peer), coverage.metrics, base(peer).and_then(|p| p.metrics)) {
                let ratio = pm.mae / cm.mae.max(1e-6);
                out.push(format!(
                    "| {scene} | coverage MAE ≤ ⅓ {} | {:.4} vs {:.4}: {ratio:.1}× better | {} |",
                    p.config.technique.name(),
                    cm.mae,
                    pm.mae,
                    verdict(ratio >= 3.0)
                ));
            }
        }
        if let Some(cm) = coverage.metrics {
            out.push(format!(
                "| {scene} | coverage MAE ≤ 0.01, p99 ≤ 0.08, umbra over ≤ 0.1% | {:.4}, {:.3}, {:.2}% | {} |",
                cm.mae,
                cm.p99,
                cm.umbra_over * 100.0,
                verdict(cm.mae <= 0.01 && cm.p99 <= 0.08 && cm.umbra_over <= 0.001)
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Axes;
    use shadow_fins::refine::Falloff;

    #[test]
    fn spread_interpolates_percentiles_and_ignores_nan() {
        let s = Spread::of(&[5.0, 1.0, 3.0, f64::NAN, 2.0, 4.0]);
        assert_eq!((s.median, s.samples), (3.0, 5));
        assert!((s.p10 - 1.4).abs() < 1e-12 && (s.p90 - 4.6).abs() < 1e-12, "{s:?}");
        assert!(Spread::of(&[]).median.is_nan());
    }

    fn rows() -> Vec<Row> {
        let axes = Axes {
            techniques: Technique::ALL.to_vec(),
            layers: vec![16],
            refinement: vec![true],
            falloffs: vec![Falloff::DiskSegment],
            map_resolutions: vec![1024],
            coverage_samples: vec![256],
            radii: vec![0.5],
            base_layers: 16,
            base_map_resolution: 1024,
            base_radius: 0.5,
        };
        axes.configs(false)
            .into_iter()
            .enumerate()
            .map(|(i, config)| Row {
                scene: "s".into(),
                triangles: 12,
                config,
                metrics: Some(ErrorMetrics::compute(&[0.5, 0.1 * i as f32], &[0.5, 0.0])),
                frame_ms: Spread::of(&[10.0 + i as f64]),
                passes: vec![("render/fin_shadows/maps/elapsed_gpu".into(), Spread::of(&[1.5]))],
                color_check: None,
                non_finite: 0,
                out_of_range: 0,
                modelled: None,
                memory: None,
            })
            .collect()
    }

    #[test]
    fn csv_has_one_line_per_row_with_every_column() {
        let mut rows = rows();
        // Two reasons, one with a comma of its own: still one field.
        rows[1].memory = Some((3 << 20, Some("maps 4 layers at 512², over 128 MiB | fins: 9 of 10 kept".into())));
        let text = csv(&rows);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), rows.len() + 1);
        let columns = HEADER.split(',').count();
        for l in &lines {
            assert_eq!(l.split(',').count(), columns, "{l}");
        }
        assert!(lines[1].starts_with("s,12,fins,fins 16L,16,true,disk-segment,1024,0.5,"), "{}", lines[1]);
        assert!(lines[1].ends_with("render/fin_shadows/maps/elapsed_gpu=1.5000,,"), "{}", lines[1]);
        assert!(lines[2].ends_with(",3.00,maps 4 layers at 512²; over 128 MiB | fins: 9 of 10 kept"), "{}", lines[2]);
    }

    #[test]
    fn json_is_balanced_and_writes_nan_as_null() {
        let mut rows = rows();
        rows[0].frame_ms = Spread::of(&[]);
        let text = json(&rows);
        assert_eq!(text.matches('{').count(), text.matches('}').count());
        assert_eq!(text.matches("\"scene\"").count(), rows.len());
        assert!(text.contains("\"median\": null"));
        assert!(!text.contains("NaN"));
        assert!(text.contains("\"layers\": null"), "Bevy peers have no layer count");
    }

    #[test]
    fn targets_compare_the_baselines_with_their_ratios() {
        let rows = rows();
        let t = targets("s", &rows);
        assert_eq!(t.len(), 7, "{t:?}");
        // Frame times 10 (fins) vs 14 (bevy-hard, fifth technique): met.
        assert!(t[0].contains("0.71×") && t[0].ends_with("met |"), "{}", t[0]);
        // fins MAE 0 vs PCSS's > 0: met.
        assert!(t[1].contains("bevy-pcss") && t[1].ends_with("met |"), "{}", t[1]);
        // Coverage (eighth technique) takes 17 ms against fins' 10.
        assert!(t[3].contains("17.0 ms vs fins 10.0 ms = 1.70×"), "{}", t[3]);
        // Its MAE (0.35) against PCSS's (sixth: 0.25) is not 3× better.
        assert!(t[4].contains("bevy-pcss") && t[4].ends_with("**missed** |"), "{}", t[4]);
        assert!(t[6].contains("umbra over ≤ 0.1%") && t[6].ends_with("**missed** |"), "{}", t[6]);
    }
}
