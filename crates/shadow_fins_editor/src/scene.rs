//! The scene (built-in demo or a glTF), the light and the camera, and the one
//! system that turns the UI's [`LightParams`] into components.

use std::sync::Arc;

use bevy::{
    camera::RenderTarget, input::mouse::AccumulatedMouseMotion, light::SunDisk, prelude::*, window::FileDragAndDrop,
};
use bevy_egui::input::EguiWantsInput;
use bevy_shadow_fins::{FinLight, FinShadowSettings, FinShadowView, FinShadows, NotFinShadowCaster};
use shadow_fins::{light::Light, scenes::SceneId};

use crate::state::{
    DEFAULT_ILLUMINANCE, DEFAULT_RECT_ASPECT, DEFAULT_SUN_ANGLE, EditorCamera, EditorLight, EditorMesh, EditorMethod,
    EditorSceneRoot, GltfLoadsFinished, LightKind, LightMarker, LightParams, LoadedScene, SPOT_CONE, SceneSource,
};
use crate::{EditorOptions, EditorState, gltf_scene, orbit::OrbitCamera, settings_file::EditorSettings};

/// A request to (re)load a scene, from the command line, the UI or a drop.
#[derive(Message, Debug, Clone)]
pub struct LoadScene {
    pub source: SceneSource,
    /// Keep the current light instead of placing one over the new scene (the
    /// light of a `--settings` file given with the scene).
    pub keep_light: bool,
}

impl LoadScene {
    pub fn new(source: SceneSource) -> Self {
        Self { source, keep_light: false }
    }
}

pub(crate) fn build(app: &mut App) {
    app.add_message::<LoadScene>().add_systems(Startup, (spawn_rig, request_initial_scene).chain()).add_systems(
        Update,
        (
            load_dropped_files,
            load_scene,
            gltf_scene::finish_gltf_loads.in_set(GltfLoadsFinished),
            crate::ground::apply_added_ground,
            drag_light_with_shift,
            sync_light,
            sync_marker,
        )
            .chain(),
    );
}

/// The light's range: the whole scene from anywhere in it, at any scale
/// (at least Bevy's default range, so a small scene's light is not cut).
pub(crate) fn light_range(scene: Option<&LoadedScene>) -> f32 {
    scene.map_or(1000.0, |s| (s.extent * 10.0).max(1000.0))
}

/// Whether the settings the editor started from (`--settings` or the
/// autosave) were read.
#[derive(Resource, Debug, Clone, Copy)]
pub(crate) struct StartSettings {
    pub loaded: bool,
}

fn request_initial_scene(
    options: Res<EditorOptions>,
    start: Option<Res<StartSettings>>,
    mut load: MessageWriter<LoadScene>,
) {
    let source = options.scene.clone().map_or(SceneSource::Demo, SceneSource::Gltf);
    // A settings file's light stays; so does an autosaved one, unless a new
    // scene was asked for; a file that did not read keeps nothing.
    let loaded = start.is_some_and(|s| s.loaded);
    let keep_light = loaded && (options.settings.is_some() || options.scene.is_none());
    load.write(LoadScene { source, keep_light });
}

