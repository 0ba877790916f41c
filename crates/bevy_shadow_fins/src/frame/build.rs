//! One light's frame (one cube face's, for a point light): the casters it
//! sees, fitted to its frame, and the method's data — the GPU extraction's
//! scene, or the core's CPU extraction, coverage or plateaus — under the
//! budget and the device's buffer limit.

use crate::{
    budget::{FinDegradation, FinDegradations, allocate_maps_by},
    casters::CasterScene,
    frame::{coverage::coverage_frame, sun_fit},
    settings::{FinMethod, FinShadowSettings},
};
use crate::{
    casters::{
        gpu_scene::{GpuCapacity, GpuSceneBuilder},
        reach::LightSees,
    },
    frame::{
        FinFrameData,
        in_frame::InFrame,
        map_casters::{fit_cutouts, gpu_casters, gpu_fin},
        map_tiles::{self, TileDemand},
    },
    gpu_layout::{GpuCaster, GpuFin},
    stats::{FinExtraction, FinFrameStats, warn_degradation},
};
use bevy::prelude::*;
use shadow_fins::{
    light::{CubeFace, Light, LightFrame},
    oracle::{FinShadowModel, MapRegion},
    scene::{Scene, SceneObject},
};

/// Per light: what its frame was built from and the GPU extraction's state.
#[derive(Default)]
pub(crate) struct LightState {
    pub(crate) signature: u64,
    pub(crate) gpu: GpuSceneBuilder,
    /// GPU buffer sizes, grown when a read-back says a frame overflowed them.
    pub(crate) capacity: Option<GpuCapacity>,
    pub(crate) capacity_epoch: u64,
    /// What the latest GPU read-back said did not fit (kept into new frames).
    pub(crate) shortfall: FinDegradations,
    /// How many map tiles the GPU's last redraw wanted (`map_tiles`): the
    /// next frame's maps are sized by it.
    pub(crate) tile_demand: Option<TileDemand>,
    /// The maps' shape of this light's last few GPU frames, by generation (a
    /// read-back of an earlier one still sizes the pool, `extraction.rs`).
    pub(crate) recent_frames: [Option<(u32, map_tiles::MapShape)>; 4],
    /// The reasons last warned about.
    pub(crate) warned: FinDegradations,
    /// A sun's map window in its last frame (`sun_fit::sun_window` keeps it
    /// while it still fits).
    pub(crate) window: Option<[f32; 4]>,
    /// What this frame models now (a light's stats combine its frames').
    pub(crate) stats: FinFrameStats,
    /// The objects as this light saw them in its last frame.
    pub(crate) built: Option<LightBuild>,
}

impl LightState {
    /// The maps' shape of this light's recent GPU frame of `generation`
    /// (its low 32 bits, as the read-back has it).
    pub(crate) fn recent_shape(&self, generation: u32) -> Option<map_tiles::MapShape> {
        self.recent_frames.iter().flatten().find(|(g, _)| *g == generation).map(|(_, shape)| *shape)
    }

    pub(crate) fn remember_frame(&mut self, generation: u64, shape: map_tiles::MapShape) {
        self.recent_frames.rotate_right(1);
        self.recent_frames[0] = Some((generation as u32, shape));
    }
}

/// The objects one light's last frame was built from, kept so that the next
/// frame recomputes only the slots the scene's update changed.
pub(crate) struct LightBuild {
    /// The [`CasterScene::version`] they were seen from.
    pub(crate) scene_version: u64,
    /// The light's own part of the signature they were seen with.
    pub(crate) light_part: u64,
    /// The frame they were culled in, and the one the GPU records were made
    /// in (a sun fitted to the views moves it; `None`: not on the GPU).
    pub(crate) seen_frame: LightFrame,
    pub(crate) gpu_frame: Option<LightFrame>,
    pub(crate) objects: Vec<SceneObject>,
}

/// What one light's frame is asked for.
pub(crate) struct FrameAsked<'a> {
    pub(crate) light: Light,
    pub(crate) face: Option<CubeFace>,
    pub(crate) window: Option<[f32; 4]>,
    pub(crate) sees: LightSees<'a>,
    pub(crate) settings: FinShadowSettings,
    /// The light's own part of its frame's signature (not the casters').
    pub(crate) light_part: u64,
}

