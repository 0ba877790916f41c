//! `shadow-fins-render-lab`: the speed/accuracy trade of every method, as
//! Bevy renders it with the plugin, and the numerical extremes.
//!
//! - `measure`: a grid of configurations per scene against 1024-sample
//!   ground truth, frame and per-pass times, Bevy's shadow maps and PCSS and
//!   the CPU oracle as peers; CSV, JSON, Pareto plots, image strips;
//! - `stability`: the extremes; exits 1 if any NaN or Inf reaches the
//!   visibility buffer;
//! - `lights`: the frame cost of N fin-shadowed spot lights beside Bevy's own
//!   shadow maps for the same N lights;
//! - `sun`: a fin-shadowed `DirectionalLight` against the truth and beside
//!   Bevy's cascades;
//! - `scaling`: the frame cost against the object count, static and moving;
//! - `posing`: what a skinned mesh's new pose costs, by mesh size, posed on the GPU and on the CPU;
//! - `foliage`: alpha-masked leaf cards at scale, one moving, extracted on
//!   the GPU against on the CPU.

use std::{io::Write, path::PathBuf, process::ExitCode};

use bevy_shadow_fins::FinExtraction;
use clap::{Args, Parser, Subcommand};
use shadow_fins::{
    glam::{Affine3A, Vec3},
    light::Light,
    refine::Falloff,
    scene::{Scene, SceneObject},
    scenes::SceneId,
    shapes,
};
use shadow_fins_app::render_lab::{foliage, lights, measure, scaling, stability, sun};
use shadow_fins_lab::{
    LabError,
    grid::{Axes, Technique, parse_list},
    plot::{Point, pareto_plot},
    results::{self, Row},
    setup::SceneArgs,
};

#[derive(Parser)]
#[command(
    name = "shadow-fins-render-lab",
    version,
    about = "Fin shadows rendered by Bevy: speed against accuracy, and the extremes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// What the timing runs (`lights`, `scaling`) share.
