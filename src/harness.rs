//! Headless rendering of a core-crate scene with the plugin, visibility read back.

use std::sync::{Arc, Mutex};

use bevy::{
    asset::RenderAssetUsages,
    camera::RenderTarget,
    core_pipeline::tonemapping::{DebandDither, Tonemapping},
    diagnostic::DiagnosticsStore,
    light::{PointLightShadowMap, SunDisk},
    pbr::DefaultOpaqueRendererMethod,
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
    FinFrames, FinLight, FinLightStats, FinShadowSettings, FinShadowView, FinShadows, NotFinShadowCaster,
    NotFinShadowReceiver, ShadowFinsPlugin,
};
use shadow_fins::{camera::Camera as CoreCamera, light::Light, scene::Scene};
use shadow_fins_lab::picture::srgb;

/// A scene to render: the core's scene, a disk light (a `FinLight`, or a
/// Bevy `SpotLight` / `PointLight`) or a sun (a Bevy `DirectionalLight` with
/// `FinShadows` and a `SunDisk` of the sun's angular size), and a camera.
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
    /// Shadows of the Bevy `PointLight` (with `bevy_point_light`): none, its
    /// shadow maps (PCF) or its PCSS; the cube faces are
    /// `settings.map_resolution` texels wide.
    pub bevy_shadows: BevyShadows,
    /// Read the colour back as linear floats (`Shot::linear`): an HDR camera
    /// into an `Rgba16Float` target, no tonemapping, no dithering, so colour
    /// ratios are light ratios.
    pub linear_color: bool,
    /// The global ambient light's brightness (Bevy's default when `None`);
    /// the lab sets 0 so that a pixel's colour is the light's alone.
    pub ambient: Option<f32>,
    /// The cameras' near and far planes (Bevy's defaults when `None`).
    pub near: Option<f32>,
    pub far: Option<f32>,
    /// The first camera draws only into this part of the target
    /// (`Camera::viewport`: pixel position and size); the whole target when `None`.
    pub viewport: Option<(UVec2, UVec2)>,
    /// The light is a Bevy `SpotLight` with `FinShadows` (same colour,
    /// intensity, range, radius; cone [`SPOT_OUTER_ANGLE`]) instead of a
    /// `FinLight`.
    pub spot: bool,
    /// More fin-shadowed lights, as Bevy lights with `FinShadows` (and the
    /// setup's settings): a disk is a `SpotLight`, a sphere a `PointLight`, a
    /// rectangle a `RectLight`, the sun a `DirectionalLight`; each one's
    /// visibility read back from the first camera into [`Shot::light_visibility`].
    pub extra_lights: Vec<Light>,
    /// The illuminance of a `Light::Sun`'s `DirectionalLight`, lux.
    pub sun_illuminance: f32,
    /// Render without Bevy's pipelined rendering: each `update` runs the main
    /// world, then the render world (to time them apart).
    pub sequential_rendering: bool,
    /// A glTF file loaded by Bevy's own loader (`WorldAssetRoot` of its first
    /// scene: materials, textures, hierarchy, lights and cameras as a Bevy app
    /// gets them), spawned instead of `scene`'s meshes. `scene` then only
    /// sizes the lights' range; judge the render on [`Session::scene_snapshot`].
    pub gltf: Option<std::path::PathBuf>,
    /// With `gltf`: its own spot and directional lights get `FinShadows` with
    /// `settings` (`give_gltf_lights_fin_shadows`, radius from their extras,
    /// else [`Setup::gltf_light_radius`]) and the harness spawns `light` only
    /// if the file has no light at all (one with only point lights has no
    /// fin-shadowed light: they keep Bevy's shadows).
    pub gltf_lights: bool,
    /// The radius a glTF light without one in its extras gets.
    pub gltf_light_radius: f32,
    /// With `gltf`: the first camera takes the glTF's first camera's view.
    pub gltf_camera: bool,
    /// Leave Bevy's default opaque method (forward) as it is: every mesh is
    /// drawn by Bevy's forward pass, and fin shadows reach it through the
    /// forward hook. (By default the harness makes deferred the default, as a
    /// game that wants the G-buffer path would.)
    pub forward: bool,
}

/// Marks `Setup::extra_lights` (kept when the main light is replaced).
#[derive(Component)]
struct ExtraLight;

/// The outer cone angle of the harness's spot lights (their inner angle is 0).
pub const SPOT_OUTER_ANGLE: f32 = 1.2;

