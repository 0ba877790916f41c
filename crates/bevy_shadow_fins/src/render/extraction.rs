//! Render world side of GPU fin extraction and layer assignment: the buffers
//! and compute passes of `extract_*.wgsl`, run before the penumbra-map passes
//! whenever the fin frame changed, and the read-back of their counts.

use std::sync::Arc;

use bevy::{
    asset::{embedded_asset, load_embedded_asset},
    prelude::*,
    render::{
        extract_resource::{ExtractResource, ExtractResourcePlugin},
        gpu_readback::{Readback, ReadbackComplete},
        render_asset::RenderAssets,
        render_resource::{
            binding_types::{storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized},
            *,
        },
        renderer::{RenderDevice, RenderQueue},
        storage::{GpuShaderBuffer, ShaderBuffer},
    },
};

use crate::{
    budget::{FinDegradation, FinDegradations},
    casters::gpu_scene::{GpuCapacity, GpuInstance, GpuScene},
    frame::{FinFrameData, FinFrames, MAX_FIN_FRAMES, map_tiles::TileDemand, update::MeshCache},
    settings::FinMethod,
    stats::{FinFrameStats, FinLightStats},
};
use shadow_fins::light::Aperture;

/// `control` buffer layout (u32 words), as in `extract_common.wgsl`.
pub(super) const C_PARAMS: u64 = 16;
/// The maps' `FinParams` the extraction writes, bytes.
const PARAMS_BYTES: u64 = crate::render::params::GPU_WRITTEN_BYTES;
pub(super) const C_ARGS_CLEAR: u64 = 56;
pub(super) const C_ARGS_CASTERS: u64 = 59;
pub(super) const C_ARGS_FINS: u64 = 62;
pub(super) const C_ARGS_SILHOUETTES: u64 = 65;
pub(super) const C_ARGS_FIN_THREADS: u64 = 68;
pub(super) const C_ARGS_CASTER_THREADS: u64 = 71;
/// Stages 1–9's dispatch sizes (vertices, faces, edges, instances), and
/// `retire_moved`'s.
pub(super) const C_ARGS_ITEMS: u64 = 112;
pub(super) const C_ARGS_RETIRE: u64 = 124;
pub(super) const C_HISTOGRAM: u64 = 128;
/// Stats words: whether the last update redrew the maps in part (bit 0) and
/// extracted the moved instances only (bit 1), and the texels it cleared
/// and drew again.
pub(super) const C_PARTIAL: usize = 13;
pub(super) const C_REDRAWN: usize = 14;
/// After the histogram, what a partial redraw keeps between frames
/// (`history` in `extract_common.wgsl`, words relative to its start): the dirty
/// list's length (or [`FULL`]), then `INSTANCE_WORDS` per instance (its
/// footprint, deepest vertex, silhouette depths), then `DIRTY_WORDS` per
/// dirty instance, then the redraw lists.
pub(super) const H_DIRTY_COUNT: u64 = 64;
/// 1: the GPU may extract the moved instances alone ([`FinIncrementalExtraction`](crate::settings::FinIncrementalExtraction)).
pub(super) const H_INCREMENTAL: u64 = 66;
/// The maps' header after their last redraw (`H_TILES` in `extract_common.wgsl`).
pub(super) const H_TILES: u64 = 92;
/// Header words copied: tiles wanted, before, pool (`maps.wgsl`).
const TILE_HEADER_WORDS: u64 = 3;
pub(super) const H_INSTANCES: u64 = 96;
pub(super) const INSTANCE_WORDS: u64 = 8;
pub(super) const DIRTY_WORDS: u64 = 4;
/// Redraw the maps whole.
pub(super) const FULL: u32 = u32::MAX;
/// The most moved instances a partial redraw takes; past it the maps are
/// redrawn whole (many moved: their footprints would cover much of the maps).
const MAX_REDRAWN_INSTANCES: usize = 256;
/// Words 0..16 of `control` go back to the main world: counts, generation, layers.
const STATS_WORDS: u64 = 16;
pub(super) const FACE_WORDS: u64 = crate::gpu_layout::FACE_STATE_WORDS;
pub(super) const VERTEX_WORDS: u64 = crate::gpu_layout::VERTEX_STATE_WORDS;
pub(super) use crate::gpu_layout::WORKGROUP;

use crate::gpu_layout::CUTOUT_BYTES;
use crate::gpu_layout::SILHOUETTE_BYTES;
pub(super) use crate::gpu_layout::{CASTER_BYTES, FIN_BYTES};

/// The most workgroups a posing pass dispatches per job (its threads stride).
const MAX_POSE_GROUPS: u32 = 1024;