fn spawn_rig(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    options: Res<EditorOptions>,
    mut state: ResMut<EditorState>,
) {
    let demo = SceneId::Demo.build();
    let Light::Disk(disk) = demo.light else { unreachable!("the demo light is a disk") };
    let mut params = LightParams {
        position: disk.center,
        direction: disk.normal,
        radius: disk.radius,
        intensity: FinLight::default().intensity,
        color: [1.0, 1.0, 1.0],
        method: EditorMethod::default(),
        kind: LightKind::FinLight,
        sun_angle: DEFAULT_SUN_ANGLE,
        illuminance: DEFAULT_ILLUMINANCE,
        rect_aspect: DEFAULT_RECT_ASPECT,
    };
    let mut settings = FinShadowSettings::default();
    // `--settings`, or the autosave an earlier run left.
    let mut loaded = false;
    if let Some(path) = options.start_settings() {
        match EditorSettings::load_into(&path, &mut params, &mut settings) {
            Ok(()) => {
                loaded = true;
                if options.settings.is_none() {
                    state.status = Some(format!("restored the autosaved settings from {}", path.display()));
                }
            }
            // An autosave that does not read is kept aside, not overwritten by
            // the next autosave: nothing of the user's is lost.
            Err(e) if options.settings.is_none() => {
                let aside = path.with_extension("ron.bad");
                let kept = std::fs::rename(&path, &aside).map_or_else(
                    |err| format!("it could not be moved aside ({err}); autosave is off"),
                    |()| format!("it was kept as {}", aside.display()),
                );
                state.error = Some(format!("the autosaved settings could not be read: {e}; {kept}"));
            }
            Err(e) => state.error = Some(e.to_string()),
        }
    }
    commands.insert_resource(StartSettings { loaded });
    commands.insert_resource(params);
    commands.spawn((EditorLight, settings, params.transform()));
    // The light's position, drawn as a small unlit disc that casts nothing.
    commands.spawn((
        LightMarker,
        Mesh3d(meshes.add(Sphere::new(1.0).mesh().ico(2).unwrap_or_else(|_| Sphere::new(1.0).mesh().uv(16, 8)))),
        MeshMaterial3d(materials.add(StandardMaterial {
            unlit: true,
            base_color: Color::srgb(1.0, 0.9, 0.4),
            ..default()
        })),
        NotFinShadowCaster,
        bevy::light::NotShadowCaster,
        params.transform().with_scale(Vec3::new(1.0, 1.0, 0.05) * params.radius.max(0.02)),
    ));
    let camera = demo.camera;
    commands.spawn((
        EditorCamera,
        Camera3d::default(),
        bevy::camera::Hdr,
        RenderTarget::default(),
        FinShadowView::default(),
        OrbitCamera::looking_at(camera.position, camera.target),
        Projection::Perspective(PerspectiveProjection { fov: camera.vertical_fov.to_radians(), ..default() }),
        Transform::from_translation(camera.position).looking_at(camera.target, Vec3::Y),
    ));
}

fn load_dropped_files(mut drops: MessageReader<FileDragAndDrop>, mut load: MessageWriter<LoadScene>) {
    for drop in drops.read() {
        if let FileDragAndDrop::DroppedFile { path_buf, .. } = drop {
            load.write(LoadScene::new(SceneSource::Gltf(path_buf.clone())));
        }
    }
}

/// Replaces the scene: the demo at once; a glTF is handed to Bevy's loader
/// and replaces the scene once spawned (`gltf_scene.rs`). A broken file
/// leaves the current scene and shows the error.
#[allow(clippy::too_many_arguments)]
fn load_scene(
    mut commands: Commands,
    mut requests: MessageReader<LoadScene>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    assets: Res<AssetServer>,
    old: Query<Entity, Or<(With<EditorMesh>, With<EditorSceneRoot>)>>,
    pending: Query<Entity, With<gltf_scene::PendingGltf>>,
    mut cameras: Query<(&mut OrbitCamera, &mut Projection), With<EditorCamera>>,
    loaded: Option<Res<LoadedScene>>,
    mut state: ResMut<EditorState>,
) {
    let Some(LoadScene { source, keep_light }) = requests.read().last().cloned() else { return };
    let path = match source {
        SceneSource::Gltf(path) => {
            // An earlier error (a bad settings file, a broken glTF) stays until dismissed.
            match gltf_scene::start_gltf_load(&mut commands, &assets, pending.iter(), &path, keep_light) {
                Ok(()) => state.status = Some(format!("loading {}…", path.display())),
                Err(e) => state.error = Some(e),
            }
            return;
        }
        SceneSource::Demo => SceneId::Demo.build(),
    };
    // The demo replaces the scene, and any glTF still loading.
    gltf_scene::cancel_pending(&mut commands, pending.iter());
    for e in &old {
        commands.entity(e).despawn();
    }
    let material = materials.add(StandardMaterial { perceptual_roughness: 0.8, ..default() });
    for object in &path.scene.objects {
        let mesh = meshes.add(bevy_shadow_fins::mesh_from_core(&object.mesh));
        let mut e = commands.spawn((
            EditorMesh,
            Mesh3d(mesh),
            MeshMaterial3d(material.clone()),
            Transform::from_matrix(Mat4::from(object.transform)),
        ));
        if !object.casts_shadows {
            e.insert(NotFinShadowCaster);
        }
    }
    // The demo keeps the user's light and view.
    let generation = loaded.map_or(1, |l| l.generation + 1);
    let extent = path.scene.diagonal().unwrap_or(1.0);
    // A glTF before may have left a far near plane and a kilometre zoom.
    for (mut orbit, mut projection) in &mut cameras {
        orbit.scale = extent;
        *projection =
            Projection::Perspective(PerspectiveProjection { fov: path.camera.vertical_fov.to_radians(), ..default() });
        gltf_scene::fit_clip_planes(&mut projection, None, extent);
    }
    commands.insert_resource(LoadedScene { name: "demo".into(), scene: Arc::new(path.scene), generation, extent });
    // The demo has its own ground.
    commands.remove_resource::<crate::ground::AddedGround>();
    // The demo does not animate.
    commands.insert_resource(crate::animation::EditorAnimation::default());
    state.status = Some("loaded demo".into());
}

