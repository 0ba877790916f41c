//! What every method's per-camera pass shares: the camera's illuminance
//! buffer ([`FinViewTexture`]), the prepass and G-buffer inputs, the view →
//! light transform, one compute dispatch per view and light, and the copy
//! to the targets; and the helpers every compute pass uses.

use std::borrow::Cow;

use bevy::{
    core_pipeline::prepass::ViewPrepassTextures,
    prelude::*,
    render::{
        camera::ExtractedCamera,
        diagnostic::RecordDiagnostics,
        render_asset::RenderAssets,
        render_resource::{binding_types::texture_2d, *},
        renderer::{RenderContext, RenderDevice, RenderQueue},
        texture::{CachedTexture, GpuImage, TextureCache},
    },
};

use crate::{
    frame::{FinFrameData, FinFrames},
    settings::FinShadowView,
};

/// The per-light passes of the root render graph (maps, coverage lists,
/// convolution basis): before the cameras' schedules, which read what they
/// write, and after the diagnostics recorder begins its frame.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct FinLightPasses;

/// Queues a compute pipeline of one bind group (every pass of the plugin).
pub(crate) fn queue_compute(
    pipeline_cache: &PipelineCache,
    label: impl Into<Cow<'static, str>>,
    layout: &BindGroupLayoutDescriptor,
    shader: &Handle<Shader>,
    entry: &'static str,
) -> CachedComputePipelineId {
    pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
        label: Some(label.into()),
        layout: vec![layout.clone()],
        shader: shader.clone(),
        entry_point: Some(Cow::from(entry)),
        ..default()
    })
}

/// Workgroup counts for `n` items, split over y when x would exceed the limit.
pub(crate) fn workgroups(n: u32) -> (u32, u32) {
    if n <= 65535 { (n, 1) } else { (65535, n.div_ceil(65535)) }
}

/// Per camera: its visibility (illuminance) buffers, one layer per fin-shadowed
/// light (`FinLightFrame::layer`; at least one), and a view of each layer.
#[derive(Component)]
pub struct FinViewTexture {
    pub(super) texture: CachedTexture,
    /// One 2D view per light layer (what a visibility pass writes).
    pub(super) layers: Vec<TextureView>,
    /// All layers as one array (what the compositing pass reads).
    pub(super) array: TextureView,
}

/// The view's view → light-frame uniform of frame slot `slot`, written for
/// this frame (created the first time).
pub(crate) fn view_transform(
    device: &RenderDevice,
    queue: &RenderQueue,
    frame: &FinFrameData,
    world_from_view: &GlobalTransform,
    buffers: &mut Vec<Buffer>,
    slot: usize,
) -> Buffer {
    while buffers.len() <= slot {
        buffers.push(device.create_buffer(&BufferDescriptor {
            label: Some("fin_view_uniform"),
            size: size_of::<FinViewUniform>() as u64,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }));
    }
    let buffer = buffers[slot].clone();
    queue.write_buffer(&buffer, 0, bytemuck::bytes_of(&FinViewUniform::new(frame, world_from_view)));
    buffer
}

/// `FinView` in `visibility.wgsl`: the columns of the linear part and the translation.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct FinViewUniform {
    pub(crate) linear: [[f32; 4]; 3],
    pub(crate) translation: [f32; 4],
}

impl FinViewUniform {
    /// The camera's view space → the light frame, composed in f64:
    /// `A (R_v p + t_v − o) = (A R_v) p + A (t_v − o)` with `A` the frame's axes
    /// as rows and `o` its origin. `t_v − o` is taken in f64, so a camera and
    /// light 1e5 from the world origin keep their small offset exact.
    fn new(frame: &FinFrameData, world_from_view: &GlobalTransform) -> Self {
        use bevy::math::{DMat3, DVec3};
        let a = world_from_view.affine();
        let rows = DMat3::from_cols(frame.axes[0], frame.axes[1], frame.axes[2]).transpose();
        let linear = rows * Mat3::from(a.matrix3).as_dmat3();
        let translation = rows * (Vec3::from(a.translation).as_dvec3() - frame.origin);
        let v4 = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        let mut translation = v4(translation);
        translation[3] = camera_raster_error(Vec3::from(a.translation));
        Self { linear: [v4(linear.x_axis), v4(linear.y_axis), v4(linear.z_axis)], translation }
    }
}

