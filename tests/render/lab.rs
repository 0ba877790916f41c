//! The rendered lab: `measure` scores every technique on the same pixels and
//! ranks them as the ground truth does; `stability` finds no NaN in the
//! extremes; the binary writes what it says it writes.

use std::{path::PathBuf, process::Command};

use shadow_fins::{light::Light, oracle::Method, refine::Falloff, scenes::SceneId};
use shadow_fins_app::render_lab::{measure, stability};
use shadow_fins_lab::grid::{Axes, Technique};

fn near_contact() -> measure::Input {
    let b = SceneId::NearContact.build();
    let Light::Disk(light) = b.light else { unreachable!("near-contact has a disk light") };
    measure::Input { name: "near-contact".into(), scene: b.scene, gltf: None, light, camera: b.camera }
}

#[test]
fn measure_ranks_fins_above_bevy_hard_shadows_and_reads_bevy_visibility_from_colour() {
    let input = near_contact();
    let axes = Axes {
        techniques: vec![
            Technique::Fins(Method::MultiLayer),
            Technique::BevyHard,
            Technique::BevyPcss,
            Technique::CpuOracle,
        ],
        layers: vec![16],
        refinement: vec![true],
        falloffs: vec![Falloff::DiskSegment],
        map_resolutions: vec![256],
        radii: vec![input.light.radius],
        coverage_samples: vec![256],
        base_layers: 16,
        base_map_resolution: 256,
        base_radius: input.light.radius,
    };
    let configs = axes.configs(false);
    assert_eq!(configs.len(), 4);
    let options = measure::Options {
        width: 96,
        height: 72,
        warmup: 1,
        frames: 3,
        samples: 128,
        moving_light: true,
        extraction: bevy_shadow_fins::FinExtraction::Gpu,
    };
    let mut seen = 0;
    let result =
        measure::measure(&input, &configs, &options, input.light.radius, &mut |_| seen += 1).expect("headless render");
    assert_eq!(seen, 4, "progress is reported per configuration");
    let row = |t: Technique| result.rows.iter().find(|r| r.config.technique == t).expect("row");
    let fins = row(Technique::Fins(Method::MultiLayer));
    let hard = row(Technique::BevyHard);
    let pcss = row(Technique::BevyPcss);
    let oracle = row(Technique::CpuOracle);
    for r in &result.rows {
        let m = r.metrics.expect("ground truth was on");
        assert!(m.count > 100, "{}: only {} pixels scored", r.config.label(), m.count);
        assert!(m.mae.is_finite() && r.frame_ms.median > 0.0, "{}: {m:?} {:?}", r.config.label(), r.frame_ms);
        assert_eq!(r.non_finite, 0, "{}", r.config.label());
    }
    assert_eq!(fins.frame_ms.samples, 3);
    // Bevy's shadows were really read from colour: they darken the scene (an
    // all-lit reading would make the error equal to the shadow's mean depth).
    let (fm, hm, pm) = (fins.metrics.unwrap(), hard.metrics.unwrap(), pcss.metrics.unwrap());
    assert!(hm.mae < 0.3 && pm.mae < 0.3, "Bevy rows look unshadowed: hard {hm:?} pcss {pm:?}");
    assert!(hm.umbra_over < 0.9);
    // Hard shadows of a 0.6-radius light are wrong across the penumbra; fins are not.
    assert!(fm.mae < hm.mae, "fins {} vs bevy-hard {}", fm.mae, hm.mae);
    // The GPU and the oracle implement the same semantics at the same map size.
    let om = oracle.metrics.unwrap();
    assert!((fm.mae - om.mae).abs() < 0.02, "GPU {} vs oracle {}", fm.mae, om.mae);
    // The compositing applied what the visibility buffer holds.
    let check = fins.color_check.expect("fins rows check colour against the buffer");
    assert!(check < 0.03, "colour ratio differs from the visibility buffer by {check}");
    let strip = result.strip.expect("a strip with ground truth");
    let distinct: std::collections::HashSet<[u8; 3]> = strip.pixels.iter().copied().collect();
    assert!(distinct.len() > 50, "the strip is nearly flat: {} colours", distinct.len());
    strip.save_png(&PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("lab/near-contact-strip.png")).expect("png");
}