/// How Bevy's own point light casts shadows (the lab's peers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BevyShadows {
    #[default]
    None,
    /// Cube shadow maps filtered by the camera's default PCF.
    Hard,
    /// Percentage-closer soft shadows sized by the light's radius.
    Pcss,
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
            bevy_shadows: BevyShadows::None,
            linear_color: false,
            ambient: None,
            near: None,
            far: None,
            viewport: None,
            spot: false,
            extra_lights: vec![],
            sun_illuminance: 3000.0,
            sequential_rendering: false,
            gltf: None,
            gltf_lights: false,
            gltf_light_radius: 0.0,
            gltf_camera: false,
            forward: false,
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
    /// The camera's output in linear RGB (only with `Setup::linear_color`).
    pub linear: Vec<[f32; 3]>,
}

/// A rendered frame: the first camera's buffers, the others', and the counts.
#[derive(Debug, Clone)]
pub struct Shot {
    pub width: u32,
    pub height: u32,
    pub visibility: Vec<f32>,
    pub color: Vec<[u8; 4]>,
    /// Linear RGB (only with `Setup::linear_color`).
    pub linear: Vec<[f32; 3]>,
    /// The cameras of `Setup::extra_cameras`, in order.
    pub extra_views: Vec<ViewShot>,
    /// The first camera's visibility of each fin-shadowed light spawned with
    /// the app: the setup's light first (unless it is Bevy's point light),
    /// then `Setup::extra_lights` in order.
    pub light_visibility: Vec<Vec<f32>>,
    /// Silhouettes, fins and layers the frame modelled.
    pub stats: bevy_shadow_fins::FinFrameStats,
    /// Every `render/fin_shadows/…` diagnostic (per-pass GPU and CPU times,
    /// ms) with its latest value.
    pub pass_times: Vec<(String, f64)>,
}

/// Frames [`render`] waits at most for the image to settle.
pub const MAX_FRAMES: u32 = 60;

/// How long [`Session::wait_for_gltf`] waits for Bevy's loader.
pub const GLTF_LOAD_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(60);

/// The latest read-back of one image (rows padded to 256 bytes).
pub type Slot = Arc<Mutex<Option<Vec<u8>>>>;

/// Read-back slots of one camera.
#[derive(Clone, Default)]
pub struct ViewSlots {
    pub visibility: Slot,
    pub color: Slot,
    /// One per fin-shadowed light (first camera only), as [`Shot::light_visibility`].
    pub lights: Vec<Slot>,
}

