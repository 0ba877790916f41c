//! `measure`: every configuration of a grid rendered by Bevy in one app per
//! scene, scored against the ground truth at the very pixels the GPU shaded,
//! and timed in the same run.
//!
//! How each technique's visibility is read:
//! - fins and coverage: the plugin's visibility buffer;
//! - Bevy's hard shadows and PCSS: the colour ratio shadowed / unshadowed of
//!   the same Bevy point light, read back as linear floats with ambient light,
//!   tonemapping and dithering off — Bevy multiplies its light's whole
//!   contribution by the shadow factor, so the ratio *is* its visibility;
//! - the CPU oracle: the core crate's raster maps at the same resolution;
//! - the other papers' methods (`single-sample`, `plateaus`, …): the core
//!   crate's `peers` on the CPU at the same pixels, timed on the CPU (their
//!   "frame ms" is CPU prepare + evaluate, not a GPU frame).
//!
//! Pixels scored: the camera sees a surface there, the light's centre faces
//! it, and the unshadowed light reaches it (≥ 1e-3 of the brightest pixel),
//! the same set for every technique.

use bevy_shadow_fins::{FinExtraction, FinMethod, FinShadowSettings};
use shadow_fins::{
    camera::Camera as CoreCamera,
    light::{DiskLight, Light},
    metrics::ErrorMetrics,
    oracle::{FinSettings, Method, Receiver},
    scene::{LightSpaceScene, Scene},
};
use shadow_fins_lab::{
    eval::{camera_receivers, evaluate},
    grid::{Config, Technique},
    picture::{Column, Picture, Pixel, strip},
    results::{Row, Spread},
    setup::Measured,
};

use crate::harness::{BevyShadows, Session, Setup, Shot};

/// How a run measures.
#[derive(Debug, Clone)]
pub struct Options {
    pub width: u32,
    pub height: u32,
    /// Frames rendered and thrown away after the image settles.
    pub warmup: u32,
    /// Frames timed per configuration.
    pub frames: u32,
    /// Ground-truth samples on the disk; 0: no ground truth (timing only).
    pub samples: u32,
    /// Nudge the light every timed frame (by 1e-5 of the scene, back and
    /// forth), so the plugin re-extracts, re-uploads and re-renders its maps
    /// each frame as in a scene where something moves. Off: a static scene,
    /// where the plugin reuses its maps and Bevy still redraws its cube map.
    pub moving_light: bool,
    /// Where the plugin extracts fins: on the GPU (default) or with the core on the CPU.
    pub extraction: FinExtraction,
}

/// A scene to measure.
#[derive(Debug, Clone)]
pub struct Input {
    pub name: String,
    /// What the ground truth traces; with `gltf`, replaced by what the
    /// plugin saw of the file once Bevy loaded it.
    pub scene: Scene,
    /// A glTF file Bevy's own loader loads (materials, hierarchy) instead of
    /// drawing `scene`'s meshes flat.
    pub gltf: Option<std::path::PathBuf>,
    pub light: DiskLight,
    pub camera: CoreCamera,
}

/// What one scene produced.
pub struct SceneMeasurement {
    pub rows: Vec<Row>,
    /// Baselines of every rendered technique at the base radius | ground
    /// truth, error maps below (absent without ground truth).
    pub strip: Option<Picture>,
}

/// Bevy's own point light, unshadowed, gives the denominator of the colour
/// ratios; pixels it leaves darker than this share of the brightest are not
/// scored (their ratio is noise).
const LIT_THRESHOLD: f32 = 1e-3;

/// Per-pixel luminance-like sum of linear RGB.
fn energy(c: &[f32; 3]) -> f32 {
    c[0] + c[1] + c[2]
}