/// The light's "drag gizmo": Shift + drag in the viewport moves the light
/// over the ground (x/z); Shift + Ctrl + drag moves it up and down.
fn drag_light_with_shift(
    buttons: Res<ButtonInput<MouseButton>>,
    keys: Res<ButtonInput<KeyCode>>,
    motion: Res<AccumulatedMouseMotion>,
    egui_input: Res<EguiWantsInput>,
    camera: Query<&Transform, With<EditorCamera>>,
    mut params: ResMut<LightParams>,
) {
    let shift = keys.any_pressed([KeyCode::ShiftLeft, KeyCode::ShiftRight]);
    if !shift
        || !buttons.pressed(MouseButton::Left)
        || egui_input.wants_any_pointer_input()
        || motion.delta == Vec2::ZERO
    {
        return;
    }
    let Ok(camera) = camera.single() else { return };
    let speed = 0.01 * (camera.translation - params.position).length().max(1.0) * 0.2;
    if keys.any_pressed([KeyCode::ControlLeft, KeyCode::ControlRight]) {
        params.position.y -= motion.delta.y * speed;
    } else {
        let right = camera.right().as_vec3().with_y(0.0).normalize_or_zero();
        let forward = camera.forward().as_vec3().with_y(0.0).normalize_or_zero();
        params.position += right * motion.delta.x * speed - forward * motion.delta.y * speed;
    }
}

/// The power of a Bevy `RectLight` as bright on its axis as the editor's disk
/// light of `intensity` lumens: Bevy spreads a point or spot light's lumens over
/// the sphere (`E = P / 4πd²`) but a rectangle's over its one lit hemisphere as
/// a Lambertian emitter (`L = P / πA`, so `E ≈ P / πd²` on its axis): a quarter.
pub(crate) fn rect_intensity(intensity: f32) -> f32 {
    intensity * 0.25
}

