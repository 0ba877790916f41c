//! The fin methods' penumbra maps (`shaders/maps.wgsl`): per light frame,
//! the uploads (or the GPU extraction, `extraction.rs`), then each layer's
//! slab depth, inner and outer fin weights rasterised (eq. 1), only when
//! the frame changed; redrawn in part under moved casters. The maps are
//! sparse (`frame::map_tiles`): each redraw resets the page table, marks
//! the tiles its casters and fins write, allocates and clears those, then
//! draws; the tiles it wanted go back with the read-back.

use std::sync::Arc;

use bevy::{
    asset::load_embedded_asset,
    prelude::*,
    render::{
        diagnostic::RecordDiagnostics,
        render_asset::RenderAssets,
        render_resource::{
            binding_types::{
                storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_depth_2d, texture_storage_2d,
                uniform_buffer, uniform_buffer_sized,
            },
            *,
        },
        renderer::{RenderContext, RenderDevice, RenderQueue},
        view::ViewUniform,
    },
};

use crate::frame::{FinFrameData, FinFrames};

use crate::{
    render::{
        extraction,
        params::{FinParams, WORKGROUP, params_of},
        view::{gbuffer_entry, queue_compute, workgroups},
    },
    settings::{FinIncrementalExtraction, FinPartialRedraw},
};

#[derive(Resource)]
pub(crate) struct FinPipelines {
    pub(crate) maps_layout: BindGroupLayoutDescriptor,
    pub(crate) view_layout: BindGroupLayoutDescriptor,
    pub(crate) reset_tiles: CachedComputePipelineId,
    pub(crate) mark_casters: CachedComputePipelineId,
    pub(crate) mark_fins: CachedComputePipelineId,
    pub(crate) allocate_tiles: CachedComputePipelineId,
    pub(crate) clear: CachedComputePipelineId,
    pub(crate) casters: CachedComputePipelineId,
    pub(crate) fins: CachedComputePipelineId,
    pub(crate) fin_depths: CachedComputePipelineId,
    pub(crate) visibility: CachedComputePipelineId,
    pub(crate) extract: extraction::ExtractPipelines,
}

pub(crate) fn init_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    asset_server: Res<AssetServer>,
) {
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
        reset_tiles: compute("fin_reset_tiles", &maps_layout, &maps_shader, "reset_tiles"),
        mark_casters: compute("fin_mark_casters", &maps_layout, &maps_shader, "mark_casters"),
        mark_fins: compute("fin_mark_fins", &maps_layout, &maps_shader, "mark_fins"),
        allocate_tiles: compute("fin_allocate_tiles", &maps_layout, &maps_shader, "allocate_tiles"),
        clear: compute("fin_clear_maps", &maps_layout, &maps_shader, "clear_maps"),
        casters: compute("fin_raster_casters", &maps_layout, &maps_shader, "raster_casters"),
        fins: compute("fin_raster_fins", &maps_layout, &maps_shader, "raster_fins"),
        fin_depths: compute("fin_raster_fin_depths", &maps_layout, &maps_shader, "raster_fin_depths"),
        visibility: compute("fin_visibility", &view_layout, &visibility_shader, "visibility_pass"),
        extract: extraction::ExtractPipelines::queue(&pipeline_cache, &asset_server),
        maps_layout,
        view_layout,
    });
}

/// Every fin-shadowed frame's GPU maps (fin methods; the coverage method's
/// are in `coverage.rs`), by main-world light entity and cube face.
#[derive(Resource, Default)]
pub(crate) struct FinLightsGpu(pub(crate) std::collections::HashMap<crate::frame::FrameKey, FinMapsGpu>);

