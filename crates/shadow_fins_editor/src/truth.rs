//! Ground truth and the CPU views, computed in the background.
//!
//! Ground truth is the visible fraction of the disk at each pixel of a
//! reduced grid over the camera's view (DESIGN §4: 1024 Fibonacci samples on
//! the disk, exact ray–triangle tests through a BVH), filled in row by row so
//! the UI shows progress and the error view fills in as it goes. It restarts
//! when the light, the camera or the scene changes. Receivers the light's
//! centre does not face are left out, as in the lab (Bevy's cosine term
//! darkens them whatever the shadow).
//!
//! The *analysis* job builds the core's fin model with the light's current
//! settings and returns the layer index of every grid pixel and one layer's
//! light-space maps, rasterised exactly as the GPU rasterises them (the
//! rendering tests hold the two texel for texel).

use std::sync::{
    Arc, Mutex,
    atomic::{AtomicBool, AtomicU32, Ordering},
};

use bevy::{
    prelude::*,
    tasks::{AsyncComputeTaskPool, Task},
    window::PrimaryWindow,
};
use bevy_shadow_fins::FinShadowSettings;
use shadow_fins::{
    camera::{Camera as CoreCamera, pixel_receiver},
    ground_truth::GroundTruth as CoreGroundTruth,
    oracle::{FinShadowModel, LayerTexel, RasterMaps},
    scene::LightSpaceScene,
};

use crate::{
    EditorState,
    state::{EditorCamera, EditorLight, LightParams, LoadedScene, ViewKind, window_size},
};

/// Disk samples of the ground truth.
pub const SAMPLES: u32 = 1024;
/// Width of the ground-truth grid (its height follows the window's aspect).
pub const GRID_WIDTH: u32 = 192;

/// A grid of values over the camera's view; NaN where nothing is measured.
#[derive(Debug, Clone)]
pub struct Grid {
    pub width: u32,
    pub height: u32,
    pub values: Vec<f32>,
}

/// Progress of the ground truth, for the UI.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GroundTruthStatus {
    pub rows_done: u32,
    pub rows: u32,
    pub samples: u32,
}

impl GroundTruthStatus {
    pub fn done(&self) -> bool {
        self.rows > 0 && self.rows_done == self.rows
    }
}

/// One background job: its inputs' key, progress, result and cancel flag.
pub(crate) struct Job<T> {
    pub key: u64,
    pub progress: Arc<AtomicU32>,
    pub cancel: Arc<AtomicBool>,
    pub result: Arc<Mutex<Option<T>>>,
    pub _task: Task<()>,
}

impl<T> Drop for Job<T> {
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}

/// The ground truth so far: rows not done yet are NaN.
#[derive(Resource, Default)]
pub struct GroundTruthJob {
    job: Option<Job<Grid>>,
    pub status: GroundTruthStatus,
    /// The latest (partial) grid.
    pub grid: Option<Grid>,
}

/// Layer index per grid pixel and one layer's maps.
#[derive(Debug, Clone)]
pub struct Analysis {
    pub layers: Grid,
    pub layer_count: u32,
    pub map_layer: u32,
    pub map_resolution: u32,
    pub map: Vec<LayerTexel>,
    pub reference_depth: f32,
}

#[derive(Resource, Default)]
pub struct AnalysisJob {
    job: Option<Job<Analysis>>,
    pub latest: Option<Arc<Analysis>>,
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<GroundTruthJob>()
        .init_resource::<AnalysisJob>()
        .add_systems(Update, (update_ground_truth, update_analysis));
}

/// The core crate's camera for the editor camera and a grid of `size`'s aspect.
pub(crate) fn core_camera(transform: &GlobalTransform, projection: &Projection) -> CoreCamera {
    let fov = match projection {
        Projection::Perspective(p) => p.fov.to_degrees(),
        _ => 45.0,
    };
    let t = transform.compute_transform();
    CoreCamera {
        position: t.translation,
        target: t.translation + t.forward().as_vec3(),
        up: t.up().as_vec3(),
        vertical_fov: fov,
    }
}

pub(crate) fn grid_size(window: UVec2) -> UVec2 {
    let height = (GRID_WIDTH as f32 * window.y as f32 / window.x as f32).round().max(1.0) as u32;
    UVec2::new(GRID_WIDTH, height)
}

/// What a background job over the view's grid depends on: the light, the
/// camera, the scene's generation, the grid's size, and `extra` (the job's
/// own inputs), hashed together (no XOR of parts that could cancel).
pub(crate) fn view_key(params: &LightParams, camera: &CoreCamera, grid: UVec2, generation: u64, extra: u64) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for v in light_key(params).into_iter().chain(camera_key(camera)) {
        v.to_bits().hash(&mut h);
    }
    (generation, grid.x, grid.y, extra).hash(&mut h);
    h.finish()
}

/// Everything of the light the core's light is made of (`LightParams::core_light`):
/// its kind (disk, sun, rectangle, sphere), place and sizes.
fn light_key(params: &LightParams) -> [f32; 10] {
    let (p, d) = (params.position, params.direction);
    let kind = params.kind as u32 as f32;
    [p.x, p.y, p.z, d.x, d.y, d.z, params.radius, kind, params.rect_aspect, params.sun_angle]
}

fn camera_key(c: &CoreCamera) -> [f32; 10] {
    [
        c.position.x,
        c.position.y,
        c.position.z,
        c.target.x,
        c.target.y,
        c.target.z,
        c.up.x,
        c.up.y,
        c.up.z,
        c.vertical_fov,
    ]
}

