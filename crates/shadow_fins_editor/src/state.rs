//! The state every part of the editor reads: what scene is loaded, the
//! light's parameters and kind, the shading method, the buffer view, and the
//! markers of the editor's own entities. It depends on nothing else in the
//! crate, so the scene, its glTF loading, the animation, the settings file,
//! the analyses and the panels can all read it without reading each other.

use std::{path::PathBuf, sync::Arc};

use bevy::{prelude::*, window::PrimaryWindow};
use bevy_shadow_fins::FinMethod;
use shadow_fins::{
    light::{DiskLight, Light, RectLight as RectArea, SphereLight, SunLight},
    scene::Scene,
};

/// Where the scene comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneSource {
    /// The built-in demo scene (also `assets/demo.gltf`).
    Demo,
    Gltf(PathBuf),
}

/// The loaded scene as the core crate sees it (the ground truth traces it).
#[derive(Resource, Clone)]
pub struct LoadedScene {
    pub name: String,
    pub scene: Arc<Scene>,
    /// Bumped on every load, so derived data (ground truth) restarts.
    pub generation: u64,
    /// The scene's bounding-box diagonal: what the light's range, the
    /// camera's near plane and zoom, and the light marker scale by.
    pub extent: f32,
}

/// How the light is rendered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EditorMethod {
    /// The fin light with one of the plugin's methods.
    Fins(FinMethod),
    /// Bevy's own point light with PCSS soft shadows (`experimental_pbr_pcss`).
    BevyPcss,
}

impl Default for EditorMethod {
    fn default() -> Self {
        EditorMethod::Fins(FinMethod::MultiLayer)
    }
}

impl EditorMethod {
    pub const ALL: [EditorMethod; 8] = [
        EditorMethod::Fins(FinMethod::Hard),
        EditorMethod::Fins(FinMethod::OuterFins),
        EditorMethod::Fins(FinMethod::SingleLayer),
        EditorMethod::Fins(FinMethod::MultiLayer),
        EditorMethod::Fins(FinMethod::Coverage),
        EditorMethod::Fins(FinMethod::Convolution),
        EditorMethod::Fins(FinMethod::Plateaus),
        EditorMethod::BevyPcss,
    ];

    /// The fin method, or `None` for Bevy's PCSS.
    pub fn fin_method(self) -> Option<FinMethod> {
        match self {
            EditorMethod::Fins(m) => Some(m),
            EditorMethod::BevyPcss => None,
        }
    }

    pub fn label(self) -> &'static str {
        match self.fin_method() {
            Some(FinMethod::Hard) => "hard shadow map",
            Some(FinMethod::OuterFins) => "outer fins only",
            Some(FinMethod::SingleLayer) => "single-layer fins",
            Some(FinMethod::MultiLayer) => "multi-layer fins",
            Some(FinMethod::Coverage) => "coverage (exact, fused)",
            Some(FinMethod::Convolution) => "convolution shadow maps",
            Some(FinMethod::Plateaus) => "plateaus (one receiver plane)",
            None => "Bevy PCSS",
        }
    }
}

/// The light as the UI edits it. Values are clamped where they are used
/// (radius ≥ 0, intensity ≥ 0), never rejected.
#[derive(Resource, Debug, Clone, Copy, PartialEq)]
pub struct LightParams {
    pub position: Vec3,
    /// The direction the disk faces (into the scene); normalised on use.
    pub direction: Vec3,
    pub radius: f32,
    /// Lumens.
    pub intensity: f32,
    pub color: [f32; 3],
    pub method: EditorMethod,
    /// Which light it is: the plugin's `FinLight`, or Bevy's own `SpotLight`,
    /// `DirectionalLight`, `RectLight` or `PointLight` with `FinShadows`.
    pub kind: LightKind,
    /// A `RectLight`'s width ÷ height; it has the area of the disk of
    /// `radius` (`shadow_fins::light::RectLight::with_area_of`).
    pub rect_aspect: f32,
    /// The sun's angular diameter, radians (`SunDisk::angular_size`).
    pub sun_angle: f32,
    /// The sun's illuminance, lux.
    pub illuminance: f32,
}

