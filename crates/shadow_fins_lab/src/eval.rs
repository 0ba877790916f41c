//! Evaluating a method or the ground truth over a set of receivers, timed.

use std::time::Instant;

use rayon::prelude::*;
use shadow_fins::{
    bvh::Bvh,
    camera::{Camera, pixel_receiver},
    coverage::{CoverageModel, CoverageWork, ReferenceCount},
    ground_truth::GroundTruth,
    light::Light,
    oracle::{FinSettings, FinShadowModel, Receiver},
    peers::PeerModel,
    scene::{LightSpaceScene, Scene},
};

use crate::setup::Measured;

/// Values per receiver and what they cost, measured in this run.
#[derive(Debug, Clone)]
pub struct Evaluation {
    pub values: Vec<f32>,
    /// Silhouettes, fins, layers (and maps, for the raster oracle), in ms.
    pub prepare_ms: f64,
    /// Per-receiver evaluation over all receivers, in ms.
    pub evaluate_ms: f64,
    pub silhouettes: usize,
    pub fins: usize,
    pub layers: usize,
    /// The coverage method's per-receiver work (`None` for the others).
    pub work: Option<WorkPercentiles>,
}

/// Per-receiver work of the coverage method over the receivers evaluated:
/// the edges listed in the receiver's cell, those its culling kept (within
/// its footprint, in front of it), and those that reached the sample loop
/// (silhouettes of the receiver).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkPercentiles {
    pub cell_edges: [u32; 2],
    pub reaching_edges: [u32; 2],
    pub counted_edges: [u32; 2],
    /// Means, for the cost of a whole frame.
    pub mean_cell_edges: f64,
    pub mean_reaching_edges: f64,
    pub mean_counted_edges: f64,
}

impl WorkPercentiles {
    /// p50 and p99 (nearest rank) of each count.
    pub fn of(work: &[CoverageWork]) -> Option<Self> {
        if work.is_empty() {
            return None;
        }
        let spread = |f: fn(&CoverageWork) -> u32| {
            let mut v: Vec<u32> = work.iter().map(f).collect();
            v.sort_unstable();
            let at = |q: f64| v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
            let mean = v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64;
            ([at(0.5), at(0.99)], mean)
        };
        let (cell_edges, mean_cell_edges) = spread(|w| w.cell_edges);
        let (reaching_edges, mean_reaching_edges) = spread(|w| w.reaching_edges);
        let (counted_edges, mean_counted_edges) = spread(|w| w.counted_edges);
        Some(Self {
            cell_edges,
            reaching_edges,
            counted_edges,
            mean_cell_edges,
            mean_reaching_edges,
            mean_counted_edges,
        })
    }
}

impl Evaluation {
    pub fn total_ms(&self) -> f64 {
        self.prepare_ms + self.evaluate_ms
    }
}

/// Caster depths per texel of the coverage method's depth lists through maps
/// (the plugin's).
pub use shadow_fins::coverage::DEPTH_LIST_LENGTH;

/// Evaluates `measured` at every receiver (light frame). With
/// `map_resolution`, fins are looked up in raster maps and the coverage
/// method counts `D(r)` from depth lists at that resolution.
///
/// A sphere light's receivers go to the cube face that shadows each
/// ([`LightSpaceScene::faces`]), evaluated in that face's frame and put back
/// in order; the counts and times are the six faces' sums.
pub fn evaluate(
    scene: &Scene,
    light_space: &LightSpaceScene,
    measured: Measured,
    settings: FinSettings,
    map_resolution: Option<u32>,
    samples: u32,
    receivers: &[Receiver],
) -> Evaluation {
    if !matches!(light_space.light, Light::Sphere(_)) {
        return evaluate_in_frame(scene, light_space, measured, settings, map_resolution, samples, receivers);
    }
    let start = Instant::now();
    let groups = light_space.group_by_face(scene, receivers);
    let faces_ms = ms(start);
    let mut total = Evaluation {
        values: vec![0.0; receivers.len()],
        prepare_ms: faces_ms,
        evaluate_ms: 0.0,
        silhouettes: 0,
        fins: 0,
        layers: 0,
        work: None,
    };
    for group in groups {
        let ev =
            evaluate_in_frame(scene, &group.light_space, measured, settings, map_resolution, samples, &group.receivers);
        for (&i, v) in group.indices.iter().zip(ev.values) {
            total.values[i] = v;
        }
        total.prepare_ms += ev.prepare_ms;
        total.evaluate_ms += ev.evaluate_ms;
        total.silhouettes += ev.silhouettes;
        total.fins += ev.fins;
        total.layers = total.layers.max(ev.layers);
    }
    total
}