/// GPU copies of one light's fin frame and its maps.
#[derive(Default)]
pub(crate) struct FinMapsGpu {
    pub(crate) generation: u64,
    /// The maps must be (re)rendered: new content, or pipelines were not ready.
    pub(crate) dirty: bool,
    pub(crate) params: Option<Buffer>,
    pub(crate) maps: Option<Buffer>,
    pub(crate) casters: Option<Buffer>,
    pub(crate) fins: Option<Buffer>,
    pub(crate) cutouts: Option<Buffer>,
    pub(crate) mask_words: Option<Buffer>,
    /// The GPU extraction's mask words in `mask_words` (none after the CPU
    /// path wrote there): a moved caster does not upload them again.
    pub(crate) uploaded_masks: Option<Arc<Vec<u32>>>,
    /// The read-back slot its counts were last copied into.
    pub(crate) stats_slot: Option<usize>,
    pub(crate) bind_group: Option<BindGroup>,
    /// Casters and fins the CPU extraction uploaded.
    pub(crate) counts: (u32, u32),
    /// The layout the maps buffer holds: a partial redraw keeps its
    /// contents only under the same one.
    pub(crate) shape: crate::frame::map_tiles::MapShape,
    /// How many times the map passes have drawn these maps (what the
    /// convolution method's basis was built from, `convolution.rs`).
    pub(crate) renders: u64,
    pub(crate) mode: MapsSource,
    pub(crate) extraction: extraction::ExtractBuffers,
}

/// Where this frame's casters and fins come from.
#[derive(Default, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MapsSource {
    /// Uploaded from the CPU extraction; dispatch sizes known here.
    #[default]
    Cpu,
    /// Written by the GPU extraction; dispatched indirectly.
    Gpu,
    /// No caster at all: no extraction, no map pass (zero layers).
    Nothing,
}