/// One compute pipeline per entry point, each a field named after its entry
/// point, grouped by the shader that holds them: `$ids` holds the queued ids
/// (`queue` takes one handle per shader, by the group's name), `$ready` the
/// compiled pipelines once every one of them is. A misspelt pass is a
/// compile error here or a pipeline error naming it, not a wrong index.
macro_rules! pipeline_set {
    (
        $(#[$doc:meta])* $ids:ident, $ready:ident, $label:literal
        { $($shader:ident: [$($entry:ident),* $(,)?]),* $(,)? }
    ) => {
        $(#[$doc])*
        struct $ids {
            $($($entry: CachedComputePipelineId,)*)*
        }

        #[doc = concat!("The compiled pipelines of [`", stringify!($ids), "`].")]
        struct $ready<'a> {
            $($($entry: &'a ComputePipeline,)*)*
        }

        impl $ids {
            fn queue(
                cache: &PipelineCache,
                layout: &BindGroupLayoutDescriptor,
                $($shader: &Handle<Shader>,)*
            ) -> Self {
                Self {
                    $($($entry: crate::render::view::queue_compute(
                        cache,
                        concat!($label, stringify!($entry)),
                        layout,
                        $shader,
                        stringify!($entry),
                    ),)*)*
                }
            }

            fn ready<'a>(&self, cache: &'a PipelineCache) -> Option<$ready<'a>> {
                Some($ready { $($($entry: cache.get_compute_pipeline(self.$entry)?,)*)* })
            }
        }
    };
}

pipeline_set! {
    /// The extraction's passes, by the shader that holds them (stages 0 and
    /// 10–12 `extract_plan.wgsl`, 1–6 `extract_silhouettes.wgsl`, 7–9
    /// `extract_fins.wgsl`); [`record`] says in which order they run.
    ExtractionPasses, ReadyExtractionPasses, "fin_extract_" {
        plan: [
            reset,
            begin,
            forget_footprints,
            reduce_instances,
            decide,
            retire_moved,
            reduce_footprints,
            reset_footprints,
            plan_layers,
            assign_fin_layers,
            assign_caster_layers,
            gather_redraw_fins,
            gather_redraw_casters,
            redraw_args,
        ],
        silhouettes: [
            transform_vertices,
            classify_faces,
            join_patches,
            flatten_patches,
            find_silhouettes,
            silhouette_args,
        ],
        fins: [
            silhouette_vertices,
            silhouette_quads,
            map_casters,
        ],
    }
}

pipeline_set! {
    /// The posing passes (`pose.wgsl`), in the order they run.
    PosingPasses, ReadyPosingPasses, "fin_extract_" {
        pose: [pose_vertices, pose_faces, pose_outline, pose_normals, pose_creases],
    }
}

pub(super) fn build(app: &mut App) {
    bevy::shader::load_shader_library!(app, "shaders/extract_common.wgsl");
    embedded_asset!(app, "shaders/extract_plan.wgsl");
    embedded_asset!(app, "shaders/extract_silhouettes.wgsl");
    embedded_asset!(app, "shaders/extract_fins.wgsl");
    embedded_asset!(app, "shaders/pose.wgsl");
    app.add_plugins(ExtractResourcePlugin::<FinStatsBuffer>::default())
        .add_systems(Startup, spawn_stats_readback)
        .add_systems(PostUpdate, read_back_while_waiting.after(crate::frame::update::FinFramesUpdate));
}

/// Marks the entity whose `Readback` brings the extraction's counts back.
#[derive(Component)]
struct StatsReadback;

/// The small buffer the extraction's counts are copied into, one slot of
/// `STATS_WORDS` per frame (in [`FinFrames`] order), read back every frame
/// into each light's [`FinLightStats`] (a point light's faces combined).
#[derive(Resource, Clone, ExtractResource)]
pub(crate) struct FinStatsBuffer(Handle<ShaderBuffer>);

/// Words per frame slot of the stats buffer: the extraction's counts, then
/// the tiles its maps wanted (`maps.wgsl`'s header, `map_tiles`).
const SLOT_WORDS: u64 = STATS_WORDS + 1;
const SLOT_TILES: usize = STATS_WORDS as usize;

/// Byte offset of frame slot `slot` in the stats buffer.
pub(super) fn stats_offset(slot: usize) -> u64 {
    slot as u64 * SLOT_WORDS * 4
}

fn spawn_stats_readback(mut commands: Commands, mut buffers: ResMut<Assets<ShaderBuffer>>) {
    let bytes = vec![0u8; stats_offset(MAX_FIN_FRAMES) as usize];
    let handle = buffers.add(ShaderBuffer::new(&bytes, bevy::asset::RenderAssetUsages::RENDER_WORLD));
    commands.insert_resource(FinStatsBuffer(handle.clone()));
    commands
        .spawn((Name::new("fin shadow stats read-back"), StatsReadback, Readback::buffer(handle)))
        .observe(on_stats_readback);
}

/// The counts are read back only while some light's GPU frame waits for
/// them (a new frame, or one redone after a buffer grew): when nothing moved,
/// no read-back runs (issue 16, item 3). A frame built this update is
/// extracted with it, and its counts copied before the read-back's copy.
fn read_back_while_waiting(
    mut commands: Commands,
    frames: Res<FinFrames>,
    cache: Res<MeshCache>,
    stats: Option<Res<FinStatsBuffer>>,
    readback: Query<(Entity, Has<Readback>), With<StatsReadback>>,
) {
    let (Some(stats), Ok((entity, reading))) = (stats, readback.single()) else { return };
    let waiting = frames.0.iter().any(|f| cache.lights.get(&f.key()).is_some_and(|s| !s.stats.up_to_date));
    match (waiting, reading) {
        (true, false) => {
            commands.entity(entity).insert(Readback::buffer(stats.0.clone()));
        }
        (false, true) => {
            commands.entity(entity).remove::<Readback>();
        }
        _ => {}
    }
}

/// Counts of the latest GPU extraction of every light: stats for the main
/// world, and the buffers grown (and the frame redone) when it wanted more
/// than they hold.
fn on_stats_readback(
    readback: On<ReadbackComplete>,
    frames: Res<FinFrames>,
    mut cache: ResMut<MeshCache>,
    mut light_stats: Query<&mut FinLightStats>,
) {
    let words: Vec<u32> = readback.data.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    let mut any = false;
    for (slot, frame) in frames.0.iter().enumerate() {
        let at = slot * SLOT_WORDS as usize;
        let Some(w) = words.get(at..at + SLOT_WORDS as usize) else { continue };
        let Some(state) = cache.lights.get_mut(&frame.key()) else { continue };
        if let Some(now) = stats_of_readback(&frame.data, w, state) {
            any |= state.stats != now;
            state.stats = now;
        }
    }
    if any {
        crate::frame::update::publish_light_stats(&frames.0, &cache, &mut light_stats);
    }
}

/// One frame's counts from its read-back slot `w`, or `None` when the slot
/// belongs to another frame (an older one, another light's, or none yet).
fn stats_of_readback(
    f: &FinFrameData,
    w: &[u32],
    state: &mut crate::frame::build::LightState,
) -> Option<FinFrameStats> {
    let gpu = f.gpu.as_ref()?;
    // Generations are unique over all lights' frames: a slot that another
    // light used last frame cannot pass for this one's.
    if gpu.totals[1] == 0 {
        return None;
    }
    if w[11] != f.generation as u32 {
        // An earlier frame of this light's (while anything moves, every
        // update makes a new frame and the read-back, a frame or more
        // behind, never matches the newest): its tiles still size the pool.
        if let Some(shape) = state.recent_shape(w[11]) {
            size_tile_pool(state, TileDemand { resolution: shape.resolution, tiles: w[SLOT_TILES] }, shape);
        }
        return None;
    }
    let wanted = GpuCapacity { silhouettes: w[0], fins: w[1], casters: w[2], layers: w[10] };
    // Grown when the frame overflowed, shrunk when the scene got smaller
    // (never below the first guess a build takes anyway).
    let floor = GpuCapacity::initial(gpu.totals[1], gpu.totals[2]);
    let grown = gpu.capacity.resized_for(wanted, floor, gpu.max_capacity);
    if let Some(next) = grown {
        state.capacity = Some(next);
        state.capacity_epoch += 1;
    }
    // Past the limit the GPU kept what fit and dropped the rest: say so.
    let layers_cut = (wanted.layers > gpu.max_capacity.layers).then_some(FinDegradation::Maps {
        resolution: f.region.resolution,
        wanted_resolution: f.settings.map_resolution,
        layers: gpu.max_capacity.layers,
        wanted_layers: wanted.layers,
        limit_bytes: f.map_limit_bytes,
    });
    let shortfall =
        FinDegradations::from(gpu.capacity.shortfalls(wanted).next().map(|(buffer, kept, wanted)| {
            FinDegradation::Capacity { buffer, kept, wanted, limit_bytes: f.limit_bytes }
        }))
        .with(layers_cut);
    // The sparse maps: the tiles this redraw wanted, past the pool's end
    // too (those were dropped: the next frame is sized for them).
    let tiles = TileDemand { resolution: f.region.resolution, tiles: w[SLOT_TILES] };
    let pool = f.map_tiles;
    let (overflowed, rebuild) = size_tile_pool(state, tiles, f.map_shape());
    let shortfall = shortfall.with(overflowed.then_some(FinDegradation::Capacity {
        buffer: "penumbra map tiles",
        kept: pool,
        wanted: tiles.tiles,
        limit_bytes: f.map_limit_bytes,
    }));
    // A frame sized anew follows: this one is not what the light will show.
    let grown = grown.or(rebuild.then_some(gpu.capacity));
    if grown.is_none() {
        state.shortfall = shortfall;
    }
    let now = FinFrameStats {
        silhouettes: w[0].min(gpu.capacity.silhouettes) as usize,
        fins: w[1].min(gpu.capacity.fins) as usize,
        layers: w[12] as usize,
        redrawn_texels: w[C_REDRAWN] as u64,
        partial_redraw: w[C_PARTIAL] & 1 != 0,
        incremental_extraction: w[C_PARTIAL] & 2 != 0,
        up_to_date: grown.is_none(),
        degraded: if grown.is_none() { shortfall.and(f.stats.degraded) } else { f.stats.degraded },
        ..f.stats
    };
    crate::stats::warn_degradation(&mut state.warned, now.degraded);
    Some(now)
}

/// The sparse maps' pool after a redraw of `shape` wanted `tiles`: grown
/// when they did not fit, shrunk when they would fit in half; else it keeps
/// its size, so that the next frame may redraw in part. Returns (the tiles
/// overflowed, a frame sized anew follows).
fn size_tile_pool(
    state: &mut crate::frame::build::LightState,
    tiles: TileDemand,
    shape: crate::frame::map_tiles::MapShape,
) -> (bool, bool) {
    let overflowed = tiles.tiles > shape.tiles;
    let roomy = TileDemand::tiles_at(Some(tiles), tiles.resolution, shape.layers);
    let resize = overflowed || roomy < shape.tiles as u64 / 2;
    let rebuild = resize && state.tile_demand != Some(tiles);
    if rebuild {
        state.tile_demand = Some(tiles);
        state.capacity_epoch += 1;
    }
    (overflowed, rebuild)
}

/// `ExtractParams` in `extract_common.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct ExtractParams {
    pub(crate) totals: [u32; 4],
    pub(crate) layering: [u32; 4],
    pub(crate) capacity: [u32; 4],
    pub(crate) light: [f32; 4],
    pub(crate) flags: [u32; 4],
    pub(crate) origin: [f32; 4],
    pub(crate) axis_u: [f32; 4],
    pub(crate) axis_v: [f32; 4],
    pub(crate) axis_n: [f32; 4],
    /// The maps' region lies within (min x, min y, max x, max y); none when min > max.
    pub(crate) window: [f32; 4],
    /// The light's support function: (rectangle half extents a, b in the
    /// unit bounding circle, 1, 0), a disk's (1, 1, 0, 0), a point light's
    /// cube face (1/stretch, window, 2, 0).
    pub(crate) aperture: [f32; 4],
}