/// The buffer limits one frame is built under.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FrameLimits {
    /// The largest buffer, bytes.
    pub(crate) max_buffer: u64,
    /// All map layers together, bytes.
    pub(crate) map_bytes: u64,
}

/// One light's frame (one cube face's, for a point light) from the scene's objects.
#[allow(clippy::too_many_arguments)]
pub(crate) fn light_frame(
    scene: &CasterScene,
    asked: FrameAsked,
    generation: u64,
    limits: FrameLimits,
    state: &mut LightState,
) -> FinFrameData {
    let FrameAsked { light, face, window, sees, settings, light_part } = asked;
    let start = std::time::Instant::now();
    // A light of no size casts no fins: one layer's slab is the exact hard
    // shadow (the min over layers of slabs is the nearest slab), and the
    // memory of the other layers goes to resolution instead.
    let settings = if light.is_zero_size() { FinShadowSettings { layers: 1, ..settings } } else { settings };
    let (frame, scene_box) = scene.frame_for(&light, face);
    // The objects as this light sees them: after an in-place update of the
    // scene, only its dirty slots again, when nothing of the light changed.
    let mut built = state.built.take().filter(|b| {
        b.scene_version + 1 == scene.version
            && b.light_part == light_part
            && b.seen_frame == frame
            && b.objects.len() == scene.objects.len()
    });
    let dirty = scene.dirty.as_deref().filter(|_| built.is_some());
    match (&mut built, dirty) {
        (Some(b), Some(dirty)) => {
            for &i in dirty {
                b.objects[i] = scene.seen_by_one(i, &light, &frame, sees);
            }
            b.scene_version = scene.version;
        }
        _ => {
            let objects = scene.seen_by(&light, &frame, sees);
            built = Some(LightBuild {
                scene_version: scene.version,
                light_part,
                seen_frame: frame,
                gpu_frame: None,
                objects,
            });
        }
    }
    let built = state.built.insert(built.expect("set above"));
    let gpu_frame = built.gpu_frame.take();
    let objects_of =
        |state: &LightState| -> Vec<SceneObject> { state.built.as_ref().expect("built above").objects.clone() };
    let unread_bounds = scene.unread_bounds.clone();
    // A sun fitted to the views works in a frame placed at its window.
    let fitted = match (light, window) {
        (Light::Sun(sun), Some(w)) => sun_fit::window_frame(w, scene_box, &sun).map(|(f, l0)| (f, l0, w)),
        _ => None,
    };
    let (frame, reference_depth) = fitted.map_or((frame, None), |(f, l0, _)| (f, Some(l0)));
    let map_window = window.map(|w| sun_fit::window_in_frame(w, &frame));
    let extent = (scene_box.1 - scene_box.0).length();
    let in_frame = InFrame { light, frame, extent, scene_box, map_window, reference_depth };
    let penumbra_texels = in_frame.widest_penumbra_texels(settings.map_resolution);
    if settings.method == FinMethod::Coverage {
        let objects = &state.built.as_ref().expect("built above").objects;
        let data = coverage_data(objects, in_frame, settings, generation, start, unread_bounds, limits);
        warn_degradation(&mut state.warned, data.stats.degraded);
        return data;
    }
    let mut extraction = settings.extraction;
    // The GPU extracts an alpha-masked caster from its mesh packed with its
    // outline (`GpuMeshGeometry::pack_outlined`, posed with the mesh when the
    // GPU poses it); one packed without (its cut-out could not be made at
    // rest) sends the frame to the CPU extraction (the maps still run on the GPU).
    let objects = &state.built.as_ref().expect("built above").objects;
    if objects
        .iter()
        .zip(&scene.gpu_meshes)
        .any(|(o, m)| o.casts_shadows && o.fitting_cutout().is_some() && !m.outlined)
    {
        extraction = FinExtraction::Cpu;
    }
    let mut gpu_scene = None;
    let max_buffer = limits.max_buffer;
    if extraction == FinExtraction::Gpu {
        let LightState { gpu, capacity, built, .. } = &mut *state;
        let built = built.as_mut().expect("built above");
        // Records of unchanged objects are kept only in the frame they were made in.
        let dirty = dirty.filter(|_| gpu_frame == Some(frame));
        built.gpu_frame = Some(frame);
        let max = GpuCapacity::max_for(max_buffer);
        let scene = gpu.build(
            &built.objects,
            &scene.gpu_meshes,
            &scene.gpu_poses,
            &frame,
            scene.objects_box,
            dirty,
            capacity,
            max,
        );
        // Buffers sized by the scene itself cannot shrink: past the limit the
        // core crate extracts on the CPU instead.
        match scene.input_bytes().into_iter().find(|(_, bytes)| *bytes > max_buffer) {
            Some((buffer, bytes)) => {
                warn_once!(
                    "fin shadows: the GPU extraction's {buffer} ({bytes} bytes) exceeds the buffer limit; extracting on the CPU"
                );
                extraction = FinExtraction::Cpu;
                gpu_scene = Some(Err(FinDegradation::ExtractedOnCpu { buffer, bytes, limit_bytes: max_buffer }));
            }
            None => gpu_scene = Some(Ok(scene)),
        }
    }
    // The plateaus' texture reads the scene in this frame; the maps below
    // are its hard shadow.
    let plateaus = (settings.method == FinMethod::Plateaus).then(|| {
        let scene = Scene::new(objects_of(state));
        let light_space = in_frame.light_space(&scene, unread_bounds.iter().flatten().copied());
        crate::frame::plateaus::plateau_frame(&scene, &light_space)
    });
    let receiver_bound = unread_bounds.into_iter().flatten();
    let mut data = match (extraction, gpu_scene) {
        (FinExtraction::Gpu, Some(Ok(scene))) => {
            // Layers are known to the GPU only (a read-back grows them): the
            // maps hold what the GPU last wanted, at the best resolution that
            // fits, and may grow to the most layers that fit at all.
            // The maps are sparse: sized by the tiles the last read-back
            // said the GPU drew; before one, their pool takes what fits.
            let asked = if settings.method == FinMethod::MultiLayer { settings.layers } else { 1 };
            // A frame that was empty (demand 0) and now has casters starts
            // again from what fits, not from a pool of no tiles.
            if scene.totals[1] != 0 && state.tile_demand.is_some_and(|d| d.tiles == 0) {
                state.tile_demand = None;
            }
            let demand = state.tile_demand;
            let needed = |r: u32, l: u32| map_tiles::bytes_needed(demand, r, l);
            let allocate = |layers: u32| {
                allocate_maps_by(settings.map_resolution, layers, limits.map_bytes, penumbra_texels, needed)
            };
            let most = allocate(asked).layers;
            let mut scene = scene;
            let alloc = allocate(scene.capacity.layers.min(most));
            // A frame no caster face reaches (a cube face that sees nothing)
            // draws no tile: it takes its page table only.
            let tiles = if scene.totals[1] == 0 {
                // And says so to the budget's split (`shares_by_need`).
                state.tile_demand = Some(TileDemand { resolution: alloc.resolution, tiles: 0 });
                0
            } else {
                TileDemand::tiles_at(demand, alloc.resolution, alloc.layers)
            };
            let shape = map_tiles::shape_within(alloc.resolution, alloc.layers, tiles, limits.map_bytes);
            scene.capacity.layers = alloc.layers;
            scene.max_capacity.layers = most;
            scene.map_window = in_frame.map_window;
            scene.receiver_depth = match in_frame.reference_depth {
                Some(l0) => l0,
                None => receiver_bound.map(|p| frame.to_frame(p).z).fold(0.0, f32::max),
            };
            scene.fixed_reference_depth = in_frame.reference_depth.is_some();
            let objects = &state.built.as_ref().expect("built above").objects;
            let stats = FinFrameStats {
                casters: objects.iter().filter(|o| o.casts_shadows).count(),
                triangles: objects.iter().map(|o| o.mesh.triangle_count()).sum(),
                extract_ms: start.elapsed().as_secs_f32() * 1e3,
                // No caster face: the GPU runs no pass and there is nothing to read back.
                up_to_date: scene.totals[1] == 0,
                degraded: alloc.degradation.into(),
                map_resolution: alloc.resolution,
                posed_on_gpu: scene.pose_sizes()[0] as usize,
                ..default()
            };
            FinFrameData {
                generation,
                stats,
                casters: Vec::new(),
                cutouts: Vec::new(),
                mask_words: Vec::new(),
                fins: Vec::new(),
                region: MapRegion { min: Vec2::ZERO, texel: 1.0, resolution: alloc.resolution },
                map_layers: alloc.layers,
                map_tiles: shape.tiles,
                limit_bytes: limits.max_buffer,
                map_limit_bytes: limits.map_bytes,
                origin: frame.origin(),
                axes: frame.axes_f64(),
                size: frame.size(),
                aperture: frame.aperture,
                orthographic: !frame.is_perspective(),
                reference_depth: 0.0,
                near: 0.0,
                scene_extent: scene.extent,
                settings,
                gpu: Some(scene),
                coverage: None,
                plateaus: None,
                convolution: None,
                windowed: false,
            }
        }
        (_, fallback) => {
            let mut data =
                cpu_frame(Scene::new(objects_of(state)), in_frame, settings, generation, start, receiver_bound, limits);
            if let Some(Err(why)) = fallback {
                // What the CPU path had to cut (maps, dropped casters) shows first.
                data.stats.degraded = data.stats.degraded.with(why);
            }
            data
        }
    };
    if let Some(p) = plateaus {
        data.stats.silhouettes = p.sheets.len();
        let longest = p.cell_starts.windows(2).map(|w| w[1].saturating_sub(w[0])).max().unwrap_or(0);
        if longest > crate::frame::plateaus::MAX_CELL_SHEETS {
            let why =
                FinDegradation::LongPlateauCell { sheets: longest, limit: crate::frame::plateaus::MAX_CELL_SHEETS };
            data.stats.degraded = data.stats.degraded.with(why);
        }
        data.plateaus = Some(p);
    }
    data.windowed = map_window.is_some();
    if settings.method == FinMethod::Convolution {
        // The basis shares the light's map budget with the maps it filters.
        let room = limits.map_bytes.saturating_sub(data.map_bytes()).min(limits.max_buffer);
        match crate::budget::BasisLayout::new(data.region.resolution, settings.convolution_order, room) {
            Ok(layout) => {
                if layout.first > 0 {
                    let why = FinDegradation::ConvolutionLevels { dropped: layout.first, limit_bytes: room };
                    data.stats.degraded = data.stats.degraded.with(why);
                }
                data.convolution = Some(layout);
            }
            Err(bytes) => {
                let why = FinDegradation::ConvolutionBasis { bytes, limit_bytes: room };
                data.stats.degraded = data.stats.degraded.with(why);
            }
        }
    }
    data.stats.map_resolution = data.region.resolution;
    data.stats.gpu_bytes = data.map_bytes() + data.convolution.as_ref().map_or(0, |basis| basis.bytes());
    data.stats.extraction = if data.gpu.is_some() { FinExtraction::Gpu } else { FinExtraction::Cpu };
    // What the last read-back said the GPU had to drop still holds until a
    // read-back says otherwise (no flicker between re-extractions).
    data.stats.degraded = data.stats.degraded.and(state.shortfall);
    warn_degradation(&mut state.warned, data.stats.degraded);
    if data.gpu.is_some() {
        state.remember_frame(data.generation, data.map_shape());
    }
    data
}

