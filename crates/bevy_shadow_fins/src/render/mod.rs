//! Render world: the penumbra-map passes (once per frame, only when the fin
//! frame changed) and the per-camera visibility pass.

use std::{borrow::Cow, sync::Arc};

use bevy::{
    asset::{embedded_asset, load_embedded_asset},
    core_pipeline::{
        prepass::ViewPrepassTextures,
        schedule::{Core3d, Core3dSystems, camera_driver},
    },
    prelude::*,
    render::{
        Render, RenderApp, RenderSystems,
        camera::ExtractedCamera,
        diagnostic::RecordDiagnostics,
        extract_component::{ExtractComponent, ExtractComponentPlugin},
        extract_resource::ExtractResourcePlugin,
        render_asset::RenderAssets,
        render_resource::{
            binding_types::{
                storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_depth_2d, texture_storage_2d,
                uniform_buffer, uniform_buffer_sized,
            },
            *,
        },
        renderer::{RenderContext, RenderDevice, RenderGraph, RenderGraphSystems, RenderQueue, ViewQuery},
        texture::{CachedTexture, GpuImage, TextureCache},
        view::{ExtractedView, ViewUniform, ViewUniformOffset, ViewUniforms},
    },
    shader::load_shader_library,
};

use crate::{
    extract::{FinFrameData, FinFrames},
    light::FinShadowView,
};

mod bevy_lights;
mod composite;
mod convolution;
mod coverage;
mod extract_gpu;
mod forward;
mod plateaus;

pub use forward::FinForwardShading;
pub(crate) use forward::PbrFragment;

pub(crate) fn build(app: &mut App) {
    load_shader_library!(app, "shaders/fin_types.wgsl");
    load_shader_library!(app, "shaders/cutout.wgsl");
    load_shader_library!(app, "shaders/fin_view.wgsl");
    load_shader_library!(app, "shaders/receiver_normal.wgsl");
    embedded_asset!(app, "shaders/maps.wgsl");
    embedded_asset!(app, "shaders/visibility.wgsl");
    app.init_resource::<FinPartialRedraw>().init_resource::<FinIncrementalExtraction>().add_plugins((
        ExtractResourcePlugin::<FinFrames>::default(),
        ExtractResourcePlugin::<FinPartialRedraw>::default(),
        ExtractResourcePlugin::<FinIncrementalExtraction>::default(),
        ExtractResourcePlugin::<crate::BevyShadowMapsKept>::default(),
        ExtractComponentPlugin::<FinShadowView>::default(),
    ));
    composite::build(app);
    forward::build(app);
    coverage::build(app);
    convolution::build(app);
    plateaus::build(app);
    extract_gpu::build(app);
}

/// Whether the GPU extraction may redraw the penumbra maps in part when a few
/// casters of many moved (only the texels under their old and new
/// footprints; see `FinFrameStats::partial_redraw`). On by default: the
/// result is texel for texel a full redraw's. Off, every update redraws the
/// maps whole — for measuring what the partial redraw saves
/// (`shadow-fins-render-lab scaling`).
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq, bevy::render::extract_resource::ExtractResource)]
pub struct FinPartialRedraw(pub bool);

impl Default for FinPartialRedraw {
    fn default() -> Self {
        Self(true)
    }
}

/// Whether the GPU extraction may extract only the casters that moved, when
/// a few of many moved, and keep every other caster's silhouettes, fins and
/// map triangles from the update before (see
/// `FinFrameStats::incremental_extraction`). On by default: the result is
/// record for record a full extraction's. Off, every update extracts every
/// caster — for measuring what it saves (`shadow-fins-render-lab scaling`).
/// It applies where a partial redraw may ([`FinPartialRedraw`]).
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq, bevy::render::extract_resource::ExtractResource)]
pub struct FinIncrementalExtraction(pub bool);

impl Default for FinIncrementalExtraction {
    fn default() -> Self {
        Self(true)
    }
}