pub(super) struct ExtractPipelines {
    layout: BindGroupLayoutDescriptor,
    passes: ExtractionPasses,
    pose_layout: BindGroupLayoutDescriptor,
    posing: PosingPasses,
}

impl ExtractPipelines {
    pub(super) fn queue(pipeline_cache: &PipelineCache, asset_server: &AssetServer) -> Self {
        let layout = BindGroupLayoutDescriptor::new(
            "fin_extract_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    uniform_buffer_sized(false, None),
                    storage_buffer_read_only_sized(false, None),
                    storage_buffer_read_only_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                ),
            ),
        );
        let pose_layout = BindGroupLayoutDescriptor::new(
            "fin_pose_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (storage_buffer_read_only_sized(false, None), storage_buffer_sized(false, None)),
            ),
        );
        let passes = ExtractionPasses::queue(
            pipeline_cache,
            &layout,
            &load_embedded_asset!(asset_server, "shaders/extract_plan.wgsl"),
            &load_embedded_asset!(asset_server, "shaders/extract_silhouettes.wgsl"),
            &load_embedded_asset!(asset_server, "shaders/extract_fins.wgsl"),
        );
        let posing =
            PosingPasses::queue(pipeline_cache, &pose_layout, &load_embedded_asset!(asset_server, "shaders/pose.wgsl"));
        Self { layout, passes, pose_layout, posing }
    }
}

