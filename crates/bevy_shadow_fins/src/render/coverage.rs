//! Render world of the coverage method: the depth lists (`coverage_lists.wgsl`,
//! once per frame, only when the frame changed) and, per camera and light,
//! one visibility pass (`coverage.wgsl`: one walk over each pixel's edges
//! that corrects the reference count and moves every sample's count at once)
//! writing the same visibility buffer the fins write, so compositing is
//! unchanged.

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

use crate::render::{
    extraction::ensure,
    view::{FinViewTexture, ViewsWithVisibility, view_transform, workgroups},
};
use crate::{
    frame::{
        FinFrameData, FinFrames,
        coverage::{FAR_DEPTHS, LIST_WORDS, NEAR_DEPTHS},
    },
    settings::FinShadowView,
};

pub(super) use crate::gpu_layout::WORKGROUP;

pub(super) fn build(app: &mut App) {
    load_shader_library!(app, "shaders/coverage_types.wgsl");
    embedded_asset!(app, "shaders/coverage_lists.wgsl");
    embedded_asset!(app, "shaders/coverage.wgsl");
}

pub(super) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app
        .init_resource::<CoverageLightsGpu>()
        .add_systems(bevy::render::RenderStartup, init_pipelines)
        .add_systems(
            Render,
            (
                prepare_coverage.in_set(RenderSystems::PrepareResources),
                prepare_view_bind_groups.in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(RenderGraph, render_lists.in_set(crate::render::view::FinLightPasses))
        .add_systems(Core3d, coverage_visibility.after(Core3dSystems::Prepass).before(Core3dSystems::MainPass));
}

/// `CoverageParams` in `coverage_types.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct CoverageParams {
    pub(crate) lists: [f32; 4],
    pub(crate) counts: [u32; 4],
    pub(crate) light: [f32; 4],
    pub(crate) grid: [f32; 4],
    pub(crate) info: [u32; 4],
    pub(crate) axis_u: [f32; 4],
    pub(crate) axis_v: [f32; 4],
    pub(crate) axis_n: [f32; 4],
}

fn params_of(f: &FinFrameData) -> Option<CoverageParams> {
    let c = f.coverage.as_ref()?;
    let v4 = |v: bevy::math::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
    Some(CoverageParams {
        // w: edges, so that casters without raster work still shadow.
        lists: [c.region.min.x, c.region.min.y, c.region.texel, c.edges.len() as f32],
        counts: [c.region.resolution, NEAR_DEPTHS, FAR_DEPTHS, c.raster_work.len() as u32],
        light: [f.size, c.near.max(-3.0e38), c.extent * 1e-7, shadow_fins::scene::SURFACE_EPSILON],
        grid: c.grid,
        // w: the fins' projection code (a point light's cube face: the light
        // is the sphere's outline seen from each receiver, of radius
        // axis_n.w, and only the face's frustum is shaded).
        info: [c.dims[0], c.dims[1], c.samples.len() as u32, crate::render::params::projection_code(f)],
        axis_u: v4(f.axes[0]),
        axis_v: v4(f.axes[1]),
        axis_n: {
            let mut n = v4(f.axes[2]);
            n[3] = f.sphere_radius().unwrap_or(0.0);
            n
        },
    })
}

#[derive(Resource)]
struct CoveragePipelines {
    lists_layout: BindGroupLayoutDescriptor,
    view_layout: BindGroupLayoutDescriptor,
    clear: CachedComputePipelineId,
    raster: CachedComputePipelineId,
    visibility: CachedComputePipelineId,
}

