//! Settings saved and loaded as RON: the light and the fin settings. Values
//! out of range load clamped (as the plugin clamps them), never as an error.

use std::path::Path;

use bevy::math::Vec3;
use bevy_shadow_fins::{FinMethod, FinShadowSettings};
use serde::{Deserialize, Serialize};
use shadow_fins::{oracle::Overlap, refine::Falloff};

use crate::state::{EditorMethod, LightKind, LightParams};

/// Everything the editor saves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EditorSettings {
    pub light_position: [f32; 3],
    pub light_direction: [f32; 3],
    pub radius: f32,
    pub intensity: f32,
    pub color: [f32; 3],
    /// `hard`, `outer-fins`, `single-layer`, `multi-layer`, `coverage`,
    /// `convolution`, `plateaus` or `bevy-pcss`.
    pub method: String,
    pub layers: u32,
    pub sub_layers: u32,
    pub map_resolution: u32,
    pub refinement: bool,
    /// `linear`, `bernstein` or `disk-segment`.
    pub falloff: String,
    /// `union` or `min-max`.
    pub overlap: String,
    /// Light samples of the coverage method (absent in files from before it).
    #[serde(default = "default_coverage_samples")]
    pub coverage_samples: u32,
    /// Order of the convolution method (absent in files from before it).
    #[serde(default = "default_convolution_order")]
    pub convolution_order: u32,
    /// The light is Bevy's `SpotLight` with `FinShadows` (absent in files from
    /// before it: the plugin's `FinLight`). Read only when `kind` is absent;
    /// still written, for editors from before `kind`.
    #[serde(default)]
    pub spot: bool,
    /// `fin-light`, `spot`, `sun` or `rect` (absent in files from before the sun:
    /// `spot` says which).
    #[serde(default)]
    pub kind: Option<String>,
    /// The sun's angular diameter, radians.
    #[serde(default = "default_sun_angle")]
    pub sun_angle: f32,
    /// The sun's illuminance, lux.
    #[serde(default = "default_illuminance")]
    pub illuminance: f32,
    /// A `RectLight`'s width ÷ height (absent in files from before it).
    #[serde(default = "default_rect_aspect")]
    pub rect_aspect: f32,
}

fn default_rect_aspect() -> f32 {
    crate::state::DEFAULT_RECT_ASPECT
}

fn default_sun_angle() -> f32 {
    crate::state::DEFAULT_SUN_ANGLE
}

fn default_illuminance() -> f32 {
    crate::state::DEFAULT_ILLUMINANCE
}

fn default_coverage_samples() -> u32 {
    FinShadowSettings::default().coverage_samples
}