/// GPU copies of the extraction's inputs and its work buffers.
#[derive(Default)]
pub(super) struct ExtractBuffers {
    params: Option<Buffer>,
    instances: Option<Buffer>,
    /// What `instances` holds (a copy, to write only the records that differ).
    uploaded_instances: Vec<u8>,
    geometry: Option<Buffer>,
    geometry_key: u64,
    control: Option<Buffer>,
    /// Where `history` starts in `control`, words.
    history: u64,
    /// Indirect dispatch arguments, copied out of `control` between passes.
    pub(super) indirect: Option<Buffer>,
    state: Option<Buffer>,
    /// The cut-outs of the casters the extraction writes (`CasterCutout`,
    /// one per caster record, at its index), which the maps read: as large
    /// as the casters' buffer allows when an instance is alpha-masked, a
    /// stand-in otherwise.
    cutouts: Option<Buffer>,
    silhouettes: Option<Buffer>,
    bind_group: Option<BindGroup>,
    /// What poses the posed instances' geometry copies (`pose.wgsl`), as
    /// uploaded (its first words: the posing passes' sizes).
    poses: Option<Buffer>,
    uploaded_poses: Option<Arc<Vec<u32>>>,
    pose_bind_group: Option<BindGroup>,
    /// The posing passes must run before the next extraction (new poses,
    /// or the geometry went up at rest).
    pose_pending: bool,
    /// Instances whose records changed this frame: how many (`FULL` when
    /// the maps must be redrawn whole), the dispatch of `forget_footprints`.
    dirty: u32,
    /// The last parameters uploaded, generation zeroed: a partial redraw
    /// needs the same light, settings and capacities.
    last_params: Option<ExtractParams>,
    /// The last map update was this extraction's, recorded (else its dirty
    /// list never reached the GPU, or another path drew the maps since, and
    /// the next update must redraw whole).
    recorded: bool,
    /// The buffers last frame's extraction left its records in (control,
    /// state, cut-outs, silhouettes, fins, casters): an update may extract
    /// the moved instances only while they are all still there.
    work_buffers: [Option<BufferId>; 6],
}

/// Allocates `buf` (half again as large, so a growing scene does not reallocate
/// every frame, but never past `cap` nor the device's binding limit) when it
/// is missing, smaller than `size`, or larger than `cap` allows. The main
/// world keeps `size` within both (`budget.rs`).
pub(super) fn ensure(
    buf: &mut Option<Buffer>,
    device: &RenderDevice,
    label: &str,
    size: u64,
    usage: BufferUsages,
    cap: u64,
) {
    // Whole 16-byte steps: a binding must be a multiple of 4 bytes.
    let cap = (device.limits().max_storage_buffer_binding_size.min(cap) & !15).max(size);
    // Too small, or larger than a lowered budget allows: allocate anew.
    if buf.as_ref().is_none_or(|b| b.size() < size || b.size() > cap.max(64).next_multiple_of(16)) {
        *buf = Some(device.create_buffer(&BufferDescriptor {
            label: Some(label),
            size: (size + size / 2).min(cap).max(64).next_multiple_of(16).min(cap.max(64).next_multiple_of(16)),
            usage,
            mapped_at_creation: false,
        }));
    }
}

/// The byte ranges of `new` to write over a buffer holding `old`: runs of
/// whole `record`-sized records that differ, and everything past `old`.
fn changed_runs(old: &[u8], new: &[u8], record: usize) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for (k, chunk) in new.chunks(record).enumerate() {
        let at = k * record;
        if old.get(at..at + chunk.len()) == Some(chunk) {
            continue;
        }
        match runs.last_mut() {
            Some(run) if run.end == at => run.end = at + chunk.len(),
            _ => runs.push(at..at + chunk.len()),
        }
    }
    runs
}