fn init_pipelines(mut commands: Commands, pipeline_cache: Res<PipelineCache>, asset_server: Res<AssetServer>) {
    let lists_layout = BindGroupLayoutDescriptor::new(
        "fin_coverage_lists_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                // The casters' cut-outs and alpha masks (`cutout.wgsl`).
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
            ),
        ),
    );
    let view_layout = BindGroupLayoutDescriptor::new(
        "fin_coverage_view_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_depth_2d(),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                uniform_buffer::<ViewUniform>(true),
                uniform_buffer_sized(false, None),
                crate::render::view::gbuffer_entry(),
                storage_buffer_read_only_sized(false, None),
            ),
        ),
    );
    let lists_shader = load_embedded_asset!(asset_server.as_ref(), "shaders/coverage_lists.wgsl");
    let visibility_shader = load_embedded_asset!(asset_server.as_ref(), "shaders/coverage.wgsl");
    let compute = |label, layout: &_, shader: &_, entry| {
        crate::render::view::queue_compute(&pipeline_cache, label, layout, shader, entry)
    };
    commands.insert_resource(CoveragePipelines {
        clear: compute("fin_coverage_clear_lists", &lists_layout, &lists_shader, "clear_lists"),
        raster: compute("fin_coverage_raster_lists", &lists_layout, &lists_shader, "raster_lists"),
        visibility: compute("fin_coverage_visibility", &view_layout, &visibility_shader, "coverage_visibility"),
        lists_layout,
        view_layout,
    });
}

/// Every coverage-method frame's GPU lists, by main-world light entity and cube face.
#[derive(Resource, Default)]
struct CoverageLightsGpu(std::collections::HashMap<crate::frame::FrameKey, CoverageGpu>);

/// GPU copies of one light's coverage frame.
#[derive(Default)]
struct CoverageGpu {
    generation: u64,
    /// The depth lists must be (re)built: new content, or pipelines were not ready.
    dirty: bool,
    params: Option<Buffer>,
    lists: Option<Buffer>,
    casters: Option<Buffer>,
    edges: Option<Buffer>,
    faces: Option<Buffer>,
    starts: Option<Buffer>,
    items: Option<Buffer>,
    samples: Option<Buffer>,
    work: Option<Buffer>,
    cutouts: Option<Buffer>,
    mask_words: Option<Buffer>,
    lists_bind_group: Option<BindGroup>,
    /// (raster work items, texels)
    counts: (u32, u32),
}

impl CoverageGpu {
    fn ready(&self) -> bool {
        self.lists_bind_group.is_some()
    }
}

fn prepare_coverage(
    frames: Res<FinFrames>,
    mut lights: ResMut<CoverageLightsGpu>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    pipelines: Option<Res<CoveragePipelines>>,
    pipeline_cache: Res<PipelineCache>,
) {
    lights.0.retain(|key, _| frames.on_coverage(true).any(|f| f.key() == *key));
    let Some(pipelines) = pipelines else {
        lights.0.clear();
        return;
    };
    for frame in frames.on_coverage(true) {
        let gpu = lights.0.entry(frame.key()).or_default();
        prepare_light(&frame.data, gpu, &device, &queue, &pipelines, &pipeline_cache);
    }
}