/// Runs `configs` on `input`; `progress` is told after each configuration.
pub fn measure(
    input: &Input,
    configs: &[Config],
    options: &Options,
    base_radius: f32,
    progress: &mut dyn FnMut(&Config),
) -> Result<SceneMeasurement, String> {
    let (w, h) = (options.width, options.height);
    let mut base =
        Setup::new(input.scene.clone(), Light::Disk(input.light), input.camera, FinShadowSettings::default(), (w, h));
    base.settings.extraction = options.extraction;
    base.linear_color = true;
    base.ambient = Some(0.0);
    base.bevy_point_light = true;
    base.gltf = input.gltf.clone();
    let mut session = Session::new(&base);
    // Judged on the triangles Bevy drew.
    let input = &if input.gltf.is_some() {
        session.wait_for_gltf()?;
        let snapshot = session.scene_snapshot();
        if !snapshot.skipped.is_empty() || !snapshot.approximated.is_empty() {
            eprintln!(
                "warning: {}: {} meshes Bevy draws are not in the ground truth, {} are modelled solid (an alpha mask unreadable) or unposed",
                input.name,
                snapshot.skipped.len(),
                snapshot.approximated.len()
            );
        }
        Input { scene: snapshot.scene, ..input.clone() }
    } else {
        input.clone()
    };
    let mut rows = vec![];
    let mut columns: Vec<Column> = vec![];
    let mut strip_reference: Option<Vec<Pixel>> = None;
    let mut radii: Vec<f32> = vec![];
    for c in configs {
        if !radii.contains(&c.radius) {
            radii.push(c.radius);
        }
    }
    for radius in radii {
        let light = DiskLight { radius, ..input.light };
        let ls = LightSpaceScene::new(&input.scene, Light::Disk(light));
        let receivers = camera_receivers(&input.camera, w, h, &ls);
        let hits: Vec<(usize, Receiver)> =
            receivers.iter().enumerate().filter_map(|(i, r)| r.map(|r| (i, r))).collect();
        let hit_receivers: Vec<Receiver> = hits.iter().map(|(_, r)| *r).collect();

        // The unshadowed Bevy light: the denominator and the lit mask. Shaders
        // load asynchronously: a first image can be black and already "settled".
        let mut unshadowed = session_shot(&mut session, &setup_for(&base, None, radius))?;
        for _ in 0..10 {
            if unshadowed.linear.iter().any(|c| energy(c) > 0.0) {
                break;
            }
            unshadowed = session.settle(6)?;
        }
        let brightest = unshadowed.linear.iter().map(energy).fold(0.0f32, f32::max);
        if !(brightest > 0.0) {
            return Err(format!("{}: Bevy's unshadowed point light lit no pixel of the view", input.name));
        }
        let scored: Vec<bool> = hits
            .iter()
            .map(|(i, r)| r.faces_light(&ls.frame) && energy(&unshadowed.linear[*i]) > LIT_THRESHOLD * brightest)
            .collect();
        let pick =
            |values: &[f32]| -> Vec<f32> { values.iter().zip(&scored).filter(|(_, s)| **s).map(|(v, _)| *v).collect() };
        let truth = (options.samples > 0).then(|| {
            let all = evaluate(
                &input.scene,
                &ls,
                Measured::GroundTruth,
                FinSettings::default(),
                None,
                options.samples,
                &hit_receivers,
            );
            all.values
        });
        let truth_scored = truth.as_deref().map(pick);
        let as_pixels = |values: &[f32]| -> Vec<Pixel> {
            let mut out: Vec<Pixel> = vec![None; (w * h) as usize];
            for ((i, _), (v, s)) in hits.iter().zip(values.iter().zip(&scored)) {
                out[*i] = Some(s.then_some(*v));
            }
            out
        };
        let strip_here = radius == base_radius;
        if strip_here && let Some(t) = &truth {
            strip_reference = Some(as_pixels(t));
        }

        for config in configs.iter().filter(|c| c.radius == radius) {
            let mut row = Row {
                scene: input.name.clone(),
                triangles: input.scene.triangle_count(),
                config: *config,
                metrics: None,
                frame_ms: Spread::default(),
                passes: vec![],
                color_check: None,
                non_finite: 0,
                out_of_range: 0,
                modelled: None,
                memory: None,
            };
            // A method on the CPU at the same pixels, timed as prepare + evaluate
            // over `runs` runs; its last values.
            let on_cpu = |measured: Measured, settings: FinSettings, map: Option<u32>, runs: u32| {
                let mut times = vec![];
                let mut last = None;
                for _ in 0..runs {
                    let e = evaluate(&input.scene, &ls, measured, settings, map, 0, &hit_receivers);
                    times.push(e.total_ms());
                    last = Some(e);
                }
                (Spread::of(&times), last.expect("at least one run"))
            };
            let values: Vec<f32> = if config.technique == Technique::CpuOracle {
                let measured = Measured::Method(Method::MultiLayer);
                let settings = fin_settings(config).core();
                let (time, e) = on_cpu(measured, settings, Some(config.map_resolution), (options.frames / 10).max(3));
                row.frame_ms = time;
                row.modelled = Some((e.silhouettes, e.fins, e.layers));
                e.values
            } else if let Technique::Peer(peer) = config.technique {
                // Another paper's method (a few runs: single sample is slow).
                let runs = (options.frames / 10).clamp(1, 3);
                let (time, e) = on_cpu(Measured::Peer(peer), FinSettings::default(), None, runs);
                row.frame_ms = time;
                row.non_finite = e.values.iter().filter(|v| !v.is_finite()).count();
                row.out_of_range = e.values.iter().filter(|v| **v < -1e-3 || **v > 1.0 + 1e-3).count();
                e.values
            } else {
                let setup = setup_for(&base, Some(config), radius);
                let shot = session_shot(&mut session, &setup)?;
                let step = input.scene.bounds().map_or(1e-5, |(lo, hi)| (hi - lo).length() * 1e-5);
                let moving = options.moving_light;
                let nudge = move |world: &mut bevy::prelude::World, frame: u32| {
                    if !moving {
                        return;
                    }
                    let offset = if frame % 2 == 0 { step } else { -step };
                    let mut lights = world.query_filtered::<&mut bevy::prelude::Transform, bevy::prelude::Or<(
                        bevy::prelude::With<bevy_shadow_fins::FinLight>,
                        bevy::prelude::With<bevy::prelude::PointLight>,
                    )>>();
                    for mut t in lights.iter_mut(world) {
                        t.translation.x += offset;
                    }
                };
                session.timed_with(options.warmup, nudge);
                let timing = session.timed_with(options.frames, nudge);
                row.frame_ms = Spread::of(&timing.frame_ms);
                row.passes = timing.passes.iter().map(|(n, v)| (n.clone(), Spread::of(v))).collect();
                let ratio: Vec<f32> = hits
                    .iter()
                    .map(|(i, _)| {
                        let den = energy(&unshadowed.linear[*i]);
                        if den > 0.0 { energy(&shot.linear[*i]) / den } else { 1.0 }
                    })
                    .collect();
                if matches!(
                    config.technique,
                    Technique::Fins(_) | Technique::Coverage | Technique::Convolution | Technique::Plateaus
                ) {
                    row.modelled = Some((shot.stats.silhouettes, shot.stats.fins, shot.stats.layers));
                    row.memory = Some((
                        shot.stats.gpu_bytes,
                        (!shot.stats.degraded.is_empty())
                            .then(|| shot.stats.degraded.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(" | ")),
                    ));
                    row.non_finite = shot.visibility.iter().filter(|v| !v.is_finite()).count();
                    row.out_of_range = shot.visibility.iter().filter(|v| **v < -1e-3 || **v > 1.0 + 1e-3).count();
                    let buffer: Vec<f32> = hits.iter().map(|(i, _)| shot.visibility[*i]).collect();
                    let (b, r) = (pick(&buffer), pick(&ratio));
                    let n = b.len().max(1) as f32;
                    row.color_check = Some(b.iter().zip(&r).map(|(b, r)| (b - r).abs()).sum::<f32>() / n);
                    buffer
                } else {
                    row.non_finite = ratio.iter().filter(|v| !v.is_finite()).count();
                    // f16 colour rounding: a ratio a hair above 1 is noise, not light.
                    row.out_of_range = ratio.iter().filter(|v| **v < -1e-3 || **v > 1.0 + 1e-2).count();
                    ratio.iter().map(|v| v.clamp(0.0, 1.0)).collect()
                }
            };
            if let Some(t) = &truth_scored {
                row.metrics = Some(ErrorMetrics::compute(&pick(&values), t));
            }
            if strip_here && config.baseline && strip_reference.is_some() {
                columns.push(Column {
                    label: config.label(),
                    values: as_pixels(&values),
                    mae: row.metrics.map_or(f32::NAN, |m| m.mae),
                });
            }
            progress(config);
            rows.push(row);
        }
    }
    let strip = strip_reference.map(|reference| strip(w, h, &columns, &reference));
    Ok(SceneMeasurement { rows, strip })
}