/// Builds the headless app for `setup`; returns it with every camera's
/// read-back slots (the first camera first).
pub fn app(setup: &Setup) -> (App, Vec<ViewSlots>) {
    let mut app = App::new();
    let mut plugins = DefaultPlugins
        .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() })
        .set(RenderPlugin { synchronous_pipeline_compilation: true, ..default() })
        // Headless: no event loop (it needs a display); the caller drives `update`.
        .disable::<bevy::winit::WinitPlugin>()
        // A glTF given by path may live anywhere, as a file opened in an editor does.
        .set(AssetPlugin { unapproved_path_mode: bevy::asset::UnapprovedPathMode::Allow, ..default() });
    if setup.sequential_rendering {
        plugins = plugins.disable::<bevy::render::pipelined_rendering::PipelinedRenderingPlugin>();
    }
    app.add_plugins(plugins).add_plugins((ShadowFinsPlugin, RenderDiagnosticsPlugin));
    if !setup.forward {
        // The G-buffer path for every opaque material, as a game that wants
        // it makes deferred its default (the plugin leaves that choice to the app).
        app.insert_resource(DefaultOpaqueRendererMethod::deferred());
    }
    let world = app.world_mut();
    let (w, h) = (setup.width, setup.height);
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    let own_meshes = if setup.gltf.is_some() { &[][..] } else { &setup.scene.objects[..] };
    // An alpha-masked object (the core's cut-out) as a masked material over
    // its mask, one material per mask.
    let mut masked: Vec<(*const shadow_fins::cutout::AlphaMask, Handle<StandardMaterial>)> = Vec::new();
    for object in own_meshes {
        let uvs = object.cutout.as_ref().map(|c| c.vertex_uvs.as_slice());
        let mesh =
            world.resource_mut::<Assets<Mesh>>().add(bevy_shadow_fins::mesh_from_core_with_uvs(&object.mesh, uvs));
        let material = match &object.cutout {
            None => material.clone(),
            Some(c) => match masked.iter().find(|(m, _)| *m == Arc::as_ptr(&c.mask)) {
                Some((_, h)) => h.clone(),
                None => {
                    let h = masked_material(world, &c.mask);
                    masked.push((Arc::as_ptr(&c.mask), h.clone()));
                    h
                }
            },
        };
        let mut e =
            world.spawn((Mesh3d(mesh), MeshMaterial3d(material), Transform::from_matrix(Mat4::from(object.transform))));
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
    let main = if setup.gltf.is_some() && setup.gltf_lights {
        if let Some(brightness) = setup.ambient {
            world.resource_mut::<GlobalAmbientLight>().brightness = brightness;
        }
        None
    } else {
        replace_light(world, setup)
    };

    let extras: Vec<Entity> = setup
        .extra_lights
        .iter()
        .map(|light| {
            let e = match light {
                Light::Disk(d) => {
                    let transform = light_transform(d.center, d.normal);
                    world.spawn((spot_light(setup, d.radius), setup.settings, transform)).id()
                }
                other => spawn_bevy_light(world, setup, other),
            };
            world.entity_mut(e).insert(ExtraLight);
            e
        })
        .collect();
    let spots: Vec<Entity> = main.into_iter().chain(extras).collect();
    let cameras = std::iter::once(&setup.camera).chain(&setup.extra_cameras);
    let mut slots = vec![];
    let color_format = if setup.linear_color { TextureFormat::Rgba16Float } else { TextureFormat::Rgba8UnormSrgb };
    for (order, camera) in cameras.enumerate() {
        let mut view = ViewSlots::default();
        let light_targets: Vec<(Entity, Handle<Image>)> =
            if order == 0 { spots.iter().map(|&e| (e, visibility_image(world, w, h))).collect() } else { vec![] };
        let visibility = visibility_image(world, w, h);
        let color = {
            let mut color = Image::new_target_texture(w, h, color_format, None);
            color.texture_descriptor.usage |= TextureUsages::COPY_SRC;
            world.resource_mut::<Assets<Image>>().add(color)
        };
        let defaults = PerspectiveProjection::default();
        let (near, far) = (setup.near.unwrap_or(defaults.near), setup.far.unwrap_or(defaults.far));
        let mut e = world.spawn((
            Camera3d::default(),
            Camera {
                order: order as isize,
                viewport: setup.viewport.filter(|_| order == 0).map(|(physical_position, physical_size)| {
                    bevy::camera::Viewport { physical_position, physical_size, ..default() }
                }),
                ..default()
            },
            setup.tonemapping,
            setup.msaa,
            RenderTarget::Image(color.clone().into()),
            Projection::Perspective(PerspectiveProjection {
                fov: camera.vertical_fov.to_radians(),
                near,
                far,
                ..default()
            }),
            Transform::from_translation(camera.position).looking_at(camera.target, camera.up),
            FinShadowView {
                visibility_target: Some(visibility.clone()),
                light_visibility_targets: light_targets.clone(),
            },
        ));
        if setup.hdr || setup.linear_color {
            e.insert(bevy::camera::Hdr);
        }
        if setup.linear_color {
            e.insert((Tonemapping::None, DebandDither::Disabled));
        }
        view.lights = light_targets.iter().map(|_| Slot::default()).collect();
        let lights = light_targets.into_iter().map(|(_, image)| image).zip(view.lights.clone());
        for (image, slot) in
            [(visibility, view.visibility.clone()), (color, view.color.clone())].into_iter().chain(lights)
        {
            world.spawn(Readback::texture(image)).observe(move |e: On<ReadbackComplete>| {
                *slot.lock().unwrap() = Some(e.data.clone());
            });
        }
        slots.push(view);
    }
    if let Some(path) = &setup.gltf {
        let main_camera = world
            .query_filtered::<(Entity, &Camera), With<FinShadowView>>()
            .iter(world)
            .find(|(_, c)| c.order == 0)
            .map(|(e, _)| e);
        spawn_gltf(world, path, GltfAdoption { setup: setup.clone(), main_camera });
    }
    (app, slots)
}

/// A glTF being loaded by Bevy's loader for [`Setup::gltf`].
#[derive(Resource)]
struct GltfLoad {
    root: Entity,
    loading: bevy_shadow_fins::GltfSceneLoading,
    /// Whether its lights and camera were taken over ([`Session::update`]).
    adopted: bool,
    adoption: GltfAdoption,
}

