//! Render world of the convolution method (`FinMethod::Convolution`, Annen
//! et al. 2008): per light frame, the basis images of its hard shadow map
//! (`convolution_maps.wgsl`: nearest depth, the Fourier basis, the mip
//! chain), rebuilt right after the penumbra-map passes redraw that map; and
//! per camera the visibility pass (`convolution.wgsl`) writing the same
//! visibility buffer the fins write, so compositing is unchanged.

use bevy::{
    asset::{embedded_asset, load_embedded_asset},
    core_pipeline::{
        prepass::ViewPrepassTextures,
        schedule::{Core3d, Core3dSystems},
    },
    prelude::*,
    render::{
        Render, RenderApp, RenderSystems,
        diagnostic::RecordDiagnostics,
        render_resource::{
            binding_types::{
                storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_depth_2d, texture_storage_2d,
                uniform_buffer, uniform_buffer_sized,
            },
            *,
        },
        renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue, ViewQuery},
        view::{ExtractedView, ViewUniform, ViewUniformOffset, ViewUniforms},
    },
    shader::load_shader_library,
};
use shadow_fins::peers::convolution::{
    ConvolutionSettings, VARIANCE_MATCHED_MIP_BIAS, basis, depth_span, kernel_shape, ringing_scale, step_shift,
};

use crate::render::{
    extraction::ensure,
    maps::FinLightsGpu,
    view::{FinViewTexture, ViewsWithVisibility, view_transform, workgroups},
};
use crate::{
    budget::BasisLayout,
    frame::{FinFrameData, FinFrames, FrameKey},
    settings::{FinMethod, FinShadowView},
};

/// Mip levels a chain may have.
const MAX_LEVELS: usize = crate::budget::MAX_BASIS_LEVELS;
/// Bytes between two downsampling dispatches' level uniforms (the largest
/// dynamic-offset alignment a device may ask).
const LEVEL_STRIDE: u64 = 256;

pub(super) fn build(app: &mut App) {
    load_shader_library!(app, "shaders/convolution_types.wgsl");
    embedded_asset!(app, "shaders/convolution_maps.wgsl");
    embedded_asset!(app, "shaders/convolution.wgsl");
}

pub(super) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app
        .init_resource::<ConvolutionLightsGpu>()
        .add_systems(bevy::render::RenderStartup, init_pipelines)
        .add_systems(
            Render,
            (
                prepare_convolution.in_set(RenderSystems::PrepareResources).after(crate::render::maps::prepare_maps),
                prepare_view_bind_groups.in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            RenderGraph,
            render_basis.after(crate::render::maps::render_maps).in_set(crate::render::view::FinLightPasses),
        )
        .add_systems(Core3d, convolution_visibility.after(Core3dSystems::Prepass).before(Core3dSystems::MainPass));
}

#[derive(Resource)]
struct ConvolutionPipelines {
    maps_layout: BindGroupLayoutDescriptor,
    view_layout: BindGroupLayoutDescriptor,
    reset_near: CachedComputePipelineId,
    find_near: CachedComputePipelineId,
    first_level: CachedComputePipelineId,
    downsample: CachedComputePipelineId,
    visibility: CachedComputePipelineId,
}

fn init_pipelines(mut commands: Commands, pipeline_cache: Res<PipelineCache>, asset_server: Res<AssetServer>) {
    let maps_layout = BindGroupLayoutDescriptor::new(
        "fin_convolution_maps_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_sized(false, None),
                uniform_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                uniform_buffer_sized(true, std::num::NonZeroU64::new(16)),
            ),
        ),
    );
    let view_layout = BindGroupLayoutDescriptor::new(
        "fin_convolution_view_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_depth_2d(),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                uniform_buffer::<ViewUniform>(true),
                uniform_buffer_sized(false, None),
            ),
        ),
    );
    let maps_shader = load_embedded_asset!(asset_server.as_ref(), "shaders/convolution_maps.wgsl");
    let view_shader = load_embedded_asset!(asset_server.as_ref(), "shaders/convolution.wgsl");
    let compute = |label, layout: &_, shader: &_, entry| {
        crate::render::view::queue_compute(&pipeline_cache, label, layout, shader, entry)
    };
    commands.insert_resource(ConvolutionPipelines {
        reset_near: compute("fin_convolution_reset_near", &maps_layout, &maps_shader, "reset_near"),
        find_near: compute("fin_convolution_find_near", &maps_layout, &maps_shader, "find_near"),
        first_level: compute("fin_convolution_first_level", &maps_layout, &maps_shader, "first_level"),
        downsample: compute("fin_convolution_downsample", &maps_layout, &maps_shader, "downsample"),
        visibility: compute("fin_convolution_visibility", &view_layout, &view_shader, "convolution_pass"),
        maps_layout,
        view_layout,
    });
}