pub(crate) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    // Like Bevy's SSAO: check what the device can do before adding any pass.
    let world = render_app.world();
    let (Some(device), Some(adapter)) =
        (world.get_resource::<RenderDevice>(), world.get_resource::<bevy::render::renderer::RenderAdapter>())
    else {
        return;
    };
    let compute = adapter.get_downlevel_capabilities().flags.contains(DownlevelFlags::COMPUTE_SHADERS);
    match crate::budget::check_device(&device.limits(), compute) {
        Ok(limits) => {
            app.insert_resource(limits);
        }
        Err(why) => {
            error!("fin shadows: {why}. The plugin adds no pass; fin lights cast no light.");
            app.insert_resource(crate::budget::FinShadowsUnsupported(why));
            return;
        }
    }
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app
        .init_resource::<FinLightsGpu>()
        .init_resource::<ViewsWithVisibility>()
        .add_systems(bevy::render::RenderStartup, (init_pipelines, init_no_gbuffer))
        .add_systems(
            Render,
            (
                prepare_maps.in_set(RenderSystems::PrepareResources),
                clear_views_with_visibility.in_set(RenderSystems::PrepareResources),
                prepare_view_textures.in_set(RenderSystems::PrepareResources),
                prepare_view_bind_groups.in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        // In `Render`, after `Begin`: the diagnostics recorder clears the spans recorded before it.
        .configure_sets(RenderGraph, FinLightPasses.in_set(RenderGraphSystems::Render).before(camera_driver))
        .add_systems(RenderGraph, render_maps.in_set(FinLightPasses))
        .add_systems(Core3d, fin_visibility.after(Core3dSystems::Prepass).before(Core3dSystems::MainPass));
    coverage::finish(app);
    convolution::finish(app);
    plateaus::finish(app);
    composite::finish(app);
    forward::finish(app);
    bevy_lights::finish(app);
}

impl ExtractComponent for FinShadowView {
    type QueryData = &'static FinShadowView;
    type QueryFilter = With<Camera3d>;
    type Out = FinShadowView;
    fn extract_component(item: &FinShadowView) -> Option<FinShadowView> {
        Some(item.clone())
    }
}

impl bevy::render::sync_component::SyncComponent for FinShadowView {
    type Target = (
        FinShadowView,
        FinViewTexture,
        FinViewBindGroup,
        FinViewBuffer,
        coverage::CoverageViewBindGroup,
        coverage::CoverageViewBuffers,
        convolution::ConvolutionViewBindGroup,
        convolution::ConvolutionViewBuffer,
        plateaus::PlateauViewBindGroup,
        plateaus::PlateauViewBuffer,
        composite::FinCompositePipeline,
        composite::FinCompositeBindGroup,
        bevy::pbr::deferred::SkipDeferredLighting,
    );
}

/// The uniform every pass reads; the layout of `FinParams` in `fin_types.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FinParams {
    map: [f32; 4],
    counts: [u32; 4],
    light: [f32; 4],
    flags: [u32; 4],
    origin: [f32; 4],
    axis_u: [f32; 4],
    axis_v: [f32; 4],
    axis_n: [f32; 4],
    /// The texels the map passes redraw, inclusive (x0, x1, y0, y1): the
    /// whole maps, but on the GPU extraction's partial redraw.
    redraw: [u32; 4],
}

/// Words per layer texel (`CHANNELS` in `fin_types.wgsl`).
const CHANNELS: u64 = 9;
const WORKGROUP: u32 = 64;

#[derive(Resource)]
struct FinPipelines {
    maps_layout: BindGroupLayoutDescriptor,
    view_layout: BindGroupLayoutDescriptor,
    clear: CachedComputePipelineId,
    casters: CachedComputePipelineId,
    fins: CachedComputePipelineId,
    fin_depths: CachedComputePipelineId,
    visibility: CachedComputePipelineId,
    extract: extract_gpu::ExtractPipelines,
}

/// The per-light passes of the root render graph (maps, coverage lists,
/// convolution basis): before the cameras' schedules, which read what they
/// write, and after the diagnostics recorder begins its frame.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
struct FinLightPasses;