/// Uploads what changed (the instance records that differ, geometry when its key changed) and
/// binds the work buffers; `fins` and `casters` are the maps' input buffers.
/// `maps_kept`: the maps buffer still holds the last update's maps and
/// [`FinPartialRedraw`](crate::settings::FinPartialRedraw) is on (a partial redraw may
/// keep them; see the top of `extract_common.wgsl`); `incremental`: the GPU may then
/// extract the moved instances alone ([`FinIncrementalExtraction`](crate::settings::FinIncrementalExtraction)).
#[allow(clippy::too_many_arguments)]
pub(super) fn prepare(
    buffers: &mut ExtractBuffers,
    frame: &FinFrameData,
    scene: &GpuScene,
    resolution: u32,
    fins: &Buffer,
    casters: &Buffer,
    maps_kept: bool,
    incremental: bool,
    pipelines: &ExtractPipelines,
    pipeline_cache: &PipelineCache,
    device: &RenderDevice,
    queue: &RenderQueue,
) {
    let s = frame.settings;
    let storage = BufferUsages::STORAGE | BufferUsages::COPY_DST;
    let [vertices, faces, edges] = scene.totals;
    let method = match s.method {
        // Convolution filters the hard shadow map; plateaus widen it.
        FinMethod::Hard | FinMethod::Convolution | FinMethod::Plateaus => 0,
        FinMethod::OuterFins => 1,
        FinMethod::SingleLayer => 2,
        FinMethod::MultiLayer => 3,
        // The coverage method never runs the fin extraction.
        FinMethod::Coverage => 0,
    };
    let layers = if s.method == FinMethod::MultiLayer { s.layers } else { 1 };
    let v4 = |v: bevy::math::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
    let super_params = crate::render::params::params_of(frame);
    let params = ExtractParams {
        totals: [scene.instances.len() as u32, vertices, faces, edges],
        layering: [s.sub_layers, layers, scene.capacity.layers, resolution],
        capacity: [scene.capacity.silhouettes, scene.capacity.fins, scene.capacity.casters, method],
        // w: 0 perspective, 1 orthographic, 2 orthographic with L0 = z fixed (a sun fitted to the views).
        light: [
            frame.size,
            scene.extent,
            scene.receiver_depth,
            frame.orthographic as u32 as f32 + scene.fixed_reference_depth as u32 as f32,
        ],
        flags: [super_params.flags[0], super_params.flags[1], super_params.flags[2], frame.generation as u32],
        origin: v4(frame.origin),
        axis_u: v4(scene.axes[0]),
        axis_v: v4(scene.axes[1]),
        axis_n: v4(scene.axes[2]),
        window: scene.map_window.map_or([1.0, 1.0, -1.0, -1.0], |(lo, hi)| [lo.x, lo.y, hi.x, hi.y]),
        aperture: match frame.aperture {
            Aperture::Disk => [1.0, 1.0, 0.0, 0.0],
            Aperture::Rect { half_extents } => [half_extents.x, half_extents.y, 1.0, 0.0],
            Aperture::Sphere { stretch, window } => [1.0 / stretch, window, 2.0, 0.0],
        },
    };
    let cap = frame.limit_bytes;
    let uniform = BufferUsages::UNIFORM | BufferUsages::COPY_DST;
    ensure(&mut buffers.params, device, "fin_extract_params", size_of::<ExtractParams>() as u64, uniform, cap);
    queue.write_buffer(buffers.params.as_ref().unwrap(), 0, bytemuck::bytes_of(&params));
    let instance_bytes: &[u8] = bytemuck::cast_slice(&scene.instances);
    let old_instances = buffers.instances.as_ref().map(|b| b.id());
    ensure(&mut buffers.instances, device, "fin_extract_instances", instance_bytes.len() as u64, storage, cap);
    // One caster of many moved: only its record goes up.
    // (A count that changed changes the parameters too: no partial redraw.)
    let kept = old_instances == buffers.instances.as_ref().map(|b| b.id());
    let old = if kept { buffers.uploaded_instances.as_slice() } else { &[] };
    let runs = changed_runs(old, instance_bytes, size_of::<GpuInstance>());
    for run in &runs {
        queue.write_buffer(buffers.instances.as_ref().unwrap(), run.start as u64, &instance_bytes[run.clone()]);
    }
    // The instances that moved, for a partial redraw of the maps.
    let record = size_of::<GpuInstance>();
    let moved: Vec<u32> = runs.iter().flat_map(|r| (r.start / record..r.end / record).map(|i| i as u32)).collect();
    let same_params = {
        let mut now = params;
        now.flags[3] = 0;
        let same = buffers.last_params == Some(now);
        buffers.last_params = Some(now);
        same
    };
    buffers.uploaded_instances.clear();
    buffers.uploaded_instances.extend_from_slice(instance_bytes);
    let geometry_bytes: &[u8] = bytemuck::cast_slice(scene.geometry.as_slice());
    let old_geometry = buffers.geometry.as_ref().map(|b| b.id());
    ensure(&mut buffers.geometry, device, "fin_extract_geometry", geometry_bytes.len() as u64, storage, cap);
    // Caster geometry goes up once per set of meshes; moving casters only change instances.
    let same_geometry =
        buffers.geometry_key == scene.geometry_key && old_geometry == buffers.geometry.as_ref().map(|b| b.id());
    if !same_geometry {
        queue.write_buffer(buffers.geometry.as_ref().unwrap(), 0, geometry_bytes);
        buffers.geometry_key = scene.geometry_key;
    }
    // The poses go up (whole: a few joints each) when they changed or the
    // geometry went up at rest; then, and only then, the posing passes pose
    // every posed copy again before the extraction (`record`). A new pose
    // changed its instance's record, so the maps are redrawn under it only.
    let jobs = scene.pose_sizes()[0];
    let new_poses = !buffers.uploaded_poses.as_ref().is_some_and(|p| Arc::ptr_eq(p, &scene.poses));
    if jobs == 0 {
        (buffers.pose_bind_group, buffers.pose_pending) = (None, false);
    } else if new_poses || !same_geometry || buffers.pose_bind_group.is_none() {
        let pose_bytes: &[u8] = bytemuck::cast_slice(scene.poses.as_slice());
        ensure(&mut buffers.poses, device, "fin_extract_poses", pose_bytes.len() as u64, storage, cap);
        queue.write_buffer(buffers.poses.as_ref().unwrap(), 0, pose_bytes);
        buffers.pose_bind_group = Some(device.create_bind_group(
            "fin_pose_bind_group",
            &pipeline_cache.get_bind_group_layout(&pipelines.pose_layout),
            &BindGroupEntries::sequential((
                buffers.poses.as_ref().unwrap().as_entire_binding(),
                buffers.geometry.as_ref().unwrap().as_entire_binding(),
            )),
        ));
        buffers.pose_pending = true;
    }
    buffers.uploaded_poses = Some(scene.poses.clone());
    let instances = scene.instances.len() as u64;
    let history = C_HISTOGRAM + s.sub_layers as u64;
    buffers.history = history;
    let dirty_list = history + H_INSTANCES + INSTANCE_WORDS * instances;
    // ... then the dirty list and the redraw lists (a count, then indices).
    let control_words = dirty_list
        + DIRTY_WORDS * MAX_REDRAWN_INSTANCES as u64
        + 2
        + scene.capacity.casters as u64
        + scene.capacity.fins as u64;
    ensure(
        &mut buffers.control,
        device,
        "fin_extract_control",
        control_words * 4,
        BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST,
        cap,
    );
    ensure(
        &mut buffers.indirect,
        device,
        "fin_extract_indirect",
        C_HISTOGRAM * 4,
        BufferUsages::INDIRECT | BufferUsages::COPY_DST,
        cap,
    );
    let state_words = faces as u64 * FACE_WORDS + edges as u64 + vertices as u64 * VERTEX_WORDS;
    ensure(&mut buffers.state, device, "fin_extract_state", state_words * 4, storage, cap);
    let cutout_bytes = match scene.mask_words.is_empty() {
        true => 0,
        false => scene.capacity.casters as u64 * CUTOUT_BYTES,
    };
    ensure(&mut buffers.cutouts, device, "fin_extract_cutouts", cutout_bytes.max(64), storage, cap);
    ensure(
        &mut buffers.silhouettes,
        device,
        "fin_extract_silhouettes",
        scene.capacity.silhouettes as u64 * SILHOUETTE_BYTES,
        storage,
        cap,
    );
    // Partial when the last update reached the GPU, the same maps, light,
    // settings, geometry, history and records are there, and few instances
    // moved. The GPU then extracts the moved instances only, if it can
    // (`extract_plan.wgsl`'s `decide`), from the dirty table: per moved instance
    // its index and where its vertices, faces and edges start among the
    // moved instances'.
    let id = |b: &Option<Buffer>| b.as_ref().map(|b| b.id());
    let work_buffers = [
        id(&buffers.control),
        id(&buffers.state),
        id(&buffers.cutouts),
        id(&buffers.silhouettes),
        Some(fins.id()),
        Some(casters.id()),
    ];
    let partial = buffers.recorded
        && maps_kept
        && kept
        && same_params
        && same_geometry
        && buffers.work_buffers == work_buffers
        && moved.len() <= MAX_REDRAWN_INSTANCES;
    buffers.work_buffers = work_buffers;
    buffers.dirty = if partial { moved.len() as u32 } else { FULL };
    let control = buffers.control.as_ref().unwrap();
    queue.write_buffer(control, (history + H_DIRTY_COUNT) * 4, bytemuck::bytes_of(&buffers.dirty));
    queue.write_buffer(control, (history + H_INCREMENTAL) * 4, bytemuck::bytes_of(&(incremental as u32)));
    if partial && !moved.is_empty() {
        let table = dirty_table(&moved, |k| scene.instances[k as usize].info());
        queue.write_buffer(control, dirty_list * 4, bytemuck::cast_slice(&table));
    }
    buffers.recorded = false;
    buffers.bind_group = Some(device.create_bind_group(
        "fin_extract_bind_group",
        &pipeline_cache.get_bind_group_layout(&pipelines.layout),
        &BindGroupEntries::sequential((
            buffers.params.as_ref().unwrap().as_entire_binding(),
            buffers.instances.as_ref().unwrap().as_entire_binding(),
            buffers.geometry.as_ref().unwrap().as_entire_binding(),
            buffers.control.as_ref().unwrap().as_entire_binding(),
            buffers.state.as_ref().unwrap().as_entire_binding(),
            buffers.cutouts.as_ref().unwrap().as_entire_binding(),
            buffers.silhouettes.as_ref().unwrap().as_entire_binding(),
            fins.as_entire_binding(),
            casters.as_entire_binding(),
        )),
    ));
}

