//! The other papers' methods (issue 14) beside the plugin's: the chosen
//! peer (`shadow_fins::peers`: single sample, plateaus, penumbra wedges with
//! and without blending, convolution with SATs or mipmaps) evaluated on the
//! CPU at the ground truth's grid pixels, in the background, and scored
//! against the same ground truth as the GPU's shadows — so switching between
//! the plugin's methods and the peers shows each one's shadow and error on
//! the same view.
//!
//! A point light's sphere is routed face by face as in the lab (each
//! receiver to the cube face whose frustum holds it; the peers, which model
//! planar lights and the sun, get the disk of the sphere's radius there).

use std::sync::{
    Arc, Mutex,
    atomic::{AtomicBool, AtomicU32, Ordering},
};

use bevy::{prelude::*, tasks::AsyncComputeTaskPool, window::PrimaryWindow};
use shadow_fins::{
    bvh::Bvh,
    camera::pixel_receiver,
    light::Light,
    metrics::ErrorMetrics,
    oracle::Receiver,
    peers::{PeerMethod, PeerModel},
    scene::{LightSpaceScene, Scene},
};

use crate::{
    EditorState,
    state::{EditorCamera, LightParams, LoadedScene, window_size},
    truth::{Grid, GroundTruthJob, Job, core_camera, grid_size, view_key},
};

/// The peer shown, its visibility on the grid and its error so far.
#[derive(Resource)]
pub struct PeerJob {
    job: Option<Job<(Grid, f32)>>,
    /// The method the peer views show (the UI's switch).
    pub method: PeerMethod,
    /// Its visibility per grid pixel (NaN where not measured).
    pub grid: Option<Grid>,
    /// CPU ms it took (prepare + evaluate over the grid).
    pub cpu_ms: f32,
    /// Against the ground truth's rows done so far.
    pub metrics: Option<ErrorMetrics>,
    /// Signed error per grid pixel.
    pub signed: Option<Grid>,
    /// Bumped whenever `grid` or `signed` changes (the view's texture key).
    pub serial: u64,
}

impl Default for PeerJob {
    fn default() -> Self {
        // The most accurate peer (BENCHMARKS.md, "The other papers as measured peers").
        Self {
            job: None,
            method: PeerMethod::WedgeBlending,
            grid: None,
            cpu_ms: 0.0,
            metrics: None,
            signed: None,
            serial: 0,
        }
    }
}

pub(crate) fn build(app: &mut App) {
    // What `--peer` asks for, from the first frame.
    let method = app.world().get_resource::<crate::EditorOptions>().and_then(|o| o.peer);
    let job = PeerJob { method: method.unwrap_or(PeerJob::default().method), ..default() };
    app.insert_resource(job)
        .add_systems(Update, (update_peer, score_peer).chain().run_if(|state: Res<EditorState>| state.view.is_peer()));
}

/// Receivers evaluated between two looks at the cancel flag.
const CANCEL_CHUNK: usize = 512;

/// The peer's visibility at `receivers` (in `light_space`'s frame); a sphere
/// light routed face by face. `None` when `cancel` was raised meanwhile (a
/// newer view asked for another job).
pub fn peer_visibility(
    method: PeerMethod,
    scene: &Scene,
    light_space: &LightSpaceScene,
    receivers: &[Receiver],
    cancel: &AtomicBool,
) -> Option<Vec<f32>> {
    let evaluate = |model: &PeerModel, receivers: &[Receiver]| -> Option<Vec<f32>> {
        let mut out = Vec::with_capacity(receivers.len());
        for chunk in receivers.chunks(CANCEL_CHUNK) {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            out.extend(chunk.iter().map(|r| model.visibility(*r)));
        }
        Some(out)
    };
    if !matches!(light_space.light, Light::Sphere(_)) {
        let model = PeerModel::for_receivers(method, scene, light_space, receivers);
        return evaluate(&model, receivers);
    }
    let mut values = vec![1.0; receivers.len()];
    for group in light_space.group_by_face(scene, receivers).into_iter().filter(|g| !g.indices.is_empty()) {
        if cancel.load(Ordering::Relaxed) {
            return None;
        }
        let model = PeerModel::for_receivers(method, scene, &group.light_space, &group.receivers);
        for (&i, v) in group.indices.iter().zip(evaluate(&model, &group.receivers)?) {
            values[i] = v;
        }
    }
    Some(values)
}