/// `ConvolutionParams` in `convolution_types.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct ConvolutionUniform {
    pub(crate) counts: [u32; 4],
    pub(crate) series: [f32; 4],
    pub(crate) kernel: [f32; 4],
    pub(crate) lookup: [f32; 4],
    pub(crate) levels: [[u32; 4]; MAX_LEVELS / 2],
    pub(crate) empty: [[f32; 4]; 17],
}

fn uniform_of(f: &FinFrameData, layout: &BasisLayout) -> ConvolutionUniform {
    let order = f.settings.convolution_order.clamp(1, 16);
    let span = depth_span(order);
    let shape = kernel_shape(f.aperture);
    let rect = matches!(f.aperture, shadow_fins::light::Aperture::Rect { .. });
    let mut levels = [[0u32; 4]; MAX_LEVELS / 2];
    for (i, (r, at)) in layout.stored.iter().enumerate() {
        levels[i / 2][2 * (i % 2)] = *r;
        levels[i / 2][2 * (i % 2) + 1] = *at;
    }
    let mut empty_basis = [0.0f32; 68];
    basis(span, order, &mut empty_basis);
    let mut empty = [[0.0f32; 4]; 17];
    for (i, v) in empty_basis.iter().enumerate() {
        empty[i / 4][i % 4] = *v;
    }
    // Sharpening (eq. 9) as the core's default: their Figure 4's `A`, its
    // tightest `B`, in normalised depths.
    let (a, b) = ConvolutionSettings::default().sharpening.unwrap_or((0.0, 0.0));
    ConvolutionUniform {
        counts: [order, layout.channels, layout.first, layout.chain],
        series: [ringing_scale(order), step_shift(order), span, a],
        kernel: [b, shape.x, shape.y, if rect { 1.0 } else { 0.0 }],
        // A map that is a window onto casters going on past it (a sun fitted
        // to the views) reads its border off the map, else the empty plane.
        lookup: [VARIANCE_MATCHED_MIP_BIAS, if f.windowed { 1.0 } else { 0.0 }, 0.0, 0.0],
        levels,
        empty,
    }
}

/// Every convolution-method frame's basis images, by light and cube face.
#[derive(Resource, Default)]
struct ConvolutionLightsGpu(std::collections::HashMap<FrameKey, ConvolutionGpu>);

#[derive(Default)]
struct ConvolutionGpu {
    /// The frame generation the uniform and bind group were made for (the
    /// frame's own `convolution` layout sized them).
    generation: u64,
    basis: Option<Buffer>,
    uniform: Option<Buffer>,
    state: Option<Buffer>,
    levels: Option<Buffer>,
    bind_group: Option<BindGroup>,
    /// The map drawing (`FinMapsGpu::renders`) the basis was built from.
    built_from: Option<u64>,
}

fn on_convolution(frames: &FinFrames) -> impl Iterator<Item = &crate::frame::FinLightFrame> {
    frames.on_coverage(false).filter(|f| f.data.settings.method == FinMethod::Convolution)
}

fn prepare_convolution(
    frames: Res<FinFrames>,
    maps: Res<FinLightsGpu>,
    mut lights: ResMut<ConvolutionLightsGpu>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    pipelines: Option<Res<ConvolutionPipelines>>,
    pipeline_cache: Res<PipelineCache>,
) {
    lights.0.retain(|key, _| on_convolution(&frames).any(|f| f.key() == *key));
    let Some(pipelines) = pipelines else {
        lights.0.clear();
        return;
    };
    for frame in on_convolution(&frames) {
        let gpu = lights.0.entry(frame.key()).or_default();
        match maps.0.get(&frame.key()) {
            Some(m) if m.bind_group.is_some() => {
                prepare_light(&frame.data, m, gpu, &device, &queue, &pipelines, &pipeline_cache)
            }
            _ => *gpu = ConvolutionGpu::default(),
        }
    }
}