/// The dirty table `extract_common.wgsl`'s `item_of` reads: per moved instance
/// (`DIRTY_WORDS`) its index, then where its vertices, faces and edges start
/// among the moved instances' (`info`: an instance's
/// [`GpuInstance::info`], whose words 1..4 count them).
fn dirty_table(moved: &[u32], info: impl Fn(u32) -> [u32; 4]) -> Vec<u32> {
    let mut first = [0u32; 3];
    (moved.iter())
        .flat_map(|&k| {
            let entry = [k, first[0], first[1], first[2]];
            for (at, n) in first.iter_mut().zip(&info(k)[1..]) {
                *at += n;
            }
            entry
        })
        .collect()
}

/// Records the extraction passes; then copies the maps' parameters into their
/// uniform and the counts into the read-back buffer. `false`: not ready yet.
pub(super) fn record(
    buffers: &mut ExtractBuffers,
    pipelines: &ExtractPipelines,
    pipeline_cache: &PipelineCache,
    maps_params: &Buffer,
    stats: Option<(&Buffer, u64)>,
    encoder: &mut CommandEncoder,
) -> bool {
    let (Some(ready), Some(bind_group), Some(control)) =
        (pipelines.passes.ready(pipeline_cache), buffers.bind_group.as_ref(), buffers.control.as_ref())
    else {
        return false;
    };
    let Some(args) = buffers.indirect.as_ref() else { return false };
    let threads = |n: u32| crate::render::view::workgroups(n.div_ceil(WORKGROUP));
    let instances = buffers.uploaded_instances.len() / size_of::<GpuInstance>();
    let dirty = if buffers.dirty == FULL { 0 } else { buffers.dirty };
    // Dispatch sizes known here: the scene's instances, the moved ones.
    fn direct(pass: &mut ComputePass, pipeline: &ComputePipeline, (x, y): (u32, u32)) {
        if x > 0 {
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
    // Sizes only the GPU knows (silhouettes, fins, casters), written into
    // `control` by `silhouette_args` / `plan_layers` / `redraw_args` and
    // copied to `indirect` (a buffer may not be indirect arguments and
    // writable storage in one dispatch).
    fn indirect(pass: &mut ComputePass, pipeline: &ComputePipeline, args: &Buffer, at: u64) {
        pass.set_pipeline(pipeline);
        pass.dispatch_workgroups_indirect(args, at * 4);
    }
    let begin = |encoder: &mut CommandEncoder, f: &mut dyn FnMut(&mut ComputePass)| {
        let mut pass = encoder
            .begin_compute_pass(&ComputePassDescriptor { label: Some("fin_extraction"), timestamp_writes: None });
        pass.set_bind_group(0, bind_group, &[]);
        f(&mut pass);
    };
    let copy_args = |encoder: &mut CommandEncoder, from: u64, to: u64| {
        encoder.copy_buffer_to_buffer(control, from * 4, args, from * 4, (to - from) * 4);
    };
    if let Some(pose_bind_group) = buffers.pose_bind_group.as_ref().filter(|_| buffers.pose_pending) {
        let Some(pose) = pipelines.posing.ready(pipeline_cache) else { return false };
        let [jobs, vertices, faces, edges] =
            crate::casters::gpu_scene::pose_sizes(buffers.uploaded_poses.as_deref().map_or(&[], |p| p.as_slice()));
        let mut pass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some("fin_posing"), timestamp_writes: None });
        pass.set_bind_group(0, pose_bind_group, &[]);
        // Jobs along y, past 65 535 along z too (`pose.wgsl`'s `job_of`).
        let (y, z) = crate::render::view::workgroups(jobs);
        let passes = [
            (pose.pose_vertices, vertices),
            (pose.pose_faces, faces),
            (pose.pose_outline, vertices),
            (pose.pose_normals, vertices),
            (pose.pose_creases, edges),
        ];
        for (pipeline, n) in passes {
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(n.div_ceil(WORKGROUP).clamp(1, MAX_POSE_GROUPS), y, z);
        }
    }
    // Stages 1–9 (`extract_silhouettes.wgsl`, `extract_fins.wgsl`, after `extract_plan.wgsl`'s `reset_footprints`), over the items `item_of` gives: the
    // moved instances' (the first time), or every instance's (the second).
    let stages_1_to_9 = |encoder: &mut CommandEncoder| {
        copy_args(encoder, C_ARGS_ITEMS, C_ARGS_ITEMS + 12);
        begin(encoder, &mut |pass| {
            indirect(pass, ready.reset_footprints, args, C_ARGS_ITEMS + 9);
            indirect(pass, ready.transform_vertices, args, C_ARGS_ITEMS);
            indirect(pass, ready.classify_faces, args, C_ARGS_ITEMS + 3);
            indirect(pass, ready.join_patches, args, C_ARGS_ITEMS + 6);
            indirect(pass, ready.flatten_patches, args, C_ARGS_ITEMS + 3);
            indirect(pass, ready.find_silhouettes, args, C_ARGS_ITEMS + 6);
            direct(pass, ready.silhouette_args, (1, 1));
        });
        copy_args(encoder, C_ARGS_SILHOUETTES, C_ARGS_SILHOUETTES + 3);
        begin(encoder, &mut |pass| {
            indirect(pass, ready.silhouette_vertices, args, C_ARGS_SILHOUETTES);
            indirect(pass, ready.silhouette_quads, args, C_ARGS_SILHOUETTES);
            indirect(pass, ready.map_casters, args, C_ARGS_ITEMS + 3);
        });
    };
    begin(encoder, &mut |pass| {
        direct(pass, ready.reset, threads(C_HISTOGRAM as u32));
        direct(pass, ready.begin, (1, 1));
        direct(pass, ready.forget_footprints, threads(dirty));
    });
    // The moved instances alone first — unless the CPU asked for a full
    // update (`begin` then chooses `STAGE_FULL`: that run would do nothing).
    let attempt = buffers.dirty != FULL;
    if attempt {
        stages_1_to_9(encoder);
    }
    begin(encoder, &mut |pass| {
        if attempt {
            direct(pass, ready.reduce_instances, threads(instances as u32));
        }
        direct(pass, ready.decide, (1, 1));
    });
    stages_1_to_9(encoder);
    copy_args(encoder, C_ARGS_RETIRE, C_ARGS_RETIRE + 3);
    begin(encoder, &mut |pass| {
        indirect(pass, ready.retire_moved, args, C_ARGS_RETIRE);
        direct(pass, ready.reduce_footprints, threads(instances as u32));
        direct(pass, ready.plan_layers, (1, 1));
    });
    copy_args(encoder, C_ARGS_FIN_THREADS, C_ARGS_CASTER_THREADS + 3);
    begin(encoder, &mut |pass| {
        indirect(pass, ready.assign_fin_layers, args, C_ARGS_FIN_THREADS);
        indirect(pass, ready.assign_caster_layers, args, C_ARGS_CASTER_THREADS);
        indirect(pass, ready.gather_redraw_fins, args, C_ARGS_FIN_THREADS);
        indirect(pass, ready.gather_redraw_casters, args, C_ARGS_CASTER_THREADS);
        direct(pass, ready.redraw_args, (1, 1));
    });
    // The maps' clear and raster arguments: a partial redraw's, or all.
    copy_args(encoder, C_ARGS_CLEAR, C_ARGS_FINS + 3);
    encoder.copy_buffer_to_buffer(control, C_PARAMS * 4, maps_params, 0, PARAMS_BYTES);
    if let Some((stats, offset)) = stats {
        copy_stats(control, stats, offset, encoder);
    }
    buffers.recorded = true;
    buffers.pose_pending = false;
    true
}