/// One light's lists and inputs, uploaded when its frame changed.
fn prepare_light(
    f: &FinFrameData,
    gpu: &mut CoverageGpu,
    device: &RenderDevice,
    queue: &RenderQueue,
    pipelines: &CoveragePipelines,
    pipeline_cache: &PipelineCache,
) {
    let (Some(c), Some(params)) = (f.coverage.as_ref(), params_of(f)) else {
        gpu.lists_bind_group = None;
        gpu.generation = 0;
        return;
    };
    if f.generation == gpu.generation && gpu.ready() {
        return;
    }
    let storage = BufferUsages::STORAGE | BufferUsages::COPY_DST;
    let cap = f.limit_bytes;
    let texels = c.region.resolution as u64 * c.region.resolution as u64;
    let g = gpu;
    ensure(&mut g.params, device, "fin_coverage_params", 128, BufferUsages::UNIFORM | BufferUsages::COPY_DST, cap);
    ensure(&mut g.lists, device, "fin_coverage_lists", texels * LIST_WORDS * 4, storage, cap.min(f.map_limit_bytes));
    let upload = |buf: &mut Option<Buffer>, label: &str, bytes: &[u8]| {
        ensure(buf, device, label, (bytes.len() as u64).max(64), storage, cap);
        if !bytes.is_empty() {
            queue.write_buffer(buf.as_ref().unwrap(), 0, bytes);
        }
    };
    upload(&mut g.casters, "fin_coverage_casters", bytemuck::cast_slice(&c.casters));
    upload(&mut g.edges, "fin_coverage_edges", bytemuck::cast_slice(&c.edges));
    upload(&mut g.faces, "fin_coverage_faces", bytemuck::cast_slice(&c.faces));
    upload(&mut g.starts, "fin_coverage_cell_starts", bytemuck::cast_slice(&c.cell_starts));
    upload(&mut g.items, "fin_coverage_cell_items", bytemuck::cast_slice(&c.cell_items));
    upload(&mut g.samples, "fin_coverage_samples", bytemuck::cast_slice(&c.sample_planes()));
    upload(&mut g.work, "fin_coverage_raster_work", bytemuck::cast_slice(&c.raster_work));
    upload(&mut g.cutouts, "fin_coverage_cutouts", bytemuck::cast_slice(&c.cutouts));
    upload(&mut g.mask_words, "fin_coverage_mask_words", bytemuck::cast_slice(&c.mask_words));
    queue.write_buffer(g.params.as_ref().unwrap(), 0, bytemuck::bytes_of(&params));
    g.lists_bind_group = Some(device.create_bind_group(
        "fin_coverage_lists_bind_group",
        &pipeline_cache.get_bind_group_layout(&pipelines.lists_layout),
        &BindGroupEntries::sequential((
            g.params.as_ref().unwrap().as_entire_binding(),
            g.lists.as_ref().unwrap().as_entire_binding(),
            g.casters.as_ref().unwrap().as_entire_binding(),
            g.work.as_ref().unwrap().as_entire_binding(),
            g.cutouts.as_ref().unwrap().as_entire_binding(),
            g.mask_words.as_ref().unwrap().as_entire_binding(),
        )),
    ));
    g.counts = (c.raster_work.len() as u32, texels as u32);
    g.generation = f.generation;
    g.dirty = true;
}