/// One frame's basis buffers and uniform, made again when its frame changed.
fn prepare_light(
    f: &FinFrameData,
    maps: &crate::render::maps::FinMapsGpu,
    gpu: &mut ConvolutionGpu,
    device: &RenderDevice,
    queue: &RenderQueue,
    pipelines: &ConvolutionPipelines,
    pipeline_cache: &PipelineCache,
) {
    if f.generation == gpu.generation && gpu.bind_group.is_some() {
        return;
    }
    // The main world sized the chain to its budget (`BasisLayout`, said in
    // the light's stats when it had to drop levels or could not fit).
    let (Some(layout), Some(params), Some(map_buffer)) =
        (f.convolution.as_ref(), maps.params.clone(), maps.maps.clone())
    else {
        *gpu = ConvolutionGpu::default();
        return;
    };
    let limit = device.limits().max_storage_buffer_binding_size.min(f.limit_bytes).max(layout.bytes());
    let storage = BufferUsages::STORAGE | BufferUsages::COPY_DST;
    let uniform = BufferUsages::UNIFORM | BufferUsages::COPY_DST;
    // Exactly the chain's size: the main world fitted it to the light's map
    // budget beside the maps (no growth headroom; a new layout re-sizes it).
    let bytes = layout.bytes().max(64);
    ensure(&mut gpu.basis, device, "fin_convolution_basis", bytes, storage, bytes);
    ensure(&mut gpu.uniform, device, "fin_convolution_params", size_of::<ConvolutionUniform>() as u64, uniform, limit);
    ensure(&mut gpu.state, device, "fin_convolution_near", 16, storage, limit);
    let stride = LEVEL_STRIDE.max(device.limits().min_uniform_buffer_offset_alignment as u64);
    ensure(&mut gpu.levels, device, "fin_convolution_levels", stride * MAX_LEVELS as u64, uniform, u64::MAX);
    queue.write_buffer(gpu.uniform.as_ref().unwrap(), 0, bytemuck::bytes_of(&uniform_of(f, layout)));
    let mut levels = vec![0u8; (stride * MAX_LEVELS as u64) as usize];
    for l in 0..MAX_LEVELS {
        levels[l * stride as usize..][..4].copy_from_slice(&(l as u32).to_le_bytes());
    }
    queue.write_buffer(gpu.levels.as_ref().unwrap(), 0, &levels);
    gpu.bind_group = Some(device.create_bind_group(
        "fin_convolution_maps_bind_group",
        &pipeline_cache.get_bind_group_layout(&pipelines.maps_layout),
        &BindGroupEntries::sequential((
            params.as_entire_binding(),
            map_buffer.as_entire_binding(),
            gpu.basis.as_ref().unwrap().as_entire_binding(),
            gpu.uniform.as_ref().unwrap().as_entire_binding(),
            gpu.state.as_ref().unwrap().as_entire_binding(),
            BufferBinding { buffer: gpu.levels.as_ref().unwrap(), offset: 0, size: std::num::NonZeroU64::new(16) },
        )),
    ));
    gpu.generation = f.generation;
    gpu.built_from = None;
}

