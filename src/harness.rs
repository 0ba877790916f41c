//! Headless rendering of a core-crate scene with the plugin, visibility read back.

use std::sync::{Arc, Mutex};

use bevy::{
    asset::RenderAssetUsages,
    camera::RenderTarget,
    core_pipeline::tonemapping::Tonemapping,
    diagnostic::DiagnosticsStore,
    prelude::*,
    render::diagnostic::RenderDiagnosticsPlugin,
    render::{
        RenderPlugin,
        gpu_readback::{Readback, ReadbackComplete},
        render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages},
    },
    window::ExitCondition,
};
use bevy_shadow_fins::{
    FinFrame, FinLight, FinShadowSettings, FinShadowView, NotFinShadowCaster, NotFinShadowReceiver, ShadowFinsPlugin,
};
use shadow_fins::{camera::Camera as CoreCamera, light::Light, scene::Scene};

/// A scene to render: the core's scene, a disk light and a camera.
#[derive(Clone)]
pub struct Setup {
    pub scene: Scene,
    pub light: Light,
    pub camera: CoreCamera,
    pub settings: FinShadowSettings,
    pub width: u32,
    pub height: u32,
    /// Raw Bevy meshes spawned as they are (bad input for robustness tests), at a position.
    pub extra_meshes: Vec<(Mesh, Vec3)>,
    /// The camera's MSAA (the plugin turns it off on fin-shadowed cameras).
    pub msaa: Msaa,
    /// An HDR camera (tonemapping after lighting) or not (tonemapping inside
    /// the lighting shader).
    pub hdr: bool,
    /// Light the scene with Bevy's own `PointLight` (same colour, intensity,
    /// range, radius; no shadow maps) instead of the fin light: the reference
    /// the compositing pass is compared against.
    pub bevy_point_light: bool,
    /// More fin-shadowed cameras rendered in the same frames.
    pub extra_cameras: Vec<CoreCamera>,
    /// The cameras' tonemapping (`None` keeps the output linear in the light,
    /// which the compositing tests rely on).
    pub tonemapping: Tonemapping,
    /// The light's luminous power, lumens.
    pub intensity: f32,
}

impl Setup {
    /// A setup with the defaults of every optional field.
    pub fn new(scene: Scene, light: Light, camera: CoreCamera, settings: FinShadowSettings, size: (u32, u32)) -> Self {
        Self {
            scene,
            light,
            camera,
            settings,
            width: size.0,
            height: size.1,
            extra_meshes: vec![],
            msaa: Msaa::Off,
            hdr: false,
            bevy_point_light: false,
            extra_cameras: vec![],
            tonemapping: Tonemapping::None,
            intensity: FinLight::default().intensity,
        }
    }
}

/// What one camera produced: visibility buffer and final colour, row-major,
/// top row first.
#[derive(Debug, Clone, Default)]
pub struct ViewShot {
    pub visibility: Vec<f32>,
    /// The camera's output, sRGB bytes (RGBA).
    pub color: Vec<[u8; 4]>,
}

/// A rendered frame: the first camera's buffers, the others', and the counts.
#[derive(Debug, Clone)]
pub struct Shot {
    pub width: u32,
    pub height: u32,
    pub visibility: Vec<f32>,
    pub color: Vec<[u8; 4]>,
    /// The cameras of `Setup::extra_cameras`, in order.
    pub extra_views: Vec<ViewShot>,
    /// Silhouettes, fins and layers the frame modelled.
    pub stats: bevy_shadow_fins::FinFrameStats,
    /// Every `render/fin_shadows/…` diagnostic (per-pass GPU and CPU times,
    /// ms) with its latest value.
    pub pass_times: Vec<(String, f64)>,
}

/// Frames [`render`] waits at most for the image to settle.
pub const MAX_FRAMES: u32 = 60;

/// The latest read-back of one image (rows padded to 256 bytes).
pub type Slot = Arc<Mutex<Option<Vec<u8>>>>;

