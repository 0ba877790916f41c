//! Environment lighting, measured (issue 14's stretch; the core's
//! `shadow_fins::peers::environment`): a built-in scene under a sky cube
//! map, fitted with Annen et al.'s area lights at several thresholds, each
//! light shadowed by convolution shadow maps (256², summed-area tables or
//! mipmaps), by one hard ray or exactly (its disk sampled) — against the
//! many-light ground truth, every texel of the map a light.
//!
//! The value compared per pixel is the shadowed irradiance over the exact
//! unshadowed one, `E / E_open` (1 where nothing blocks the sky and the fit
//! were exact): it scores the fit's error and the shadows' together, and the
//! "exact" rows split them.

use std::time::Instant;

use rayon::prelude::*;
use shadow_fins::{
    bvh::Bvh,
    camera::pixel_receiver,
    glam::Vec3,
    metrics::ErrorMetrics,
    peers::{
        convolution::{ConvolutionSettings, Prefilter},
        environment::{CubeMap, EnvironmentTruth, LightShadows, WorldReceiver, fit_area_lights, shade},
    },
    scene::LightSpaceScene,
    scenes::SceneId,
};

use crate::picture::{Column, Picture, Pixel, strip};

/// One method at one threshold.
#[derive(Debug, Clone)]
pub struct EnvironmentRow {
    pub threshold: f32,
    pub lights: usize,
    pub method: &'static str,
    pub metrics: ErrorMetrics,
    /// Preparation (maps) and evaluation over every pixel, 2 threads.
    pub ms: f64,
}

/// What [`measure`] found.
pub struct EnvironmentMeasurement {
    pub rows: Vec<EnvironmentRow>,
    pub truth_ms: f64,
    pub texels: usize,
    /// Truth and every method at the middle threshold, with error maps.
    pub strip: Picture,
}

/// The scene's view, `width × height`, under the sky (`cube`² texels a
/// face; a sun 0.05 rad wide, 40° up), at each threshold of `thresholds`.
pub fn measure(id: SceneId, width: u32, height: u32, cube: usize, thresholds: &[f32]) -> EnvironmentMeasurement {
    let built = id.build();
    let scene = built.scene;
    let sky = CubeMap::sky(cube, Vec3::new(0.45, 0.64, 0.62), 0.05, 2000.0, 1.0);
    // Receivers: the scene's camera, through the light frame of its own light.
    let ls = LightSpaceScene::new(&scene, built.light);
    let bvh = Bvh::new(&ls.casters);
    let receivers: Vec<Option<WorldReceiver>> = (0..width * height)
        .map(|i| {
            pixel_receiver(&built.camera, (i % width, i / width, width, height), &ls, &bvh).map(|r| WorldReceiver {
                position: ls.frame.to_world(r.position),
                normal: ls.frame.dir_to_world(r.normal),
            })
        })
        .collect();
    let start = Instant::now();
    let truth = EnvironmentTruth::new(&scene, &sky);
    let exact: Vec<Option<(f32, f32)>> = receivers.par_iter().map(|r| r.map(|r| truth.irradiance(r))).collect();
    let truth_ms = start.elapsed().as_secs_f64() * 1e3;
    let seen: Vec<WorldReceiver> = receivers.iter().flatten().copied().collect();
    let ratio = |e: f32, open: f32| if open > 0.0 { (e / open).clamp(0.0, 2.0) } else { 1.0 };
    let reference: Vec<f32> = exact.iter().flatten().map(|(e, open)| ratio(*e, *open)).collect();
    // 256² maps, as the paper's environment results (Figure 1, 10).
    let csm = ConvolutionSettings { resolution: 256, ..Default::default() };
    let methods: [(&'static str, LightShadows); 4] = [
        ("convolution (SAT)", LightShadows::Convolution(csm)),
        (
            "convolution (mipmap)",
            LightShadows::Convolution(ConvolutionSettings { prefilter: Prefilter::Mipmap, ..csm }),
        ),
        ("hard (one ray a light)", LightShadows::Hard),
        ("exact (64 rays a light)", LightShadows::Exact { samples: 64 }),
    ];
    let mut rows = vec![];
    let mut columns = vec![];
    let middle = thresholds.len() / 2;
    for (k, &t) in thresholds.iter().enumerate() {
        let fitted = fit_area_lights(&sky, t);
        for (name, shadows) in methods {
            let start = Instant::now();
            let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
            let mut shaded = shade(&scene, &fitted, shadows, &seen, threads).into_iter();
            // `seen` is the receivers without the background, in order.
            let values: Vec<Option<f32>> =
                exact.iter().map(|e| e.map(|(_, open)| ratio(shaded.next().unwrap_or(0.0), open))).collect();
            let ms = start.elapsed().as_secs_f64() * 1e3;
            let measured: Vec<f32> = values.iter().flatten().copied().collect();
            let metrics = ErrorMetrics::compute(&measured, &reference);
            if k == middle {
                columns.push(Column {
                    label: format!("{name} {}L", fitted.len()),
                    values: values.iter().map(|v| v.map(Some)).collect(),
                    mae: metrics.mae,
                });
            }
            rows.push(EnvironmentRow { threshold: t, lights: fitted.len(), method: name, metrics, ms });
        }
    }
    let truth_pixels: Vec<Pixel> = exact.iter().map(|e| e.map(|(e, open)| Some(ratio(e, open)))).collect();
    EnvironmentMeasurement {
        rows,
        truth_ms,
        texels: 6 * cube * cube,
        strip: strip(width, height, &columns, &truth_pixels),
    }
}

/// The rows as a markdown table.
pub fn markdown(m: &EnvironmentMeasurement) -> String {
    let mut out = String::from("| t | lights | shadows | MAE | RMSE | p99 | ms |\n|---|---|---|---|---|---|---|\n");
    for r in &m.rows {
        out += &format!(
            "| {} | {} | {} | {:.4} | {:.4} | {:.3} | {:.0} |\n",
            r.threshold, r.lights, r.method, r.metrics.mae, r.metrics.rmse, r.metrics.p99, r.ms
        );
    }
    out += &format!("\nground truth: {} texel lights, {:.0} ms\n", m.texels, m.truth_ms);
    out
}