/// Copies the maps' header into the extraction's `history` after a redraw,
/// where its next plan reads how full the pool is (`tiles_to_spare`).
pub(super) fn copy_tile_header(buffers: &ExtractBuffers, maps: &Buffer, encoder: &mut CommandEncoder) {
    if let Some(control) = &buffers.control {
        encoder.copy_buffer_to_buffer(maps, 0, control, (buffers.history + H_TILES) * 4, TILE_HEADER_WORDS * 4);
    }
}

/// Copies the tiles a frame's maps wanted (their header's first word,
/// `maps.wgsl`) into its read-back slot, after the extraction's counts.
pub(super) fn copy_tile_count(maps: &Buffer, stats: &Buffer, offset: u64, encoder: &mut CommandEncoder) {
    encoder.copy_buffer_to_buffer(maps, 0, stats, offset + SLOT_TILES as u64 * 4, 4);
}

/// Copies the extraction's counts (`control`'s first words) into a frame's
/// read-back slot.
pub(super) fn copy_stats(control: &Buffer, stats: &Buffer, offset: u64, encoder: &mut CommandEncoder) {
    encoder.copy_buffer_to_buffer(control, 0, stats, offset, STATS_WORDS * 4);
}

impl ExtractBuffers {
    /// The extraction's `control` buffer (the maps passes read a partial
    /// redraw's lists from it).
    pub(super) fn control(&self) -> Option<&Buffer> {
        self.control.as_ref()
    }