/// Swaps the light and renders until the image settles.
fn session_shot(session: &mut Session, setup: &Setup) -> Result<Shot, String> {
    session.replace_light(setup);
    session.settle(3)
}

/// The plugin's settings for a configuration.
fn fin_settings(c: &Config) -> FinShadowSettings {
    let defaults = FinShadowSettings::default();
    FinShadowSettings {
        method: match c.technique {
            Technique::Fins(Method::Hard) => FinMethod::Hard,
            Technique::Fins(Method::OuterFins) => FinMethod::OuterFins,
            Technique::Fins(Method::SingleLayer) => FinMethod::SingleLayer,
            Technique::Coverage => FinMethod::Coverage,
            Technique::Convolution => FinMethod::Convolution,
            Technique::Plateaus => FinMethod::Plateaus,
            _ => FinMethod::MultiLayer,
        },
        layers: c.layers.unwrap_or(defaults.layers),
        refinement: c.refinement.unwrap_or(defaults.refinement),
        falloff: c.falloff.unwrap_or(defaults.falloff),
        map_resolution: c.map_resolution,
        coverage_samples: c.samples.unwrap_or(defaults.coverage_samples),
        ..defaults
    }
}

/// `base` lit as `config` says; `None`: Bevy's point light without shadows.
fn setup_for(base: &Setup, config: Option<&Config>, radius: f32) -> Setup {
    let mut s = base.clone();
    if let Light::Disk(d) = &mut s.light {
        d.radius = radius;
    }
    let Some(c) = config else {
        s.bevy_point_light = true;
        s.bevy_shadows = BevyShadows::None;
        return s;
    };
    s.settings = FinShadowSettings { extraction: base.settings.extraction, ..fin_settings(c) };
    (s.bevy_point_light, s.bevy_shadows) = match c.technique {
        Technique::BevyHard => (true, BevyShadows::Hard),
        Technique::BevyPcss => (true, BevyShadows::Pcss),
        _ => (false, BevyShadows::None),
    };
    s
}
