//! Turning command-line flags into a scene, a light, a camera and method settings.

use clap::Args;
use shadow_fins::{
    camera::Camera,
    glam::{Vec2, Vec3},
    gltf_import::load_gltf,
    light::{DiskLight, Light, RectLight, SphereLight, SunLight},
    oracle::{FinSettings, Method, Overlap},
    peers::PeerMethod,
    refine::Falloff,
    scene::Scene,
    scenes::SceneId,
};

use shadow_fins::coverage::CoverageSettings;

use crate::LabError;

/// Where the scene comes from and how it is lit.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Built-in scene: box-over-plane, near-contact, ring-plate, large-light,
    /// tilted-receiver, star-prism, sphere-grid, dense-blob, demo, kitbash,
    /// figure, greeble-tower, lamp-room (a sphere light), leaf-cards
    /// (alpha-masked cards).
    #[arg(long, default_value = "box-over-plane", conflicts_with = "gltf")]
    pub scene: String,
    /// A glTF/GLB file instead of a built-in scene (needs a light: --light-center or --sun-direction).
    #[arg(long)]
    pub gltf: Option<std::path::PathBuf>,
    /// Disk light centre x,y,z (world units).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub light_center: Option<Vec3>,
    /// Disk light normal x,y,z, pointing into the scene (default 0,-1,0).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub light_normal: Option<Vec3>,
    /// Disk light radius (world units); 0 gives hard shadows.
    #[arg(long, allow_hyphen_values = true)]
    pub radius: Option<f32>,
    /// A rectangle light of this width,height instead of the disk (centre
    /// and normal as for the disk; its width along world x, or z when the
    /// normal is along x). 0,0 gives hard shadows.
    #[arg(long, value_parser = parse_vec2, allow_hyphen_values = true, conflicts_with = "radius")]
    pub rect: Option<Vec2>,
    /// A sphere light (Bevy's point light with a radius) of --radius at the
    /// light centre instead of the disk: shadows all around it, by six
    /// cube-face frames. 0 gives hard shadows. (A scene lit by a sphere,
    /// lamp-room, keeps it unless --light-normal asks for a disk.)
    #[arg(long, conflicts_with_all = ["rect", "light_normal"])]
    pub point: bool,
    /// Sun light travel direction x,y,z (instead of a disk light).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, conflicts_with = "light_center")]
    pub sun_direction: Option<Vec3>,
    /// Sun angular radius in radians (the real sun: 0.0047).
    #[arg(long, default_value_t = 0.05)]
    pub sun_angle: f32,
}

/// How the fin method is set up.
#[derive(Args, Debug, Clone)]
pub struct FinArgs {
    /// Layers N (1..=64).
    #[arg(long, default_value_t = 16)]
    pub layers: u32,
    /// Sub-layers S (1..=65536).
    #[arg(long, default_value_t = 1024)]
    pub sub_layers: u32,
    /// Turn refinement (eq. 5) off.
    #[arg(long)]
    pub no_refinement: bool,
    /// Falloff: linear, bernstein, disk-segment.
    #[arg(long, default_value = "disk-segment")]
    pub falloff: String,
    /// How overlapping fins and layers combine: union (ours) or min-max (the paper).
    #[arg(long, default_value = "union")]
    pub overlap: String,
    /// Evaluate on light-space maps of this resolution (as the GPU does) instead of exactly.
    #[arg(long)]
    pub map_resolution: Option<u32>,
    /// Ground-truth samples on the disk.
    #[arg(long, default_value_t = 1024)]
    pub samples: u32,
    /// Light samples of the coverage method (1..=4096).
    #[arg(long, default_value_t = CoverageSettings::default().samples)]
    pub coverage_samples: u32,
}

impl FinArgs {
    pub fn settings(&self) -> Result<FinSettings, LabError> {
        let falloff = Falloff::parse(&self.falloff).ok_or_else(|| {
            LabError::Usage(format!("unknown falloff '{}': use linear, bernstein or disk-segment", self.falloff))
        })?;
        if let Some(r) = self.map_resolution {
            if !(16..=8192).contains(&r) {
                return Err(shadow_fins::SettingsError::MapResolution(r).into());
            }
        }
        if !(1..=1 << 20).contains(&self.samples) {
            return Err(shadow_fins::SettingsError::Samples(self.samples).into());
        }
        if !(1..=4096).contains(&self.coverage_samples) {
            return Err(LabError::Usage(format!("--coverage-samples {} is not in 1..=4096", self.coverage_samples)));
        }
        let overlap = Overlap::parse(&self.overlap)
            .ok_or_else(|| LabError::Usage(format!("unknown overlap rule '{}': use union or min-max", self.overlap)))?;
        Ok(FinSettings {
            layers: self.layers,
            sub_layers: self.sub_layers,
            refinement: !self.no_refinement,
            falloff,
            overlap,
        }
        .validate()?)
    }
}