/// Queues a compute pipeline of one bind group (every pass of the plugin).
pub(super) fn queue_compute(
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

fn init_pipelines(mut commands: Commands, pipeline_cache: Res<PipelineCache>, asset_server: Res<AssetServer>) {
    let maps_layout = BindGroupLayoutDescriptor::new(
        "fin_maps_layout",
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
                // The GPU extraction's `control`: a partial redraw's lists.
                storage_buffer_read_only_sized(false, None),
            ),
        ),
    );
    let view_layout = BindGroupLayoutDescriptor::new(
        "fin_visibility_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_depth_2d(),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                uniform_buffer::<ViewUniform>(true),
                uniform_buffer_sized(false, None),
                gbuffer_entry(),
            ),
        ),
    );
    let maps_shader = load_embedded_asset!(asset_server.as_ref(), "shaders/maps.wgsl");
    let visibility_shader = load_embedded_asset!(asset_server.as_ref(), "shaders/visibility.wgsl");
    let compute = |label, layout: &_, shader: &_, entry| queue_compute(&pipeline_cache, label, layout, shader, entry);
    commands.insert_resource(FinPipelines {
        clear: compute("fin_clear_maps", &maps_layout, &maps_shader, "clear_maps"),
        casters: compute("fin_raster_casters", &maps_layout, &maps_shader, "raster_casters"),
        fins: compute("fin_raster_fins", &maps_layout, &maps_shader, "raster_fins"),
        fin_depths: compute("fin_raster_fin_depths", &maps_layout, &maps_shader, "raster_fin_depths"),
        visibility: compute("fin_visibility", &view_layout, &visibility_shader, "visibility_pass"),
        extract: extract_gpu::ExtractPipelines::queue(&pipeline_cache, &asset_server),
        maps_layout,
        view_layout,
    });
}

/// Every fin-shadowed frame's GPU maps (fin methods; the coverage method's
/// are in `coverage.rs`), by main-world light entity and cube face.
#[derive(Resource, Default)]
struct FinLightsGpu(std::collections::HashMap<crate::extract::FrameKey, FinMapsGpu>);

/// GPU copies of one light's fin frame and its maps.
#[derive(Default)]
struct FinMapsGpu {
    generation: u64,
    /// The maps must be (re)rendered: new content, or pipelines were not ready.
    dirty: bool,
    params: Option<Buffer>,
    maps: Option<Buffer>,
    casters: Option<Buffer>,
    fins: Option<Buffer>,
    cutouts: Option<Buffer>,
    mask_words: Option<Buffer>,
    /// The GPU extraction's mask words in `mask_words` (none after the CPU
    /// path wrote there): a moved caster does not upload them again.
    uploaded_masks: Option<Arc<Vec<u32>>>,
    /// The read-back slot its counts were last copied into.
    stats_slot: Option<usize>,
    bind_group: Option<BindGroup>,
    counts: (u32, u32, u64),
    /// How many times the map passes have drawn these maps (what the
    /// convolution method's basis was built from, `convolution.rs`).
    renders: u64,
    mode: MapsSource,
    extraction: extract_gpu::ExtractBuffers,
}

/// Where this frame's casters and fins come from.
#[derive(Default, Clone, Copy, PartialEq, Eq)]
enum MapsSource {
    /// Uploaded from the CPU extraction; dispatch sizes known here.
    #[default]
    Cpu,
    /// Written by the GPU extraction; dispatched indirectly.
    Gpu,
    /// No caster at all: no extraction, no map pass (zero layers).
    Nothing,
}

/// `FinParams.flags.w`: how the frame's maps project.
pub(super) fn projection_code(f: &FinFrameData) -> u32 {
    match (f.orthographic, f.aperture) {
        (true, _) => 1,
        (false, shadow_fins::light::Aperture::Sphere { .. }) => 2,
        (false, _) => 0,
    }
}

