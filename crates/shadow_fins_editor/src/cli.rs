//! Command line: the scene, a settings file, and the screenshot mode tests and
//! docs use (`--screenshot PATH --frames N`: render N frames, save the whole
//! window, panels included, exit).

use bevy::{
    prelude::*,
    render::view::screenshot::{Screenshot, ScreenshotCaptured},
};

use crate::{EditorOptions, EditorState};

/// A command line that could not be understood.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CliError {
    #[error("{0} needs a value")]
    MissingValue(&'static str),
    #[error("--frames must be a whole number ≥ 1, got {0:?}")]
    BadFrames(String),
    #[error("--animation-time must be a finite number of seconds, got {0:?}")]
    BadAnimationTime(String),
    #[error(
        "--view: unknown view {0:?} (final, visibility, layer-index, slab-depth, inner-map, outer-map, error, peer, peer-error)"
    )]
    BadView(String),
    #[error(
        "--peer: unknown method {0:?} (single-sample, plateaus, penumbra-wedges, wedge-blending, convolution, convolution-mipmap)"
    )]
    BadPeer(String),
    #[error(
        "unknown option {0:?} (options: [scene.gltf] --settings FILE --screenshot PATH --frames N --autosave FILE --no-autosave --view NAME --peer METHOD --animation-time SECONDS --no-ground)"
    )]
    Unknown(String),
}

/// Frames the screenshot may take to arrive before the editor gives up.
const SCREENSHOT_TIMEOUT_FRAMES: u32 = 300;

impl EditorOptions {
    /// Parses the arguments after the program name.
    pub fn parse(args: impl IntoIterator<Item = String>) -> Result<Self, CliError> {
        let mut options = Self::default();
        let mut args = args.into_iter();
        while let Some(arg) = args.next() {
            let mut value = |name: &'static str| args.next().ok_or(CliError::MissingValue(name));
            match arg.as_str() {
                "--screenshot" => options.screenshot = Some(value("--screenshot")?.into()),
                "--settings" => options.settings = Some(value("--settings")?.into()),
                "--autosave" => {
                    options.autosave = crate::AutosaveOption::Path(value("--autosave")?.into());
                }
                "--no-autosave" => options.autosave = crate::AutosaveOption::Off,
                "--no-ground" => options.add_ground = false,
                "--frames" => {
                    let v = value("--frames")?;
                    options.frames = v.parse().ok().filter(|n| *n >= 1).ok_or(CliError::BadFrames(v))?;
                }
                "--view" => {
                    let v = value("--view")?;
                    options.view = Some(crate::ViewKind::parse(&v).ok_or(CliError::BadView(v))?);
                }
                "--peer" => {
                    let v = value("--peer")?;
                    options.peer = Some(shadow_fins::peers::PeerMethod::parse(&v).ok_or(CliError::BadPeer(v))?);
                }
                "--animation-time" => {
                    let v = value("--animation-time")?;
                    let seconds = v.parse::<f32>().ok().filter(|s| s.is_finite());
                    options.animation_time = Some(seconds.ok_or(CliError::BadAnimationTime(v))?);
                }
                a if a.starts_with("--") => return Err(CliError::Unknown(arg)),
                _ => options.scene = Some(arg.into()),
            }
        }
        Ok(options)
    }
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<PipelinesReady>().add_systems(Last, (count_frames, take_screenshot_when_due).chain());
    if let Some(render) = app.get_sub_app_mut(bevy::render::RenderApp) {
        render.add_systems(bevy::render::ExtractSchedule, report_pipelines_ready);
    }
}

/// Frames in a row that Bevy's pipeline cache had nothing left to compile
/// (a mesh whose pipeline is still compiling is not drawn: a screenshot
/// then shows an empty view; a skinned mesh's own variant compiles late).
#[derive(Resource, Default)]
struct PipelinesReady(u32);

fn report_pipelines_ready(
    mut main_world: ResMut<bevy::render::MainWorld>,
    pipelines: Res<bevy::render::render_resource::PipelineCache>,
) {
    if let Some(mut ready) = main_world.get_resource_mut::<PipelinesReady>() {
        ready.0 = if pipelines.waiting_pipelines().next().is_none() { ready.0.saturating_add(1) } else { 0 };
    }
}

fn count_frames(mut state: ResMut<EditorState>) {
    state.frames += 1;
}

/// Frames a screenshot waits past `--frames` for the fin shadows to settle
/// (GPU extraction: pipelines compiled, counts read back) before it is taken anyway.
const SETTLE_LIMIT_FRAMES: u32 = 600;