/// Starts the peer's job when the peer views are shown and the light, the
/// camera, the scene or the method changed; collects its result.
fn update_peer(
    mut job: ResMut<PeerJob>,
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
    let key = view_key(&params, &camera, grid, scene.generation, job.method as u64);
    if job.job.as_ref().is_none_or(|j| j.key != key) {
        let Some(light) = params.core_light() else {
            if job.job.take().is_some() || job.grid.is_some() {
                (job.grid, job.metrics, job.signed) = (None, None, None);
                job.serial += 1;
            }
            return;
        };
        (job.grid, job.metrics, job.signed) = (None, None, None);
        job.serial += 1;
        let result: Arc<Mutex<Option<(Grid, f32)>>> = Arc::default();
        let (progress, cancel) = (Arc::new(AtomicU32::new(0)), Arc::new(AtomicBool::new(false)));
        let (r, c, scene, method) = (Arc::clone(&result), cancel.clone(), scene.scene.clone(), job.method);
        let task = AsyncComputeTaskPool::get().spawn(async move {
            let start = std::time::Instant::now();
            let ls = LightSpaceScene::new(&scene, light);
            let bvh = Bvh::new(&ls.casters);
            // The ground truth's pixels: a surface seen, facing the light's centre.
            let mut at = vec![];
            let mut receivers = vec![];
            for y in 0..grid.y {
                for x in 0..grid.x {
                    let receiver = pixel_receiver(&camera, (x, y, grid.x, grid.y), &ls, &bvh);
                    if let Some(receiver) = receiver.filter(|r| r.faces_light(&ls.frame)) {
                        at.push((y * grid.x + x) as usize);
                        receivers.push(receiver);
                    }
                }
            }
            let Some(visibility) = peer_visibility(method, &scene, &ls, &receivers, &c) else { return };
            let mut values = vec![f32::NAN; (grid.x * grid.y) as usize];
            for (i, v) in at.into_iter().zip(visibility) {
                values[i] = v;
            }
            let ms = start.elapsed().as_secs_f32() * 1e3;
            *r.lock().unwrap_or_else(|e| e.into_inner()) = Some((Grid { width: grid.x, height: grid.y, values }, ms));
        });
        job.job = Some(Job { key, progress, cancel, result, _task: task });
    }
    let done = job.job.as_ref().and_then(|j| j.result.lock().unwrap_or_else(|e| e.into_inner()).take());
    if let Some((grid, ms)) = done {
        job.grid = Some(grid);
        job.cpu_ms = ms;
        job.serial += 1;
    }
}

/// The peer's error against the ground truth's rows done so far.
fn score_peer(mut job: ResMut<PeerJob>, truth: Res<GroundTruthJob>, mut last: Local<(u32, u64)>) {
    let (Some(peer), Some(reference)) = (job.grid.as_ref(), truth.grid.as_ref()) else {
        return;
    };
    // Scored again when the truth gained rows or the peer's grid changed.
    let key = (truth.status.rows_done, job.serial);
    if *last == key {
        return;
    }
    let (metrics, signed) = score(peer, reference);
    (job.metrics, job.signed) = (metrics, Some(signed));
    job.serial += 1;
    *last = (truth.status.rows_done, job.serial);
}

/// Error metrics of `method` against `reference` where both are measured,
/// and the signed error per pixel (NaN elsewhere).
pub fn score(method: &Grid, reference: &Grid) -> (Option<ErrorMetrics>, Grid) {
    let mut signed = vec![f32::NAN; reference.values.len()];
    let (mut values, mut truth) = (vec![], vec![]);
    if (method.width, method.height) == (reference.width, reference.height) {
        for (i, (&m, &r)) in method.values.iter().zip(&reference.values).enumerate() {
            if m.is_nan() || r.is_nan() {
                continue;
            }
            values.push(m);
            truth.push(r);
            signed[i] = m - r;
        }
    }
    let metrics = (!values.is_empty()).then(|| ErrorMetrics::compute(&values, &truth));
    (metrics, Grid { width: reference.width, height: reference.height, values: signed })
}