fn params_of(f: &FinFrameData) -> FinParams {
    let s = f.settings;
    let falloff = match s.falloff {
        shadow_fins::refine::Falloff::Linear => 0,
        shadow_fins::refine::Falloff::Bernstein => 1,
        shadow_fins::refine::Falloff::DiskSegment => 2,
    };
    let overlap = match s.overlap {
        shadow_fins::oracle::Overlap::MinMax => 0,
        shadow_fins::oracle::Overlap::Union => 1,
    };
    let v4 = |v: bevy::math::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
    FinParams {
        map: [f.region.min.x, f.region.min.y, f.region.texel, f.reference_depth],
        counts: [f.region.resolution, f.stats.layers as u32, f.casters.len() as u32, f.fins.len() as u32],
        // The sun's near depth is −∞ (no near plane); the shaders' stand-in is
        // the most negative finite float.
        light: [f.size, f.near.max(-3.0e38), f.scene_extent * 1e-7, shadow_fins::scene::SURFACE_EPSILON],
        // Projection: 0 a disk's perspective, 1 the sun's orthographic, 2 a
        // point light's cube face (its visibility pass shades its frustum only).
        flags: [s.refinement as u32, falloff, overlap, projection_code(f)],
        origin: v4(f.origin),
        axis_u: v4(f.axes[0]),
        axis_v: v4(f.axes[1]),
        axis_n: v4(f.axes[2]),
        redraw: {
            let last = f.region.resolution.max(1) - 1;
            [0, last, 0, last]
        },
    }
}

/// Uploads each light's changed fin frame; buffers grow on demand and are
/// reused otherwise. Lights gone (or now on the coverage method) free theirs.
fn prepare_maps(
    frames: Res<FinFrames>,
    mut lights: ResMut<FinLightsGpu>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    pipelines: Option<Res<FinPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    partial: Option<Res<FinPartialRedraw>>,
    incremental: Option<Res<FinIncrementalExtraction>>,
) {
    let scope = UpdateScope {
        partial_redraw: partial.is_none_or(|p| p.0),
        incremental_extraction: incremental.is_none_or(|i| i.0),
    };
    lights.0.retain(|key, _| frames.on_coverage(false).any(|f| f.key() == *key));
    let Some(pipelines) = pipelines else {
        lights.0.clear();
        return;
    };
    for frame in frames.on_coverage(false) {
        let gpu = lights.0.entry(frame.key()).or_default();
        prepare_light_maps(&frame.data, gpu, &device, &queue, &pipelines, &pipeline_cache, scope);
    }
}

/// What an update of the GPU extraction may leave as it was
/// ([`FinPartialRedraw`], [`FinIncrementalExtraction`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct UpdateScope {
    pub partial_redraw: bool,
    pub incremental_extraction: bool,
}