/// Read-back slots of one camera.
#[derive(Clone, Default)]
pub struct ViewSlots {
    pub visibility: Slot,
    pub color: Slot,
}

/// Builds the headless app for `setup`; returns it with every camera's
/// read-back slots (the first camera first).
pub fn app(setup: &Setup) -> (App, Vec<ViewSlots>) {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() })
            .set(RenderPlugin { synchronous_pipeline_compilation: true, ..default() })
            // Headless: no event loop (it needs a display); the caller drives `update`.
            .disable::<bevy::winit::WinitPlugin>(),
    )
    .add_plugins((ShadowFinsPlugin, RenderDiagnosticsPlugin));
    let world = app.world_mut();
    let (w, h) = (setup.width, setup.height);
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    for object in &setup.scene.objects {
        let mesh = world.resource_mut::<Assets<Mesh>>().add(bevy_shadow_fins::mesh_from_core(&object.mesh));
        let mut e = world.spawn((
            Mesh3d(mesh),
            MeshMaterial3d(material.clone()),
            Transform::from_matrix(Mat4::from(object.transform)),
        ));
        if !object.casts_shadows {
            e.insert(NotFinShadowCaster);
        }
        if !object.receives_shadows {
            e.insert(NotFinShadowReceiver);
        }
    }
    for (mesh, at) in &setup.extra_meshes {
        let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh.clone());
        world.spawn((Mesh3d(mesh), MeshMaterial3d(material.clone()), Transform::from_translation(*at)));
    }
    if let Light::Disk(d) = setup.light {
        let target = d.center + d.normal;
        let up = if d.normal.cross(Vec3::Z).length() > 1e-3 { Vec3::Z } else { Vec3::X };
        let transform = Transform::from_translation(d.center).looking_at(target, up);
        // The range covers the whole scene, whatever its scale.
        let reach =
            setup.scene.bounds().map_or(20.0, |(lo, hi)| (hi - lo).length() + (d.center - (lo + hi) * 0.5).length());
        let fin = FinLight { radius: d.radius, intensity: setup.intensity, range: reach.max(20.0), ..default() };
        if setup.bevy_point_light {
            world.spawn((
                PointLight {
                    color: fin.color,
                    intensity: fin.intensity,
                    range: fin.range,
                    radius: fin.radius,
                    shadow_maps_enabled: false,
                    ..default()
                },
                transform,
            ));
        } else {
            world.spawn((fin, setup.settings, transform));
        }
    }
    let cameras = std::iter::once(&setup.camera).chain(&setup.extra_cameras);
    let mut slots = vec![];
    for (order, camera) in cameras.enumerate() {
        let view = ViewSlots::default();
        let (color, visibility) = {
            let mut images = world.resource_mut::<Assets<Image>>();
            let mut color = Image::new_target_texture(w, h, TextureFormat::Rgba8UnormSrgb, None);
            color.texture_descriptor.usage |= TextureUsages::COPY_SRC;
            let color = images.add(color);
            let mut vis = Image::new_fill(
                Extent3d { width: w, height: h, depth_or_array_layers: 1 },
                TextureDimension::D2,
                &0f32.to_le_bytes(),
                TextureFormat::R32Float,
                RenderAssetUsages::RENDER_WORLD,
            );
            vis.texture_descriptor.usage |= TextureUsages::COPY_DST | TextureUsages::COPY_SRC;
            (color, images.add(vis))
        };
        let mut e = world.spawn((
            Camera3d::default(),
            Camera { order: order as isize, ..default() },
            setup.tonemapping,
            setup.msaa,
            RenderTarget::Image(color.clone().into()),
            Projection::Perspective(PerspectiveProjection { fov: camera.vertical_fov.to_radians(), ..default() }),
            Transform::from_translation(camera.position).looking_at(camera.target, camera.up),
            FinShadowView { visibility_target: Some(visibility.clone()) },
        ));
        if setup.hdr {
            e.insert(bevy::camera::Hdr);
        }
        for (image, slot) in [(visibility, view.visibility.clone()), (color, view.color.clone())] {
            world.spawn(Readback::texture(image)).observe(move |e: On<ReadbackComplete>| {
                *slot.lock().unwrap() = Some(e.data.clone());
            });
        }
        slots.push(view);
    }
    (app, slots)
}