fn spawn_gltf(world: &mut World, path: &std::path::Path, adoption: GltfAdoption) {
    // The scene the core's importer reads (the file's default) is the one Bevy spawns.
    let scene_index = shadow_fins::gltf_import::load_gltf(path).ok().and_then(|import| import.scene_index).unwrap_or(0);
    let assets = world.resource::<AssetServer>().clone();
    let root = bevy_shadow_fins::spawn_gltf_scene(&mut world.commands(), &assets, path, scene_index);
    world.flush();
    let loading = world.get::<bevy_shadow_fins::GltfSceneLoading>(root).expect("just spawned").clone();
    world.insert_resource(GltfLoad { root, loading, adopted: false, adoption });
}

/// Once the glTF is spawned: its lights get fin shadows and its camera gives
/// the first camera its view, as [`Setup`] asks (its own cameras are off:
/// `spawn_gltf_scene` turns them off).
fn adopt_gltf(world: &mut World) {
    let Some((root, setup)) = world
        .get_resource::<GltfLoad>()
        .filter(|l| !l.adopted && l.loading.is_ready())
        .map(|l| (l.root, l.adoption.clone()))
    else {
        return;
    };
    world.resource_mut::<GltfLoad>().adopted = true;
    if setup.setup.gltf_lights {
        let s = &setup.setup;
        let adopted = bevy_shadow_fins::give_gltf_lights_fin_shadows(world, root, s.settings, s.gltf_light_radius);
        // A file without lights gets the setup's.
        if adopted.lights.is_empty() {
            replace_light(world, s);
        }
    }
    let gltf_cameras: Vec<(GlobalTransform, Projection)> = bevy_shadow_fins::descendants_with::<Camera3d>(world, root)
        .into_iter()
        .filter_map(|e| Some((*world.get::<GlobalTransform>(e)?, world.get::<Projection>(e)?.clone())))
        .filter(|(t, _)| t.translation().is_finite())
        .collect();
    if let (true, Some((transform, projection)), Some(main)) =
        (setup.setup.gltf_camera, gltf_cameras.first(), setup.main_camera)
    {
        let mut e = world.entity_mut(main);
        // Its place and turn, not its node's scale (a scaled node would skew the view).
        e.insert(Transform { scale: Vec3::ONE, ..transform.compute_transform() });
        if let (Projection::Perspective(theirs), Some(mut ours)) = (projection, e.get_mut::<Projection>())
            && let Projection::Perspective(ours) = &mut *ours
        {
            ours.fov = theirs.fov;
        }
    }
}

/// What [`adopt_gltf`] does with the glTF's lights and cameras: what the
/// setup asks, to the first camera.
#[derive(Clone)]
struct GltfAdoption {
    setup: Setup,
    main_camera: Option<Entity>,
}

/// Despawns every fin light and Bevy point light, then spawns the light
/// `setup` asks for (and its ambient and cube-map settings): the lab swaps
/// methods in one app this way, so pipelines compile once per scene.
/// An `R32Float` image a camera's visibility layer is copied into.
fn visibility_image(world: &mut World, width: u32, height: u32) -> Handle<Image> {
    let mut image = Image::new_fill(
        Extent3d { width, height, depth_or_array_layers: 1 },
        TextureDimension::D2,
        &0f32.to_le_bytes(),
        TextureFormat::R32Float,
        RenderAssetUsages::RENDER_WORLD,
    );
    image.texture_descriptor.usage |= TextureUsages::COPY_DST | TextureUsages::COPY_SRC;
    world.resource_mut::<Assets<Image>>().add(image)
}

/// Returns the fin-shadowed light spawned (`None` for Bevy's point light).
pub fn replace_light(world: &mut World, setup: &Setup) -> Option<Entity> {
    let old: Vec<Entity> = world
        .query_filtered::<Entity, (
            Or<(With<FinLight>, With<PointLight>, With<DirectionalLight>, With<RectLight>, With<SpotLight>)>,
            Without<ExtraLight>,
        )>()
        .iter(world)
        .collect();
    for e in old {
        world.despawn(e);
    }
    if let Some(brightness) = setup.ambient {
        world.resource_mut::<GlobalAmbientLight>().brightness = brightness;
    }
    world.insert_resource(PointLightShadowMap { size: setup.settings.clamped().map_resolution as usize });
    let d = match setup.light {
        Light::Disk(d) => d,
        other => return Some(spawn_bevy_light(world, setup, &other)),
    };
    let transform = light_transform(d.center, d.normal);
    let fin =
        FinLight { radius: d.radius, intensity: setup.intensity, range: light_range(setup, d.center), ..default() };
    let reach = fin.range;
    if setup.bevy_point_light {
        // Bevy's cube maps need a near plane inside the scene's scale.
        let near = (reach * 1e-3).clamp(1e-6, 0.1);
        world.spawn((
            PointLight {
                color: fin.color,
                intensity: fin.intensity,
                range: fin.range,
                radius: fin.radius,
                shadow_maps_enabled: setup.bevy_shadows != BevyShadows::None,
                soft_shadows_enabled: setup.bevy_shadows == BevyShadows::Pcss,
                shadow_map_near_z: near,
                ..default()
            },
            transform,
        ));
        None
    } else if setup.spot {
        Some(world.spawn((spot_light(setup, d.radius), setup.settings, transform)).id())
    } else {
        Some(world.spawn((fin, setup.settings, transform)).id())
    }
}

