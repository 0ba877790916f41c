//! `shadow-fins-lab`: measures the fin method against ground truth.
//!
//! - `visibility`: visibility at the points of a CSV, by one method;
//! - `image`: a camera view rendered by each method beside the ground truth,
//!   with error heat maps, and the error table;
//! - `report`: the error table of every built-in scene (for BENCHMARKS.md);
//! - `export-gltf`: writes a built-in scene as a glTF file;
//! - `make-assets`: writes our glTF test assets (courtyard, leaf cards,
//!   skinned arm, morph blob), the same bytes every run.

use std::{io::Write, path::PathBuf};

use clap::{Parser, Subcommand};
use shadow_fins::{
    glam::Vec3,
    oracle::{FinSettings, Method, Receiver},
    peers::PeerMethod,
    scene::LightSpaceScene,
    scenes::SceneId,
};

use shadow_fins_lab::{
    LabError,
    compare::{Comparison, Config, compare, markdown_table, standard_configs},
    eval::evaluate,
    picture::{Column, Picture, strip as strip_picture},
    plot::{Point, pareto_plot},
    setup::{FinArgs, SceneArgs, parse_measured, parse_vec3},
};

#[derive(Parser)]
#[command(
    name = "shadow-fins-lab",
    version,
    about = "Soft shadows by multi-layered shadow fins, measured against ground truth"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Visibility of the light at the points of a CSV (x,y,z[,nx,ny,nz] per line).
    Visibility {
        #[command(flatten)]
        scene: SceneArgs,
        #[command(flatten)]
        fins: FinArgs,
        /// CSV of world points: x,y,z or x,y,z,nx,ny,nz (a header line is skipped).
        #[arg(long)]
        points: PathBuf,
        /// ground-truth, coverage, fins, hard, outer-fins, single-layer, or a peer
        /// paper's method: single-sample (Parker et al. 1998), plateaus
        /// (Haines 2001; one receiver plane, see `shadow_fins::peers::plateaus`),
        /// penumbra-wedges (Assarsson, Akenine-Möller 2002), wedge-blending
        /// (Forest, Barthe, Paulin 2006), convolution or convolution-mipmap
        /// (Annen et al. 2008: 512² maps, order 4, summed-area tables or mipmaps).
        #[arg(long, default_value = "fins")]
        method: String,
        /// Output CSV (default: standard output).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Render the scene's view by each method beside the ground truth, with error maps.
    Image {
        #[command(flatten)]
        scene: SceneArgs,
        #[command(flatten)]
        fins: FinArgs,
        /// Camera position x,y,z (default: the scene's).
        #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
        camera_position: Option<Vec3>,
        /// Camera target x,y,z.
        #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
        camera_target: Option<Vec3>,
        #[arg(long, default_value_t = 240)]
        width: u32,
        #[arg(long, default_value_t = 180)]
        height: u32,
        /// Output PNG.
        #[arg(long, default_value = "out/image.png")]
        out: PathBuf,
    },
    /// Error tables of every built-in scene against ground truth (markdown).
    Report {
        #[command(flatten)]
        fins: FinArgs,
        /// Scenes to measure (default: all but dense-blob, whose ground truth is slow).
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<String>,
        #[arg(long, default_value_t = 160)]
        width: u32,
        #[arg(long, default_value_t = 120)]
        height: u32,
        /// Also write each scene's image strip into this folder.
        #[arg(long)]
        images: Option<PathBuf>,
        /// Light each scene by a rectangle of its disk's area and this
        /// width ÷ height (width along world x) instead of the disk.
        #[arg(long, conflicts_with = "point")]
        rect_aspect: Option<f32>,
        /// Light each scene by a sphere (a point light with a size) of its
        /// disk's radius at the disk's centre instead of the disk.
        #[arg(long)]
        point: bool,
    },
    /// Environment lighting (Annen et al. 2008 §4.2): the scene under a sky
    /// cube map fitted with area lights at each threshold, each shadowed by
    /// convolution shadow maps, a hard ray or exactly, against every texel
    /// of the map as a light (markdown table, and an image strip at the
    /// middle threshold).
    Environment {
        #[arg(long, default_value = "kitbash")]
        scene: String,
        /// Fit thresholds `t` (larger: more, smaller lights).
        #[arg(long, value_delimiter = ',', default_value = "0.03,0.06,0.12")]
        thresholds: Vec<f32>,
        /// Texels per cube face side (the truth casts 6 × cube² rays a pixel).
        #[arg(long, default_value_t = 24)]
        cube: usize,
        #[arg(long, default_value_t = 80)]
        width: u32,
        #[arg(long, default_value_t = 60)]
        height: u32,
        /// Output PNG (the strip).
        #[arg(long, default_value = "out/environment.png")]
        out: PathBuf,
    },
    /// Write a built-in scene as a self-contained glTF file.
    ExportGltf {
        #[arg(long, default_value = "box-over-plane")]
        scene: String,
        #[arg(long)]
        out: PathBuf,
    },
    /// Write our own glTF test assets (a textured courtyard with a node
    /// hierarchy, a spot light and a camera; alpha-masked leaf cards; a
    /// skinned arm; a morph-target blob), the same bytes every run.
    MakeAssets {
        /// Folder to write them into (made if missing).
        #[arg(long, default_value = "assets")]
        out: PathBuf,
    },
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli.command) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run(command: Command) -> Result<(), LabError> {
    match command {
        Command::Visibility { scene, fins, points, method, out } => {
            let loaded = scene.load()?;
            let settings = fins.settings()?;
            let measured = parse_measured(&method, fins.coverage_samples)?;
            let pts = read_points(&points)?;
            let mut ls = LightSpaceScene::new(&loaded.scene, loaded.light);
            let receivers: Vec<Receiver> = pts
                .iter()
                .map(|(p, n)| Receiver {
                    position: ls.frame.to_frame(*p),
                    normal: ls.frame.dir_to_frame(n.normalize_or_zero()),
                })
                .collect();
            // Points beyond the scene's deepest surface get fins wide enough for them.
            ls.cover_receivers(receivers.iter().map(|r| r.position));
            let ev = evaluate(&loaded.scene, &ls, measured, settings, fins.map_resolution, fins.samples, &receivers);
            let mut text = String::from("x,y,z,visibility\n");
            for ((p, _), v) in pts.iter().zip(&ev.values) {
                text += &format!("{},{},{},{v:.6}\n", p.x, p.y, p.z);
            }
            write_text(out.as_deref(), &text)?;
            eprintln!("{method}: {} points in {:.1} ms", pts.len(), ev.total_ms());
        }
        Command::Image { scene, fins, camera_position, camera_target, width, height, out } => {
            let mut loaded = scene.load()?;
            if let Some(p) = camera_position {
                loaded.camera.position = p;
            }
            if let Some(t) = camera_target {
                loaded.camera.target = t;
            }
            let settings = fins.settings()?;
            let configs = standard_configs(settings, fins.coverage_samples);
            let c = compare(
                &loaded,
                width.clamp(8, 4096),
                height.clamp(8, 4096),
                &configs,
                fins.map_resolution,
                fins.samples,
            );
            println!("{}", title(&loaded.name, &loaded.light, &fins));
            println!("{}", markdown_table(&c));
            strip(&c).save_png(&out)?;
            eprintln!("wrote {}", out.display());
        }
        Command::Environment { scene, thresholds, cube, width, height, out } => {
            let id = SceneId::parse(&scene).ok_or_else(|| LabError::Usage(format!("unknown scene '{scene}'")))?;
            let thresholds: Vec<f32> = thresholds.into_iter().filter(|t| t.is_finite() && *t > 0.0).collect();
            if thresholds.is_empty() {
                return Err(LabError::Usage("--thresholds needs at least one positive number".into()));
            }
            let m = shadow_fins_lab::environment::measure(
                id,
                width.clamp(8, 1024),
                height.clamp(8, 1024),
                cube.clamp(4, 128),
                &thresholds,
            );
            println!("### {scene} under a sky ({}² texels a face)\n", cube.clamp(4, 128));
            println!("{}", shadow_fins_lab::environment::markdown(&m));
            m.strip.save_png(&out)?;
            eprintln!("wrote {}", out.display());
        }
        Command::Report { fins, scenes, width, height, images, rect_aspect, point } => {
            let settings = fins.settings()?;
            let ids: Vec<SceneId> = if scenes.is_empty() {
                SceneId::ALL.into_iter().filter(|s| *s != SceneId::DenseBlob).collect()
            } else {
                scenes
                    .iter()
                    .map(|s| SceneId::parse(s).ok_or_else(|| LabError::Usage(format!("unknown scene '{s}'"))))
                    .collect::<Result<_, _>>()?
            };
            let mut configs = standard_configs(settings, fins.coverage_samples);
            for f in shadow_fins::refine::Falloff::ALL {
                if f != settings.falloff {
                    let s = FinSettings { falloff: f, ..settings };
                    configs.push(Config::new(Method::MultiLayer, s).labelled(format!(
                        "fins {}L {}",
                        s.layers,
                        f.name()
                    )));
                }
            }
            let coverage_label = Config::coverage(fins.coverage_samples).label;
            let mut accuracy = String::from(
                "| scene | coverage MAE | p99 | umbra over | outer-fins ÷ coverage MAE | MAE ≤ 0.01 | p99 ≤ 0.08 | umbra over ≤ 0.1% | ≥ 3× outer-fins |\n|---|---|---|---|---|---|---|---|---|\n",
            );
            let mut cost = String::from(
                "| scene | potential silhouettes | edges per pixel's cell p50 / p99 (mean) | within its footprint p50 / p99 (mean) | edges counted per pixel p50 / p99 (mean) | coverage prepare + evaluate ms | fins 16L prepare + evaluate ms |\n|---|---|---|---|---|---|---|\n",
            );
            let mut targets = String::from(
                "| scene | hard MAE | outer-fins MAE | fins 16L paper MAE | fins 16L MAE | beats hard & outer (paper / ours) | umbra over (paper / ours) |\n|---|---|---|---|---|---|---|\n",
            );
            let mut peers = format!(
                "| scene | fins {}L MAE |{}\n|---|---|{}\n",
                settings.layers,
                PeerMethod::ALL
                    .map(|m| format!(" {} ({}) MAE / p99 / umbra over / leak |", m.name(), m.paper()))
                    .concat(),
                "---|".repeat(PeerMethod::ALL.len())
            );
            // Per configuration over all scenes: (MAE sum, total ms, scenes).
            let mut overall: Vec<(String, f64, f64, u32)> = vec![];
            for id in ids {
                let args = SceneArgs {
                    scene: id.name().into(),
                    gltf: None,
                    light_center: None,
                    light_normal: None,
                    radius: None,
                    rect: None,
                    point,
                    sun_direction: None,
                    sun_angle: 0.05,
                };
                let mut loaded = args.load()?;
                if let Some(aspect) = rect_aspect {
                    loaded.light = disk_as_rect(loaded.light, aspect)?;
                }
                let c = compare(&loaded, width, height, &configs, fins.map_resolution, fins.samples);
                println!("### {}\n", title(&loaded.name, &loaded.light, &fins));
                println!("{}", markdown_table(&c));
                std::io::stdout().flush().ok();
                if let Some(dir) = &images {
                    strip(&c).save_png(&dir.join(format!("{}.png", id.name())))?;
                }
                for r in &c.rows {
                    let i = overall.iter().position(|o| o.0 == r.config.label).unwrap_or_else(|| {
                        overall.push((r.config.label.clone(), 0.0, 0.0, 0));
                        overall.len() - 1
                    });
                    overall[i].1 += r.metrics.mae as f64;
                    overall[i].2 += r.evaluation.total_ms();
                    overall[i].3 += 1;
                }
                let row = |label: &str| c.rows.iter().find(|r| r.config.label == label);
                let mae = |label: &str| row(label).map(|r| r.metrics);
                if let (Some(cov), Some(o)) = (row(&coverage_label), mae("outer-fins")) {
                    let m = cov.metrics;
                    let yes = |ok: bool| if ok { "yes" } else { "**no**" };
                    let ratio = o.mae / m.mae.max(1e-6);
                    accuracy += &format!(
                        "| {} | {:.4} | {:.3} | {:.2}% | {:.1}× | {} | {} | {} | {} |\n",
                        id.name(),
                        m.mae,
                        m.p99,
                        m.umbra_over * 100.0,
                        ratio,
                        yes(m.mae <= 0.01),
                        yes(m.p99 <= 0.08),
                        yes(m.umbra_over <= 0.001),
                        yes(ratio >= 3.0)
                    );
                    if let Some(w) = cov.evaluation.work {
                        let fins_ms =
                            row(&format!("fins {}L", settings.layers)).map_or(f64::NAN, |r| r.evaluation.total_ms());
                        cost += &format!(
                            "| {} | {} | {} / {} ({:.1}) | {} / {} ({:.1}) | {} / {} ({:.1}) | {:.1} | {:.1} |\n",
                            id.name(),
                            cov.evaluation.silhouettes,
                            w.cell_edges[0],
                            w.cell_edges[1],
                            w.mean_cell_edges,
                            w.reaching_edges[0],
                            w.reaching_edges[1],
                            w.mean_reaching_edges,
                            w.counted_edges[0],
                            w.counted_edges[1],
                            w.mean_counted_edges,
                            cov.evaluation.total_ms(),
                            fins_ms
                        );
                    }
                }
                let fins_label = format!("fins {}L", settings.layers);
                if let Some(f) = mae(&fins_label) {
                    let four = |m: Option<shadow_fins::metrics::ErrorMetrics>| {
                        m.map_or(" – |".to_string(), |m| {
                            format!(
                                " {:.4} / {:.3} / {:.2}% / {:.2}% |",
                                m.mae,
                                m.p99,
                                m.umbra_over * 100.0,
                                m.leak * 100.0
                            )
                        })
                    };
                    let cells = PeerMethod::ALL.map(|m| four(mae(m.name()))).concat();
                    peers += &format!("| {} | {:.4} |{cells}\n", id.name(), f.mae);
                }
                let paper_label = format!("fins {}L paper", settings.layers);
                if let (Some(h), Some(o), Some(p), Some(f)) =
                    (mae("hard"), mae("outer-fins"), mae(&paper_label), mae(&fins_label))
                {
                    let beats = |m: f32| if m < h.mae && m < o.mae { "yes" } else { "**no**" };
                    targets += &format!(
                        "| {} | {:.4} | {:.4} | {:.4} | {:.4} | {} / {} | {:.2}% / {:.2}% |\n",
                        id.name(),
                        h.mae,
                        o.mae,
                        p.mae,
                        f.mae,
                        beats(p.mae),
                        beats(f.mae),
                        p.umbra_over * 100.0,
                        f.umbra_over * 100.0
                    );
                }
            }
            println!("### Targets\n\n{targets}");
            let mut table = String::from(
                "| method | mean MAE over the scenes | CPU ms, all scenes (prepare + evaluate) |\n|---|---|---|\n",
            );
            let points: Vec<Point> = overall
                .iter()
                .map(|(label, mae, ms, n)| {
                    let n = (*n).max(1) as f64;
                    table += &format!("| {label} | {:.4} | {ms:.0} |\n", mae / n);
                    Point { series: method_family(label).to_string(), time_ms: *ms, error: mae / n }
                })
                .collect();
            println!(
                "### Speed against accuracy, every method ({} threads; Bevy's own shadows are in the rendered lab)\n\n{table}",
                rayon::current_num_threads()
            );
            if let Some(dir) = &images {
                let path = dir.join("pareto.png");
                pareto_plot("every method: mean MAE vs CPU time", "CPU ms, all scenes (log)", "mean MAE", &points)
                    .save_png(&path)?;
                eprintln!("wrote {}", path.display());
            }
            println!(
                "### Peers (other papers' methods; plateaus shade only their receiver plane, other receivers get the hard shadow)\n\n{peers}"
            );
            println!(
                "### Accuracy targets of the coverage method ({coverage_label}, against {} ground-truth samples)\n\n{accuracy}",
                fins.samples
            );
            println!(
                "### Cost of the coverage method per pixel ({width}×{height} view, {} threads)\n\n{cost}",
                rayon::current_num_threads()
            );
        }
        Command::ExportGltf { scene, out } => {
            let id = SceneId::parse(&scene).ok_or_else(|| LabError::Usage(format!("unknown scene '{scene}'")))?;
            let text = shadow_fins::gltf_import::write_gltf(&id.build().scene);
            write_text(Some(&out), &text)?;
            eprintln!("wrote {}", out.display());
        }
        Command::MakeAssets { out } => {
            for path in shadow_fins_lab::assets::write_all(&out)? {
                eprintln!("wrote {}", path.display());
            }
        }
    }
    Ok(())
}