/// Writes the light parameters into the light entity: a `FinLight` for the
/// fin methods, Bevy's `PointLight` with PCSS for the PCSS method.
fn sync_light(
    mut commands: Commands,
    params: Res<LightParams>,
    loaded: Option<Res<LoadedScene>>,
    mut lights: Query<
        (
            Entity,
            &mut Transform,
            &mut FinShadowSettings,
            Option<&mut FinLight>,
            Option<&mut SpotLight>,
            Option<&mut DirectionalLight>,
            Option<&mut RectLight>,
            (Option<&mut PointLight>, Has<FinShadows>),
        ),
        With<EditorLight>,
    >,
) {
    if !params.is_changed() {
        return;
    }
    let Ok((entity, mut transform, mut settings, fin, spot, directional, rect, (point, fin_shadowed))) =
        lights.single_mut()
    else {
        return;
    };
    let finite = |x: f32| if x.is_finite() { x.max(0.0) } else { 0.0 };
    *transform = params.transform();
    let color = Color::srgb(params.color[0], params.color[1], params.color[2]);
    let radius = params.radius.max(0.0);
    let intensity = params.intensity.max(0.0);
    let range = light_range(loaded.as_deref());
    match params.method.fin_method() {
        Some(method) => {
            if settings.method != method {
                settings.method = method;
            }
            if params.kind == LightKind::Sun {
                let sun = DirectionalLight {
                    color,
                    illuminance: finite(params.illuminance),
                    shadow_maps_enabled: true,
                    ..default()
                };
                let disk = SunDisk { angular_size: 2.0 * params.sun_angular_radius(), intensity: 1.0 };
                match directional {
                    Some(mut d) => *d = sun,
                    None => {
                        commands.entity(entity).remove::<(PointLight, FinLight, SpotLight, RectLight)>().insert(sun);
                    }
                }
                // Also after Bevy PCSS, which kept the DirectionalLight but not FinShadows.
                commands.entity(entity).insert((disk, FinShadows));
                return;
            }
            if params.kind == LightKind::Spot {
                let light = SpotLight {
                    color,
                    intensity,
                    range,
                    radius,
                    outer_angle: SPOT_CONE,
                    inner_angle: SPOT_CONE * 0.7,
                    ..default()
                };
                match spot {
                    Some(mut s) => *s = light,
                    None => {
                        commands
                            .entity(entity)
                            .remove::<(PointLight, FinLight, DirectionalLight, SunDisk, RectLight)>()
                            .insert((light, FinShadows));
                    }
                }
                return;
            }
            if params.kind == LightKind::Rect {
                // Bevy divides a RectLight's power by its area: 0 × 0 would
                // light with infinite radiance (NaN on screen). A millimetre
                // square is a hard shadow for any scene the editor shows.
                let (width, height) = params.rect_size();
                let light = RectLight {
                    color,
                    intensity: rect_intensity(intensity),
                    range,
                    width: width.max(1e-3),
                    height: height.max(1e-3),
                };
                match rect {
                    Some(mut r) => *r = light,
                    None => {
                        commands
                            .entity(entity)
                            .remove::<(PointLight, FinLight, SpotLight, DirectionalLight, SunDisk)>()
                            .insert((light, FinShadows));
                    }
                }
                return;
            }
            if params.kind == LightKind::Point {
                let light = PointLight { color, intensity, range, radius, shadow_maps_enabled: true, ..default() };
                match point {
                    // After Bevy PCSS the PointLight stays but has no FinShadows.
                    Some(mut p) if fin_shadowed => *p = light,
                    _ => {
                        commands
                            .entity(entity)
                            .remove::<(PointLight, FinLight, SpotLight, DirectionalLight, SunDisk, RectLight)>()
                            .insert((light, FinShadows));
                    }
                }
                return;
            }
            let light = FinLight { color, intensity, range, radius };
            match fin {
                Some(mut f) => *f = light,
                None => {
                    commands
                        .entity(entity)
                        .remove::<(PointLight, SpotLight, DirectionalLight, SunDisk, RectLight, FinShadows)>()
                        .insert(light);
                }
            }
        }
        None => {
            // Bevy's PCSS peer. For the sun: Bevy's cascades with PCSS, whose
            // `soft_shadow_size` is a size in cascade depth units, not an
            // angle (Bevy's knob; given the sun's angular diameter here).
            let mut e = commands.entity(entity);
            e.remove::<(FinLight, SpotLight, PointLight, DirectionalLight, SunDisk, RectLight, FinShadows)>();
            if params.kind == LightKind::Sun {
                e.insert(DirectionalLight {
                    color,
                    illuminance: finite(params.illuminance),
                    shadow_maps_enabled: true,
                    soft_shadow_size: Some(2.0 * params.sun_angular_radius()),
                    ..default()
                });
            } else {
                e.insert(PointLight {
                    color,
                    intensity,
                    range,
                    radius,
                    shadow_maps_enabled: true,
                    soft_shadows_enabled: true,
                    ..default()
                });
            }
        }
    }
}

