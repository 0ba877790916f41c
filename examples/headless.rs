//! Renders the demo scene (or a glTF given as argument) headless with the
//! plugin and writes the final image as a PNG, and its visibility
//! (illuminance) buffer beside it (`…_visibility.png`).
//!
//! `cargo run --release --example headless -- [scene.gltf] [--out out/headless.png]`
//!
//! A glTF gets a light of radius 5% of its size, 1× its size above its centre.

use shadow_fins::scenes::SceneId;
use shadow_fins_app::harness::{Setup, render, save_srgb8};

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .cloned()
        .unwrap_or("out/headless.png".into());
    let gltf = args.iter().find(|a| !a.starts_with("--") && Some(*a) != Some(&out));
    let (scene, light, camera) = match gltf {
        Some(path) => {
            let import = shadow_fins::gltf_import::load_gltf(path).map_err(|e| e.to_string())?;
            for s in &import.skipped {
                eprintln!("warning: skipped {s}");
            }
            let (light, camera) = shadow_fins::scenes::default_view(&import.scene).ok_or("empty scene")?;
            (import.scene, light, camera)
        }
        None => {
            let demo = SceneId::Demo.build();
            (demo.scene, demo.light, demo.camera)
        }
    };
    let (width, height) = (640, 480);
    let mut setup = Setup::new(scene, light, camera, Default::default(), (width, height));
    setup.hdr = true;
    setup.tonemapping = bevy::core_pipeline::tonemapping::Tonemapping::TonyMcMapface;
    let shot = render(&setup, 8)?;
    let gray: Vec<[u8; 4]> = shot
        .visibility
        .iter()
        .map(|v| {
            let g = (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8;
            [g, g, g, 255]
        })
        .collect();
    let visibility_out = match out.strip_suffix(".png") {
        Some(stem) => format!("{stem}_visibility.png"),
        None => format!("{out}_visibility.png"),
    };
    for (pixels, path) in [(&shot.color, &out), (&gray, &visibility_out)] {
        save_srgb8(width, height, pixels, path)?;
    }
    println!("wrote {visibility_out}");
    let s = shot.stats;
    println!(
        "wrote {out}: {} casters, {} triangles, {} silhouette edges, {} fins, {} layers, extraction {:.2} ms",
        s.casters, s.triangles, s.silhouettes, s.fins, s.layers, s.extract_ms
    );
    Ok(())
}