/// In screenshot mode: from frame N on, once the fin shadows of the current
/// settings are extracted and their counts read back and Bevy has compiled
/// every pipeline it asked for (for a few frames), capture the window,
/// save it, exit.
fn take_screenshot_when_due(
    mut commands: Commands,
    options: Res<EditorOptions>,
    state: Res<EditorState>,
    main_light: Query<&bevy_shadow_fins::FinLightStats, With<crate::state::EditorLight>>,
    frames: Res<bevy_shadow_fins::FinFrames>,
    loading: Query<(), With<crate::gltf_scene::PendingGltf>>,
    peer: Res<crate::peers::PeerJob>,
    (pipelines, animation, loaded): (
        Res<PipelinesReady>,
        Res<crate::animation::EditorAnimation>,
        Option<Res<crate::state::LoadedScene>>,
    ),
    (mut requested_at, mut peer_shown_for): (Local<Option<u32>>, Local<u32>),
    mut exit: MessageWriter<AppExit>,
) {
    let Some(path) = options.screenshot.clone() else { return };
    if let Some(at) = *requested_at {
        if state.frames == at + SCREENSHOT_TIMEOUT_FRAMES {
            error!("no screenshot arrived {SCREENSHOT_TIMEOUT_FRAMES} frames after it was asked for; giving up");
            exit.write(AppExit::error());
        }
        return;
    }
    let due = options.frames.max(1);
    // Every light's counts, the main light's and those of "More lights"; a
    // glTF still loading is not the scene asked for.
    let settled = (main_light.iter().all(|s| s.0.up_to_date) || frames.0.is_empty()) && loading.is_empty();
    // The peer view shows its method once the CPU has evaluated it and egui
    // has had a few frames to upload its texture.
    *peer_shown_for = if peer.grid.is_some() { *peer_shown_for + 1 } else { 0 };
    let peer_ready = match state.view {
        crate::ViewKind::Peer => *peer_shown_for >= 3,
        // Its error needs the ground truth's rows too (it fills in as they come).
        crate::ViewKind::PeerError => *peer_shown_for >= 3 && peer.signed.is_some(),
        _ => true,
    };
    // A resting animation's pose applied and its snapshot taken (the views trace it).
    let posed = animation.clips.is_empty()
        || animation.playing
        || animation.snapshot_pose == Some((animation.selected, animation.time));
    let settled = settled && peer_ready && pipelines.0 >= 3 && posed;
    if state.frames < due || (!settled && state.frames < due + SETTLE_LIMIT_FRAMES) {
        return;
    }
    if !settled {
        warn!("fin shadows not settled {SETTLE_LIMIT_FRAMES} frames after --frames; taking the screenshot anyway");
    }
    *requested_at = Some(state.frames);
    // What the panel shows, for whoever runs the editor from a script.
    for (label, line) in [("status", &state.status), ("error", &state.error)] {
        if let Some(line) = line {
            println!("editor {label}: {line}");
        }
    }
    // The pose shown and the one the ground truth traces (its scene's top).
    if let (Some(clip), Some(loaded)) = (animation.clips.get(animation.selected), &loaded) {
        let top = loaded.scene.bounds().map_or(f32::NAN, |(_, hi)| hi.y);
        let traced = animation.snapshot_pose.map_or("none".into(), |(_, t)| format!("{t:.2} s"));
        println!(
            "editor animation: {:?} at {:.2} s; ground truth traces the pose at {traced}, its scene's top at y = {top:.3}",
            clip.name, animation.time
        );
    }
    commands.spawn(Screenshot::primary_window()).observe(
        move |captured: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
            let saved = captured.image.clone().try_into_dynamic().map_err(|e| e.to_string()).and_then(|image| {
                if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
                }
                image.to_rgb8().save(&path).map_err(|e| e.to_string())
            });
            match saved {
                Ok(()) => {
                    info!("screenshot written to {}", path.display());
                    exit.write(AppExit::Success);
                }
                Err(e) => {
                    error!("could not write the screenshot {}: {e}", path.display());
                    exit.write(AppExit::error());
                }
            }
        },
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<EditorOptions, CliError> {
        EditorOptions::parse(args.iter().map(|s| s.to_string()))
    }

    #[test]
    fn parses_scene_screenshot_and_frames() {
        let o = parse(&["scene.glb", "--screenshot", "out/e.png", "--frames", "5"]).unwrap();
        assert_eq!(o.scene, Some("scene.glb".into()));
        assert_eq!(o.screenshot, Some("out/e.png".into()));
        assert_eq!(o.frames, 5);
        assert_eq!(parse(&[]).unwrap().frames, 30);
    }

    #[test]
    fn rejects_bad_frames_and_unknown_options() {
        assert_eq!(parse(&["--frames", "0"]), Err(CliError::BadFrames("0".into())));
        assert_eq!(parse(&["--frames", "x"]), Err(CliError::BadFrames("x".into())));
        assert_eq!(parse(&["--screenshot"]), Err(CliError::MissingValue("--screenshot")));
        assert_eq!(parse(&["--fast"]), Err(CliError::Unknown("--fast".into())));
        let o = parse(&["--view", "peer", "--peer", "plateaus"]).unwrap();
        assert_eq!((o.view, o.peer), (Some(crate::ViewKind::Peer), Some(shadow_fins::peers::PeerMethod::Plateaus)));
        assert_eq!(parse(&["--view", "shadows"]), Err(CliError::BadView("shadows".into())));
        assert_eq!(parse(&["--peer", "fins"]), Err(CliError::BadPeer("fins".into())));
    }

    #[test]
    fn an_animation_time_is_a_finite_number_of_seconds() {
        assert_eq!(parse(&["--animation-time", "1.25"]).unwrap().animation_time, Some(1.25));
        assert_eq!(parse(&[]).unwrap().animation_time, None);
        for bad in ["NaN", "inf", "-inf", "soon"] {
            assert_eq!(parse(&["--animation-time", bad]), Err(CliError::BadAnimationTime(bad.into())), "{bad}");
        }
        assert_eq!(parse(&["--animation-time"]), Err(CliError::MissingValue("--animation-time")));
    }
}