/// [`evaluate`] in one frame.
fn evaluate_in_frame(
    scene: &Scene,
    light_space: &LightSpaceScene,
    measured: Measured,
    settings: FinSettings,
    map_resolution: Option<u32>,
    samples: u32,
    receivers: &[Receiver],
) -> Evaluation {
    let start = Instant::now();
    match measured {
        Measured::GroundTruth => {
            let gt = GroundTruth::new(light_space, samples);
            let prepare_ms = ms(start);
            let t = Instant::now();
            let values = receivers.par_iter().map(|r| gt.visibility(*r)).collect();
            Evaluation { values, prepare_ms, evaluate_ms: ms(t), silhouettes: 0, fins: 0, layers: 0, work: None }
        }
        Measured::Coverage(mut cs) => {
            // Through maps: the reference count from depth lists, as a GPU finds it.
            if let Some(resolution) = map_resolution {
                cs.reference = ReferenceCount::Raster { resolution, depths: DEPTH_LIST_LENGTH };
            }
            let model = CoverageModel::new(scene, light_space, cs);
            let prepare_ms = ms(start);
            let t = Instant::now();
            let (values, work): (Vec<f32>, Vec<CoverageWork>) =
                receivers.par_iter().map(|r| model.visibility_and_work(*r)).unzip();
            let evaluate_ms = ms(t);
            let work = WorkPercentiles::of(&work);
            Evaluation { values, prepare_ms, evaluate_ms, silhouettes: model.edges.len(), fins: 0, layers: 0, work }
        }
        Measured::Peer(peer) => {
            let model = PeerModel::for_receivers(peer, scene, light_space, receivers);
            let prepare_ms = ms(start);
            let t = Instant::now();
            let values = receivers.par_iter().map(|r| model.visibility(*r)).collect();
            Evaluation { values, prepare_ms, evaluate_ms: ms(t), silhouettes: 0, fins: 0, layers: 0, work: None }
        }
        Measured::Method(method) => {
            let model = FinShadowModel::new(scene, light_space, method, settings);
            let (silhouettes, fins, layers) = (model.silhouettes.len(), model.fins.len(), model.plan.len());
            let (values, prepare_ms, evaluate_ms) = match map_resolution {
                Some(res) => {
                    let maps = model.raster(res);
                    let prepare_ms = ms(start);
                    let t = Instant::now();
                    let v = receivers.par_iter().map(|r| maps.visibility(*r)).collect();
                    (v, prepare_ms, ms(t))
                }
                None => {
                    let index = model.analytic();
                    let prepare_ms = ms(start);
                    let t = Instant::now();
                    let v = receivers.par_iter().map_init(Vec::new, |buf, r| index.visibility_with(*r, buf)).collect();
                    (v, prepare_ms, ms(t))
                }
            };
            Evaluation { values, prepare_ms, evaluate_ms, silhouettes, fins, layers, work: None }
        }
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Primary hits of a camera: per pixel, the receiver it sees (light frame), or
/// `None` for the background. Normals face the camera.
pub fn camera_receivers(
    camera: &Camera,
    width: u32,
    height: u32,
    light_space: &LightSpaceScene,
) -> Vec<Option<Receiver>> {
    let bvh = Bvh::new(&light_space.casters);
    (0..width * height)
        .into_par_iter()
        .map(|i| pixel_receiver(camera, (i % width, i / width, width, height), light_space, &bvh))
        .collect()
}
