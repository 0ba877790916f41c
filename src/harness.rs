//! Headless rendering of a core-crate scene with the plugin, visibility read back.

use std::sync::{Arc, Mutex};

use bevy::{
    asset::RenderAssetUsages,
    camera::RenderTarget,
    mesh::{Indices, PrimitiveTopology},
    prelude::*,
    render::{
        RenderPlugin,
        gpu_readback::{Readback, ReadbackComplete},
        render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages},
    },
    window::ExitCondition,
};
use bevy_shadow_fins::{FinFrame, FinLight, FinShadowSettings, FinShadowView, NotFinShadowCaster, ShadowFinsPlugin};
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
    /// The camera's MSAA (the plugin needs `Msaa::Off`; others must not crash).
    pub msaa: Msaa,
}

/// A read-back visibility buffer, row-major, top row first.
#[derive(Debug, Clone)]
pub struct Shot {
    pub width: u32,
    pub height: u32,
    pub visibility: Vec<f32>,
    /// Silhouettes, fins and layers the frame modelled.
    pub stats: bevy_shadow_fins::FinFrameStats,
}

/// A Bevy mesh (flat-shaded, so the normal prepass holds face normals) from a core mesh.
pub fn bevy_mesh(mesh: &shadow_fins::mesh::Mesh) -> Mesh {
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_POSITION,
            mesh.positions().iter().map(|p| p.to_array()).collect::<Vec<_>>(),
        )
        .with_inserted_indices(Indices::U32(mesh.indices().to_vec()))
        .with_duplicated_vertices()
        .with_computed_flat_normals()
}

/// Builds the headless app for `setup`; returns it with the shared read-back slot.
pub fn app(setup: &Setup) -> (App, Arc<Mutex<Option<Vec<u8>>>>) {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() })
            .set(RenderPlugin { synchronous_pipeline_compilation: true, ..default() }),
    )
    .add_plugins(ShadowFinsPlugin);
    let slot = Arc::new(Mutex::new(None));
    let world = app.world_mut();
    let (w, h) = (setup.width, setup.height);
    let (color, visibility) = {
        let mut images = world.resource_mut::<Assets<Image>>();
        let color = images.add(Image::new_target_texture(w, h, TextureFormat::Rgba8UnormSrgb, None));
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
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    for object in &setup.scene.objects {
        let mesh = world.resource_mut::<Assets<Mesh>>().add(bevy_mesh(&object.mesh));
        let mut e = world.spawn((
            Mesh3d(mesh),
            MeshMaterial3d(material.clone()),
            Transform::from_matrix(Mat4::from(object.transform)),
        ));
        if !object.casts_shadows {
            e.insert(NotFinShadowCaster);
        }
    }
    for (mesh, at) in &setup.extra_meshes {
        let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh.clone());
        world.spawn((Mesh3d(mesh), MeshMaterial3d(material.clone()), Transform::from_translation(*at)));
    }
    if let Light::Disk(d) = setup.light {
        let target = d.center + d.normal;
        let up = if d.normal.cross(Vec3::Z).length() > 1e-3 { Vec3::Z } else { Vec3::X };
        world.spawn((
            FinLight { radius: d.radius, ..default() },
            setup.settings,
            Transform::from_translation(d.center).looking_at(target, up),
        ));
    }
    world.spawn((
        Camera3d::default(),
        setup.msaa,
        RenderTarget::Image(color.into()),
        Projection::Perspective(PerspectiveProjection { fov: setup.camera.vertical_fov.to_radians(), ..default() }),
        Transform::from_translation(setup.camera.position).looking_at(setup.camera.target, setup.camera.up),
        FinShadowView { visibility_target: Some(visibility.clone()) },
    ));
    let sink = slot.clone();
    world.spawn(Readback::texture(visibility)).observe(move |e: On<ReadbackComplete>| {
        *sink.lock().unwrap() = Some(e.data.clone());
    });
    (app, slot)
}

/// Renders `frames` frames and returns the last visibility read-back.
pub fn render(setup: &Setup, frames: u32) -> Result<Shot, String> {
    let (mut app, slot) = app(setup);
    app.finish();
    app.cleanup();
    for _ in 0..frames.max(3) {
        app.update();
    }
    let data = slot.lock().unwrap().take().ok_or("no visibility read back (no GPU adapter?)")?;
    let stats = app.world().resource::<FinFrame>().0.as_ref().map(|f| f.stats).unwrap_or_default();
    Ok(unpad(setup.width, setup.height, &data, stats))
}

/// Texture read-backs pad rows to 256 bytes.
fn unpad(width: u32, height: u32, data: &[u8], stats: bevy_shadow_fins::FinFrameStats) -> Shot {
    let row = width as usize * 4;
    let padded = if height > 1 { row.div_ceil(256) * 256 } else { row };
    let mut visibility = Vec::with_capacity((width * height) as usize);
    for y in 0..height as usize {
        let line = &data[y * padded..y * padded + row];
        visibility.extend(line.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])));
    }
    Shot { width, height, visibility, stats }
}