#[derive(Args)]
struct TimedArgs {
    /// Frames timed per configuration (median reported).
    #[arg(long, default_value_t = 20)]
    frames: u32,
    #[arg(long, default_value_t = 320)]
    width: u32,
    #[arg(long, default_value_t = 240)]
    height: u32,
    /// Fin maps' (and Bevy's shadow maps') resolution.
    #[arg(long, default_value_t = 1024)]
    map_resolution: u32,
    /// Also write the table here.
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Subcommand)]
enum Command {
    /// Render a grid of configurations per scene; score and time each.
    Measure(MeasureArgs),
    /// Render the numerical extremes; exit 1 if any NaN/Inf reaches the visibility buffer.
    Stability {
        /// Only these cases (comma-separated names; default all).
        #[arg(long, default_value = "")]
        cases: String,
        /// Ground-truth samples on the disk (0: no error column).
        #[arg(long, default_value_t = 1024)]
        samples: u32,
        /// The plugin's method: fins (16-layer, the cases' own settings),
        /// coverage, convolution or plateaus.
        #[arg(long, default_value = "fins")]
        method: String,
        /// Also write the report table here.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Frame cost of N fin-shadowed SpotLights beside Bevy's shadow maps for the same N lights.
    Lights {
        /// Built-in scene (its light, plus N − 1 more on a ring).
        #[arg(long, default_value = "demo")]
        scene: String,
        /// Light counts, comma-separated.
        #[arg(long, default_value = "1,2,4,8")]
        counts: String,
        #[command(flatten)]
        timed: TimedArgs,
    },
    /// Frame cost against the object count (cubes of one mesh), static and one moving; main and render world apart.
    Scaling {
        /// Object counts, comma-separated (1 to 100 000).
        #[arg(long, default_value = "10,100,1000,10000")]
        counts: String,
        #[command(flatten)]
        timed: TimedArgs,
    },
    /// What a skinned mesh's new pose costs the main world (CPU) and the render world, by mesh size.
    Posing {
        /// Rings of the skinned arm (about 32 vertices each), comma-separated (1 to 4096).
        #[arg(long, default_value = "1,64,512")]
        segments: String,
        #[command(flatten)]
        timed: TimedArgs,
    },
    /// Frame cost against the count of alpha-masked leaf cards, one moving: GPU extraction against CPU extraction.
    Foliage {
        /// Card counts, comma-separated (1 to 100 000).
        #[arg(long, default_value = "10,100,1000")]
        counts: String,
        #[command(flatten)]
        timed: TimedArgs,
    },
    /// A fin-shadowed sun (DirectionalLight) against the truth, beside Bevy's cascades.
    Sun {
        /// Built-in scenes, comma-separated (the sun is placed by their disk light).
        #[arg(long, default_value = "box-over-plane,near-contact,ring-plate,demo")]
        scenes: String,
        /// Angular radii in radians, comma-separated; `scene`: the scene's own
        /// (the disk seen from the origin); 0.00465 is the real sun.
        #[arg(long, default_value = "scene,0.00465")]
        angles: String,
        /// Frames timed per configuration (median reported).
        #[arg(long, default_value_t = 20)]
        frames: u32,
        #[arg(long, default_value_t = 160)]
        width: u32,
        #[arg(long, default_value_t = 120)]
        height: u32,
        /// Fin maps' and Bevy's cascades' resolution.
        #[arg(long, default_value_t = 1024)]
        map_resolution: u32,
        /// Ground-truth samples on the sun's disk.
        #[arg(long, default_value_t = 1024)]
        samples: u32,
        /// Layers of the fins' maps.
        #[arg(long, default_value_t = 16)]
        layers: u32,
        /// Also write the table here.
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

#[derive(Args)]
struct MeasureArgs {
    /// Built-in scenes, comma-separated.
    #[arg(long, default_value = "large-light,near-contact")]
    scenes: String,
    /// A glTF/GLB file instead, loaded by Bevy's own loader (lit by the core's default view's disk).
    #[arg(long)]
    gltf: Option<PathBuf>,
    /// Instead of scenes: the bumpy blob over a plane at these triangle counts (GPU scaling run).
    #[arg(long)]
    blob_triangles: Option<String>,
    /// Techniques: fins, coverage, single-layer, outer-fins, hard, bevy-hard, bevy-pcss, cpu-oracle;
    /// the other papers' methods on the CPU at the same pixels: single-sample, plateaus,
    /// penumbra-wedges, wedge-blending, convolution, convolution-mipmap.
    #[arg(long, default_value = "fins,coverage,single-layer,outer-fins,hard,bevy-hard,bevy-pcss,cpu-oracle")]
    methods: String,
    /// Layer counts swept for multi-layer fins (1..=32; more is clamped).
    #[arg(long, default_value = "1,2,4,8,16,32")]
    layers: String,
    /// Refinement values swept: on, off.
    #[arg(long, default_value = "on,off")]
    refinement: String,
    /// Falloffs swept: linear, bernstein, disk-segment.
    #[arg(long, default_value = "linear,bernstein,disk-segment")]
    falloff: String,
    /// Map (and Bevy cube face) resolutions swept.
    #[arg(long, default_value = "256,512,1024,2048")]
    map_resolution: String,
    /// Light radii swept (world units; default: the scene's own).
    #[arg(long)]
    radius: Option<String>,
    /// Light samples swept for the coverage method (1..=256; the baseline is 256).
    #[arg(long, default_value = "256")]
    coverage_samples: String,
    /// The baseline's layer count.
    #[arg(long, default_value_t = 16)]
    base_layers: u32,
    /// The baseline's map resolution.
    #[arg(long, default_value_t = 1024)]
    base_map_resolution: u32,
    /// The whole Cartesian product instead of one factor at a time.
    #[arg(long)]
    full: bool,
    #[arg(long, default_value_t = 160)]
    width: u32,
    #[arg(long, default_value_t = 120)]
    height: u32,
    /// Frames timed per configuration (≥ 30 for the record).
    #[arg(long, default_value_t = 30)]
    frames: u32,
    /// Frames rendered and dropped after the image settles, before timing.
    #[arg(long, default_value_t = 5)]
    warmup: u32,
    /// Ground-truth samples on the disk.
    #[arg(long, default_value_t = 1024)]
    samples: u32,
    /// No ground truth: timing only (the scaling run).
    #[arg(long)]
    no_truth: bool,
    /// Move the light a hair every timed frame, so the plugin redoes extraction
    /// and maps each frame (a dynamic scene); default: a static scene.
    #[arg(long)]
    moving_light: bool,
    /// Where the plugin extracts fins and assigns layers: gpu (compute passes) or cpu (the core crate).
    #[arg(long, default_value = "gpu")]
    extraction: String,
    /// Directory for the CSV, the Pareto plots and the image strips.
    #[arg(long, default_value = "target/render-lab")]
    out: PathBuf,
    /// Also write every row as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Measure(args) => run_measure(args).map(|()| ExitCode::SUCCESS),
        Command::Stability { cases, samples, method, out } => run_stability(&cases, samples, &method, out),
        Command::Lights { scene, counts, timed } => run_lights(&scene, &counts, &timed).map(|()| ExitCode::SUCCESS),
        Command::Scaling { counts, timed } => run_scaling(&counts, &timed, false).map(|()| ExitCode::SUCCESS),
        Command::Posing { segments, timed } => run_posing(&segments, &timed).map(|()| ExitCode::SUCCESS),
        Command::Foliage { counts, timed } => run_scaling(&counts, &timed, true).map(|()| ExitCode::SUCCESS),
        Command::Sun { scenes, angles, frames, width, height, map_resolution, samples, layers, out } => {
            let parsed = parse_sun(&scenes, &angles);
            parsed
                .and_then(|(scenes, angles)| {
                    let run = sun::SunRun {
                        scenes,
                        angles,
                        frames: frames.max(1),
                        width: width.clamp(1, 4096),
                        height: height.clamp(1, 4096),
                        map_resolution,
                        layers,
                        samples: samples.clamp(1, 1 << 16),
                    };
                    let table = sun::markdown(&sun::run(&run).map_err(usage)?);
                    println!("{table}");
                    match &out {
                        Some(path) => write(path, &table),
                        None => Ok(()),
                    }
                })
                .map(|()| ExitCode::SUCCESS)
        }
    };
    result.unwrap_or_else(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })
}

fn run_lights(scene: &str, counts: &str, timed: &TimedArgs) -> Result<(), LabError> {
    let TimedArgs { frames, width, height, map_resolution, ref out } = *timed;
    let scene = SceneId::parse(scene).ok_or_else(|| usage(format!("unknown scene '{scene}'")))?;
    let max = bevy_shadow_fins::MAX_FIN_LIGHTS;
    let counts =
        parse_list("counts", counts, |s| s.parse::<usize>().ok().filter(|n| (1..=max).contains(n))).map_err(usage)?;
    let run = lights::LightsRun { scene, counts, frames: frames.max(1), width, height, map_resolution };
    let rows = lights::run(&run).map_err(usage)?;
    print_table(&lights::markdown(&rows), out)
}

/// Prints a timing run's table, and writes it to `out` when given.
fn print_table(table: &str, out: &Option<PathBuf>) -> Result<(), LabError> {
    println!("{table}");
    match out {
        Some(path) => write(path, table),
        None => Ok(()),
    }
}

/// The scaling run (cubes), or with `cards` the foliage run (masked leaf cards).
fn run_scaling(counts: &str, timed: &TimedArgs, cards: bool) -> Result<(), LabError> {
    let counts = parse_list("counts", counts, |s| s.parse::<usize>().ok().filter(|n| (1..=100_000).contains(n)))
        .map_err(usage)?;
    let run = scaling_run(counts, timed);
    let table = match cards {
        true => foliage::markdown(&foliage::run(&run).map_err(usage)?),
        false => scaling::markdown(&scaling::run(&run).map_err(usage)?),
    };
    print_table(&table, &timed.out)
}

/// The timed arguments as a scaling run over `counts` (frames at least 1, sizes clamped).
fn scaling_run(counts: Vec<usize>, timed: &TimedArgs) -> scaling::ScalingRun {
    let TimedArgs { frames, width, height, map_resolution, .. } = *timed;
    scaling::ScalingRun {
        counts,
        frames: frames.max(1),
        width: width.clamp(1, 4096),
        height: height.clamp(1, 4096),
        map_resolution,
    }
}

/// The posing run: one skinned arm per size (the run's counts unused).
fn run_posing(segments: &str, timed: &TimedArgs) -> Result<(), LabError> {
    let segments = parse_list("segments", segments, |s| s.parse::<u32>().ok().filter(|n| (1..=4096).contains(n)))
        .map_err(usage)?;
    let run = scaling_run(vec![], timed);
    print_table(&scaling::posing_markdown(&scaling::posing(&run, &segments).map_err(usage)?), &timed.out)
}

/// The sun run's scenes and angles (`scene` or a finite angle in [0, 1.4] rad).
fn parse_sun(scenes: &str, angles: &str) -> Result<(Vec<SceneId>, Vec<Option<f32>>), LabError> {
    let scenes = parse_list("scenes", scenes, SceneId::parse).map_err(usage)?;
    let angles = parse_list("angles", angles, |s| match s {
        "scene" => Some(None),
        _ => s.parse::<f32>().ok().filter(|a| (0.0..=1.4).contains(a)).map(Some),
    })
    .map_err(usage)?;
    Ok((scenes, angles))
}

fn usage(e: String) -> LabError {
    LabError::Usage(e)
}

fn write(path: &std::path::Path, text: &str) -> Result<(), LabError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| LabError::Io(dir.display().to_string(), e))?;
    }
    std::fs::write(path, text).map_err(|e| LabError::Io(path.display().to_string(), e))
}