/// FinView's w: the camera's part of the rasteriser's f32 error in world
/// space, 2ε·|camera| (|p_world| ≤ |camera| + |p_view|; `coverage.wgsl` adds
/// the view part per pixel) — the least lift the coverage method gives a
/// receiver rebuilt from the depth buffer: 0.004 at 1e4, 0.04 at 1e5, 0 for a
/// non-finite camera. `visibility.wgsl` ignores it.
pub(crate) fn camera_raster_error(camera: Vec3) -> f32 {
    let e = 2.0 * f32::EPSILON * camera.length();
    if e.is_finite() { e } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_view_lift_is_the_cameras_f32_error_and_never_nan() {
        // 2ε·|camera|: 1.2e-6 five units from the origin (far below the core's
        // 1e-5-relative lift), 0.041 at (1e5, 1e5, 1e5).
        assert!((camera_raster_error(Vec3::new(3.0, 4.0, 0.0)) - 10.0 * f32::EPSILON).abs() < 1e-12);
        let far = camera_raster_error(Vec3::splat(1e5));
        assert!((far - 2.0 * f32::EPSILON * 1.732_050_8e5).abs() < 1e-6, "{far}");
        assert_eq!(camera_raster_error(Vec3::splat(f32::INFINITY)), 0.0);
        assert_eq!(camera_raster_error(Vec3::NAN), 0.0);
    }
}

/// (view, frame slot) pairs whose visibility pass ran this frame (the
/// compositing pass uses a light's layer only when all its frames' did).
#[derive(Resource, Default)]
pub(crate) struct ViewsWithVisibility(pub(super) std::collections::HashSet<(Entity, usize)>);

pub(crate) fn clear_views_with_visibility(mut views: ResMut<ViewsWithVisibility>) {
    views.0.clear();
}

pub(crate) fn prepare_view_textures(
    mut commands: Commands,
    mut cache: ResMut<TextureCache>,
    device: Res<RenderDevice>,
    frames: Res<FinFrames>,
    views: Query<(Entity, &ExtractedCamera), With<FinShadowView>>,
) {
    let layers = frames.light_count().max(1) as u32;
    for (entity, camera) in &views {
        // Target-sized like the prepass textures, so that a camera with a
        // `Camera::viewport` reads and writes at the same (target) pixels.
        let Some(size) = camera.physical_target_size else { continue };
        let texture = cache.get(
            &device,
            TextureDescriptor {
                label: Some("fin_visibility"),
                size: Extent3d { width: size.x.max(1), height: size.y.max(1), depth_or_array_layers: layers },
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: TextureFormat::R32Float,
                usage: TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_SRC,
                view_formats: &[],
            },
        );
        let view = |dimension, base_array_layer, array_layer_count| {
            texture.texture.create_view(&TextureViewDescriptor {
                label: Some("fin_visibility_view"),
                dimension: Some(dimension),
                base_array_layer,
                array_layer_count: Some(array_layer_count),
                ..default()
            })
        };
        let layer_views = (0..layers).map(|l| view(TextureViewDimension::D2, l, 1)).collect();
        let array = view(TextureViewDimension::D2Array, 0, layers);
        commands.entity(entity).insert(FinViewTexture { texture, layers: layer_views, array });
    }
}

/// The depth and normal prepass views a visibility pass reads (fins' and
/// coverage's), or `None`, said once, when the camera cannot give them:
/// multisampled prepass textures cannot be bound as single-sample inputs
/// (skip the view with a clear message, not a crash), or a prepass is off.
pub(crate) fn prepass_inputs(prepass: &ViewPrepassTextures) -> Option<(&TextureView, &TextureView)> {
    if prepass.depth.as_ref().is_some_and(|d| d.texture.texture.sample_count() > 1) {
        warn_once!("fin shadows: the camera uses MSAA; add `Msaa::Off` to it for fin shadows");
        return None;
    }
    let (Some(depth), Some(normal)) = (prepass.depth_view(), prepass.normal_view()) else {
        warn_once!("fin shadows: the camera needs DepthPrepass and NormalPrepass (FinShadowView adds them)");
        return None;
    };
    Some((depth, normal))
}

/// The camera's deferred G-buffer, whose normal says which side of a
/// double-sided surface Bevy shades (`receiver_normal.wgsl`),
/// or [`NoGBuffer`]'s when it has no deferred prepass.
pub(crate) fn gbuffer_input<'a>(prepass: &'a ViewPrepassTextures, no_gbuffer: &'a NoGBuffer) -> &'a TextureView {
    prepass.deferred_view().unwrap_or(&no_gbuffer.0)
}

