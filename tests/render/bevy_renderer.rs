//! The plugin does not take over Bevy's renderer (issue 12, item 3): no
//! app-wide setting changes; a camera without `FinShadowView` renders as it
//! would without the plugin, fin-shadowed lights' Bevy shadow maps included;
//! a receiver fin shadows cannot reach (a forward material) gets Bevy's hard
//! shadow; and a fin-shadowed camera shows the same fin shadow whether Bevy's
//! maps are kept for those or not (the compositing pass replaces Bevy's
//! shadow S by V).
//!
//! Its own small app (not the harness): the comparisons need an app without
//! the plugin, cameras without `FinShadowView` and cameras spawned later.
//! Tolerances: the same app with and without the plugin runs the same Bevy
//! passes on the same inputs, so its images are compared exactly; the fin
//! camera's `(V − S)·L` against `(V − 1)·L` differs by float rounding before
//! 8-bit quantisation: at most one sRGB step.

use bevy::{
    camera::RenderTarget,
    core_pipeline::tonemapping::Tonemapping,
    material::OpaqueRendererMethod,
    pbr::{DefaultOpaqueRendererMethod, ExtractedDirectionalLight, ExtractedPointLight},
    prelude::*,
    render::{
        RenderApp, RenderPlugin,
        gpu_readback::{Readback, ReadbackComplete},
        render_resource::{TextureFormat, TextureUsages},
    },
    window::ExitCondition,
};
use bevy_shadow_fins::{BevyShadowMapsKept, FinReceivers, FinShadowView, FinShadows, ShadowFinsPlugin};
use shadow_fins_app::harness::{Slot, save_srgb8, unpad};

const W: u32 = 96;
const H: u32 = 72;

/// What the app holds.
#[derive(Clone, Copy)]
struct Scene {
    plugin: bool,
    /// `FinShadows` on the spot light.
    fin_light: bool,
    /// The user's `shadow_maps_enabled` on the spot light.
    bevy_shadows: bool,
    /// The user chose deferred as the default opaque method (for fin shadows on every material).
    deferred_default: bool,
    /// The ground's material's method.
    ground: OpaqueRendererMethod,
    fin_camera: bool,
    plain_camera: bool,
    /// A sun (`DirectionalLight` + `SunDisk`) instead of the spot light.
    sun: bool,
    /// Bevy's contact shadows on the light and the fin camera.
    contact: bool,
    /// A point light and a sun beside the spot light, all three as
    /// `fin_light` and `bevy_shadows` say: several lights' maps kept at once.
    several: bool,
    /// The ground's material is alpha-masked (`AlphaMode::Mask`, no holes).
    ground_mask: bool,
    /// The ground receives no shadow (`NotFinShadowReceiver`).
    ground_not_receiver: bool,
}

impl Scene {
    fn new() -> Self {
        Scene {
            plugin: true,
            fin_light: true,
            bevy_shadows: true,
            deferred_default: true,
            ground: OpaqueRendererMethod::Auto,
            fin_camera: true,
            plain_camera: false,
            sun: false,
            contact: false,
            several: false,
            ground_mask: false,
            ground_not_receiver: false,
        }
    }
}

/// The app and its cameras' colour read-backs (`None` for a camera it lacks).
struct Rendering {
    app: App,
    fin: Option<Slot>,
    plain: Option<Slot>,
}

/// Marks the camera without `FinShadowView`.
#[derive(Component)]
struct PlainCamera;

fn camera_transform() -> Transform {
    Transform::from_xyz(0.0, 6.0, 5.0).looking_at(Vec3::new(0.0, 0.0, 0.5), Vec3::Y)
}

/// A camera rendering into a readable image, its read-back in the slot.
fn spawn_camera(world: &mut World, order: isize, fin: bool) -> Slot {
    let mut image = Image::new_target_texture(W, H, TextureFormat::Rgba8UnormSrgb, None);
    image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
    let image = world.resource_mut::<Assets<Image>>().add(image);
    let mut camera = world.spawn((
        Camera3d::default(),
        Camera { order, ..default() },
        Tonemapping::None,
        Msaa::Off,
        RenderTarget::Image(image.clone().into()),
        camera_transform(),
    ));
    if fin {
        camera.insert(FinShadowView::default());
    } else {
        camera.insert(PlainCamera);
    }
    let slot = Slot::default();
    let into = slot.clone();
    world.spawn(Readback::texture(image)).observe(move |e: On<ReadbackComplete>| {
        *into.lock().unwrap() = Some(e.data.clone());
    });
    slot
}