/// Renders at least `frames` frames, then on until the first camera's image
/// stops changing (shaders load and pipelines compile asynchronously, and
/// read-backs arrive a frame or two late), at most [`MAX_FRAMES`]; returns
/// the last read-backs.
pub fn render(setup: &Setup, frames: u32) -> Result<Shot, String> {
    let (mut app, slots) = app(setup);
    app.finish();
    app.cleanup();
    let take = |slot: &Slot| slot.lock().unwrap().take();
    let mut latest: Vec<(Option<Vec<u8>>, Option<Vec<u8>>)> = vec![(None, None); slots.len()];
    let mut previous_color: Option<Vec<u8>> = None;
    let mut stable = 0;
    for frame in 0..MAX_FRAMES {
        app.update();
        for (view, latest) in slots.iter().zip(&mut latest) {
            if let Some(v) = take(&view.visibility) {
                latest.0 = Some(v);
            }
            if let Some(c) = take(&view.color) {
                latest.1 = Some(c);
            }
        }
        let color = latest[0].1.clone();
        stable = if color.is_some() && color == previous_color { stable + 1 } else { 0 };
        previous_color = color;
        if frame + 1 >= frames.max(3) && stable >= 2 {
            break;
        }
    }
    let mut views = vec![];
    for (visibility, color) in latest {
        let missing = || "no read-back (no GPU adapter?)".to_string();
        let visibility =
            unpad(setup.width, setup.height, &visibility.ok_or_else(missing)?).map(f32::from_le_bytes).collect();
        let color = unpad(setup.width, setup.height, &color.ok_or_else(missing)?).collect();
        views.push(ViewShot { visibility, color });
    }
    let stats = app.world().resource::<FinFrame>().0.as_ref().map(|f| f.stats).unwrap_or_default();
    let pass_times = pass_times(app.world());
    let first = views.remove(0);
    Ok(Shot {
        width: setup.width,
        height: setup.height,
        visibility: first.visibility,
        color: first.color,
        extra_views: views,
        stats,
        pass_times,
    })
}

/// The latest value of every `render/fin_shadows/…` diagnostic.
pub fn pass_times(world: &World) -> Vec<(String, f64)> {
    let Some(store) = world.get_resource::<DiagnosticsStore>() else { return vec![] };
    let mut times: Vec<(String, f64)> = store
        .iter()
        .filter(|d| d.path().as_str().starts_with("render/fin_shadows/"))
        .filter_map(|d| Some((d.path().as_str().to_string(), d.value()?)))
        .collect();
    times.sort_by(|a, b| a.0.cmp(&b.0));
    times
}

/// The 4-byte texels of a read-back, rows unpadded (texture read-backs pad
/// rows to 256 bytes).
pub fn unpad(width: u32, height: u32, data: &[u8]) -> impl Iterator<Item = [u8; 4]> + '_ {
    let row = width as usize * 4;
    let padded = if height > 1 { row.div_ceil(256) * 256 } else { row };
    (0..height as usize)
        .flat_map(move |y| data[y * padded..y * padded + row].chunks_exact(4).map(|b| [b[0], b[1], b[2], b[3]]))
}

impl Shot {
    /// Writes the first camera's final image as a PNG (for looking at what a
    /// test rendered).
    pub fn save_color(&self, path: &str) -> Result<(), String> {
        let image = Image::new(
            Extent3d { width: self.width, height: self.height, depth_or_array_layers: 1 },
            TextureDimension::D2,
            self.color.iter().flatten().copied().collect(),
            TextureFormat::Rgba8UnormSrgb,
            RenderAssetUsages::MAIN_WORLD,
        );
        if let Some(dir) = std::path::Path::new(path).parent() {
            std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
        }
        image.try_into_dynamic().map_err(|e| e.to_string())?.to_rgba8().save(path).map_err(|e| e.to_string())
    }
}
