//! Crash-safe autosave of the settings: whenever the light or the fin settings
//! change, at most twice a second, they are written (atomically, flushed to
//! disk: see [`EditorSettings::save`]) to the autosave file; the next start
//! without `--settings` restores them. A crash, a killed process or a power
//! cut loses at most the last half second of tuning, never the file. Nothing
//! is written before the first change, and an autosave that does not read at
//! start is moved aside to `*.ron.bad` rather than overwritten.
//!
//! Where: `--autosave PATH`, or by default (interactive runs only, not
//! `--screenshot` runs) `$XDG_STATE_HOME/shadow-fins/editor-autosave.ron`
//! (`~/.local/state/…` without it); `--no-autosave` turns it off.

use std::{path::PathBuf, time::Instant};

use bevy::prelude::*;
use bevy_shadow_fins::FinShadowSettings;

use crate::{AutosaveOption, EditorOptions, EditorState, LightParams, settings_file::EditorSettings};

/// The per-user default autosave file.
fn default_path() -> Option<PathBuf> {
    let state = std::env::var_os("XDG_STATE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/state")))?;
    Some(state.join("shadow-fins/editor-autosave.ron"))
}

impl EditorOptions {
    /// The autosave file of this run, if any.
    pub fn autosave_path(&self) -> Option<PathBuf> {
        match &self.autosave {
            AutosaveOption::Path(p) => Some(p.clone()),
            AutosaveOption::Default if self.screenshot.is_none() => default_path(),
            _ => None,
        }
    }

    /// The settings file to start from: `--settings`, else the autosave if one
    /// was left by an earlier run.
    pub fn start_settings(&self) -> Option<PathBuf> {
        self.settings.clone().or_else(|| self.autosave_path().filter(|p| p.is_file()))
    }
}

#[derive(Resource)]
struct Autosave {
    path: PathBuf,
    written: Option<EditorSettings>,
    last_write: Option<Instant>,
}

/// Seconds between two autosaves at most.
const INTERVAL_S: f32 = 0.5;

pub(crate) fn build(app: &mut App) {
    let Some(path) = app.world().resource::<EditorOptions>().autosave_path() else { return };
    app.insert_resource(Autosave { path, written: None, last_write: None }).add_systems(Last, autosave_settings);
}

fn autosave_settings(
    mut autosave: ResMut<Autosave>,
    params: Option<Res<LightParams>>,
    fins: Query<&FinShadowSettings, With<crate::state::EditorLight>>,
    mut exits: MessageReader<AppExit>,
    mut state: ResMut<EditorState>,
) {
    let (Some(params), Ok(fins)) = (params, fins.single()) else { return };
    let now = EditorSettings::capture(&params, fins);
    // Until the user changes something, the settings the editor started from
    // are on disk already (or were kept aside if they did not read): the
    // first write waits for a change, so nothing is overwritten for nothing.
    if autosave.written.is_none() && autosave.last_write.is_none() {
        autosave.written = Some(now);
        autosave.last_write = Some(Instant::now());
        return;
    }
    let exiting = exits.read().count() > 0;
    let due = autosave.last_write.is_none_or(|t| t.elapsed().as_secs_f32() >= INTERVAL_S);
    if autosave.written.as_ref() == Some(&now) || !(due || exiting) {
        return;
    }
    match now.save(&autosave.path) {
        Ok(()) => {
            autosave.written = Some(now);
            autosave.last_write = Some(Instant::now());
        }
        Err(e) => {
            // Said once; tuning goes on, the previous autosave is intact.
            if autosave.last_write.is_none() || autosave.written.is_some() {
                state.error = Some(format!("autosave failed: {e}"));
            }
            autosave.written = None;
            autosave.last_write = Some(Instant::now());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(args: &[&str]) -> EditorOptions {
        EditorOptions::parse(args.iter().map(|s| s.to_string())).unwrap()
    }

    #[test]
    fn the_autosave_goes_where_the_options_say() {
        assert_eq!(options(&["--autosave", "a.ron"]).autosave_path(), Some("a.ron".into()));
        assert_eq!(options(&["--no-autosave"]).autosave_path(), None);
        // Screenshot runs (tests, docs) leave the user's default autosave alone.
        assert_eq!(options(&["--screenshot", "x.png"]).autosave_path(), None);
        assert_eq!(options(&["--screenshot", "x.png", "--autosave", "a.ron"]).autosave_path(), Some("a.ron".into()));
    }

    #[test]
    fn a_start_without_settings_restores_the_autosave_if_there_is_one() {
        let dir = std::env::temp_dir().join(format!("fin-editor-autosave-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let autosave = dir.join("auto.ron");
        let path = autosave.to_str().unwrap();
        assert_eq!(options(&["--autosave", path]).start_settings(), None, "nothing saved yet");
        std::fs::write(&autosave, "()").unwrap();
        assert_eq!(options(&["--autosave", path]).start_settings(), Some(autosave.clone()));
        // --settings wins over the autosave.
        assert_eq!(options(&["--autosave", path, "--settings", "s.ron"]).start_settings(), Some("s.ron".into()));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