fn build(scene: Scene) -> Rendering {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() })
            .set(RenderPlugin { synchronous_pipeline_compilation: true, ..default() })
            .disable::<bevy::winit::WinitPlugin>()
            // The render world stays in the app, to be inspected.
            .disable::<bevy::render::pipelined_rendering::PipelinedRenderingPlugin>(),
    );
    if scene.plugin {
        app.add_plugins(ShadowFinsPlugin);
    }
    if scene.deferred_default {
        app.insert_resource(DefaultOpaqueRendererMethod::deferred());
    }
    let world = app.world_mut();
    let alpha_mode = if scene.ground_mask { AlphaMode::Mask(0.5) } else { AlphaMode::Opaque };
    let ground_material = StandardMaterial { opaque_render_method: scene.ground, alpha_mode, ..default() };
    let ground_material = world.resource_mut::<Assets<StandardMaterial>>().add(ground_material);
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    let plane = world.resource_mut::<Assets<Mesh>>().add(Plane3d::default().mesh().size(8.0, 8.0));
    let cube = world.resource_mut::<Assets<Mesh>>().add(Cuboid::new(1.0, 1.0, 1.0));
    let mut ground = world.spawn((Mesh3d(plane), MeshMaterial3d(ground_material)));
    if scene.ground_not_receiver {
        ground.insert(bevy_shadow_fins::NotFinShadowReceiver);
    }
    world.spawn((Mesh3d(cube), MeshMaterial3d(material), Transform::from_xyz(0.0, 1.0, 0.0)));
    // Off to the side, so the shadow falls beside the cube as the camera sees
    // it; wide enough for a penumbra band of several pixels.
    let mut light = if scene.sun {
        // Dim enough that the lit ground does not clip at white.
        let sun = DirectionalLight {
            illuminance: 400.0,
            shadow_maps_enabled: scene.bevy_shadows,
            contact_shadows_enabled: scene.contact,
            ..default()
        };
        let disk = bevy::light::SunDisk { angular_size: 8f32.to_radians(), intensity: 1.0 };
        world.spawn((sun, disk, Transform::default().looking_to(Vec3::new(-0.1, -1.0, 0.4), Vec3::Z)))
    } else {
        let spot = SpotLight {
            intensity: 2.0e5,
            range: 30.0,
            radius: 0.8,
            outer_angle: 1.0,
            shadow_maps_enabled: scene.bevy_shadows,
            contact_shadows_enabled: scene.contact,
            ..default()
        };
        world.spawn((spot, Transform::from_xyz(0.5, 5.0, -2.0).looking_at(Vec3::ZERO, Vec3::Z)))
    };
    if scene.fin_light {
        light.insert(FinShadows);
    }
    if scene.several {
        let point = PointLight {
            intensity: 1.0e5,
            range: 30.0,
            radius: 0.5,
            shadow_maps_enabled: scene.bevy_shadows,
            ..default()
        };
        let sun = DirectionalLight { illuminance: 150.0, shadow_maps_enabled: scene.bevy_shadows, ..default() };
        let disk = bevy::light::SunDisk { angular_size: 6f32.to_radians(), intensity: 1.0 };
        let others = [
            world.spawn((point, Transform::from_xyz(-1.8, 3.0, 1.2))).id(),
            world.spawn((sun, disk, Transform::default().looking_to(Vec3::new(0.5, -1.0, -0.2), Vec3::Z))).id(),
        ];
        if scene.fin_light {
            for e in others {
                world.entity_mut(e).insert(FinShadows);
            }
        }
    }
    let fin = scene.fin_camera.then(|| spawn_camera(world, 0, true));
    let plain = scene.plain_camera.then(|| spawn_camera(world, 1, false));
    if scene.contact {
        let cameras: Vec<Entity> = world.query_filtered::<Entity, With<FinShadowView>>().iter(world).collect();
        for camera in cameras {
            world.entity_mut(camera).insert(bevy::pbr::ContactShadows::default());
        }
    }
    app.finish();
    app.cleanup();
    Rendering { app, fin, plain }
}

type Image8 = Vec<[u8; 4]>;

