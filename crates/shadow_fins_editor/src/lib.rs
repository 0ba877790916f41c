//! # shadow_fins_editor
//!
//! Live tuning of fin shadows: the light (position, direction, radius,
//! intensity, colour), the fins (layers, sub-layers, map resolution,
//! refinement, falloff), the method (hard, outer fins, single-layer,
//! multi-layer, Bevy's PCSS), every intermediate buffer, and the error against
//! a progressively computed ground truth — the other papers' methods too
//! (`peers.rs`: on the CPU, on the ground truth's grid, scored the same way).
//!
//! UI code is plain systems over resources (`ui.rs`); the UI edits the
//! [`LightParams`] and the light's `FinShadowSettings`, `scene.rs` turns them
//! into components, the plugin renders. Nothing else is shared.
//!
//! A glTF's animations play through Bevy's own animation (`animation.rs`).
//!
//! `cargo run --example editor -- [scene.gltf] [--settings FILE.ron]
//! [--screenshot PATH --frames N] [--autosave FILE.ron | --no-autosave]
//! [--animation-time SECONDS]`

mod animation;
mod autosave;
mod cli;
mod gltf_scene;
mod ground;
mod lights;
mod orbit;
mod peers;
mod picking;
mod scene;
mod settings_file;
mod state;
mod truth;
mod ui;
mod views;

pub use animation::EditorAnimation;
pub use cli::CliError;
pub use gltf_scene::{READABLE_LUX, readable_lumens};
pub use settings_file::{EditorSettings, SettingsFileError, check_settings_text};
pub use state::{AutosaveOption, EditorMethod, EditorOptions, LightParams, SceneSource, ViewKind};
pub use truth::GroundTruthStatus;

use bevy::{prelude::*, render::diagnostic::RenderDiagnosticsPlugin, window::WindowResolution};
use bevy_egui::EguiPlugin;
use bevy_shadow_fins::ShadowFinsPlugin;

/// What the editor shows and where it stands; the UI reads and edits it.
#[derive(Resource, Debug, Default)]
pub struct EditorState {
    /// The last error (a broken glTF, a settings file that did not parse):
    /// shown in the UI until dismissed; the editor keeps running.
    pub error: Option<String>,
    /// A one-line status (saved, loaded, screenshot written).
    pub status: Option<String>,
    /// The buffer shown over the viewport.
    pub view: ViewKind,
    /// The layer whose maps the map views show.
    pub layer: u32,
    /// Frames rendered so far.
    pub frames: u32,
}

/// The editor: scene, light, camera, panels, ground truth. Add it after
/// `DefaultPlugins`; it adds the fin-shadow plugin, egui and render diagnostics.
pub struct EditorPlugin {
    pub options: EditorOptions,
}

impl Plugin for EditorPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins((ShadowFinsPlugin, EguiPlugin::default(), RenderDiagnosticsPlugin))
            // The editor shows the G-buffer path (fin shadows reach forward
            // materials as well; the plugin leaves the app-wide choice to the app).
            .insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred())
            .insert_resource(self.options.clone())
            // `--view`: what the viewport shows from the first frame.
            .insert_resource(EditorState { view: self.options.view.unwrap_or_default(), ..default() });
        scene::build(app);
        orbit::build(app);
        views::build(app);
        truth::build(app);
        peers::build(app);
        ui::build(app);
        lights::build(app);
        picking::build(app);
        cli::build(app);
        autosave::build(app);
        animation::build(app);
    }
}

/// The editor's `main`: options from the command line (a usage error exits
/// with code 2), then [`run`].
pub fn main_from_args() -> AppExit {
    match EditorOptions::parse(std::env::args().skip(1)) {
        Ok(options) => run(options),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
}

/// Runs the editor with `options` in a window.
pub fn run(options: EditorOptions) -> AppExit {
    App::new()
        .add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: Some(Window {
                        title: "shadow fins editor".into(),
                        resolution: WindowResolution::new(1280, 800),
                        ..default()
                    }),
                    ..default()
                })
                // The user opens glTFs from anywhere (a path, a drop), not
                // only from Bevy's asset folder.
                .set(AssetPlugin { unapproved_path_mode: bevy::asset::UnapprovedPathMode::Allow, ..default() }),
        )
        .add_plugins(EditorPlugin { options })
        .run()
}