/// A fin-shadowed Bevy light of the setup's intensity for a sun, a
/// rectangle or a sphere (a disk is a `FinLight` or a `SpotLight`, see
/// [`replace_light`]).
fn spawn_bevy_light(world: &mut World, setup: &Setup, light: &Light) -> Entity {
    match *light {
        Light::Disk(d) => {
            let transform = light_transform(d.center, d.normal);
            world.spawn((spot_light(setup, d.radius), setup.settings, transform)).id()
        }
        Light::Sun(sun) => {
            let sun_light =
                DirectionalLight { illuminance: setup.sun_illuminance, shadow_maps_enabled: true, ..default() };
            let disk = SunDisk { angular_size: 2.0 * sun.angular_radius, intensity: 1.0 };
            let transform = light_transform(Vec3::ZERO, sun.direction);
            world.spawn((sun_light, disk, FinShadows, setup.settings, transform)).id()
        }
        Light::Rect(r) => {
            let rect = RectLight {
                intensity: setup.intensity,
                range: light_range(setup, r.center),
                width: 2.0 * r.half_extents.x,
                height: 2.0 * r.half_extents.y,
                ..default()
            };
            // Bevy's rectangle spans local X (width) and Y and faces −Z.
            let rotation = Quat::from_mat3(&Mat3::from_cols(r.tangent, r.tangent.cross(r.normal), -r.normal));
            let transform = Transform::from_translation(r.center).with_rotation(rotation);
            world.spawn((rect, FinShadows, setup.settings, transform)).id()
        }
        Light::Sphere(s) => {
            // Bevy's own point light of that radius, its shadow fin-shadowed
            // (the user's shadow_maps_enabled kept: `bevy_lights.rs` turns the
            // cube maps off in the render world only).
            let point = PointLight {
                intensity: setup.intensity,
                range: light_range(setup, s.center),
                radius: s.radius,
                shadow_maps_enabled: true,
                ..default()
            };
            let transform = Transform::from_translation(s.center);
            world.spawn((point, FinShadows, setup.settings, transform)).id()
        }
    }
}

/// A light at `center` facing along `normal`.
fn light_transform(center: Vec3, normal: Vec3) -> Transform {
    let up = if normal.cross(Vec3::Z).length() > 1e-3 { Vec3::Z } else { Vec3::X };
    Transform::from_translation(center).looking_at(center + normal, up)
}

/// A range that covers the whole scene from `center`, whatever its scale.
fn light_range(setup: &Setup, center: Vec3) -> f32 {
    let reach = setup.scene.bounds().map_or(20.0, |(lo, hi)| (hi - lo).length() + (center - (lo + hi) * 0.5).length());
    reach.max(20.0)
}

/// A fin-shadowed Bevy spot light of the setup's intensity and this radius
/// (its range covers the scene from the first light).
fn spot_light(setup: &Setup, radius: f32) -> (SpotLight, FinShadows) {
    let center = setup.light.planar().map_or(Vec3::ZERO, |(c, _)| c);
    let spot = SpotLight {
        intensity: setup.intensity,
        range: light_range(setup, center) * 2.0,
        radius,
        outer_angle: SPOT_OUTER_ANGLE,
        inner_angle: 0.0,
        shadow_maps_enabled: true,
        ..default()
    };
    (spot, FinShadows)
}

/// A headless app kept alive across measurements: settle it, read it back,
/// time it, change its light, settle again.
pub struct Session {
    pub app: App,
    slots: Vec<ViewSlots>,
    latest: Vec<(Option<Vec<u8>>, Option<Vec<u8>>)>,
    /// The first camera's per-light visibility read-backs.
    latest_lights: Vec<Option<Vec<u8>>>,
    width: u32,
    height: u32,
    linear_color: bool,
}