impl Rendering {
    /// Renders until every camera's image stops changing (three equal frames
    /// after at least 12), at most 60 frames; returns (fin camera, plain camera).
    fn settle(&mut self) -> (Option<Image8>, Option<Image8>) {
        let mut previous: (Option<Vec<u8>>, Option<Vec<u8>>) = (None, None);
        let mut stable = 0;
        for slot in self.fin.iter().chain(&self.plain) {
            *slot.lock().unwrap() = None;
        }
        let mut latest = previous.clone();
        for frame in 0..60 {
            self.app.update();
            if let Some(v) = self.fin.as_ref().and_then(|s| s.lock().unwrap().take()) {
                latest.0 = Some(v);
            }
            if let Some(v) = self.plain.as_ref().and_then(|s| s.lock().unwrap().take()) {
                latest.1 = Some(v);
            }
            let complete = (self.fin.is_none() || latest.0.is_some()) && (self.plain.is_none() || latest.1.is_some());
            stable = if complete && latest == previous { stable + 1 } else { 0 };
            previous = latest.clone();
            if frame >= 12 && stable >= 3 {
                break;
            }
        }
        let image = |bytes: Option<Vec<u8>>| bytes.map(|b| unpad(W, H, &b).collect::<Image8>());
        (image(latest.0), image(latest.1))
    }

    /// Whether the render world's copy of the light has Bevy's shadow map on.
    fn render_world_shadow_map_on(&mut self) -> bool {
        let world = self.app.sub_app_mut(RenderApp).world_mut();
        let spot = world.query::<&ExtractedPointLight>().iter(world).any(|l| l.shadow_maps_enabled);
        spot || world.query::<&ExtractedDirectionalLight>().iter(world).any(|l| l.shadow_maps_enabled)
    }
}

/// Writes an image to `<target>/tmp/test-images/` when `SHADOW_FINS_TEST_IMAGES` is set.
fn save(image: &[[u8; 4]], name: &str) {
    if std::env::var_os("SHADOW_FINS_TEST_IMAGES").is_some() {
        let path = format!("{}/test-images/{name}.png", env!("CARGO_TARGET_TMPDIR"));
        save_srgb8(W, H, image, &path).expect("write test image");
    }
}

/// The largest per-channel difference of two images.
fn max_difference(a: &[[u8; 4]], b: &[[u8; 4]]) -> u8 {
    a.iter().zip(b).flat_map(|(p, q)| (0..3).map(move |c| p[c].abs_diff(q[c]))).max().unwrap_or(0)
}

/// Pixels at least 10 sRGB steps darker in `shadowed` than in `unshadowed`.
fn darkened(shadowed: &[[u8; 4]], unshadowed: &[[u8; 4]]) -> usize {
    shadowed.iter().zip(unshadowed).filter(|(s, u)| (u[1] as i32) - (s[1] as i32) >= 10).count()
}

#[test]
fn a_camera_without_fin_shadow_view_renders_as_without_the_plugin() {
    // The user's app left at Bevy's default (forward) opaque method: the
    // plugin must not change it (every mesh of the plain camera would vanish:
    // Bevy 0.19 draws deferred materials only on cameras with a deferred
    // prepass), nor turn off the fin-shadowed light's shadow map that camera
    // shows.
    let with = Scene { deferred_default: false, plain_camera: true, ..Scene::new() };
    let mut with_plugin = build(with);
    let (fin, plain) = with_plugin.settle();
    let (fin, plain) = (fin.expect("fin camera read back"), plain.expect("plain camera read back"));
    let kept = *with_plugin.app.world().resource::<BevyShadowMapsKept>();
    assert_eq!(kept.cameras_without_fin_view, 1, "{kept:?}");
    assert!(with_plugin.render_world_shadow_map_on(), "the plain camera's light lost its Bevy shadow map");

    let without = Scene { plugin: false, fin_light: false, fin_camera: false, ..with };
    let (_, alone) = build(without).settle();
    let alone = alone.expect("read back");
    let no_shadow = Scene { bevy_shadows: false, ..without };
    let (_, unshadowed) = build(no_shadow).settle();
    let unshadowed = unshadowed.expect("read back");
    // Not a trivial picture: Bevy's shadow of the cube darkens the ground.
    let shadow_pixels = darkened(&alone, &unshadowed);
    save(&plain, "plain_camera_with_plugin");
    save(&fin, "fin_camera_forward_default");
    println!(
        "plain camera: {shadow_pixels} shadow pixels; with vs without the plugin: max difference {}",
        max_difference(&plain, &alone)
    );
    assert!(shadow_pixels > 200, "no shadow in the picture ({shadow_pixels} pixels)");
    assert_eq!(max_difference(&plain, &alone), 0, "the plugin changed a camera without FinShadowView");
    // And the fin camera of the same app did render something.
    assert!(darkened(&fin, &unshadowed) > 200, "the fin camera shows no shadow");
}