/// The coverage method's frame: edges and lists from the core crate.
pub(crate) fn coverage_data(
    objects: &[SceneObject],
    in_frame: InFrame,
    settings: FinShadowSettings,
    generation: u64,
    start: std::time::Instant,
    unread_bounds: Vec<[Vec3; 8]>,
    limits: FrameLimits,
) -> FinFrameData {
    let scene = Scene::new(objects.to_vec());
    let (coverage, degraded, potential_silhouettes) = coverage_frame(
        &scene,
        in_frame,
        settings.map_resolution,
        settings.coverage_samples,
        unread_bounds.into_iter().flatten(),
        limits.map_bytes,
        limits.max_buffer,
    );
    let stats = FinFrameStats {
        casters: scene.objects.iter().filter(|o| o.casts_shadows).count(),
        triangles: scene.triangle_count(),
        silhouettes: potential_silhouettes,
        fins: 0,
        layers: if coverage.casters.is_empty() { 0 } else { 1 },
        extract_ms: start.elapsed().as_secs_f32() * 1e3,
        up_to_date: true,
        degraded,
        map_resolution: coverage.region.resolution,
        gpu_bytes: coverage.gpu_bytes(),
        extraction: FinExtraction::Cpu,
        partial_redraw: false,
        incremental_extraction: false,
        redrawn_texels: 0,
        posed_on_gpu: 0,
    };
    FinFrameData {
        generation,
        stats,
        casters: Vec::new(),
        cutouts: Vec::new(),
        mask_words: Vec::new(),
        fins: Vec::new(),
        region: coverage.region,
        map_layers: 1,
        // The coverage method's lists are its own (`CoverageFrame::gpu_bytes`).
        map_tiles: 0,
        limit_bytes: limits.max_buffer,
        map_limit_bytes: limits.map_bytes,
        origin: in_frame.frame.origin(),
        axes: in_frame.frame.axes_f64(),
        size: in_frame.frame.size(),
        aperture: in_frame.frame.aperture,
        orthographic: !in_frame.frame.is_perspective(),
        reference_depth: 0.0,
        near: coverage.near,
        scene_extent: coverage.extent,
        settings,
        gpu: None,
        coverage: Some(coverage),
        plateaus: None,
        convolution: None,
        windowed: false,
    }
}

