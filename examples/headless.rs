//! Renders the demo scene (or a glTF given as argument, loaded by Bevy's own
//! loader with its materials, textures, lights and camera) headless with the
//! plugin and writes the final image as a PNG, and its visibility
//! (illuminance) buffer beside it (`…_visibility.png`).
//!
//! `cargo run --release --example headless -- [scene.gltf] [--out out/headless.png]`
//!
//! A glTF's own spot and directional lights get fin shadows (radius from
//! their `extras`, else 5% of the scene's size) and its first camera is the
//! view; without them, the core's default view (inside a room when the
//! scene is one) and a light bright enough for Bevy's default exposure.

use shadow_fins::scenes::SceneId;
use shadow_fins_app::harness::{Setup, render};

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
    let (width, height) = (640, 480);
    let mut setup = match gltf {
        Some(path) => {
            // The core's reading sizes the default view (Bevy's sizes the rest).
            let import = shadow_fins::gltf_import::load_gltf(path).map_err(|e| e.to_string())?;
            for s in &import.skipped {
                eprintln!("warning: skipped {s}");
            }
            let view = shadow_fins::default_view::default_view_of(&import.scene).ok_or("no mesh in the file")?;
            let extent = import.scene.diagonal().unwrap_or(1.0);
            let mut setup = Setup::new(import.scene, view.light, view.camera, Default::default(), (width, height));
            setup.gltf = Some(path.into());
            (setup.gltf_lights, setup.gltf_camera, setup.gltf_light_radius) = (true, true, extent * 0.05);
            setup.intensity = shadow_fins_editor::readable_lumens(view.light_distance);
            // Wide enough for the file's camera too (the view's are the default camera's).
            (setup.near, setup.far) = (Some(view.near.min(extent * 1e-3)), Some(view.far.max(extent * 100.0)));
            setup
        }
        None => {
            let demo = SceneId::Demo.build();
            Setup::new(demo.scene, demo.light, demo.camera, Default::default(), (width, height))
        }
    };
    setup.hdr = true;
    setup.tonemapping = bevy::core_pipeline::tonemapping::Tonemapping::TonyMcMapface;
    let shot = render(&setup, 8)?;
    let visibility_out = match out.strip_suffix(".png") {
        Some(stem) => format!("{stem}_visibility.png"),
        None => format!("{out}_visibility.png"),
    };
    shot.save_color(&out)?;
    shot.save_visibility(&visibility_out)?;
    println!("wrote {visibility_out}");
    let s = shot.stats;
    println!(
        "wrote {out}: {} casters, {} triangles, {} silhouette edges, {} fins, {} layers, extraction {:.2} ms",
        s.casters, s.triangles, s.silhouettes, s.fins, s.layers, s.extract_ms
    );
    Ok(())
}