#[test]
fn a_fin_camera_shows_the_same_fin_shadow_whether_bevys_maps_are_kept_or_not() {
    // For a spot, a sun (its index in the view's list is found differently
    // while the maps are kept) and a spot with Bevy's contact shadows (part
    // of S, compiled into the composite only with `ContactShadows`).
    let spot = Scene::new();
    for (label, scene) in [
        ("spot", spot),
        ("sun", Scene { sun: true, ..spot }),
        ("spot, contact shadows", Scene { contact: true, ..spot }),
        // Three kinds at once: each light's S found and replaced by its own V.
        ("spot, point and sun", Scene { several: true, ..spot }),
        // Every material forward (Bevy's default): the forward hook's
        // `fetch_*_shadow` overrides make Bevy's S 1 once the maps are kept.
        ("spot, forward", Scene { deferred_default: false, ..spot }),
        ("spot, point and sun, forward", Scene { several: true, deferred_default: false, ..spot }),
    ] {
        println!("{label}:");
        same_fin_shadow_kept_or_not(scene, &label.replace([' ', ','], "_"));
    }
}

/// One app: the fin camera alone (Bevy's map off), then a plain camera joins
/// (Bevy's map back on for it; the fin camera's composite replaces Bevy's
/// shadow by V), then it goes (the map off again). The fin image must be a
/// soft shadow (not Bevy's hard one, not none) and the same all along.
fn same_fin_shadow_kept_or_not(scene: Scene, name: &str) {
    let mut app = build(scene);
    let (alone, _) = app.settle();
    let alone = alone.expect("read back");
    assert!(!app.app.world().resource::<BevyShadowMapsKept>().kept());
    assert!(!app.render_world_shadow_map_on(), "no camera needs Bevy's map, yet it is on");
    let (unshadowed, _) = build(Scene { fin_light: false, bevy_shadows: false, ..scene }).settle();
    let (hard, _) = build(Scene { fin_light: false, ..scene }).settle();
    let (unshadowed, hard) = (unshadowed.expect("read back"), hard.expect("read back"));
    let shadow_pixels = darkened(&alone, &unshadowed);
    let soft_pixels = alone.iter().zip(&hard).filter(|(a, h)| a[1].abs_diff(h[1]) > 3).count();
    println!("  fin shadow: {shadow_pixels} pixels darkened, {soft_pixels} differ from Bevy's hard shadow");
    assert!(shadow_pixels > 100, "no fin shadow ({shadow_pixels} pixels)");
    assert!(soft_pixels > 40, "the fin shadow is Bevy's hard shadow ({soft_pixels} pixels differ)");

    app.plain = Some(spawn_camera(app.app.world_mut(), 1, false));
    let (fin, _) = app.settle();
    let fin = fin.expect("read back");
    assert!(app.app.world().resource::<BevyShadowMapsKept>().kept());
    // The plain camera (deferred default, no deferred prepass) draws no
    // deferred mesh — Bevy's behaviour, with or without the plugin — so the
    // map is checked in the render world.
    assert!(app.render_world_shadow_map_on(), "the plain camera did not get Bevy's map back");
    let kept_gap = max_difference(&fin, &alone);
    save(&alone, &format!("fin_camera_{name}_bevy_map_off"));
    save(&fin, &format!("fin_camera_{name}_bevy_map_kept"));
    save(&hard, &format!("fin_camera_{name}_bevy_hard"));

    let world = app.app.world_mut();
    let plain_camera = world.query_filtered::<Entity, With<PlainCamera>>().single(world).expect("one plain camera");
    world.despawn(plain_camera);
    app.plain = None;
    let (again, _) = app.settle();
    let again = again.expect("read back");
    assert!(!app.render_world_shadow_map_on(), "Bevy's map stayed on after the plain camera went");
    let again_gap = max_difference(&again, &alone);
    println!("  Bevy's map kept vs off: max difference {kept_gap}; after the plain camera went: {again_gap}");
    assert!(kept_gap <= 1, "with Bevy's map kept the fin shadow changed by {kept_gap} sRGB steps");
    assert!(again_gap <= 1, "after the plain camera went the fin shadow changed by {again_gap} sRGB steps");
}