/// What a run measures: a fin method, the coverage method, a peer paper's
/// method or the ground truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measured {
    Method(Method),
    /// Another paper's method (`shadow_fins::peers`).
    Peer(PeerMethod),
    /// Exact coverage with occluder fusion (`shadow_fins::coverage`).
    Coverage(CoverageSettings),
    GroundTruth,
}

/// A method name: `ground-truth`, `coverage` (with `samples` light samples),
/// a fin method or a peer method.
pub fn parse_measured(s: &str, coverage_samples: u32) -> Result<Measured, LabError> {
    match s {
        "ground-truth" => return Ok(Measured::GroundTruth),
        "coverage" => {
            return Ok(Measured::Coverage(CoverageSettings { samples: coverage_samples, ..Default::default() }));
        }
        _ => {}
    }
    if let Some(peer) = PeerMethod::parse(s) {
        return Ok(Measured::Peer(peer));
    }
    Method::parse(s).map(Measured::Method).ok_or_else(|| {
        LabError::Usage(format!(
            "unknown method '{s}': use ground-truth, coverage, fins, hard, outer-fins, single-layer, \
             single-sample, plateaus, penumbra-wedges, wedge-blending, convolution or convolution-mipmap"
        ))
    })
}

/// A loaded scene with its light and camera.
pub struct Loaded {
    pub name: String,
    pub scene: Scene,
    pub light: Light,
    pub camera: Camera,
}

impl SceneArgs {
    pub fn load(&self) -> Result<Loaded, LabError> {
        let (name, scene, default_light, camera) = match &self.gltf {
            Some(path) => {
                let import = load_gltf(path)?;
                for s in &import.skipped {
                    eprintln!("warning: skipped {s}");
                }
                let (lo, hi) = import.scene.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
                let center = (lo + hi) * 0.5;
                let size = (hi - lo).length().max(1e-6);
                let camera = Camera::looking_at(center + Vec3::new(0.6, 0.7, 0.9).normalize() * size * 1.2, center);
                let light = DiskLight::new(center + Vec3::Y * size, Vec3::NEG_Y, size * 0.05).map(Light::Disk)?;
                (path.display().to_string(), import.scene, light, camera)
            }
            None => {
                let id = SceneId::parse(&self.scene).ok_or_else(|| {
                    let names: Vec<_> = SceneId::ALL.iter().map(|s| s.name()).collect();
                    LabError::Usage(format!("unknown scene '{}': use one of {}", self.scene, names.join(", ")))
                })?;
                let b = id.build();
                (id.name().to_string(), b.scene, b.light, b.camera)
            }
        };
        let light = self.light(default_light)?;
        Ok(Loaded { name, scene, light, camera })
    }

    fn light(&self, default: Light) -> Result<Light, LabError> {
        if let Some(dir) = self.sun_direction {
            return Ok(Light::Sun(SunLight::new(dir, self.sun_angle)?));
        }
        let (c, n, r) = match default {
            Light::Disk(d) => (d.center, d.normal, d.radius),
            Light::Rect(l) => (l.center, l.normal, l.bounding_radius()),
            Light::Sun(_) => (Vec3::Y * 5.0, Vec3::NEG_Y, 0.5),
            Light::Sphere(s) => (s.center, Vec3::NEG_Y, s.radius),
        };
        let center = self.light_center.unwrap_or(c);
        let normal = self.light_normal.unwrap_or(n);
        if let Some(size) = self.rect {
            let tangent = RectLight::world_tangent(normal);
            return Ok(Light::Rect(RectLight::new(center, normal, tangent, size.x, size.y)?));
        }
        let radius = self.radius.unwrap_or(r);
        // A scene lit by a sphere stays so unless a disk's normal is given.
        let sphere_default = matches!(default, Light::Sphere(_)) && self.light_normal.is_none();
        if self.point || sphere_default {
            return Ok(Light::Sphere(SphereLight::new(center, radius)?));
        }
        Ok(Light::Disk(DiskLight::new(center, normal, radius)?))
    }
}

pub fn parse_vec2(s: &str) -> Result<Vec2, String> {
    parse_floats::<2>(s, "w,h").map(Vec2::from_array)
}

pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    parse_floats::<3>(s, "x,y,z").map(Vec3::from_array)
}

/// `N` finite comma-separated numbers (`shape` names them in the error).
fn parse_floats<const N: usize>(s: &str, shape: &str) -> Result<[f32; N], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != N {
        return Err(format!("'{s}' is not {shape}"));
    }
    let mut v = [0.0f32; N];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p.parse().map_err(|_| format!("'{p}' is not a number"))?;
        if !slot.is_finite() {
            return Err(format!("'{p}' is not finite"));
        }
    }
    Ok(v)
}