#[cfg(test)]
mod tests {
    use super::*;
    use shadow_fins::{
        ground_truth::GroundTruth,
        light::{DiskLight, SphereLight},
        scenes::SceneId,
    };

    /// Receivers on the ground of box-over-plane, around the box's shadow.
    fn ground_receivers(ls: &LightSpaceScene) -> Vec<Receiver> {
        let mut out = vec![];
        for i in 0..24 {
            for j in 0..24 {
                let world = Vec3::new(-1.5 + i as f32 * 0.125, 0.0, -1.5 + j as f32 * 0.125);
                out.push(Receiver { position: ls.frame.to_frame(world), normal: ls.frame.dir_to_frame(Vec3::Y) });
            }
        }
        out
    }

    #[test]
    fn the_best_peer_is_close_to_the_truth_and_a_sphere_light_is_routed_by_face() {
        let built = SceneId::BoxOverPlane.build();
        for light in [
            Light::Disk(DiskLight::new(Vec3::new(0.3, 4.5, 0.2), Vec3::NEG_Y, 0.5).unwrap()),
            Light::Sphere(SphereLight::new(Vec3::new(0.3, 4.5, 0.2), 0.5).unwrap()),
        ] {
            let ls = LightSpaceScene::new(&built.scene, light);
            let receivers = ground_receivers(&ls);
            let truth = GroundTruth::new(&ls, 1024);
            let reference: Vec<f32> = receivers.iter().map(|r| truth.visibility(*r)).collect();
            let go = AtomicBool::new(false);
            let blended = peer_visibility(PeerMethod::WedgeBlending, &built.scene, &ls, &receivers, &go).unwrap();
            let grid = |values: Vec<f32>| Grid { width: 24, height: 24, values };
            let (metrics, signed) = score(&grid(blended.clone()), &grid(reference.clone()));
            let metrics = metrics.expect("measured");
            // The box's shadow is on these receivers: not a trivially lit patch.
            assert!(reference.iter().any(|v| *v < 0.05) && reference.iter().any(|v| *v > 0.95));
            assert!(metrics.mae < 0.03, "{light:?}: wedge blending MAE {}", metrics.mae);
            assert!(blended.iter().all(|v| (0.0..=1.0).contains(v)));
            assert_eq!(signed.values.iter().filter(|v| v.is_finite()).count(), 24 * 24);
            // And the outer-only plateaus are far worse (their umbra is the hard one).
            let plateaus = peer_visibility(PeerMethod::Plateaus, &built.scene, &ls, &receivers, &go).unwrap();
            // A raised cancel flag stops the job with nothing.
            let stop = AtomicBool::new(true);
            assert!(peer_visibility(PeerMethod::Plateaus, &built.scene, &ls, &receivers, &stop).is_none());
            let (plateau_metrics, _) = score(&grid(plateaus), &grid(reference));
            assert!(plateau_metrics.unwrap().mae > 2.0 * metrics.mae, "{light:?}");
        }
    }

    #[test]
    fn only_pixels_measured_by_both_are_scored() {
        let grid = |values: Vec<f32>| Grid { width: 2, height: 2, values };
        let (metrics, signed) = score(&grid(vec![0.5, f32::NAN, 1.0, 0.0]), &grid(vec![0.25, 0.5, f32::NAN, 0.0]));
        let m = metrics.unwrap();
        assert_eq!(m.count, 2);
        assert!((m.mae - 0.125).abs() < 1e-6);
        assert_eq!(signed.values[0], 0.25);
        assert!(signed.values[1].is_nan() && signed.values[2].is_nan());
        // Grids of another size (a resized window) score nothing.
        let other = Grid { width: 1, height: 4, values: vec![0.0; 4] };
        assert!(score(&other, &grid(vec![0.0; 4])).0.is_none());
    }
}