/// One light's maps: uploaded when its frame changed.
fn prepare_light_maps(
    f: &FinFrameData,
    gpu: &mut FinMapsGpu,
    device: &RenderDevice,
    queue: &RenderQueue,
    pipelines: &FinPipelines,
    pipeline_cache: &PipelineCache,
    scope: UpdateScope,
) {
    if f.generation == gpu.generation && gpu.bind_group.is_some() {
        return;
    }
    let mut params = params_of(f);
    // The main world sized the maps to fit the budget and the device
    // (`budget::allocate_maps`); GPU extraction uses up to `map_layers`.
    let (layers, resolution) = (f.map_layers.max(1) as u64, f.region.resolution);
    let texels = layers * resolution as u64 * resolution as u64;
    let maps_size = (texels * CHANNELS * 4).max(16);
    if maps_size > device.limits().max_storage_buffer_binding_size {
        warn_once!("fin shadows: {maps_size}-byte maps exceed this GPU's storage binding limit; no fin shadows");
        gpu.bind_group = None;
        return;
    }
    let storage = BufferUsages::STORAGE | BufferUsages::COPY_DST;
    use extract_gpu::ensure;
    let cap = f.limit_bytes;
    let params_bytes = size_of::<FinParams>() as u64;
    ensure(&mut gpu.params, device, "fin_params", params_bytes, BufferUsages::UNIFORM | BufferUsages::COPY_DST, cap);
    // The maps grow to their budget at most (their size is already within it).
    let old_maps = gpu.maps.as_ref().map(|b| b.id());
    ensure(&mut gpu.maps, device, "fin_maps", maps_size, storage | BufferUsages::COPY_SRC, cap.min(f.map_limit_bytes));
    // New maps hold nothing a partial redraw could keep.
    let maps_kept = scope.partial_redraw && old_maps == gpu.maps.as_ref().map(|b| b.id());
    let (caster_bytes, fin_bytes) = match &f.gpu {
        Some(scene) => (
            scene.capacity.casters as u64 * extract_gpu::CASTER_BYTES,
            scene.capacity.fins as u64 * extract_gpu::FIN_BYTES,
        ),
        None => (size_of_val(f.casters.as_slice()) as u64, size_of_val(f.fins.as_slice()) as u64),
    };
    ensure(&mut gpu.casters, device, "fin_casters", caster_bytes.max(64), storage, cap);
    ensure(&mut gpu.fins, device, "fin_fins", fin_bytes.max(64), storage, cap);
    // Alpha-masked casters' cut-outs: from the CPU extraction, or (on the
    // GPU extraction) written by it beside its casters; their masks.
    let cutout_bytes: &[u8] = bytemuck::cast_slice(&f.cutouts);
    let masks = f.gpu.as_ref().map(|scene| &scene.mask_words);
    let mask_bytes: &[u8] = bytemuck::cast_slice(masks.map_or(&f.mask_words, |m| m.as_slice()));
    ensure(&mut gpu.cutouts, device, "fin_cutouts", (cutout_bytes.len() as u64).max(64), storage, cap);
    let old_masks = gpu.mask_words.as_ref().map(|b| b.id());
    ensure(&mut gpu.mask_words, device, "fin_mask_words", (mask_bytes.len() as u64).max(64), storage, cap);
    if !cutout_bytes.is_empty() {
        queue.write_buffer(gpu.cutouts.as_ref().unwrap(), 0, cutout_bytes);
    }
    let uploaded = old_masks == gpu.mask_words.as_ref().map(|b| b.id())
        && masks.zip(gpu.uploaded_masks.as_ref()).is_some_and(|(now, was)| Arc::ptr_eq(now, was));
    if !mask_bytes.is_empty() && !uploaded {
        queue.write_buffer(gpu.mask_words.as_ref().unwrap(), 0, mask_bytes);
    }
    gpu.uploaded_masks = masks.cloned();
    gpu.mode = match &f.gpu {
        None => MapsSource::Cpu,
        Some(scene) if scene.totals[1] == 0 => MapsSource::Nothing,
        Some(_) => MapsSource::Gpu,
    };
    match (&f.gpu, gpu.mode) {
        (Some(scene), MapsSource::Gpu) => {
            let FinMapsGpu { extraction, fins, casters, .. } = gpu;
            extract_gpu::prepare(
                extraction,
                f,
                scene,
                resolution,
                fins.as_ref().unwrap(),
                casters.as_ref().unwrap(),
                maps_kept,
                scope.incremental_extraction,
                &pipelines.extract,
                pipeline_cache,
                device,
                queue,
            );
        }
        _ => {
            // The maps are another path's now: no base for a partial redraw.
            gpu.extraction.forget_history();
            // CPU extraction (or nothing to extract): the parameters are known here.
            if gpu.mode == MapsSource::Nothing {
                params.counts = [resolution, 0, 0, 0];
            }
            queue.write_buffer(gpu.params.as_ref().unwrap(), 0, bytemuck::bytes_of(&params));
            if !f.casters.is_empty() {
                queue.write_buffer(gpu.casters.as_ref().unwrap(), 0, bytemuck::cast_slice(&f.casters));
            }
            if !f.fins.is_empty() {
                queue.write_buffer(gpu.fins.as_ref().unwrap(), 0, bytemuck::cast_slice(&f.fins));
            }
        }
    }
    gpu.bind_group = Some(
        device.create_bind_group(
            "fin_maps_bind_group",
            &pipeline_cache.get_bind_group_layout(&pipelines.maps_layout),
            &BindGroupEntries::sequential((
                gpu.params.as_ref().unwrap().as_entire_binding(),
                gpu.maps.as_ref().unwrap().as_entire_binding(),
                gpu.casters.as_ref().unwrap().as_entire_binding(),
                gpu.fins.as_ref().unwrap().as_entire_binding(),
                match gpu.mode {
                    MapsSource::Gpu => gpu.extraction.cutouts().unwrap(),
                    _ => gpu.cutouts.as_ref().unwrap(),
                }
                .as_entire_binding(),
                gpu.mask_words.as_ref().unwrap().as_entire_binding(),
                // Read only on a partial redraw, which the CPU path never does:
                // there the cut-outs stand in.
                match gpu.mode {
                    MapsSource::Gpu => gpu.extraction.control().unwrap(),
                    _ => gpu.cutouts.as_ref().unwrap(),
                }
                .as_entire_binding(),
            )),
        ),
    );
    gpu.counts = (f.casters.len() as u32, f.fins.len() as u32, texels);
    gpu.generation = f.generation;
    gpu.dirty = true;
}