/// Builds each frame's basis images after its map passes drew a new map.
fn render_basis(
    frames: Res<FinFrames>,
    maps: Res<FinLightsGpu>,
    mut lights: ResMut<ConvolutionLightsGpu>,
    pipelines: Option<Res<ConvolutionPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    mut ctx: RenderContext,
) {
    let Some(pipelines) = pipelines else { return };
    let (Some(reset_near), Some(find_near), Some(first_level), Some(downsample)) = (
        pipeline_cache.get_compute_pipeline(pipelines.reset_near),
        pipeline_cache.get_compute_pipeline(pipelines.find_near),
        pipeline_cache.get_compute_pipeline(pipelines.first_level),
        pipeline_cache.get_compute_pipeline(pipelines.downsample),
    ) else {
        return;
    };
    let stride = LEVEL_STRIDE.max(device.limits().min_uniform_buffer_offset_alignment as u64) as u32;
    for frame in on_convolution(&frames) {
        let (Some(m), Some(gpu)) = (maps.0.get(&frame.key()), lights.0.get_mut(&frame.key())) else { continue };
        // Only a map the passes finished drawing, once per drawing.
        if m.dirty || gpu.built_from == Some(m.renders) {
            continue;
        }
        let (Some(bind_group), Some(layout)) = (gpu.bind_group.as_ref(), frame.data.convolution.as_ref()) else {
            continue;
        };
        let diagnostics = ctx.diagnostic_recorder();
        let diagnostics = diagnostics.as_deref();
        let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/convolution_basis");
        {
            let mut pass = ctx.command_encoder().begin_compute_pass(&ComputePassDescriptor {
                label: Some("fin_convolution_basis"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, bind_group, &[0]);
            pass.set_pipeline(reset_near);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(find_near);
            let texels = frame.data.region.resolution * frame.data.region.resolution;
            let (x, y) = workgroups(texels.div_ceil(256));
            pass.dispatch_workgroups(x, y, 1);
            let groups = |r: u32| r.div_ceil(8);
            pass.set_pipeline(first_level);
            let r0 = layout.stored[0].0;
            pass.dispatch_workgroups(groups(r0), groups(r0), 1);
            pass.set_pipeline(downsample);
            for (l, (r, _)) in layout.stored.iter().enumerate().skip(1) {
                pass.set_bind_group(0, bind_group, &[l as u32 * stride]);
                pass.dispatch_workgroups(groups(*r), groups(*r), 1);
            }
        }
        span.end(ctx.command_encoder());
        gpu.built_from = Some(m.renders);
    }
}

/// Per camera and frame slot: the convolution pass's bind group (`None` for
/// lights on other methods, or whose basis cannot be built this frame).
#[derive(Component)]
pub struct ConvolutionViewBindGroup(Vec<Option<BindGroup>>);

/// Per camera and frame slot: its view → light-frame transform.
#[derive(Component, Default)]
pub struct ConvolutionViewBuffer(Vec<Buffer>);

#[allow(clippy::too_many_arguments)]
fn prepare_view_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    maps: Res<FinLightsGpu>,
    lights: Res<ConvolutionLightsGpu>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<ConvolutionPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    view_uniforms: Res<ViewUniforms>,
    mut views: Query<(
        Entity,
        &FinViewTexture,
        &ViewPrepassTextures,
        &ExtractedView,
        Option<&mut ConvolutionViewBuffer>,
    )>,
) {
    let binding = view_uniforms.uniforms.binding();
    for (entity, texture, prepass, view, buffers) in &mut views {
        let (Some(pipelines), Some(view_binding), false, Some((depth, normal))) =
            (pipelines.as_ref(), binding.clone(), lights.0.is_empty(), crate::render::view::prepass_inputs(prepass))
        else {
            commands.entity(entity).remove::<ConvolutionViewBindGroup>();
            continue;
        };
        let mut buffers = buffers.map(|mut b| std::mem::take(&mut b.0)).unwrap_or_default();
        let groups = frames
            .0
            .iter()
            .enumerate()
            .map(|(slot, frame)| {
                let gpu = lights.0.get(&frame.key())?;
                let m = maps.0.get(&frame.key())?;
                let (Some(params), Some(basis), Some(uniform), Some(state), Some(_), Some(layer)) = (
                    m.params.as_ref(),
                    gpu.basis.as_ref(),
                    gpu.uniform.as_ref(),
                    gpu.state.as_ref(),
                    gpu.bind_group.as_ref(),
                    texture.layers.get(frame.layer),
                ) else {
                    return None;
                };
                let buffer = view_transform(&device, &queue, &frame.data, &view.world_from_view, &mut buffers, slot);
                Some(device.create_bind_group(
                    "fin_convolution_view_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.view_layout),
                    &BindGroupEntries::sequential((
                        params.as_entire_binding(),
                        basis.as_entire_binding(),
                        uniform.as_entire_binding(),
                        state.as_entire_binding(),
                        depth,
                        normal,
                        layer,
                        view_binding.clone(),
                        buffer.as_entire_binding(),
                    )),
                ))
            })
            .collect();
        commands.entity(entity).insert((ConvolutionViewBindGroup(groups), ConvolutionViewBuffer(buffers)));
    }
}

#[allow(clippy::too_many_arguments)]
fn convolution_visibility(
    view: ViewQuery<(Entity, &FinShadowView, &FinViewTexture, &ConvolutionViewBindGroup, &ViewUniformOffset)>,
    frames: Res<FinFrames>,
    maps: Res<FinLightsGpu>,
    lights: Res<ConvolutionLightsGpu>,
    pipelines: Option<Res<ConvolutionPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    images: Res<bevy::render::render_asset::RenderAssets<bevy::render::texture::GpuImage>>,
    mut written: ResMut<ViewsWithVisibility>,
    mut ctx: RenderContext,
) {
    let (entity, settings, texture, bind_groups, offset) = view.into_inner();
    let Some(pipeline) = pipelines.and_then(|p| pipeline_cache.get_compute_pipeline(p.visibility)) else { return };
    for (slot, bind_group) in bind_groups.0.iter().enumerate() {
        let Some(bind_group) = bind_group else { continue };
        // Only over a basis built from the map as it is now (a frame whose
        // basis passes could not run yet gets no visibility: not stale ones).
        let key = frames.0[slot].key();
        let built = match (maps.0.get(&key), lights.0.get(&key)) {
            (Some(m), Some(g)) => !m.dirty && g.built_from == Some(m.renders),
            _ => false,
        };
        if !built {
            continue;
        }
        let view = crate::render::view::ViewPass { entity, settings, texture, offset: offset.offset };
        crate::render::view::run_view_pass(
            &mut ctx,
            &view,
            "fin_convolution_visibility",
            pipeline,
            bind_group,
            slot,
            &images,
            &frames,
            &mut written,
        );
    }
}
