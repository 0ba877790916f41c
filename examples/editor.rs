//! The editor: `cargo run --example editor -- [scene.gltf] [--settings FILE.ron] [--screenshot PATH --frames N]`.
//! Without a display, run it under `xvfb-run -a` (see `scripts/run.sh`).
fn main() -> bevy::app::AppExit {
    shadow_fins_editor::main_from_args()
}