fn inputs(args: &MeasureArgs) -> Result<Vec<measure::Input>, LabError> {
    let disk = |light: Light| match light {
        Light::Disk(d) => Ok(d),
        Light::Rect(_) | Light::Sun(_) | Light::Sphere(_) => Err(usage("measure needs a disk light".into())),
    };
    if let Some(list) = &args.blob_triangles {
        let counts =
            parse_list("blob-triangles", list, |s| s.parse::<u32>().ok().filter(|n| *n >= 8)).map_err(usage)?;
        let b = SceneId::DenseBlob.build();
        return counts
            .into_iter()
            .map(|n| {
                let blob = SceneObject::new("blob", shapes::bumpy_blob(n), Affine3A::from_translation(Vec3::Y * 1.5))
                    .map_err(|e| usage(format!("blob of {n} triangles: {e}")))?;
                let scene = Scene::new(vec![b.scene.objects[0].clone(), blob]);
                Ok(measure::Input {
                    name: format!("blob-{n}"),
                    scene,
                    gltf: None,
                    light: disk(b.light)?,
                    camera: b.camera,
                })
            })
            .collect();
    }
    let names: Vec<String> = match &args.gltf {
        Some(_) => vec![String::new()],
        None => args.scenes.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect(),
    };
    names
        .into_iter()
        .map(|name| {
            let loaded = SceneArgs {
                scene: if name.is_empty() { "box-over-plane".into() } else { name },
                gltf: args.gltf.clone(),
                light_center: None,
                light_normal: None,
                radius: None,
                rect: None,
                point: false,
                sun_direction: None,
                sun_angle: 0.05,
            }
            .load()?;
            Ok(measure::Input {
                name: loaded.name.rsplit('/').next().unwrap_or(&loaded.name).to_string(),
                scene: loaded.scene,
                gltf: args.gltf.clone(),
                light: disk(loaded.light)?,
                camera: loaded.camera,
            })
        })
        .collect()
}

