//! Settings saved and loaded as RON: the light and the fin settings. Values
//! out of range load clamped (as the plugin clamps them), never as an error.

use std::path::Path;

use bevy::math::Vec3;
use bevy_shadow_fins::{FinMethod, FinShadowSettings};
use serde::{Deserialize, Serialize};
use shadow_fins::{oracle::Overlap, refine::Falloff};

use crate::scene::{EditorMethod, LightParams};

/// Everything the editor saves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EditorSettings {
    pub light_position: [f32; 3],
    pub light_direction: [f32; 3],
    pub radius: f32,
    pub intensity: f32,
    pub color: [f32; 3],
    /// `hard`, `outer-fins`, `single-layer`, `multi-layer` or `bevy-pcss`.
    pub method: String,
    pub layers: u32,
    pub sub_layers: u32,
    pub map_resolution: u32,
    pub refinement: bool,
    /// `linear`, `bernstein` or `disk-segment`.
    pub falloff: String,
    /// `union` or `min-max`.
    pub overlap: String,
}

/// A settings file that could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum SettingsFileError {
    #[error("could not read {path}: {source}")]
    Read { path: String, source: std::io::Error },
    #[error("could not write {path}: {source}")]
    Write { path: String, source: std::io::Error },
    #[error("{path} is not an editor settings file: {message}")]
    Parse { path: String, message: String },
}

fn method_name(m: EditorMethod) -> &'static str {
    match m {
        EditorMethod::Fins(FinMethod::Hard) => "hard",
        EditorMethod::Fins(FinMethod::OuterFins) => "outer-fins",
        EditorMethod::Fins(FinMethod::SingleLayer) => "single-layer",
        EditorMethod::Fins(FinMethod::MultiLayer) => "multi-layer",
        EditorMethod::BevyPcss => "bevy-pcss",
    }
}

impl EditorSettings {
    /// The settings of the current light and fins.
    pub fn capture(light: &LightParams, fins: &FinShadowSettings) -> Self {
        Self {
            light_position: light.position.to_array(),
            light_direction: light.direction.to_array(),
            radius: light.radius,
            intensity: light.intensity,
            color: light.color,
            method: method_name(light.method).into(),
            layers: fins.layers,
            sub_layers: fins.sub_layers,
            map_resolution: fins.map_resolution,
            refinement: fins.refinement,
            falloff: fins.falloff.name().into(),
            overlap: fins.overlap.name().into(),
        }
    }

    /// Writes these into the light and fin settings; unknown names keep the
    /// current value, numbers are clamped into range.
    pub fn apply(&self, light: &mut LightParams, fins: &mut FinShadowSettings) {
        let finite3 = |v: [f32; 3], fallback: Vec3| {
            let v = Vec3::from_array(v);
            if v.is_finite() { v } else { fallback }
        };
        light.position = finite3(self.light_position, light.position);
        light.direction = finite3(self.light_direction, light.direction).try_normalize().unwrap_or(light.direction);
        light.radius = if self.radius.is_finite() { self.radius.max(0.0) } else { 0.0 };
        light.intensity = if self.intensity.is_finite() { self.intensity.max(0.0) } else { light.intensity };
        light.color = self.color.map(|c| if c.is_finite() { c.clamp(0.0, 1.0) } else { 1.0 });
        if let Some(m) = EditorMethod::ALL.into_iter().find(|m| method_name(*m) == self.method) {
            light.method = m;
        }
        *fins = FinShadowSettings {
            layers: self.layers,
            sub_layers: self.sub_layers,
            map_resolution: self.map_resolution,
            refinement: self.refinement,
            falloff: Falloff::parse(&self.falloff).unwrap_or(fins.falloff),
            overlap: Overlap::parse(&self.overlap).unwrap_or(fins.overlap),
            ..*fins
        }
        .clamped();
        if let Some(m) = light.method.fin_method() {
            fins.method = m;
        }
    }

    pub fn to_ron(&self) -> String {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default()).expect("plain data serialises")
    }

    pub fn from_ron(text: &str, path: &str) -> Result<Self, SettingsFileError> {
        ron::from_str(text).map_err(|e| SettingsFileError::Parse { path: path.into(), message: e.to_string() })
    }

    pub fn load(path: &Path) -> Result<Self, SettingsFileError> {
        let p = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| SettingsFileError::Read { path: p.clone(), source })?;
        Self::from_ron(&text, &p)
    }

    /// Writes the file through a temporary next to it, so a failed write
    /// never destroys the previous settings.
    pub fn save(&self, path: &Path) -> Result<(), SettingsFileError> {
        let p = path.display().to_string();
        let write = |source| SettingsFileError::Write { path: p.clone(), source };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(write)?;
        }
        let tmp = path.with_extension("ron.tmp");
        std::fs::write(&tmp, self.to_ron()).map_err(write)?;
        std::fs::rename(&tmp, path).map_err(write)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light() -> LightParams {
        LightParams {
            position: Vec3::new(1.0, 4.0, 0.0),
            direction: Vec3::NEG_Y,
            radius: 0.5,
            intensity: 1e6,
            color: [1.0, 0.9, 0.8],
            method: EditorMethod::BevyPcss,
        }
    }

    #[test]
    fn settings_round_trip_through_ron() {
        let fins =
            FinShadowSettings { layers: 8, refinement: false, falloff: Falloff::Bernstein, ..Default::default() };
        let saved = EditorSettings::capture(&light(), &fins);
        let loaded = EditorSettings::from_ron(&saved.to_ron(), "x.ron").unwrap();
        assert_eq!(saved, loaded);
        let (mut l, mut f) = (LightParams { method: EditorMethod::default(), ..light() }, FinShadowSettings::default());
        loaded.apply(&mut l, &mut f);
        assert_eq!((l, f.layers, f.refinement, f.falloff), (light(), 8, false, Falloff::Bernstein));
    }

    #[test]
    fn out_of_range_values_load_clamped_and_garbage_is_a_typed_error() {
        let mut s = EditorSettings::capture(&light(), &FinShadowSettings::default());
        (s.radius, s.layers, s.map_resolution, s.intensity) = (-1.0, 0, 1 << 20, f32::NAN);
        let (mut l, mut f) = (light(), FinShadowSettings::default());
        s.apply(&mut l, &mut f);
        assert_eq!((l.radius, f.layers, f.map_resolution, l.intensity), (0.0, 1, 4096, 1e6));
        assert!(matches!(EditorSettings::from_ron("(radius: oops", "bad.ron"), Err(SettingsFileError::Parse { .. })));
    }
}