fn default_convolution_order() -> u32 {
    FinShadowSettings::default().convolution_order
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
        EditorMethod::Fins(FinMethod::Coverage) => "coverage",
        EditorMethod::Fins(FinMethod::Convolution) => "convolution",
        EditorMethod::Fins(FinMethod::Plateaus) => "plateaus",
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
            coverage_samples: fins.coverage_samples,
            convolution_order: fins.convolution_order,
            spot: light.kind == LightKind::Spot,
            kind: Some(light.kind.name().into()),
            sun_angle: light.sun_angle,
            illuminance: light.illuminance,
            rect_aspect: light.rect_aspect,
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
        light.kind = match &self.kind {
            // An unknown kind keeps the current light.
            Some(name) => LightKind::parse(name).unwrap_or(light.kind),
            None if self.spot => LightKind::Spot,
            None => LightKind::FinLight,
        };
        // At most 80°, as the plugin clamps it; never negative or NaN.
        light.sun_angle = if self.sun_angle.is_finite() { self.sun_angle.clamp(0.0, 2.8) } else { 0.0 };
        light.illuminance = if self.illuminance.is_finite() { self.illuminance.max(0.0) } else { light.illuminance };
        // The editor's slider range; NaN keeps the current shape.
        light.rect_aspect =
            if self.rect_aspect.is_finite() { self.rect_aspect.clamp(0.01, 100.0) } else { light.rect_aspect };
        *fins = FinShadowSettings {
            layers: self.layers,
            sub_layers: self.sub_layers,
            map_resolution: self.map_resolution,
            refinement: self.refinement,
            falloff: Falloff::parse(&self.falloff).unwrap_or(fins.falloff),
            overlap: Overlap::parse(&self.overlap).unwrap_or(fins.overlap),
            coverage_samples: self.coverage_samples,
            convolution_order: self.convolution_order,
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

    /// Writes the file through a temporary next to it, flushed to disk before
    /// it replaces the old one: a failed write or a crash (of the editor or
    /// the machine) leaves either the old settings or the new, never half a file.
    pub fn save(&self, path: &Path) -> Result<(), SettingsFileError> {
        use std::io::Write;
        let p = path.display().to_string();
        let write = |source| SettingsFileError::Write { path: p.clone(), source };
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
        if let Some(dir) = dir {
            std::fs::create_dir_all(dir).map_err(write)?;
        }
        let tmp = path.with_extension("ron.tmp");
        let mut file = std::fs::File::create(&tmp).map_err(write)?;
        file.write_all(self.to_ron().as_bytes()).and_then(|()| file.sync_all()).map_err(write)?;
        drop(file);
        std::fs::rename(&tmp, path).map_err(write)?;
        // The rename itself is durable once the directory is flushed (best effort:
        // not every platform can open a directory).
        if let Ok(d) = std::fs::File::open(dir.unwrap_or(Path::new("."))) {
            let _ = d.sync_all();
        }
        Ok(())
    }

    /// Loads `path` into the light and fin settings. On any error nothing is
    /// changed: the user's current settings stay as they were.
    pub fn load_into(
        path: &Path,
        light: &mut LightParams,
        fins: &mut FinShadowSettings,
    ) -> Result<(), SettingsFileError> {
        let file = Self::load(path)?;
        file.apply(light, fins);
        Ok(())
    }
}

/// What the `settings_ron` fuzz target and the corpus test assert of any text:
/// no panic; a file that parses applies to finite, in-range settings.
#[doc(hidden)]
pub fn check_settings_text(text: &str) {
    let Ok(file) = EditorSettings::from_ron(text, "fuzz.ron") else { return };
    let mut light = LightParams {
        position: Vec3::new(0.0, 4.0, 0.0),
        direction: Vec3::NEG_Y,
        radius: 0.5,
        intensity: 1e6,
        color: [1.0; 3],
        method: EditorMethod::default(),
        kind: LightKind::FinLight,
        sun_angle: crate::state::DEFAULT_SUN_ANGLE,
        illuminance: crate::state::DEFAULT_ILLUMINANCE,
        rect_aspect: crate::state::DEFAULT_RECT_ASPECT,
    };
    let mut fins = FinShadowSettings::default();
    file.apply(&mut light, &mut fins);
    assert!(light.position.is_finite() && light.direction.is_finite() && light.direction != Vec3::ZERO);
    assert!(light.radius.is_finite() && light.radius >= 0.0);
    assert!(light.intensity.is_finite() && light.intensity >= 0.0);
    assert!(light.color.iter().all(|c| (0.0..=1.0).contains(c)));
    assert!(light.sun_angle.is_finite() && (0.0..=2.8).contains(&light.sun_angle));
    assert!(light.illuminance.is_finite() && light.illuminance >= 0.0);
    assert!(light.rect_aspect.is_finite() && (0.01..=100.0).contains(&light.rect_aspect));
    assert_eq!(fins, fins.clamped(), "applied settings are within their ranges");
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
            kind: LightKind::FinLight,
            sun_angle: 0.02,
            illuminance: 1500.0,
            rect_aspect: 2.5,
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

    #[test]
    fn the_light_kind_is_saved_and_older_files_keep_their_light() {
        for kind in LightKind::ALL {
            let saved = EditorSettings::capture(&LightParams { kind, ..light() }, &FinShadowSettings::default());
            let (mut l, mut f) = (light(), FinShadowSettings::default());
            EditorSettings::from_ron(&saved.to_ron(), "x.ron").unwrap().apply(&mut l, &mut f);
            assert_eq!((l.kind, l.sun_angle, l.illuminance, l.rect_aspect), (kind, 0.02, 1500.0, 2.5));
        }
        // A file from before the rectangle light gets the default aspect.
        let saved = EditorSettings::capture(&light(), &FinShadowSettings::default()).to_ron();
        let before_rect = saved.replace("rect_aspect: 2.5,", "");
        assert_ne!(before_rect, saved, "the field must be in the file to be dropped from it");
        let (mut l, mut f) = (light(), FinShadowSettings::default());
        EditorSettings::from_ron(&before_rect, "old.ron").unwrap().apply(&mut l, &mut f);
        assert_eq!(l.rect_aspect, crate::state::DEFAULT_RECT_ASPECT);
        // Files from before `kind`: `spot` says which; from before `spot`: the FinLight.
        let spot =
            EditorSettings::capture(&LightParams { kind: LightKind::Spot, ..light() }, &FinShadowSettings::default());
        let before_kind = spot.to_ron().replace("kind: Some(\"spot\"),", "");
        assert_ne!(before_kind, spot.to_ron(), "the field must be in the file to be dropped from it");
        let mut l = LightParams { kind: LightKind::Sun, ..light() };
        let mut f = FinShadowSettings::default();
        EditorSettings::from_ron(&before_kind, "old.ron").unwrap().apply(&mut l, &mut f);
        assert_eq!(l.kind, LightKind::Spot);
        let before_spot = before_kind.replace("spot: true,", "");
        EditorSettings::from_ron(&before_spot, "older.ron").unwrap().apply(&mut l, &mut f);
        assert_eq!(l.kind, LightKind::FinLight);
    }

    #[test]
    fn coverage_samples_are_saved_clamped_and_default_in_older_files() {
        let fins = FinShadowSettings { method: FinMethod::Coverage, coverage_samples: 64, ..Default::default() };
        let saved =
            EditorSettings::capture(&LightParams { method: EditorMethod::Fins(FinMethod::Coverage), ..light() }, &fins);
        let (mut l, mut f) = (light(), FinShadowSettings::default());
        EditorSettings::from_ron(&saved.to_ron(), "x.ron").unwrap().apply(&mut l, &mut f);
        assert_eq!((f.method, f.coverage_samples), (FinMethod::Coverage, 64));
        let older = saved.to_ron().replace("coverage_samples: 64,", "");
        assert!(!older.contains("coverage_samples"));
        let loaded = EditorSettings::from_ron(&older, "old.ron").unwrap();
        assert_eq!(loaded.coverage_samples, FinShadowSettings::default().coverage_samples);
        let mut huge = saved.clone();
        huge.coverage_samples = 1 << 30;
        huge.apply(&mut l, &mut f);
        assert_eq!(f.coverage_samples, 256);
    }

    #[test]
    fn the_convolution_method_and_order_are_saved_clamped_and_default_in_older_files() {
        let fins = FinShadowSettings { method: FinMethod::Convolution, convolution_order: 7, ..Default::default() };
        let method = EditorMethod::Fins(FinMethod::Convolution);
        let saved = EditorSettings::capture(&LightParams { method, ..light() }, &fins);
        assert_eq!(saved.method, "convolution");
        let (mut l, mut f) = (light(), FinShadowSettings::default());
        EditorSettings::from_ron(&saved.to_ron(), "x.ron").unwrap().apply(&mut l, &mut f);
        assert_eq!((l.method, f.method, f.convolution_order), (method, FinMethod::Convolution, 7));
        let older = saved.to_ron().replace("convolution_order: 7,", "");
        assert_ne!(older, saved.to_ron(), "the field must be in the file to be dropped from it");
        let loaded = EditorSettings::from_ron(&older, "old.ron").unwrap();
        assert_eq!(loaded.convolution_order, FinShadowSettings::default().convolution_order);
        let mut huge = saved.clone();
        huge.convolution_order = 0;
        huge.apply(&mut l, &mut f);
        assert_eq!(f.convolution_order, 1, "order 0 clamps to 1");
    }

    #[test]
    fn a_failed_load_leaves_the_current_settings_as_they_were() {
        let dir = std::env::temp_dir().join(format!("fin-editor-load-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let broken = dir.join("broken.ron");
        std::fs::write(&broken, "(light_position: (1.0, 2.0").unwrap();
        let fins = FinShadowSettings { layers: 7, refinement: false, ..Default::default() };
        let (mut l, mut f) = (light(), fins);
        for path in [broken.clone(), dir.join("missing.ron")] {
            assert!(EditorSettings::load_into(&path, &mut l, &mut f).is_err());
            assert_eq!((l, f), (light(), fins), "{}", path.display());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn saving_replaces_the_file_whole_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("fin-editor-save-{}", std::process::id()));
        let path = dir.join("nested/settings.ron");
        let a = EditorSettings::capture(&light(), &FinShadowSettings::default());
        let b = EditorSettings { layers: 3, ..a.clone() };
        a.save(&path).unwrap();
        b.save(&path).unwrap();
        assert_eq!(EditorSettings::load(&path).unwrap(), b);
        assert!(!path.with_extension("ron.tmp").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The fuzz target's seeds (and what it kept), on the stable toolchain.
    #[test]
    fn the_fuzz_corpus_parses_without_panic_and_in_bounded_time() {
        let dir = Path::new(&std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("../../fuzz/corpus/settings_ron");
        let mut files = 0;
        for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
            let bytes = std::fs::read(entry.unwrap().path()).unwrap();
            let start = std::time::Instant::now();
            if let Ok(text) = std::str::from_utf8(&bytes) {
                check_settings_text(text);
            }
            assert!(start.elapsed().as_secs_f32() < 2.0, "slow input");
            files += 1;
        }
        assert!(files >= 5, "the seed corpus is committed ({files} files)");
    }

    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
        #[test]
        fn generated_settings_never_panic(
            radius in prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(-1.0f32), any::<f32>()],
            layers in any::<u32>(),
            map in any::<u32>(),
            direction in proptest::array::uniform3(prop_oneof![Just(0.0f32), Just(f32::NAN), any::<f32>()]),
            method in "[a-z-]{0,12}",
        ) {
            let mut s = EditorSettings::capture(&light(), &FinShadowSettings::default());
            (s.radius, s.layers, s.map_resolution, s.light_direction, s.method) = (radius, layers, map, direction, method);
            check_settings_text(&s.to_ron());
        }

        #[test]
        fn mutated_settings_text_never_panics(cut in any::<usize>(), flips in proptest::collection::vec((any::<usize>(), 32u8..127), 0..6)) {
            let mut text = EditorSettings::capture(&light(), &FinShadowSettings::default()).to_ron().into_bytes();
            for (at, c) in flips {
                let n = text.len();
                text[at % n] = c;
            }
            let n = text.len();
            text.truncate(cut % (n + 1));
            check_settings_text(&String::from_utf8(text).unwrap());
        }
    }
}