/// The whole extraction on the CPU with the core crate.
pub(crate) fn cpu_frame(
    scene: Scene,
    in_frame: InFrame,
    settings: FinShadowSettings,
    generation: u64,
    start: std::time::Instant,
    receiver_bound: impl Iterator<Item = Vec3>,
    limits: FrameLimits,
) -> FinFrameData {
    let ls = in_frame.light_space(&scene, receiver_bound);
    let mut core = settings.core();
    let mut model = FinShadowModel::new(&scene, &ls, settings.method.into(), core);
    let penumbra_texels = in_frame.widest_penumbra_texels(settings.map_resolution);
    // Sparse maps: the page table must fit first; the tiles are counted below.
    let mut alloc = allocate_maps_by(
        settings.map_resolution,
        model.plan.len() as u32,
        limits.map_bytes,
        penumbra_texels,
        |r, l| map_tiles::bytes_needed(None, r, l),
    );
    if (alloc.layers as usize) < model.plan.len() {
        // Fewer layers fit than the plan made: plan again with that many.
        core.layers = alloc.layers;
        model = FinShadowModel::new(&scene, &ls, settings.method.into(), core);
        alloc.layers = alloc.layers.max(model.plan.len() as u32);
    }
    let bounds = || model.casters.iter().map(|c| c.bounds()).chain(model.fins.iter().map(|f| f.bounds()));
    let mut region = in_frame.covering(bounds(), alloc.resolution);
    // What the maps lost comes first (the tile count below may add to it);
    // then what the buffers dropped.
    let mut maps_cut = alloc.degradation;
    let mut degraded = FinDegradations::default();
    // What does not fit one buffer is dropped (and said so: the first buffer cut).
    let mut capped = |buffer: &'static str, n: usize, bytes: u64| {
        let keep = (limits.max_buffer / bytes) as usize;
        if n > keep {
            degraded = degraded.with(FinDegradation::Capacity {
                buffer,
                kept: keep as u32,
                wanted: n as u32,
                limit_bytes: limits.max_buffer,
            });
        }
        n.min(keep)
    };
    let n_casters = capped("map casters", model.casters.len(), size_of::<GpuCaster>() as u64);
    let n_fins = capped("fins", model.fins.len(), size_of::<GpuFin>() as u64);
    let (mut casters_gpu, mut cutouts, mut mask_words) =
        gpu_casters(&model.casters[..n_casters], Some(&model.caster_layers[..n_casters]), &ls.masks);
    if let Some(why) = fit_cutouts(&mut casters_gpu, &mut cutouts, &mut mask_words, limits.max_buffer) {
        degraded = degraded.with(why);
    }
    let fins_gpu: Vec<GpuFin> =
        model.fins.iter().take(n_fins).zip(&model.fin_layers).map(|(f, &l)| gpu_fin(f, l)).collect();
    // The sparse maps' tiles, counted by the primitives' bounds (never fewer
    // than the GPU marks); past the limit, the resolution halves as the
    // budget says and they are counted again.
    let count = |region: &MapRegion| {
        let casters = model.casters[..n_casters].iter().zip(&model.caster_layers).map(|(c, &l)| (l, c.bounds()));
        let fins = model.fins[..n_fins].iter().zip(&model.fin_layers).map(|(f, &l)| (l, f.bounds()));
        let tiles = map_tiles::count_tiles(region, alloc.layers, casters.chain(fins));
        TileDemand { resolution: region.resolution, tiles }
    };
    let mut demand = count(&region);
    let exact = |d: TileDemand| {
        move |r: u32, l: u32| {
            // Counted at this resolution: the tiles exactly, no room (nothing
            // moves between a CPU frame and its maps).
            let tiles = if r == d.resolution { d.tiles as u64 } else { TileDemand::tiles_at(Some(d), r, l) };
            map_tiles::MapShape { resolution: r, layers: l.max(1), tiles: tiles as u32 }.bytes()
        }
    };
    for _ in 0..4 {
        let refit = allocate_maps_by(region.resolution, alloc.layers, limits.map_bytes, f32::INFINITY, exact(demand));
        if refit.resolution == region.resolution {
            break;
        }
        alloc.resolution = refit.resolution;
        maps_cut = Some(FinDegradation::Maps {
            resolution: refit.resolution,
            wanted_resolution: settings.map_resolution,
            layers: alloc.layers,
            wanted_layers: model.plan.len() as u32,
            limit_bytes: limits.map_bytes,
        });
        region = in_frame.covering(bounds(), alloc.resolution);
        demand = count(&region);
    }
    let mut degraded = FinDegradations::from(maps_cut).and(degraded);
    let shape = map_tiles::shape_within(region.resolution, alloc.layers, demand.tiles as u64, limits.map_bytes);
    if shape.tiles < demand.tiles {
        degraded = degraded.with(FinDegradation::Capacity {
            buffer: "penumbra map tiles",
            kept: shape.tiles,
            wanted: demand.tiles,
            limit_bytes: limits.map_bytes,
        });
    }
    let stats = FinFrameStats {
        casters: scene.objects.iter().filter(|o| o.casts_shadows).count(),
        triangles: scene.triangle_count(),
        silhouettes: model.silhouettes.len(),
        fins: model.fins.len(),
        // Nothing casts: no layer, no map, and the passes have nothing to do.
        layers: if model.casters.is_empty() && model.fins.is_empty() { 0 } else { model.plan.len() },
        extract_ms: start.elapsed().as_secs_f32() * 1e3,
        up_to_date: true,
        degraded,
        map_resolution: region.resolution,
        // Set with the convolution basis known (`light_frame`'s end).
        gpu_bytes: 0,
        extraction: FinExtraction::Cpu,
        partial_redraw: false,
        incremental_extraction: false,
        redrawn_texels: (model.plan.len() as u64) * (region.resolution as u64).pow(2),
        posed_on_gpu: 0,
    };
    FinFrameData {
        generation,
        stats,
        casters: casters_gpu,
        cutouts,
        mask_words,
        fins: fins_gpu,
        region,
        map_layers: alloc.layers,
        map_tiles: shape.tiles,
        limit_bytes: limits.max_buffer,
        map_limit_bytes: limits.map_bytes,
        origin: ls.frame.origin(),
        axes: ls.frame.axes_f64(),
        size: ls.frame.size(),
        aperture: ls.frame.aperture,
        orthographic: !ls.frame.is_perspective(),
        reference_depth: ls.reference_depth,
        near: model.near,
        scene_extent: ls.extent,
        settings,
        gpu: None,
        coverage: None,
        plateaus: None,
        convolution: None,
        windowed: false,
    }
}