/// Per-frame times of [`Session::timed`].
#[derive(Debug, Clone, Default)]
pub struct Timing {
    /// Wall time of each `App::update` (main and render world, GPU work
    /// waited on by the read-back), ms.
    pub frame_ms: Vec<f64>,
    /// Every `render/fin_shadows/…` diagnostic, one value per frame.
    pub passes: Vec<(String, Vec<f64>)>,
}

impl Session {
    pub fn new(setup: &Setup) -> Self {
        let (mut app, slots) = app(setup);
        app.finish();
        app.cleanup();
        let latest = vec![(None, None); slots.len()];
        let latest_lights = vec![None; slots[0].lights.len()];
        Self {
            app,
            slots,
            latest,
            latest_lights,
            width: setup.width,
            height: setup.height,
            linear_color: setup.linear_color,
        }
    }

    /// One frame; the read-backs that arrived are kept for [`Session::shot`].
    pub fn update(&mut self) {
        self.app.update();
        adopt_gltf(self.app.world_mut());
        let take = |slot: &Slot| slot.lock().unwrap().take();
        for (view, latest) in self.slots.iter().zip(&mut self.latest) {
            if let Some(v) = take(&view.visibility) {
                latest.0 = Some(v);
            }
            if let Some(c) = take(&view.color) {
                latest.1 = Some(c);
            }
        }
        for (slot, latest) in self.slots[0].lights.iter().zip(&mut self.latest_lights) {
            if let Some(v) = take(slot) {
                *latest = Some(v);
            }
        }
    }

    /// Renders at least `frames` frames, then on until the first camera's
    /// image stops changing (shaders load and pipelines compile
    /// asynchronously, and read-backs arrive a frame or two late), at most
    /// [`MAX_FRAMES`]; returns the last read-backs.
    pub fn settle(&mut self, frames: u32) -> Result<Shot, String> {
        let mut previous_color: Option<Vec<u8>> = None;
        let mut stable = 0;
        for slot in &mut self.latest {
            *slot = (None, None);
        }
        for slot in &mut self.latest_lights {
            *slot = None;
        }
        self.wait_for_gltf()?;
        for frame in 0..MAX_FRAMES {
            self.update();
            let color = self.latest[0].1.clone();
            // GPU extraction: its counts come back a few frames late, and a
            // frame that overflowed a buffer is redone once they do.
            let world = self.app.world_mut();
            let extracted = world.query::<&FinLightStats>().iter(world).all(|s| s.0.up_to_date)
                || world.resource::<FinFrames>().0.is_empty();
            stable = if color.is_some() && color == previous_color && extracted { stable + 1 } else { 0 };
            previous_color = color;
            // Three equal frames in a row: Bevy's own lights take a few frames
            // to appear (clustering warm-up; seen as two equal ambient-only
            // frames on lavapipe), which two equal frames could mistake for
            // the settled image.
            if frame + 1 >= frames.max(3) && stable >= 3 {
                break;
            }
        }
        // A pipeline whose shader does not build leaves its pass out (Bevy
        // logs it once): the picture would show another method's result.
        if let Some(why) = self.failed_pipelines().first() {
            return Err(format!("a render pipeline failed to build: {why}"));
        }
        self.shot()
    }

    /// The render pipelines whose shader failed to build (a WGSL or import
    /// error), one line each: label and Bevy's error's first line. A shader
    /// still loading is not a failure. Bevy keeps every pipeline it was
    /// asked for, so one such error fails every later `settle`, by design.
    /// A wgpu validation error at pipeline creation (a binding the layout
    /// lacks) goes to wgpu's error handler instead and is not seen here.
    pub fn failed_pipelines(&self) -> Vec<String> {
        use bevy::render::render_resource::{CachedPipelineState, PipelineCache};
        use bevy::shader::ShaderCacheError;
        let Some(render) = self.app.get_sub_app(bevy::render::RenderApp) else { return Vec::new() };
        let Some(cache) = render.world().get_resource::<PipelineCache>() else { return Vec::new() };
        cache
            .pipelines()
            .filter_map(|p| {
                let CachedPipelineState::Err(e) = &p.state else { return None };
                if matches!(e, ShaderCacheError::ShaderNotLoaded(_) | ShaderCacheError::ShaderImportNotYetAvailable) {
                    return None;
                }
                let label = match &p.descriptor {
                    bevy::material::descriptor::PipelineDescriptor::RenderPipelineDescriptor(d) => d.label.clone(),
                    bevy::material::descriptor::PipelineDescriptor::ComputePipelineDescriptor(d) => d.label.clone(),
                };
                let label = label.unwrap_or_else(|| "unlabelled".into());
                Some(format!("{label}: {}", bevy_shadow_fins::first_line(&e.to_string())))
            })
            .collect()
    }