/// Workgroup counts for `n` items, split over y when x would exceed the limit.
pub(super) fn workgroups(n: u32) -> (u32, u32) {
    if n <= 65535 { (n, 1) } else { (65535, n.div_ceil(65535)) }
}

/// Per light whose frame changed: extracts fins on the GPU when that is the
/// source, then renders every layer's maps: clear, casters (slab depths),
/// fins (keys). The extraction's counts go to the light's read-back slot.
fn render_maps(
    frames: Res<FinFrames>,
    mut lights: ResMut<FinLightsGpu>,
    pipelines: Option<Res<FinPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    stats_handle: Option<Res<extract_gpu::FinStatsBuffer>>,
    shader_buffers: Res<RenderAssets<bevy::render::storage::GpuShaderBuffer>>,
    mut ctx: RenderContext,
) {
    let Some(pipelines) = pipelines else { return };
    for (slot, frame) in frames.0.iter().enumerate() {
        let Some(gpu) = lights.0.get_mut(&frame.key()) else { continue };
        let stats = extract_gpu::stats_buffer(stats_handle.as_deref(), &shader_buffers)
            .map(|b| (b, extract_gpu::stats_offset(slot)));
        let redrawing = gpu.dirty;
        render_light_maps(gpu, &pipelines, &pipeline_cache, stats, &mut ctx);
        if redrawing && !gpu.dirty && stats.is_some() {
            // Recorded, its counts copied into this slot.
            gpu.stats_slot = Some(slot);
        } else if let (false, MapsSource::Gpu, Some(control), Some((stats, offset))) =
            (gpu.dirty, gpu.mode, gpu.extraction.control(), stats)
            && gpu.stats_slot != Some(slot)
        {
            // The lights changed order since: its counts follow it to its new
            // slot, where a read-back still waiting for them looks.
            extract_gpu::copy_stats(control, stats, offset, ctx.command_encoder());
            gpu.stats_slot = Some(slot);
        }
    }
}

/// One light's extraction and map passes, when its maps are dirty.
fn render_light_maps(
    gpu: &mut FinMapsGpu,
    pipelines: &FinPipelines,
    pipeline_cache: &PipelineCache,
    stats: Option<(&Buffer, u64)>,
    ctx: &mut RenderContext,
) {
    if !gpu.dirty {
        return;
    }
    let Some(bind_group) = gpu.bind_group.clone() else { return };
    let (Some(clear), Some(casters), Some(fins), Some(fin_depths)) = (
        pipeline_cache.get_compute_pipeline(pipelines.clear),
        pipeline_cache.get_compute_pipeline(pipelines.casters),
        pipeline_cache.get_compute_pipeline(pipelines.fins),
        pipeline_cache.get_compute_pipeline(pipelines.fin_depths),
    ) else {
        return;
    };
    let (n_casters, n_fins, texels) = gpu.counts;
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    match gpu.mode {
        MapsSource::Nothing => {
            gpu.dirty = false;
            gpu.renders += 1;
            return;
        }
        MapsSource::Gpu => {
            let (Some(params), Some(control)) = (gpu.params.clone(), gpu.extraction.indirect.clone()) else { return };
            let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/extraction");
            let recorded = extract_gpu::record(
                &mut gpu.extraction,
                &pipelines.extract,
                pipeline_cache,
                &params,
                stats,
                ctx.command_encoder(),
            );
            span.end(ctx.command_encoder());
            if !recorded {
                return;
            }
            let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/penumbra_maps");
            {
                let mut pass = ctx.command_encoder().begin_compute_pass(&ComputePassDescriptor {
                    label: Some("fin_penumbra_maps"),
                    timestamp_writes: None,
                });
                pass.set_bind_group(0, &bind_group, &[]);
                for (pipeline, args) in [
                    (clear, extract_gpu::C_ARGS_CLEAR),
                    (casters, extract_gpu::C_ARGS_CASTERS),
                    (fins, extract_gpu::C_ARGS_FINS),
                    (fin_depths, extract_gpu::C_ARGS_FINS),
                ] {
                    pass.set_pipeline(pipeline);
                    pass.dispatch_workgroups_indirect(&control, args * 4);
                }
            }
            span.end(ctx.command_encoder());
            gpu.dirty = false;
            gpu.renders += 1;
            return;
        }
        MapsSource::Cpu => {}
    }
    let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/penumbra_maps");
    {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor { label: Some("fin_penumbra_maps"), timestamp_writes: None });
        pass.set_bind_group(0, &bind_group, &[]);
        if texels > 0 {
            pass.set_pipeline(clear);
            let (x, y) = workgroups((texels as u32).div_ceil(WORKGROUP));
            pass.dispatch_workgroups(x, y, 1);
        }
        if n_casters > 0 {
            pass.set_pipeline(casters);
            let (x, y) = workgroups(n_casters);
            pass.dispatch_workgroups(x, y, 1);
        }
        if n_fins > 0 {
            let (x, y) = workgroups(n_fins);
            // Keys first, then the exact depths of the winners (a second
            // dispatch, so that it compares against final keys).
            for pipeline in [fins, fin_depths] {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(x, y, 1);
            }
        }
    }
    span.end(ctx.command_encoder());
    gpu.dirty = false;
    gpu.renders += 1;
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