#[test]
fn a_forward_receiver_gets_the_fin_shadow_with_bevys_maps_off() {
    // The ground forced forward: the forward hook shades it with the fin
    // shadow inside Bevy's forward pass (`render/forward.rs`), so nothing
    // keeps Bevy's map on, and its shadow is the one the deferred ground
    // gets from the compositing pass — not Bevy's hard one, not none. Opaque
    // and alpha-masked (Bevy's other forward phase, its own draw function).
    for mask in [false, true] {
        forward_receiver_gets_the_fin_shadow(mask);
    }
}

fn forward_receiver_gets_the_fin_shadow(mask: bool) {
    let forward = Scene { ground: OpaqueRendererMethod::Forward, ground_mask: mask, ..Scene::new() };
    let mut app = build(forward);
    let (shadowed, _) = app.settle();
    let shadowed = shadowed.expect("read back");
    assert_eq!(*app.app.world().resource::<FinReceivers>(), FinReceivers { forward: 1, blended: 0 });
    assert_eq!(app.app.world().resource::<BevyShadowMapsKept>().unreached_receivers, 0);
    assert!(!app.render_world_shadow_map_on(), "Bevy's map is on for a receiver fin shadows reach");
    let (unshadowed, _) = build(Scene { fin_light: false, bevy_shadows: false, ..forward }).settle();
    let (hard, _) = build(Scene { fin_light: false, ..forward }).settle();
    let (deferred, _) = build(Scene { ground_mask: mask, ..Scene::new() }).settle();
    let (unshadowed, hard, deferred) =
        (unshadowed.expect("read back"), hard.expect("read back"), deferred.expect("read back"));
    let shadow_pixels = darkened(&shadowed, &unshadowed);
    let soft_pixels = shadowed.iter().zip(&hard).filter(|(a, h)| a[1].abs_diff(h[1]) > 3).count();
    let from_deferred = shadowed.iter().zip(&deferred).filter(|(a, d)| a[1].abs_diff(d[1]) > 3).count();
    save(&shadowed, "forward_ground");
    save(&deferred, "deferred_ground");
    let apart = max_difference(&shadowed, &deferred);
    println!(
        "forward ground (mask {mask}): {shadow_pixels} pixels darkened, {soft_pixels} differ from Bevy's hard \
         shadow, {from_deferred} from the deferred ground's by more than 3 steps (max {apart})"
    );
    assert!(shadow_pixels > 200, "the forward receiver is unshadowed ({shadow_pixels} pixels)");
    assert!(soft_pixels > 40, "the forward receiver's shadow is Bevy's hard one ({soft_pixels} pixels differ)");
    // Forward shading against the G-buffer's (8-bit material channels,
    // packed normals): measured 1 step apart at most.
    assert!(apart <= 3, "the forward ground is {apart} sRGB steps from the deferred one");
}

#[test]
fn a_mesh_that_receives_no_shadow_gets_no_fin_shadow_forward_or_deferred() {
    // `NotFinShadowReceiver` on the ground: no fin shadow on it on either
    // path (the visibility buffer has one there all the same; the compositing
    // pass and the forward hook read the mesh's receiver flag).
    for ground in [OpaqueRendererMethod::Forward, OpaqueRendererMethod::Deferred] {
        let scene = Scene { ground, ground_not_receiver: true, ..Scene::new() };
        let (image, _) = build(scene).settle();
        let (unshadowed, _) = build(Scene { fin_light: false, bevy_shadows: false, ..scene }).settle();
        let (image, unshadowed) = (image.expect("read back"), unshadowed.expect("read back"));
        let darkened_pixels = darkened(&image, &unshadowed);
        println!("{ground:?} ground that receives no shadow: {darkened_pixels} pixels darkened");
        assert_eq!(darkened_pixels, 0, "{ground:?}: a mesh that receives no shadow got a fin shadow");
    }
}