#[allow(clippy::too_many_arguments)]
fn update_ground_truth(
    mut job: ResMut<GroundTruthJob>,
    scene: Option<Res<LoadedScene>>,
    params: Res<LightParams>,
    camera: Query<(&GlobalTransform, &Projection), With<EditorCamera>>,
    window: Query<&Window, With<PrimaryWindow>>,
) {
    let (Some(scene), Ok((transform, projection)), Some(size)) = (scene, camera.single(), window_size(&window)) else {
        return;
    };
    let camera = core_camera(transform, projection);
    let grid = grid_size(size);
    let key = view_key(&params, &camera, grid, scene.generation, 0);
    if job.job.as_ref().is_none_or(|j| j.key != key) {
        job.grid = None;
        job.status = GroundTruthStatus { rows_done: 0, rows: grid.y, samples: SAMPLES };
        let Some(light) = params.core_light() else {
            job.job = None;
            return;
        };
        let result: Arc<Mutex<Option<Grid>>> = Arc::default();
        let (progress, cancel) = (Arc::new(AtomicU32::new(0)), Arc::new(AtomicBool::new(false)));
        let (p, c, r, scene) = (progress.clone(), cancel.clone(), Arc::clone(&result), scene.scene.clone());
        let task = AsyncComputeTaskPool::get().spawn(async move {
            let ls = LightSpaceScene::new(&scene, light);
            let truth = CoreGroundTruth::new(&ls, SAMPLES);
            let mut values = vec![f32::NAN; (grid.x * grid.y) as usize];
            for y in 0..grid.y {
                if c.load(Ordering::Relaxed) {
                    return;
                }
                for x in 0..grid.x {
                    let receiver = pixel_receiver(&camera, (x, y, grid.x, grid.y), &ls, truth.bvh());
                    if let Some(r) = receiver.filter(|r| r.faces_light(&ls.frame)) {
                        values[(y * grid.x + x) as usize] = truth.visibility(r);
                    }
                }
                // Publish every few rows so the error view fills in.
                if y % 8 == 7 || y + 1 == grid.y {
                    *r.lock().unwrap() = Some(Grid { width: grid.x, height: grid.y, values: values.clone() });
                }
                p.store(y + 1, Ordering::Relaxed);
            }
        });
        job.job = Some(Job { key, progress, cancel, result, _task: task });
    }
    let Some(j) = job.job.as_ref() else { return };
    let rows_done = j.progress.load(Ordering::Relaxed);
    let latest = j.result.lock().unwrap().take();
    job.status.rows_done = rows_done;
    if let Some(grid) = latest {
        job.grid = Some(grid);
    }
}

#[allow(clippy::too_many_arguments)]
fn update_analysis(
    mut job: ResMut<AnalysisJob>,
    state: Res<EditorState>,
    scene: Option<Res<LoadedScene>>,
    params: Res<LightParams>,
    settings: Query<&FinShadowSettings, With<EditorLight>>,
    camera: Query<(&GlobalTransform, &Projection), With<EditorCamera>>,
    window: Query<&Window, With<PrimaryWindow>>,
) {
    if !matches!(state.view, ViewKind::LayerIndex | ViewKind::SlabDepth | ViewKind::InnerMap | ViewKind::OuterMap) {
        return;
    }
    let (Some(scene), Ok(settings), Ok((transform, projection)), Some(size)) =
        (scene, settings.single(), camera.single(), window_size(&window))
    else {
        return;
    };
    let settings = settings.clamped();
    let camera = core_camera(transform, projection);
    let grid = grid_size(size);
    let settings_hash = {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        settings.hash(&mut h);
        state.layer.hash(&mut h);
        h.finish()
    };
    let key = view_key(&params, &camera, grid, scene.generation, settings_hash);
    if job.job.as_ref().is_none_or(|j| j.key != key) {
        let Some(light) = params.core_light() else { return };
        let result: Arc<Mutex<Option<Analysis>>> = Arc::default();
        let (progress, cancel) = (Arc::new(AtomicU32::new(0)), Arc::new(AtomicBool::new(false)));
        let (c, r, scene, layer) = (cancel.clone(), Arc::clone(&result), scene.scene.clone(), state.layer);
        let task = AsyncComputeTaskPool::get().spawn(async move {
            let ls = LightSpaceScene::new(&scene, light);
            let model = FinShadowModel::new(&scene, &ls, settings.method.into(), settings.core());
            let maps = RasterMaps::new(&model, settings.map_resolution.min(1024));
            let bvh = shadow_fins::bvh::Bvh::new(&ls.casters);
            let mut layers = vec![f32::NAN; (grid.x * grid.y) as usize];
            for y in 0..grid.y {
                if c.load(Ordering::Relaxed) {
                    return;
                }
                for x in 0..grid.x {
                    if let Some(r) = pixel_receiver(&camera, (x, y, grid.x, grid.y), &ls, &bvh) {
                        layers[(y * grid.x + x) as usize] = model.plan.layer_of(r.position.z) as f32;
                    }
                }
            }
            let layer_count = maps.layers.len() as u32;
            let map_layer = layer.min(layer_count.saturating_sub(1));
            *r.lock().unwrap() = Some(Analysis {
                layers: Grid { width: grid.x, height: grid.y, values: layers },
                layer_count,
                map_layer,
                map_resolution: maps.region.resolution,
                map: maps.layers.get(map_layer as usize).cloned().unwrap_or_default(),
                reference_depth: ls.reference_depth,
            });
        });
        job.job = Some(Job { key, progress, cancel, result, _task: task });
    }
    if let Some(done) = job.job.as_ref().and_then(|j| j.result.lock().unwrap().take()) {
        job.latest = Some(Arc::new(done));
    }
}
