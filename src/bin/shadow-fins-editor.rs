//! The editor as a binary target, so the rendering tests can run it
//! (`CARGO_BIN_EXE_shadow-fins-editor`); users run `cargo run --example editor`.
fn main() -> bevy::app::AppExit {
    shadow_fins_editor::main_from_args()
}