fn run_measure(args: MeasureArgs) -> Result<(), LabError> {
    let techniques = parse_list("methods", &args.methods, Technique::parse).map_err(usage)?;
    let layers = parse_list("layers", &args.layers, |s| s.parse::<u32>().ok().filter(|l| *l >= 1)).map_err(usage)?;
    let refinement = parse_list("refinement", &args.refinement, |s| match s {
        "on" => Some(true),
        "off" => Some(false),
        _ => None,
    })
    .map_err(usage)?;
    let falloffs = parse_list("falloff", &args.falloff, Falloff::parse).map_err(usage)?;
    let maps = parse_list("map-resolution", &args.map_resolution, |s| {
        s.parse::<u32>().ok().filter(|r| (16..=4096).contains(r))
    })
    .map_err(usage)?;
    let coverage_samples = parse_list("coverage-samples", &args.coverage_samples, |s| {
        s.parse::<u32>().ok().filter(|n| (1..=256).contains(n))
    })
    .map_err(usage)?;
    let radii = match &args.radius {
        Some(list) => Some(
            parse_list("radius", list, |s| s.parse::<f32>().ok().filter(|r| r.is_finite() && *r >= 0.0))
                .map_err(usage)?,
        ),
        None => None,
    };
    if args.frames == 0 || args.width == 0 || args.height == 0 {
        return Err(usage("--frames, --width and --height must be at least 1".into()));
    }
    let options = measure::Options {
        width: args.width,
        height: args.height,
        warmup: args.warmup,
        frames: args.frames,
        samples: if args.no_truth { 0 } else { args.samples.clamp(1, 1 << 16) },
        moving_light: args.moving_light,
        extraction: match args.extraction.as_str() {
            "gpu" => FinExtraction::Gpu,
            "cpu" => FinExtraction::Cpu,
            other => return Err(LabError::Usage(format!("--extraction: `{other}` is neither gpu nor cpu"))),
        },
    };
    let inputs = inputs(&args)?;
    let plans: Vec<_> = inputs
        .iter()
        .map(|input| {
            let base_radius = input.light.radius;
            let axes = Axes {
                techniques: techniques.clone(),
                layers: layers.clone(),
                refinement: refinement.clone(),
                falloffs: falloffs.clone(),
                map_resolutions: maps.clone(),
                radii: radii.clone().unwrap_or_else(|| vec![base_radius]),
                coverage_samples: coverage_samples.clone(),
                base_layers: args.base_layers,
                base_map_resolution: args.base_map_resolution,
                base_radius,
            };
            axes.configs(args.full)
        })
        .collect();
    let total: usize = plans.iter().map(Vec::len).sum();
    let mut done = 0usize;
    let mut all_rows: Vec<Row> = vec![];
    let mut targets = vec![];
    for (input, configs) in inputs.iter().zip(&plans) {
        let mut progress = |c: &shadow_fins_lab::grid::Config| {
            done += 1;
            let filled = done * 30 / total.max(1);
            eprint!(
                "\r[{}{}] {done}/{total} {}: {:<40}",
                "#".repeat(filled),
                "-".repeat(30 - filled),
                input.name,
                c.label()
            );
            std::io::stderr().flush().ok();
        };
        let result =
            measure::measure(input, configs, &options, input.light.radius, &mut progress).map_err(LabError::Usage)?;
        eprintln!();
        println!(
            "### {} ({} triangles, light radius {})\n",
            input.name,
            input.scene.triangle_count(),
            input.light.radius
        );
        println!("{}", results::markdown(&result.rows));
        targets.extend(results::targets(&input.name, &result.rows));
        // Every method: the GPU's frame times, and the CPU-only methods' CPU
        // times, marked as such (not a ratio with the GPU's).
        let points: Vec<Point> = result
            .rows
            .iter()
            .filter_map(|r| {
                let t = r.config.technique;
                let series = if t.is_rendered() { t.name().to_string() } else { format!("{} (CPU)", t.name()) };
                r.metrics.map(|m| Point { series, time_ms: r.frame_ms.median, error: m.mae as f64 })
            })
            .collect();
        if !points.is_empty() {
            let path = args.out.join(format!("{}-pareto.png", input.name));
            pareto_plot(
                &format!("{}: MAE vs time", input.name),
                "ms (log): GPU frame, or CPU for (CPU)",
                "MAE",
                &points,
            )
            .save_png(&path)?;
            eprintln!("wrote {}", path.display());
        }
        if let Some(strip) = &result.strip {
            let path = args.out.join(format!("{}-strip.png", input.name));
            strip.save_png(&path)?;
            eprintln!("wrote {}", path.display());
        }
        all_rows.extend(result.rows);
    }
    if !targets.is_empty() {
        println!("### Targets\n\n| scene | target | measured | verdict |\n|---|---|---|---|\n{}\n", targets.join("\n"));
    }
    let csv = args.out.join("measure.csv");
    write(&csv, &results::csv(&all_rows))?;
    eprintln!("wrote {}", csv.display());
    if let Some(path) = &args.json {
        write(path, &results::json(&all_rows))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

fn run_stability(cases: &str, samples: u32, method: &str, out: Option<PathBuf>) -> Result<ExitCode, LabError> {
    let Some((_, method)) = stability::METHODS.iter().find(|(name, _)| *name == method) else {
        let names: Vec<&str> = stability::METHODS.iter().map(|(name, _)| *name).collect();
        return Err(usage(format!("unknown method '{method}': use {}", names.join(", "))));
    };
    let wanted: Vec<&str> = cases.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
    let all = stability::cases();
    for w in &wanted {
        if !all.iter().any(|c| c.name == *w) {
            let names: Vec<&str> = all.iter().map(|c| c.name).collect();
            return Err(usage(format!("unknown case '{w}': use {}", names.join(", "))));
        }
    }
    let selected: Vec<_> = all.into_iter().filter(|c| wanted.is_empty() || wanted.contains(&c.name)).collect();
    let mut outcomes = vec![];
    for (i, case) in selected.iter().enumerate() {
        eprint!("\r[{}/{}] {:<40}", i + 1, selected.len(), case.name);
        std::io::stderr().flush().ok();
        outcomes.push(stability::run(case, samples, *method));
    }
    eprintln!();
    let table = stability::markdown(&outcomes);
    println!("{table}");
    if let Some(path) = &out {
        write(path, &table)?;
    }
    let bad: Vec<&str> = outcomes.iter().filter(|o| o.non_finite > 0 || o.error.is_some()).map(|o| o.name).collect();
    if bad.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!("NaN/Inf in the visibility buffer (or no render) in: {}", bad.join(", "));
        Ok(ExitCode::FAILURE)
    }
}