/// The method a configuration's label belongs to (one colour per method on the plot).
fn method_family(label: &str) -> &str {
    if label.starts_with("fins") {
        if label.contains("paper") { "fins (paper)" } else { "fins (ours)" }
    } else if label.starts_with("coverage") {
        "coverage"
    } else if label.starts_with("convolution") {
        "convolution"
    } else {
        label
    }
}

/// A rectangle of the disk's area `πR²` and `width ÷ height = aspect`,
/// centred and facing as the disk, its width along world x (z when the disk
/// faces along x).
fn disk_as_rect(light: shadow_fins::light::Light, aspect: f32) -> Result<shadow_fins::light::Light, LabError> {
    use shadow_fins::light::{Light, RectLight};
    let Light::Disk(d) = light else { return Ok(light) };
    if !(aspect > 0.0 && aspect.is_finite()) {
        return Err(LabError::Usage(format!("--rect-aspect {aspect}: give a width ÷ height > 0")));
    }
    Ok(Light::Rect(RectLight::with_area_of(&d, aspect)?))
}

fn title(name: &str, light: &shadow_fins::light::Light, fins: &FinArgs) -> String {
    let light = match light {
        shadow_fins::light::Light::Disk(d) => format!("disk light R = {}", d.radius),
        shadow_fins::light::Light::Rect(r) => {
            format!("rect light {} x {}", r.half_extents.x * 2.0, r.half_extents.y * 2.0)
        }
        shadow_fins::light::Light::Sun(s) => format!("sun θ = {} rad", s.angular_radius),
        shadow_fins::light::Light::Sphere(s) => format!("sphere light R = {} (six cube faces)", s.radius),
    };
    let oracle = match fins.map_resolution {
        Some(r) => format!("raster oracle {r}²"),
        None => "analytic oracle".into(),
    };
    format!("{name}: {light}, {oracle}, ground truth {} samples", fins.samples)
}

/// Top row: visibility per method and the ground truth; bottom row: error maps.
fn strip(c: &Comparison) -> Picture {
    let columns: Vec<Column> = c
        .rows
        .iter()
        .map(|r| Column { label: r.config.label.clone(), values: c.pixels(&r.evaluation.values), mae: r.metrics.mae })
        .collect();
    strip_picture(c.width, c.height, &columns, &c.pixels(&c.reference.values))
}

fn read_points(path: &std::path::Path) -> Result<Vec<(Vec3, Vec3)>, LabError> {
    let text = std::fs::read_to_string(path).map_err(|e| LabError::Io(path.display().to_string(), e))?;
    shadow_fins_lab::points::parse_points(&text)
}

fn write_text(path: Option<&std::path::Path>, text: &str) -> Result<(), LabError> {
    match path {
        Some(p) => {
            if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|e| LabError::Io(dir.display().to_string(), e))?;
            }
            std::fs::write(p, text).map_err(|e| LabError::Io(p.display().to_string(), e))
        }
        None => {
            print!("{text}");
            Ok(())
        }
    }
}