/// The editor's main light: the plugin's own disk, or one of Bevy's lights
/// with `FinShadows`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LightKind {
    /// `FinLight`: a disk the plugin shades.
    #[default]
    FinLight,
    /// Bevy's `SpotLight` (cone [`SPOT_CONE`]; Bevy shades it): a disk of its `radius`.
    Spot,
    /// Bevy's `DirectionalLight` with a `SunDisk`: the sun, as soft as its angular size.
    Sun,
    /// Bevy's `RectLight` (Bevy shades it, and gives it no shadow of its
    /// own): a rectangle of the disk's area, [`LightParams::rect_aspect`]
    /// times as wide as high.
    Rect,
    /// Bevy's `PointLight` (Bevy shades it): a sphere of its `radius`,
    /// shadowed all around by six cube-face frames.
    Point,
}

impl LightKind {
    pub const ALL: [LightKind; 5] =
        [LightKind::FinLight, LightKind::Spot, LightKind::Sun, LightKind::Rect, LightKind::Point];

    /// The name in settings files.
    pub fn name(self) -> &'static str {
        match self {
            LightKind::FinLight => "fin-light",
            LightKind::Spot => "spot",
            LightKind::Sun => "sun",
            LightKind::Rect => "rect",
            LightKind::Point => "point",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    pub fn label(self) -> &'static str {
        match self {
            LightKind::FinLight => "FinLight (disk)",
            LightKind::Spot => "Bevy SpotLight",
            LightKind::Sun => "Bevy sun",
            LightKind::Rect => "Bevy RectLight",
            LightKind::Point => "Bevy PointLight",
        }
    }
}

/// The editor's sun by default: the real sun's angular diameter
/// (`SunDisk::EARTH`, 0.53°), at about the illuminance the default disk
/// light gives the demo's ground.
pub const DEFAULT_SUN_ANGLE: f32 = 0.00930842;
pub const DEFAULT_ILLUMINANCE: f32 = 3000.0;

/// The editor's rectangle light is four times as wide as high by default.
pub const DEFAULT_RECT_ASPECT: f32 = 4.0;

/// The outer cone angle of the editor's spot light, radians (inner: 70% of it).
pub const SPOT_CONE: f32 = 1.0;

impl LightParams {
    /// The core crate's light for these parameters (for the ground truth).
    pub fn core_light(&self) -> Option<Light> {
        let direction = self.direction.try_normalize()?;
        if self.kind == LightKind::Sun {
            return SunLight::new(direction, self.sun_angular_radius()).ok().map(Light::Sun);
        }
        if self.kind == LightKind::Rect {
            // Its width along the light's local X, as Bevy spans it.
            let (width, height) = self.rect_size();
            let tangent = self.transform().right().as_vec3();
            return RectArea::new(self.position, direction, tangent, width, height).ok().map(Light::Rect);
        }
        if self.kind == LightKind::Point {
            return SphereLight::new(self.position, self.radius.max(0.0)).ok().map(Light::Sphere);
        }
        DiskLight::new(self.position, direction, self.radius.max(0.0)).ok().map(Light::Disk)
    }

    /// The `RectLight`'s width and height: the area of the disk of `radius`,
    /// `rect_aspect` (clamped to `[0.01, 100]`, 1 for NaN) times as wide as high.
    pub fn rect_size(&self) -> (f32, f32) {
        let aspect = if self.rect_aspect.is_finite() { self.rect_aspect.clamp(0.01, 100.0) } else { 1.0 };
        let radius = if self.radius.is_finite() { self.radius.max(0.0) } else { 0.0 };
        RectArea::size_of_disk_area(radius, aspect)
    }

    /// Half the sun's angular diameter, clamped as the plugin clamps it
    /// (`[0, 1.4]` rad, NaN → 0).
    pub fn sun_angular_radius(&self) -> f32 {
        if self.sun_angle.is_finite() { (self.sun_angle * 0.5).clamp(0.0, 1.4) } else { 0.0 }
    }

    /// At `position`, facing along `direction` (−Y when it has no length).
    pub(crate) fn transform(&self) -> Transform {
        let direction = self.direction.try_normalize().unwrap_or(Vec3::NEG_Y);
        let up = if direction.cross(Vec3::Z).length() > 1e-3 { Vec3::Z } else { Vec3::X };
        Transform::from_translation(self.position).looking_to(direction, up)
    }
}

#[derive(Component)]
pub(crate) struct EditorMesh;

/// The ground the editor added under a glTF that has none (a shadow catcher).
#[derive(Component)]
pub(crate) struct EditorGround;

#[derive(Component)]
pub(crate) struct EditorLight;

#[derive(Component)]
pub(crate) struct LightMarker;

#[derive(Component)]
pub(crate) struct EditorCamera;

/// The primary window's physical size, if any.
pub(crate) fn window_size(window: &Query<&Window, With<PrimaryWindow>>) -> Option<UVec2> {
    window.single().ok().map(|w| w.physical_size()).filter(|s| s.x > 0 && s.y > 0)
}