/// Clears and fills each light's depth lists when its frame changed.
fn render_lists(
    mut lights: ResMut<CoverageLightsGpu>,
    pipelines: Option<Res<CoveragePipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let Some(pipelines) = pipelines else { return };
    let (Some(clear), Some(raster)) =
        (pipeline_cache.get_compute_pipeline(pipelines.clear), pipeline_cache.get_compute_pipeline(pipelines.raster))
    else {
        return;
    };
    for gpu in lights.0.values_mut().filter(|g| g.dirty) {
        let Some(bind_group) = gpu.lists_bind_group.clone() else { continue };
        let (work, texels) = gpu.counts;
        let diagnostics = ctx.diagnostic_recorder();
        let diagnostics = diagnostics.as_deref();
        let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/coverage_lists");
        {
            let mut pass = ctx.command_encoder().begin_compute_pass(&ComputePassDescriptor {
                label: Some("fin_coverage_lists"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, &bind_group, &[]);
            pass.set_pipeline(clear);
            let (x, y) = workgroups(texels.div_ceil(WORKGROUP));
            pass.dispatch_workgroups(x, y, 1);
            if work > 0 {
                pass.set_pipeline(raster);
                let (x, y) = workgroups(work);
                pass.dispatch_workgroups(x, y, 1);
            }
        }
        span.end(ctx.command_encoder());
        gpu.dirty = false;
    }
}

/// Per camera and light slot: the coverage visibility pass's bind group
/// (`None` for lights on a fin method, or that cannot run this frame).
#[derive(Component)]
pub struct CoverageViewBindGroup(Vec<Option<BindGroup>>);

/// Per camera: each light slot's view → light-frame transform, kept between
/// frames.
#[derive(Component)]
pub struct CoverageViewBuffers {
    transforms: Vec<Buffer>,
}

#[allow(clippy::too_many_arguments)]
fn prepare_view_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    lights: Res<CoverageLightsGpu>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<CoveragePipelines>>,
    pipeline_cache: Res<PipelineCache>,
    view_uniforms: Res<ViewUniforms>,
    no_gbuffer: Res<crate::render::view::NoGBuffer>,
    mut views: Query<(Entity, &FinViewTexture, &ViewPrepassTextures, &ExtractedView, Option<&mut CoverageViewBuffers>)>,
) {
    let binding = view_uniforms.uniforms.binding();
    for (entity, texture, prepass, view, buffers) in &mut views {
        let (Some(pipelines), Some(view_binding), false) = (pipelines.as_ref(), binding.clone(), lights.0.is_empty())
        else {
            commands.entity(entity).remove::<CoverageViewBindGroup>();
            continue;
        };
        let Some((depth, normal)) = crate::render::view::prepass_inputs(prepass) else {
            commands.entity(entity).remove::<CoverageViewBindGroup>();
            continue;
        };
        let mut kept = CoverageViewBuffers {
            transforms: buffers.map(|mut b| std::mem::take(&mut b.transforms)).unwrap_or_default(),
        };
        let groups = frames
            .0
            .iter()
            .enumerate()
            .map(|(slot, frame)| {
                let gpu = lights.0.get(&frame.key()).filter(|g| g.ready())?;
                let layer = texture.layers.get(frame.layer)?;
                let f = &frame.data;
                let buffer = view_transform(&device, &queue, f, &view.world_from_view, &mut kept.transforms, slot);
                let bind_group = device.create_bind_group(
                    "fin_coverage_view_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.view_layout),
                    &BindGroupEntries::sequential((
                        gpu.params.as_ref().unwrap().as_entire_binding(),
                        gpu.lists.as_ref().unwrap().as_entire_binding(),
                        gpu.edges.as_ref().unwrap().as_entire_binding(),
                        gpu.starts.as_ref().unwrap().as_entire_binding(),
                        gpu.items.as_ref().unwrap().as_entire_binding(),
                        gpu.samples.as_ref().unwrap().as_entire_binding(),
                        depth,
                        normal,
                        layer,
                        view_binding.clone(),
                        buffer.as_entire_binding(),
                        crate::render::view::gbuffer_input(prepass, &no_gbuffer),
                        gpu.faces.as_ref().unwrap().as_entire_binding(),
                    )),
                );
                Some(bind_group)
            })
            .collect();
        commands.entity(entity).insert((CoverageViewBindGroup(groups), kept));
    }
}

fn coverage_visibility(
    view: ViewQuery<(Entity, &FinShadowView, &FinViewTexture, &CoverageViewBindGroup, &ViewUniformOffset)>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<CoveragePipelines>>,
    pipeline_cache: Res<PipelineCache>,
    images: Res<bevy::render::render_asset::RenderAssets<bevy::render::texture::GpuImage>>,
    mut written: ResMut<ViewsWithVisibility>,
    mut ctx: RenderContext,
) {
    let (entity, settings, texture, bind_groups, offset) = view.into_inner();
    let Some(pipelines) = pipelines else { return };
    let Some(pipeline) = pipeline_cache.get_compute_pipeline(pipelines.visibility) else { return };
    let size = texture.texture.texture.size();
    for (slot, group) in bind_groups.0.iter().enumerate() {
        let Some(bind_group) = group else { continue };
        let diagnostics = ctx.diagnostic_recorder();
        let diagnostics = diagnostics.as_deref();
        let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/visibility");
        {
            let mut pass = ctx.command_encoder().begin_compute_pass(&ComputePassDescriptor {
                label: Some("fin_coverage_visibility"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, bind_group, &[offset.offset]);
            let (x, y) = (size.width.div_ceil(8), size.height.div_ceil(8));
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(x, y, 1);
        }
        span.end(ctx.command_encoder());
        written.0.insert((entity, slot));
        crate::render::view::copy_to_targets(&mut ctx, settings, texture, &images, &frames, slot);
    }
}