#[test]
fn stability_extremes_put_no_nan_in_the_visibility_buffer() {
    let wanted =
        ["radius-0", "touching", "nan-and-empty-meshes", "scale-1e-4", "receiver-beyond-reference", "far-plane-1e6"];
    let cases: Vec<_> = stability::cases().into_iter().filter(|c| wanted.contains(&c.name)).collect();
    assert_eq!(cases.len(), wanted.len());
    for (case, (label, method)) in cases.iter().flat_map(|c| stability::METHODS.iter().map(move |m| (c, *m))) {
        let o = stability::run(case, 64, method);
        let coverage = method == Some(bevy_shadow_fins::FinMethod::Coverage);
        assert!(o.error.is_none(), "{} ({label}): {:?}", o.name, o.error);
        assert!(o.values > 0, "{}: nothing checked", o.name);
        assert_eq!((o.non_finite, o.out_of_range), (0, 0), "{} ({label})", o.name);
        let m = o.metrics.expect("ground truth was on");
        println!("{} ({label}): MAE {:.4}", o.name, m.mae);
        assert!(m.mae.is_finite(), "{} ({label})", o.name);
        // Both are (nearly) hard shadows, which every method reproduces — but
        // plateaus, which draw a tall box's whole penumbra outwards from its
        // hard shadow where the truth splits it about the edge (MAE 0.37).
        let plateaus = method == Some(bevy_shadow_fins::FinMethod::Plateaus);
        if o.name == "radius-0" || (o.name == "touching" && !plateaus) {
            assert!(m.mae < 0.1, "{} ({label}): MAE {}", o.name, m.mae);
        }
        if coverage && o.name != "receiver-beyond-reference" {
            // Exact up to its samples at every extreme (a 2e6-wide ground: the
            // lift must follow the pixel, not the scene's diagonal).
            assert!(m.mae < 0.02, "{} (coverage): MAE {}", o.name, m.mae);
        }
    }
}

fn lab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_shadow-fins-render-lab")).args(args).output().expect("the render-lab binary")
}

#[test]
fn the_render_lab_binary_writes_csv_json_plot_and_strip() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("render-lab-cli");
    let _ = std::fs::remove_dir_all(&dir);
    let json = dir.join("rows.json");
    let out = lab(&[
        "measure",
        "--scenes",
        "box-over-plane",
        "--methods",
        "fins,bevy-hard",
        "--layers",
        "4,16",
        "--refinement",
        "on",
        "--falloff",
        "disk-segment",
        "--map-resolution",
        "256",
        "--base-map-resolution",
        "256",
        "--frames",
        "2",
        "--warmup",
        "0",
        "--samples",
        "32",
        "--width",
        "64",
        "--height",
        "48",
        "--out",
        dir.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let csv = std::fs::read_to_string(dir.join("measure.csv")).expect("csv");
    // Header + fins 16L, bevy-hard, fins 4L.
    assert_eq!(csv.lines().count(), 4, "{csv}");
    let json = std::fs::read_to_string(&json).expect("json");
    assert_eq!(json.matches("\"method\"").count(), 3);
    assert!(dir.join("box-over-plane-pareto.png").exists() && dir.join("box-over-plane-strip.png").exists());
    assert!(stderr.contains("3/3"), "no progress bar: {stderr}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("fins 16L frame ≤ 3× bevy-hard"), "no targets table: {stdout}");
}

#[test]
fn the_render_lab_rejects_unknown_cases_and_methods_with_a_message() {
    let out = lab(&["stability", "--cases", "radius-zero"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("unknown case 'radius-zero'") && stderr.contains("radius-0"), "{stderr}");
    let out = lab(&["measure", "--methods", "fins,pcss"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--methods: cannot read 'pcss'"));
}