    /// Runs frames until [`Setup::gltf`] is spawned (at once without one);
    /// a file Bevy's loader rejects is an error, as is one still loading
    /// after [`GLTF_LOAD_TIMEOUT`].
    pub fn wait_for_gltf(&mut self) -> Result<(), String> {
        let start = std::time::Instant::now();
        loop {
            let world = self.app.world();
            let Some(load) = world.get_resource::<GltfLoad>() else { return Ok(()) };
            if load.adopted {
                return Ok(());
            }
            if let Some(e) = load.loading.failed(world.resource::<AssetServer>()) {
                return Err(format!("Bevy could not load the glTF: {e}"));
            }
            if start.elapsed() > GLTF_LOAD_TIMEOUT {
                return Err("the glTF was still loading after a minute".into());
            }
            self.update();
        }
    }

    /// The glTF's root entity (`None` without [`Setup::gltf`]).
    pub fn gltf_root(&self) -> Option<Entity> {
        self.app.world().get_resource::<GltfLoad>().map(|l| l.root)
    }

    /// The meshes the plugin sees (those of the glTF only, with one), as
    /// the core's scene: what the oracle and the ground truth must be run on.
    pub fn scene_snapshot(&mut self) -> bevy_shadow_fins::FinSceneSnapshot {
        let root = self.gltf_root();
        bevy_shadow_fins::scene_snapshot(self.app.world_mut(), root)
    }

    /// The first camera's view as the core's camera (after [`Setup::gltf_camera`]
    /// gave it the file's): what an oracle of this view must be run from.
    pub fn main_camera(&mut self) -> Option<CoreCamera> {
        let world = self.app.world_mut();
        let mut cameras = world.query::<(&Camera, &Transform, &Projection, &FinShadowView)>();
        let (_, transform, projection, _) = cameras.iter(world).find(|(c, ..)| c.order == 0)?;
        let Projection::Perspective(p) = projection else { return None };
        Some(CoreCamera {
            position: transform.translation,
            target: transform.translation + transform.forward().as_vec3(),
            up: transform.up().as_vec3(),
            vertical_fov: p.fov.to_degrees(),
        })
    }

    /// Every fin-shadowed light's entity and shape, as the plugin models it.
    pub fn fin_lights(&self) -> Vec<(Entity, Light)> {
        self.app.world().resource::<FinFrames>().0.iter().map(|f| (f.light, f.shape)).collect()
    }

    /// The latest read-backs of every camera.
    pub fn shot(&self) -> Result<Shot, String> {
        let (w, h) = (self.width, self.height);
        let mut views = vec![];
        for (visibility, color) in &self.latest {
            let missing = || "no read-back (no GPU adapter?)".to_string();
            let visibility = unpad(w, h, visibility.as_ref().ok_or_else(missing)?).map(f32::from_le_bytes).collect();
            let color = color.as_ref().ok_or_else(missing)?;
            let (color, linear) = if self.linear_color {
                let linear: Vec<[f32; 3]> = unpad_texels::<8>(w, h, color)
                    .map(|b| std::array::from_fn(|c| f16_to_f32(u16::from_le_bytes([b[2 * c], b[2 * c + 1]]))))
                    .collect();
                let bytes = linear.iter().map(|c| [srgb(c[0]), srgb(c[1]), srgb(c[2]), 255]).collect();
                (bytes, linear)
            } else {
                (unpad(w, h, color).collect(), vec![])
            };
            views.push(ViewShot { visibility, color, linear });
        }
        let stats = self.app.world().resource::<bevy_shadow_fins::FinShadowStats>().0;
        let light_visibility = self
            .latest_lights
            .iter()
            .map(|l| Ok(unpad(w, h, l.as_ref().ok_or("no per-light read-back")?).map(f32::from_le_bytes).collect()))
            .collect::<Result<Vec<Vec<f32>>, String>>()?;
        let pass_times = pass_times(self.app.world());
        let first = views.remove(0);
        Ok(Shot {
            width: w,
            height: h,
            visibility: first.visibility,
            color: first.color,
            linear: first.linear,
            extra_views: views,
            light_visibility,
            stats,
            pass_times,
        })
    }

    /// Renders `frames` frames and times each (read-backs keep running, so
    /// every frame waits for its GPU work the same way for every method).
    pub fn timed(&mut self, frames: u32) -> Timing {
        self.timed_with(frames, |_, _| {})
    }