/// Per camera and frame slot: the fin visibility pass's bind group (`None`
/// for lights on the coverage, convolution or plateaus method, or that
/// cannot run this frame).
#[derive(Component)]
pub struct FinViewBindGroup(Vec<Option<BindGroup>>);

/// Per camera and frame slot: its view → light-frame transform (`FinView`
/// in `visibility.wgsl`).
#[derive(Component, Default)]
pub struct FinViewBuffer(pub(super) Vec<Buffer>);

/// The view's view → light-frame uniform of frame slot `slot`, written for
/// this frame (created the first time).
pub(super) fn view_transform(
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
struct FinViewUniform {
    linear: [[f32; 4]; 3],
    translation: [f32; 4],
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
fn camera_raster_error(camera: Vec3) -> f32 {
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
pub(super) struct ViewsWithVisibility(pub(super) std::collections::HashSet<(Entity, usize)>);

fn clear_views_with_visibility(mut views: ResMut<ViewsWithVisibility>) {
    views.0.clear();
}

fn prepare_view_textures(
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
pub(super) fn prepass_inputs(prepass: &ViewPrepassTextures) -> Option<(&TextureView, &TextureView)> {
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
pub(super) fn gbuffer_input<'a>(prepass: &'a ViewPrepassTextures, no_gbuffer: &'a NoGBuffer) -> &'a TextureView {
    prepass.deferred_view().unwrap_or(&no_gbuffer.0)
}

/// A 1×1 G-buffer of zeros (no deferred pixel): what the visibility passes
/// read in place of a camera's G-buffer when it has no deferred prepass
/// (every pixel forward-shaded, its prepass normal already the shaded side).
#[derive(Resource)]
pub(super) struct NoGBuffer(TextureView);

/// The layout entry of the G-buffer a visibility pass reads (Bevy's
/// `DEFERRED_PREPASS_FORMAT`, `Rgba32Uint`).
pub(super) fn gbuffer_entry() -> BindGroupLayoutEntryBuilder {
    texture_2d(TextureSampleType::Uint)
}

fn init_no_gbuffer(mut commands: Commands, device: Res<RenderDevice>, queue: Res<RenderQueue>) {
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

#[allow(clippy::too_many_arguments)]
fn prepare_view_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    lights: Res<FinLightsGpu>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<FinPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    view_uniforms: Res<ViewUniforms>,
    no_gbuffer: Res<NoGBuffer>,
    mut views: Query<(Entity, &FinViewTexture, &ViewPrepassTextures, &ExtractedView, Option<&mut FinViewBuffer>)>,
) {
    let (Some(pipelines), Some(view_binding)) = (pipelines, view_uniforms.uniforms.binding()) else {
        for (entity, ..) in &views {
            commands.entity(entity).remove::<FinViewBindGroup>();
        }
        return;
    };
    for (entity, texture, prepass, view, view_buffers) in &mut views {
        // A light that cannot run the pass this frame has no bind group, so
        // the pass does not run on last frame's maps and nothing composites
        // stale shadows.
        let inputs = prepass_inputs(prepass);
        let gbuffer = gbuffer_input(prepass, &no_gbuffer);
        let mut buffers = view_buffers.map(|mut b| std::mem::take(&mut b.0)).unwrap_or_default();
        let groups = frames
            .0
            .iter()
            .enumerate()
            .map(|(slot, frame)| {
                if !frame.data.settings.method.shaded_by_fin_pass() {
                    return None;
                }
                let gpu = lights.0.get(&frame.key())?;
                let (Some(params), Some(maps), Some(_), Some((depth, normal)), Some(layer)) = (
                    gpu.params.as_ref(),
                    gpu.maps.as_ref(),
                    gpu.bind_group.as_ref(),
                    inputs,
                    texture.layers.get(frame.layer),
                ) else {
                    return None;
                };
                let buffer = view_transform(&device, &queue, &frame.data, &view.world_from_view, &mut buffers, slot);
                Some(device.create_bind_group(
                    "fin_visibility_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.view_layout),
                    &BindGroupEntries::sequential((
                        params.as_entire_binding(),
                        maps.as_entire_binding(),
                        depth,
                        normal,
                        layer,
                        view_binding.clone(),
                        buffer.as_entire_binding(),
                        gbuffer,
                    )),
                ))
            })
            .collect();
        commands.entity(entity).insert((FinViewBindGroup(groups), FinViewBuffer(buffers)));
    }
}

fn fin_visibility(
    view: ViewQuery<(Entity, &FinShadowView, &FinViewTexture, &FinViewBindGroup, &ViewUniformOffset)>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<FinPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    images: Res<RenderAssets<GpuImage>>,
    mut written: ResMut<ViewsWithVisibility>,
    mut ctx: RenderContext,
) {
    let (entity, settings, texture, bind_groups, offset) = view.into_inner();
    let Some(pipeline) = pipelines.and_then(|p| pipeline_cache.get_compute_pipeline(p.visibility)) else { return };
    for (slot, bind_group) in bind_groups.0.iter().enumerate() {
        let Some(bind_group) = bind_group else { continue };
        let view = ViewPass { entity, settings, texture, offset: offset.offset };
        run_view_pass(&mut ctx, &view, "fin_visibility", pipeline, bind_group, slot, &images, &frames, &mut written);
    }
}

/// The camera a per-pixel visibility pass runs for.
pub(super) struct ViewPass<'a> {
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
pub(super) fn run_view_pass(
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
pub(super) fn copy_to_targets(
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

#[cfg(test)]
mod shader_layout_tests {
    /// Every pass's WGSL lives in the workspace's top-level `shaders/`; the
    /// crate sees it through the `src/render/shaders` link, which `cargo
    /// package` follows, so the published crate carries the same files.
    #[test]
    fn the_shaders_the_plugin_embeds_are_the_top_level_shaders_folder() {
        let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let linked = manifest.join("src/render/shaders").canonicalize().expect("src/render/shaders resolves");
        let top = manifest.join("../../shaders").canonicalize().expect("the top-level shaders/ folder");
        assert_eq!(linked, top);
        let sources: String =
            ["mod.rs", "composite.rs", "convolution.rs", "coverage.rs", "extract_gpu.rs", "forward.rs", "plateaus.rs"]
                .iter()
                .map(|f| std::fs::read_to_string(manifest.join("src/render").join(f)).expect("render source"))
                .collect();
        for entry in std::fs::read_dir(&top).expect("shaders/") {
            let name = entry.expect("entry").file_name().into_string().expect("utf-8 name");
            assert!(sources.contains(&format!("\"shaders/{name}\"")), "shaders/{name} is not embedded by the plugin");
        }
    }
}