/// Uploads each light's changed fin frame; buffers grow on demand and are
/// reused otherwise. Lights gone (or now on the coverage method) free theirs.
pub(crate) fn prepare_maps(
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
pub(crate) struct UpdateScope {
    pub partial_redraw: bool,
    pub incremental_extraction: bool,
}

/// One light's maps: uploaded when its frame changed.
pub(crate) fn prepare_light_maps(
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
    let (shape, resolution) = (f.map_shape(), f.region.resolution);
    let maps_size = f.map_bytes().max(16);
    if maps_size > device.limits().max_storage_buffer_binding_size {
        warn_once!("fin shadows: {maps_size}-byte maps exceed this GPU's storage binding limit; no fin shadows");
        gpu.bind_group = None;
        return;
    }
    let storage = BufferUsages::STORAGE | BufferUsages::COPY_DST;
    use extraction::ensure;
    let cap = f.limit_bytes;
    let params_bytes = size_of::<FinParams>() as u64;
    ensure(&mut gpu.params, device, "fin_params", params_bytes, BufferUsages::UNIFORM | BufferUsages::COPY_DST, cap);
    // The maps grow to their budget at most (their size is already within it).
    let old_maps = gpu.maps.as_ref().map(|b| b.id());
    ensure(&mut gpu.maps, device, "fin_maps", maps_size, storage | BufferUsages::COPY_SRC, cap.min(f.map_limit_bytes));
    // New maps hold nothing a partial redraw could keep.
    let maps_kept = scope.partial_redraw && old_maps == gpu.maps.as_ref().map(|b| b.id()) && gpu.shape == shape;
    gpu.shape = shape;
    let (caster_bytes, fin_bytes) = match &f.gpu {
        Some(scene) => (
            scene.capacity.casters as u64 * extraction::CASTER_BYTES,
            scene.capacity.fins as u64 * extraction::FIN_BYTES,
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
            // The extraction writes every params word but the maps' shape.
            let tiles_at = crate::render::params::GPU_WRITTEN_BYTES;
            queue.write_buffer(gpu.params.as_ref().unwrap(), tiles_at, bytemuck::bytes_of(&params.tiles));
            let FinMapsGpu { extraction, fins, casters, .. } = gpu;
            extraction::prepare(
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
    gpu.counts = (f.casters.len() as u32, f.fins.len() as u32);
    gpu.generation = f.generation;
    gpu.dirty = true;
}

/// Per light whose frame changed: extracts fins on the GPU when that is the
/// source, then renders every layer's maps: clear, casters (slab depths),
/// fins (keys). The extraction's counts go to the light's read-back slot.
pub(crate) fn render_maps(
    frames: Res<FinFrames>,
    mut lights: ResMut<FinLightsGpu>,
    pipelines: Option<Res<FinPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    stats_handle: Option<Res<extraction::FinStatsBuffer>>,
    shader_buffers: Res<RenderAssets<bevy::render::storage::GpuShaderBuffer>>,
    mut ctx: RenderContext,
) {
    let Some(pipelines) = pipelines else { return };
    for (slot, frame) in frames.0.iter().enumerate() {
        let Some(gpu) = lights.0.get_mut(&frame.key()) else { continue };
        let stats = extraction::stats_buffer(stats_handle.as_deref(), &shader_buffers)
            .map(|b| (b, extraction::stats_offset(slot)));
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
            extraction::copy_stats(control, stats, offset, ctx.command_encoder());
            if let Some(maps) = gpu.maps.as_ref() {
                extraction::copy_tile_count(maps, stats, offset, ctx.command_encoder());
            }
            gpu.stats_slot = Some(slot);
        }
    }
}

/// One light's extraction and map passes, when its maps are dirty.
pub(crate) fn render_light_maps(
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
    let get = |id| pipeline_cache.get_compute_pipeline(id);
    let (Some(reset), Some(mark_casters), Some(mark_fins), Some(allocate)) = (
        get(pipelines.reset_tiles),
        get(pipelines.mark_casters),
        get(pipelines.mark_fins),
        get(pipelines.allocate_tiles),
    ) else {
        return;
    };
    let (Some(casters), Some(fins), Some(fin_depths)) =
        (get(pipelines.casters), get(pipelines.fins), get(pipelines.fin_depths))
    else {
        return;
    };
    let (n_casters, n_fins) = gpu.counts;
    let page_words = gpu.shape.page_words();
    // The page table's passes, one thread per word (and thread 0 at least,
    // which resets the header).
    let pages = workgroups((page_words as u32).max(1).div_ceil(WORKGROUP));
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
            // Only a partial redraw clears (the tiles it kept).
            let Some(clear) = get(pipelines.clear) else { return };
            let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/extraction");
            let recorded = extraction::record(
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
                pass.set_pipeline(reset);
                pass.dispatch_workgroups(pages.0, pages.1, 1);
                for (pipeline, args) in
                    [(mark_casters, extraction::C_ARGS_CASTERS), (mark_fins, extraction::C_ARGS_FINS)]
                {
                    pass.set_pipeline(pipeline);
                    pass.dispatch_workgroups_indirect(&control, args * 4);
                }
                pass.set_pipeline(allocate);
                pass.dispatch_workgroups(pages.0, pages.1, 1);
                for (pipeline, args) in [
                    (clear, extraction::C_ARGS_CLEAR),
                    (casters, extraction::C_ARGS_CASTERS),
                    (fins, extraction::C_ARGS_FINS),
                    (fin_depths, extraction::C_ARGS_FINS),
                ] {
                    pass.set_pipeline(pipeline);
                    pass.dispatch_workgroups_indirect(&control, args * 4);
                }
            }
            // The tiles the maps wanted go back with the extraction's counts,
            // and to the extraction's next plan.
            if let Some(maps) = gpu.maps.as_ref() {
                extraction::copy_tile_header(&gpu.extraction, maps, ctx.command_encoder());
                if let Some((stats, offset)) = stats {
                    extraction::copy_tile_count(maps, stats, offset, ctx.command_encoder());
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
        // Always a full redraw: no clear (`allocate_tiles` clears each new tile).
        pass.set_pipeline(reset);
        pass.dispatch_workgroups(pages.0, pages.1, 1);
        let (caster_groups, fin_groups) = (workgroups(n_casters), workgroups(n_fins));
        if n_casters > 0 {
            pass.set_pipeline(mark_casters);
            pass.dispatch_workgroups(caster_groups.0, caster_groups.1, 1);
        }
        if n_fins > 0 {
            pass.set_pipeline(mark_fins);
            pass.dispatch_workgroups(fin_groups.0, fin_groups.1, 1);
        }
        pass.set_pipeline(allocate);
        pass.dispatch_workgroups(pages.0, pages.1, 1);
        if n_casters > 0 {
            pass.set_pipeline(casters);
            pass.dispatch_workgroups(caster_groups.0, caster_groups.1, 1);
        }
        if n_fins > 0 {
            // Keys first, then the exact depths of the winners (a second
            // dispatch, so that it compares against final keys).
            for pipeline in [fins, fin_depths] {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(fin_groups.0, fin_groups.1, 1);
            }
        }
    }
    span.end(ctx.command_encoder());
    gpu.dirty = false;
    gpu.renders += 1;
}