    /// [`Session::timed`], calling `before(world, frame)` ahead of each
    /// frame, outside the timing (to move something, say).
    pub fn timed_with(&mut self, frames: u32, mut before: impl FnMut(&mut World, u32)) -> Timing {
        let mut timing = Timing::default();
        for frame in 0..frames {
            before(self.app.world_mut(), frame);
            let start = std::time::Instant::now();
            self.update();
            timing.frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
            for (path, value) in pass_times(self.app.world()) {
                match timing.passes.iter_mut().find(|(p, _)| *p == path) {
                    Some((_, values)) => values.push(value),
                    None => timing.passes.push((path, vec![value])),
                }
            }
        }
        timing
    }

    /// Swaps the light for the one `setup` describes (see [`replace_light`]).
    pub fn replace_light(&mut self, setup: &Setup) {
        // Per-light read-backs follow the lights spawned with the app only.
        replace_light(self.app.world_mut(), setup);
    }
}

/// A double-sided `AlphaMode::Mask` material over `mask` (its alphas as the
/// base colour texture, its base alpha and cutoff): how an alpha-masked core
/// caster (`shadow_fins::cutout`) is drawn by Bevy.
pub fn masked_material(world: &mut World, mask: &shadow_fins::cutout::AlphaMask) -> Handle<StandardMaterial> {
    let image = world.resource_mut::<Assets<Image>>().add(bevy_shadow_fins::image_of_mask(mask));
    world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial {
        base_color: Color::WHITE.with_alpha(mask.base_alpha()),
        base_color_texture: Some(image),
        alpha_mode: AlphaMode::Mask(mask.cutoff()),
        double_sided: true,
        cull_mode: None,
        ..default()
    })
}

/// Renders at least `frames` frames until the image settles (see
/// [`Session::settle`]) and returns the last read-backs.
pub fn render(setup: &Setup, frames: u32) -> Result<Shot, String> {
    Session::new(setup).settle(frames)
}

/// IEEE half → single precision.
pub fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = (h >> 10) & 0x1f;
    let mantissa = (h & 0x3ff) as f32;
    match exponent {
        0 => sign * mantissa * 2f32.powi(-24),
        0x1f if mantissa == 0.0 => sign * f32::INFINITY,
        0x1f => f32::NAN,
        e => sign * (1.0 + mantissa / 1024.0) * 2f32.powi(e as i32 - 15),
    }
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
    unpad_texels::<4>(width, height, data)
}

/// The `N`-byte texels of a read-back, rows unpadded.
pub fn unpad_texels<const N: usize>(width: u32, height: u32, data: &[u8]) -> impl Iterator<Item = [u8; N]> + '_ {
    let row = width as usize * N;
    let padded = if height > 1 { row.div_ceil(256) * 256 } else { row };
    (0..height as usize)
        .flat_map(move |y| data[y * padded..y * padded + row].chunks_exact(N).map(|b| std::array::from_fn(|i| b[i])))
}

impl Shot {
    /// Writes the first camera's final image as a PNG (for looking at what a
    /// test rendered).
    pub fn save_color(&self, path: &str) -> Result<(), String> {
        save_srgb8(self.width, self.height, &self.color, path)
    }

    /// Writes the first camera's visibility buffer as a grey PNG (white
    /// lit, black in umbra; a value not finite is written red): the shadow
    /// alone, without the lighting that can hide it in the final image.
    pub fn save_visibility(&self, path: &str) -> Result<(), String> {
        let grey = |v: f32| -> [u8; 4] {
            if !v.is_finite() {
                return [255, 0, 0, 255];
            }
            let g = (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8;
            [g, g, g, 255]
        };
        save_srgb8(self.width, self.height, &self.visibility.iter().map(|v| grey(*v)).collect::<Vec<_>>(), path)
    }
}

/// Writes sRGB bytes (RGBA, row-major, top row first) as a PNG, making its folder.
pub fn save_srgb8(width: u32, height: u32, pixels: &[[u8; 4]], path: &str) -> Result<(), String> {
    let image = Image::new(
        Extent3d { width, height, depth_or_array_layers: 1 },
        TextureDimension::D2,
        pixels.iter().flatten().copied().collect(),
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::MAIN_WORLD,
    );
    if let Some(dir) = std::path::Path::new(path).parent() {
        std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    }
    image.try_into_dynamic().map_err(|e| e.to_string())?.to_rgba8().save(path).map_err(|e| e.to_string())
}
