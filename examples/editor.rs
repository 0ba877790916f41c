//! The editor: `cargo run --example editor -- [scene.gltf] [--settings FILE.ron] [--screenshot PATH --frames N]`.
//! Without a display, run it under `xvfb-run -a` (see `scripts/run.sh`).
use shadow_fins_editor::EditorOptions;

fn main() -> bevy::app::AppExit {
    match EditorOptions::parse(std::env::args().skip(1)) {
        Ok(options) => shadow_fins_editor::run(options),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
}