/// A 1×1 G-buffer of zeros (no deferred pixel): what the visibility passes
/// read in place of a camera's G-buffer when it has no deferred prepass
/// (every pixel forward-shaded, its prepass normal already the shaded side).
#[derive(Resource)]
pub(crate) struct NoGBuffer(pub(crate) TextureView);

/// The layout entry of the G-buffer a visibility pass reads (Bevy's
/// `DEFERRED_PREPASS_FORMAT`, `Rgba32Uint`).
pub(crate) fn gbuffer_entry() -> BindGroupLayoutEntryBuilder {
    texture_2d(TextureSampleType::Uint)
}

pub(crate) fn init_no_gbuffer(mut commands: Commands, device: Res<RenderDevice>, queue: Res<RenderQueue>) {
    let size = Extent3d { width: 1, height: 1, depth_or_array_layers: 1 };
    let texture = device.create_texture(&TextureDescriptor {
        label: Some("fin_no_gbuffer"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: TextureDimension::D2,
        format: TextureFormat::Rgba32Uint,
        usage: TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_DST,
        view_formats: &[],
    });
    queue.write_texture(
        texture.as_image_copy(),
        &[0; 16],
        TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(16), rows_per_image: None },
        size,
    );
    commands.insert_resource(NoGBuffer(texture.create_view(&TextureViewDescriptor::default())));
}

/// The camera a per-pixel visibility pass runs for.
pub(crate) struct ViewPass<'a> {
    pub entity: Entity,
    pub settings: &'a FinShadowView,
    pub texture: &'a FinViewTexture,
    /// Its `ViewUniformOffset`.
    pub offset: u32,
}

/// One light slot's per-pixel pass (fins', convolution's or plateaus'): one
/// dispatch over the camera's target, timed as `fin_shadows/visibility`, the
/// slot marked as written and its layer copied to the camera's targets.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_view_pass(
    ctx: &mut RenderContext,
    view: &ViewPass,
    label: &'static str,
    pipeline: &ComputePipeline,
    bind_group: &BindGroup,
    slot: usize,
    images: &RenderAssets<GpuImage>,
    frames: &FinFrames,
    written: &mut ViewsWithVisibility,
) {
    let size = view.texture.texture.texture.size();
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/visibility");
    {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind_group, &[view.offset]);
        pass.dispatch_workgroups(size.width.div_ceil(8), size.height.div_ceil(8), 1);
    }
    span.end(ctx.command_encoder());
    written.0.insert((view.entity, slot));
    copy_to_targets(ctx, view.settings, view.texture, images, frames, slot);
}

/// Copies the visibility layer of frame slot `slot`'s light into the
/// camera's targets for that light, once the light's last frame ran:
/// `visibility_target` for the first light, `light_visibility_targets` for
/// the light's entity.
pub(crate) fn copy_to_targets(
    ctx: &mut RenderContext,
    settings: &FinShadowView,
    texture: &FinViewTexture,
    images: &RenderAssets<GpuImage>,
    frames: &FinFrames,
    slot: usize,
) {
    let Some((light, layer)) = frames.0.get(slot).map(|f| (f.light, f.layer)) else { return };
    if !frames.ends_layer(slot) {
        return;
    }
    let first = settings.visibility_target.as_ref().filter(|_| layer == 0);
    let own = settings.light_visibility_targets.iter().filter(|(e, _)| *e == light).map(|(_, h)| h);
    let size = texture.texture.texture.size();
    let size = Extent3d { depth_or_array_layers: 1, ..size };
    for target in first.into_iter().chain(own).filter_map(|h| images.get(h)) {
        if target.texture.size() == size && target.texture_descriptor.format == TextureFormat::R32Float {
            let source = TexelCopyTextureInfo {
                texture: &texture.texture.texture,
                mip_level: 0,
                origin: Origin3d { x: 0, y: 0, z: layer as u32 },
                aspect: TextureAspect::All,
            };
            ctx.command_encoder().copy_texture_to_texture(source, target.texture.as_image_copy(), size);
        } else {
            warn_once!("fin shadows: visibility targets must be R32Float at the camera's size ({size:?})");
        }
    }
}