fn sync_marker(
    params: Res<LightParams>,
    loaded: Option<Res<LoadedScene>>,
    mut marker: Query<&mut Transform, With<LightMarker>>,
) {
    if params.is_changed() || loaded.as_ref().is_some_and(|l| l.is_changed()) {
        // Seen at any scale: at least half a percent of the scene.
        let least = loaded.map_or(0.02, |l| l.extent * 0.005);
        for mut t in &mut marker {
            let scale = match params.kind {
                // The rectangle as a flat box of its half sizes.
                LightKind::Rect => {
                    let (w, h) = params.rect_size();
                    Vec3::new((w * 0.5).max(least), (h * 0.5).max(least), 0.05 * params.radius.max(least))
                }
                // A sphere: as deep as it is wide.
                LightKind::Point => Vec3::splat(params.radius.max(least)),
                _ => Vec3::new(1.0, 1.0, 0.05) * params.radius.max(least),
            };
            *t = params.transform().with_scale(scale);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::*;

    /// The scene loading alone, on a headless app.
    fn app() -> App {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_resource::<Assets<Mesh>>()
            .init_resource::<Assets<StandardMaterial>>()
            .init_resource::<EditorState>()
            .insert_resource(LightParams {
                position: Vec3::new(1.0, 5.0, 2.0),
                direction: Vec3::NEG_Y,
                radius: 0.7,
                intensity: 5e5,
                color: [1.0, 0.5, 0.25],
                method: EditorMethod::default(),
                kind: LightKind::FinLight,
                sun_angle: DEFAULT_SUN_ANGLE,
                illuminance: DEFAULT_ILLUMINANCE,
                rect_aspect: DEFAULT_RECT_ASPECT,
            })
            .add_message::<LoadScene>()
            .add_systems(Update, load_scene);
        app
    }

    fn meshes(app: &mut App) -> Vec<Entity> {
        app.world_mut().query_filtered::<Entity, With<EditorMesh>>().iter(app.world()).collect()
    }

    #[test]
    fn the_last_load_asked_for_wins_over_one_still_pending() {
        let mut app = app();
        let courtyard = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/courtyard.gltf");
        let pending = |app: &mut App| {
            app.world_mut().query_filtered::<Entity, With<gltf_scene::PendingGltf>>().iter(app.world()).count()
        };
        for _ in 0..2 {
            app.world_mut().write_message(LoadScene::new(SceneSource::Gltf(courtyard.clone())));
            app.update();
        }
        assert_eq!(pending(&mut app), 1, "a second request replaces the first");
        app.world_mut().write_message(LoadScene::new(SceneSource::Demo));
        app.update();
        assert_eq!(pending(&mut app), 0, "the demo replaces a pending glTF");
        assert!(meshes(&mut app).len() > 3, "and is shown");
    }

    #[test]
    fn a_failed_load_leaves_the_current_scene_and_light_as_they_were() {
        let mut app = app();
        app.world_mut().write_message(LoadScene::new(SceneSource::Demo));
        app.update();
        let before = meshes(&mut app);
        assert!(before.len() > 3, "the demo scene is loaded");
        let light = *app.world().resource::<LightParams>();
        let broken = std::env::temp_dir().join(format!("fin-editor-broken-{}.gltf", std::process::id()));
        std::fs::write(&broken, "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [").unwrap();
        for path in [broken.clone(), "/nonexistent/scene.glb".into()] {
            app.world_mut().write_message(LoadScene::new(SceneSource::Gltf(path.clone())));
            app.update();
            assert_eq!(meshes(&mut app), before, "{}: the scene's meshes stay", path.display());
            assert_eq!(*app.world().resource::<LightParams>(), light, "the light stays");
            let error = app.world().resource::<EditorState>().error.clone().expect("the error is shown");
            assert!(error.contains("could not open"), "{error}");
        }
        std::fs::remove_file(&broken).unwrap();
    }
}