/// Which buffer is drawn over the viewport.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ViewKind {
    /// The final image.
    #[default]
    Final,
    /// The illuminance (visibility) buffer, GPU.
    Visibility,
    /// Each pixel's layer.
    LayerIndex,
    /// One layer's slab depth map.
    SlabDepth,
    /// One layer's inner penumbra map (lowest inner weight).
    InnerMap,
    /// One layer's outer penumbra map (highest outer weight).
    OuterMap,
    /// Signed error of the GPU visibility against the ground truth.
    Error,
    /// Another paper's method (`peers.rs`, the CPU), its visibility.
    Peer,
    /// That method's signed error against the ground truth.
    PeerError,
}

impl ViewKind {
    pub const ALL: [ViewKind; 9] = [
        ViewKind::Final,
        ViewKind::Visibility,
        ViewKind::LayerIndex,
        ViewKind::SlabDepth,
        ViewKind::InnerMap,
        ViewKind::OuterMap,
        ViewKind::Error,
        ViewKind::Peer,
        ViewKind::PeerError,
    ];

    /// One of the views of another paper's method (`peers.rs`).
    pub fn is_peer(self) -> bool {
        matches!(self, ViewKind::Peer | ViewKind::PeerError)
    }

    /// Its name on the command line (`--view`).
    pub fn cli_name(self) -> &'static str {
        match self {
            ViewKind::Final => "final",
            ViewKind::Visibility => "visibility",
            ViewKind::LayerIndex => "layer-index",
            ViewKind::SlabDepth => "slab-depth",
            ViewKind::InnerMap => "inner-map",
            ViewKind::OuterMap => "outer-map",
            ViewKind::Error => "error",
            ViewKind::Peer => "peer",
            ViewKind::PeerError => "peer-error",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.cli_name() == name)
    }

    pub fn label(self) -> &'static str {
        match self {
            ViewKind::Final => "final image",
            ViewKind::Visibility => "illuminance buffer",
            ViewKind::LayerIndex => "layer index",
            ViewKind::SlabDepth => "slab depth map",
            ViewKind::InnerMap => "inner penumbra map",
            ViewKind::OuterMap => "outer penumbra map",
            ViewKind::Error => "error vs ground truth",
            ViewKind::Peer => "other paper's method (CPU)",
            ViewKind::PeerError => "its error vs ground truth",
        }
    }
}

/// The current glTF scene's root entity.
#[derive(Component)]
pub(crate) struct EditorSceneRoot;

/// Where a glTF scene's load is finished (`gltf_scene::finish_gltf_loads`):
/// what reads the loaded scene (its animations) runs after it.
#[derive(bevy::ecs::schedule::SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct GltfLoadsFinished;

/// The editor's options.
#[derive(Resource, Debug, Clone, PartialEq)]
pub struct EditorOptions {
    /// A glTF/GLB to open instead of the built-in demo scene.
    pub scene: Option<PathBuf>,
    /// A settings file (RON) to load at start.
    pub settings: Option<PathBuf>,
    /// Save a screenshot of the window here after `frames` frames (and once the
    /// fin shadows of the current settings have settled), then exit.
    pub screenshot: Option<PathBuf>,
    /// Frames before the screenshot (default 30).
    pub frames: u32,
    /// Where settings are autosaved (see `autosave.rs`).
    pub autosave: AutosaveOption,
    /// The buffer shown over the viewport at start (`--view`).
    pub view: Option<ViewKind>,
    /// The other paper's method the peer views show at start (`--peer`).
    pub peer: Option<shadow_fins::peers::PeerMethod>,
    /// Where the opened glTF's first animation rests at start, seconds
    /// (`--animation-time`; clamped to the clip's length).
    pub animation_time: Option<f32>,
    /// Add a ground under a glTF that has none, to catch its shadow
    /// (`shadow_fins::default_view::DefaultView::missing_ground`); off with `--no-ground`.
    pub add_ground: bool,
}

impl Default for EditorOptions {
    fn default() -> Self {
        Self {
            scene: None,
            settings: None,
            screenshot: None,
            frames: 30,
            autosave: Default::default(),
            view: None,
            peer: None,
            animation_time: None,
            add_ground: true,
        }
    }
}

/// Where the options say the autosave goes.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum AutosaveOption {
    /// The per-user default, in interactive runs.
    #[default]
    Default,
    Path(PathBuf),
    Off,
}