    /// The cut-outs the extraction writes beside its casters (the maps' `cutouts`).
    pub(super) fn cutouts(&self) -> Option<&Buffer> {
        self.cutouts.as_ref()
    }

    /// The maps were drawn by another path (the CPU extraction, or none):
    /// the next GPU update redraws them whole.
    pub(super) fn forget_history(&mut self) {
        self.recorded = false;
    }
}

/// The read-back buffer's GPU copy, once its asset is prepared.
pub(super) fn stats_buffer<'a>(
    handle: Option<&FinStatsBuffer>,
    buffers: &'a RenderAssets<GpuShaderBuffer>,
) -> Option<&'a Buffer> {
    handle.and_then(|h| buffers.get(&h.0)).map(|b| &b.buffer)
}

#[cfg(test)]
mod tests {
    use super::{DIRTY_WORDS, changed_runs, dirty_table, size_tile_pool};
    use crate::frame::{
        build::LightState,
        map_tiles::{MapShape, TileDemand},
    };

    #[test]
    fn the_tile_pool_is_resized_on_overflow_or_half_use_and_kept_between() {
        let shape = MapShape { resolution: 1024, layers: 16, tiles: 1000 };
        let mut state = LightState::default();
        let want = |tiles| TileDemand { resolution: 1024, tiles };
        // Used, with room to spare but over half: kept (a partial redraw may follow).
        assert_eq!(size_tile_pool(&mut state, want(700), shape), (false, false));
        assert_eq!((state.tile_demand, state.capacity_epoch), (None, 0));
        // Overflowed: sized anew for what was wanted.
        assert_eq!(size_tile_pool(&mut state, want(1200), shape), (true, true));
        assert_eq!((state.tile_demand, state.capacity_epoch), (Some(want(1200)), 1));
        // The same overflow read back again (an older frame's slot): no second rebuild.
        assert_eq!(size_tile_pool(&mut state, want(1200), shape), (true, false));
        assert_eq!(state.capacity_epoch, 1);
        // Far under half: shrunk.
        assert_eq!(size_tile_pool(&mut state, want(100), shape), (false, true));
        assert_eq!(state.tile_demand, Some(want(100)));
    }

    #[test]
    fn a_lights_recent_frames_are_found_by_their_generation() {
        let mut state = LightState::default();
        assert_eq!(state.recent_shape(0), None, "no frame yet: the zeroed entries are not frames");
        let shape = |tiles| MapShape { resolution: 256, layers: 2, tiles };
        for g in 1..=6u64 {
            state.remember_frame(g, shape(g as u32));
        }
        assert_eq!(state.recent_shape(6), Some(shape(6)));
        assert_eq!(state.recent_shape(3), Some(shape(3)));
        assert_eq!(state.recent_shape(2), None, "only the last four are kept");
    }

    #[test]
    fn the_dirty_table_starts_each_moved_instance_after_the_ones_before_it() {
        // Instances 2, 5, 9 moved: (flags, vertices, faces, edges) each;
        // instance 5 casts nothing (no face, no edge).
        let info = |k: u32| match k {
            2 => [1, 8, 12, 18],
            5 => [0, 4, 0, 0],
            9 => [3, 24, 44, 66],
            _ => unreachable!("only moved instances are looked up"),
        };
        let table = dirty_table(&[2, 5, 9], info);
        assert_eq!(table.len(), 3 * DIRTY_WORDS as usize);
        assert_eq!(table, vec![2, 0, 0, 0, 5, 8, 12, 18, 9, 12, 12, 18]);
        assert!(dirty_table(&[], info).is_empty());
    }

    #[test]
    fn only_the_records_that_differ_are_written() {
        let old: Vec<u8> = (0..40).collect();
        let mut new = old.clone();
        new[9] = 200; // record 2 (bytes 8..12)
        new[13] = 200; // record 3: joins the run
        new[30] = 200; // record 7
        assert_eq!(changed_runs(&old, &new, 4), vec![8..16, 28..32]);
        assert_eq!(changed_runs(&old, &old, 4), Vec::<std::ops::Range<usize>>::new());
        // Nothing kept (a new buffer): everything goes up, as one run.
        assert_eq!(changed_runs(&[], &new, 4), vec![0..40]);
        // More records than before: the new ones go up.
        let mut longer = old.clone();
        longer.extend([1, 2, 3, 4]);
        assert_eq!(changed_runs(&old, &longer, 4), vec![40..44]);
    }
}
