//! Environment lighting by convolution soft shadows (Annen et al. 2008,
//! §4.2, `004_…`): an environment map decomposed into a few area lights by
//! their greedy fit, each shadowed by convolution shadow maps
//! ([`ConvolutionModel`]), the lights' irradiance summed — against a
//! many-light ground truth in which every texel of the map is a light.
//!
//! **The fit** (§4.2, per cube face): light the brightest texel not yet
//! covered with a 1×1 square; grow it while the energy a step adds is more
//! than `t` of the grown square's energy (`E_delta / E_total > t`: a larger
//! `t` gives more, smaller lights); the light takes the square's energy
//! but leaves each texel at most the face's mean ("a residual amount … the
//! average amount of energy adjusted to the size of the area"), so later
//! squares may overlap it and blend; repeat until the face is covered. Squares, as the paper used for its
//! results (mipmaps filter isotropically); a square grows one texel at a
//! time towards one of its four corners, the corner whose step keeps the
//! most energy. What is ours where the paper leaves it open: what the
//! residuals still hold once the face is covered goes to the smallest
//! square over each texel (the fit conserves each face's energy; a sun's
//! texel keeps its residual with the sun's own light, not a sky square
//! that overlaps it);
//! each square becomes a distant light of its solid angle — a disk (a cap
//! of that solid angle; our distant lights are disks, as Arbree et al.'s
//! sources) towards the squares' energy-weighted direction.
//!
//! **Shading** (their §4.4 BRDFs): each light's irradiance at its centre
//! direction, `E = Σ energy_l · max(0, n·ω_l) · V_l`, `V_l` its convolution
//! visibility. The ground truth integrates the map exactly as texels:
//! `Σ_texels L Ω max(0, n·ω) · visible(ω)`, one ray per texel.

use glam::Vec3;

use crate::{
    bvh::Bvh,
    light::{Light, SunLight},
    peers::convolution::{ConvolutionModel, ConvolutionSettings},
    receiver::Receiver,
    scene::{LightSpaceScene, Scene},
};

/// A cube map of radiance (one channel), faces `+X, −X, +Y, −Y, +Z, −Z`,
/// `resolution²` texels each, row by row.
#[derive(Debug, Clone)]
pub struct CubeMap {
    pub resolution: usize,
    pub radiance: Vec<f32>,
}

impl CubeMap {
    /// The map of `radiance(ω)` at each texel's centre direction (negative
    /// or non-finite radiance reads 0).
    pub fn from_fn(resolution: usize, radiance: impl Fn(Vec3) -> f32) -> Self {
        let resolution = resolution.clamp(1, 512);
        let mut texels = Vec::with_capacity(6 * resolution * resolution);
        for face in 0..6 {
            for j in 0..resolution {
                for i in 0..resolution {
                    let v = radiance(texel_direction(resolution, face, i, j));
                    texels.push(if v.is_finite() { v.max(0.0) } else { 0.0 });
                }
            }
        }
        Self { resolution, radiance: texels }
    }

    /// An outdoor sky: a sun of angular radius `sun_radius` towards `sun`
    /// (`sun_radiance`), a sky brighter overhead than at the horizon
    /// (`sky_radiance` at the zenith, half at the horizon) and a dim ground
    /// (a tenth of it) below.
    pub fn sky(resolution: usize, sun: Vec3, sun_radius: f32, sun_radiance: f32, sky_radiance: f32) -> Self {
        let sun = sun.try_normalize().unwrap_or(Vec3::Y);
        let cos_sun = sun_radius.clamp(0.0, 1.4).cos();
        Self::from_fn(resolution, |w| {
            let sky = if w.y >= 0.0 { sky_radiance * (0.5 + 0.5 * w.y) } else { 0.1 * sky_radiance };
            if w.dot(sun) >= cos_sun { sky + sun_radiance } else { sky }
        })
    }

    /// Radiance × solid angle of every texel: what a texel light emits.
    fn energies(&self) -> Vec<f32> {
        let n = self.resolution;
        (0..6 * n * n)
            .map(|k| {
                let (i, j) = (k % n, (k / n) % n);
                self.radiance[k] * texel_solid_angle(n, i, j)
            })
            .collect()
    }
}

/// The unit direction through texel `(i, j)`'s centre of `face`.
pub fn texel_direction(resolution: usize, face: usize, i: usize, j: usize) -> Vec3 {
    let u = 2.0 * (i as f32 + 0.5) / resolution as f32 - 1.0;
    let v = 2.0 * (j as f32 + 0.5) / resolution as f32 - 1.0;
    let d = match face {
        0 => Vec3::new(1.0, -v, -u),
        1 => Vec3::new(-1.0, -v, u),
        2 => Vec3::new(u, 1.0, v),
        3 => Vec3::new(u, -1.0, -v),
        4 => Vec3::new(u, -v, 1.0),
        _ => Vec3::new(-u, -v, -1.0),
    };
    d.normalize()
}

/// The solid angle of texel `(i, j)` of a face: `(2/n)² / (1 + u² + v²)^{3/2}`
/// at its centre (the six faces sum to 4π within 0.1% at 32²).
pub fn texel_solid_angle(resolution: usize, i: usize, j: usize) -> f32 {
    let u = 2.0 * (i as f32 + 0.5) / resolution as f32 - 1.0;
    let v = 2.0 * (j as f32 + 0.5) / resolution as f32 - 1.0;
    let s = 2.0 / resolution as f32;
    s * s / (1.0 + u * u + v * v).powf(1.5)
}

/// One fitted area light: a square of a cube face, as a distant light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvLight {
    /// Unit direction towards the light.
    pub direction: Vec3,
    /// Its square's solid angle.
    pub solid_angle: f32,
    /// What it emits: radiance × solid angle, summed.
    pub energy: f32,
    /// Face, first texel `(i, j)` and side of the square.
    pub face: usize,
    pub square: (usize, usize, usize),
}

impl EnvLight {
    /// The distant disk light of its solid angle: a cap of angular radius
    /// `θ`, `2π(1 − cos θ) = Ω` (clamped to the sun's 1.4 rad); `None` for a
    /// direction that is zero or not finite.
    pub fn light(&self) -> Option<Light> {
        let theta = (1.0 - self.solid_angle / std::f32::consts::TAU).clamp(-1.0, 1.0).acos();
        let theta = if theta.is_finite() { theta.min(1.4) } else { 0.0 };
        SunLight::new(-self.direction, theta).ok().map(Light::Sun)
    }
}

/// Annen et al.'s greedy fit of squares to each face of `map` at threshold
/// `t` (see the module docs); faces without energy get no light.
pub fn fit_area_lights(map: &CubeMap, threshold: f32) -> Vec<EnvLight> {
    let n = map.resolution;
    let t = if threshold.is_finite() { threshold.clamp(1e-4, 1.0) } else { 0.1 };
    let energies = map.energies();
    let mut lights = vec![];
    for face in 0..6 {
        let mut e: Vec<f32> = (0..n * n).map(|k| energies[face * n * n + k]).collect();
        let total: f32 = e.iter().sum();
        if !(total > 0.0) {
            continue;
        }
        let mean = total / (n * n) as f32;
        let mut covered = vec![false; n * n];
        // Per texel, the smallest square over it (light index, side).
        let mut owner: Vec<Option<(usize, usize)>> = vec![None; n * n];
        let square_energy = |e: &[f32], (x0, y0, s): (usize, usize, usize)| -> f32 {
            (y0..y0 + s).flat_map(|y| (x0..x0 + s).map(move |x| (x, y))).map(|(x, y)| e[y * n + x]).sum()
        };
        // Texels not yet covered keep their energy: one sort finds each
        // next seed (the brightest uncovered).
        let mut by_energy: Vec<usize> = (0..n * n).collect();
        by_energy.sort_by(|a, b| e[*b].total_cmp(&e[*a]));
        let mut next = 0;
        loop {
            while next < by_energy.len() && covered[by_energy[next]] {
                next += 1;
            }
            let Some(&seed) = by_energy.get(next) else { break };
            let mut sq = (seed % n, seed / n, 1usize);
            let mut energy = e[seed];
            loop {
                // Grow towards the corner that keeps the most energy, if its
                // step adds more than `t` of the grown square's.
                let (x0, y0, s) = sq;
                let mut best: Option<((usize, usize, usize), f32)> = None;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    // (dx, dy) = (1, ·): the square grows left (x0 − 1), else right.
                    if s + 1 > n || (dx == 1 && x0 == 0) || (dy == 1 && y0 == 0) {
                        continue;
                    }
                    let grown = (x0 - dx, y0 - dy, s + 1);
                    if grown.0 + grown.2 > n || grown.1 + grown.2 > n {
                        continue;
                    }
                    let grown_energy = square_energy(&e, grown);
                    let added = grown_energy - energy;
                    if grown_energy > 0.0 && added / grown_energy > t && best.is_none_or(|(_, b)| grown_energy > b) {
                        best = Some((grown, grown_energy));
                    }
                }
                match best {
                    Some((grown, grown_energy)) => (sq, energy) = (grown, grown_energy),
                    None => break,
                }
            }
            let (x0, y0, s) = sq;
            let (mut taken, mut solid_angle, mut towards) = (0.0f32, 0.0f32, Vec3::ZERO);
            for y in y0..y0 + s {
                for x in x0..x0 + s {
                    let k = y * n + x;
                    let keep = e[k].min(mean);
                    taken += e[k] - keep;
                    towards += texel_direction(n, face, x, y) * e[k].max(1e-30);
                    solid_angle += texel_solid_angle(n, x, y);
                    e[k] = keep;
                    covered[k] = true;
                    if owner[k].is_none_or(|(_, side)| s < side) {
                        owner[k] = Some((lights.len(), s));
                    }
                }
            }
            lights.push(EnvLight {
                direction: towards.try_normalize().unwrap_or(texel_direction(n, face, x0, y0)),
                solid_angle,
                energy: taken,
                face,
                square: sq,
            });
        }
        // The residuals left once the face is covered go to the smallest
        // square over each texel (the light nearest its direction).
        for (k, o) in owner.iter().enumerate() {
            if let Some((light, _)) = o {
                lights[*light].energy += e[k];
            }
        }
    }
    lights.retain(|l| l.energy > 0.0);
    lights
}

/// A world-space receiver: point and unit normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldReceiver {
    pub position: Vec3,
    pub normal: Vec3,
}

/// Every casting face of `scene` in world space, in a BVH, with each
/// face's cut-out ([`crate::scene::caster_cutouts`]): the rays of the hard,
/// exact and truth paths alpha-test them, as the ground truth does
/// (`ground_truth.rs`) and as the convolution maps do.
struct WorldCasters {
    bvh: Bvh,
    cutouts: Vec<Option<crate::cutout::CasterCutout>>,
    masks: Vec<std::sync::Arc<crate::cutout::AlphaMask>>,
}

impl WorldCasters {
    fn new(scene: &Scene) -> Self {
        let triangles: Vec<[Vec3; 3]> = (scene.objects.iter().filter(|o| o.casts_shadows))
            .flat_map(|o| {
                let world: Vec<Vec3> = o.topology.positions.iter().map(|p| o.transform.transform_point3(*p)).collect();
                o.topology.faces.iter().map(move |f| f.map(|i| world[i as usize])).collect::<Vec<_>>()
            })
            .collect();
        let (cutouts, masks) = crate::scene::caster_cutouts(scene);
        Self { bvh: Bvh::new(&triangles), cutouts, masks }
    }

    /// True when the segment `origin + t·dir`, `t ∈ (t_min, t_max)`, crosses
    /// a face where it is opaque.
    fn blocked(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> bool {
        if self.cutouts.is_empty() {
            return self.bvh.any_hit(origin, dir, t_min, t_max);
        }
        let blocks =
            |k: u32, u: f32, v: f32| crate::cutout::caster_blocks_at(&self.cutouts, &self.masks, k as usize, u, v);
        self.bvh.any_hit_where(origin, dir, t_min, t_max, blocks)
    }
}

/// The ray offset off a receiver: a relative 1e-4 of the scene's size.
fn lift(scene_size: f32) -> f32 {
    1e-4 * scene_size.max(1e-30)
}

/// The many-light ground truth: every texel of the map a distant point
/// light, one ray each.
pub struct EnvironmentTruth {
    directions: Vec<Vec3>,
    energies: Vec<f32>,
    casters: WorldCasters,
    size: f32,
}

impl EnvironmentTruth {
    pub fn new(scene: &Scene, map: &CubeMap) -> Self {
        let n = map.resolution;
        let directions = (0..6 * n * n).map(|k| texel_direction(n, k / (n * n), k % n, (k / n) % n)).collect();
        let size = scene.bounds().map_or(1.0, |(lo, hi)| (hi - lo).length());
        Self { directions, energies: map.energies(), casters: WorldCasters::new(scene), size }
    }

    /// `(irradiance with shadows, without)` at a receiver.
    pub fn irradiance(&self, r: WorldReceiver) -> (f32, f32) {
        let o = r.position + r.normal * lift(self.size);
        let far = 4.0 * self.size + o.length();
        let (mut shadowed, mut open) = (0.0f32, 0.0f32);
        for (w, e) in self.directions.iter().zip(&self.energies) {
            let c = r.normal.dot(*w);
            if c <= 0.0 || *e <= 0.0 {
                continue;
            }
            open += e * c;
            if !self.casters.blocked(o, *w, 0.0, far) {
                shadowed += e * c;
            }
        }
        (shadowed, open)
    }
}

/// How each fitted light's visibility is found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightShadows {
    /// Convolution shadow maps (the paper's method).
    Convolution(ConvolutionSettings),
    /// One ray towards the light's centre: hard shadows.
    Hard,
    /// The light's disk sampled by `samples` rays: what the fit alone
    /// costs, shadows exact.
    Exact { samples: u32 },
}

/// The shadowed irradiance `Σ energy · max(0, n·ω) · V` of the fitted
/// `lights` at each receiver, each light shadowed as `shadows` says. One
/// light at a time (a light's maps are made, used over every receiver on
/// `threads` threads, and dropped: 450 lights' summed-area tables would
/// not fit in memory at once); lights with no valid direction are skipped.
pub fn shade(
    scene: &Scene,
    lights: &[EnvLight],
    shadows: LightShadows,
    receivers: &[WorldReceiver],
    threads: usize,
) -> Vec<f32> {
    let size = scene.bounds().map_or(1.0, |(lo, hi)| (hi - lo).length());
    let bvh = matches!(shadows, LightShadows::Hard | LightShadows::Exact { .. }).then(|| WorldCasters::new(scene));
    let mut sum = vec![0.0f32; receivers.len()];
    const CHUNK: usize = 256;
    for light in lights {
        let Some(as_light) = light.light() else { continue };
        let ls = LightSpaceScene::new(scene, as_light);
        let model = match shadows {
            LightShadows::Convolution(s) => Some(ConvolutionModel::new(&ls, s)),
            _ => None,
        };
        let visibility = |r: &WorldReceiver| -> f32 {
            match (shadows, &model, &bvh) {
                (LightShadows::Convolution(_), Some(m), _) => m.visibility(Receiver {
                    position: ls.frame.to_frame(r.position),
                    normal: ls.frame.dir_to_frame(r.normal),
                }),
                (LightShadows::Hard, _, Some(bvh)) => {
                    let o = r.position + r.normal * lift(size);
                    if bvh.blocked(o, light.direction, 0.0, 4.0 * size + o.length()) { 0.0 } else { 1.0 }
                }
                (LightShadows::Exact { samples }, _, Some(bvh)) => disk_visibility(bvh, size, *r, light, samples),
                _ => 1.0,
            }
        };
        // Small chunks handed out by a counter: receivers' costs differ a lot
        // (facing away: nothing; exact: 64 rays), fixed halves would wait on
        // the slower one at every light.
        let next = std::sync::atomic::AtomicUsize::new(0);
        let chunks: Vec<std::sync::Mutex<&mut [f32]>> = sum.chunks_mut(CHUNK).map(std::sync::Mutex::new).collect();
        std::thread::scope(|scope| {
            for _ in 0..threads.max(1) {
                let (visibility, next, chunks) = (&visibility, &next, &chunks);
                scope.spawn(move || {
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(out) = chunks.get(k) else { break };
                        let mut out = out.lock().unwrap_or_else(|e| e.into_inner());
                        for (o, r) in out.iter_mut().zip(&receivers[k * CHUNK..]) {
                            let c = r.normal.dot(light.direction);
                            if c > 0.0 {
                                *o += light.energy * c * visibility(r);
                            }
                        }
                    }
                });
            }
        });
    }
    sum
}

/// The share of `light`'s disk a receiver sees: `samples` rays through a
/// golden-angle spiral over the disk (equal areas of the tangent plane,
/// equal solid angles for a small cap).
fn disk_visibility(casters: &WorldCasters, size: f32, r: WorldReceiver, light: &EnvLight, samples: u32) -> f32 {
    let (u, v) = crate::peers::geometry::across(light.direction);
    let tan = match light.light() {
        Some(Light::Sun(s)) => s.angular_radius.tan(),
        _ => 0.0,
    };
    let o = r.position + r.normal * lift(size);
    let far = 4.0 * size + o.length();
    let n = samples.max(1);
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let seen = (0..n)
        .filter(|k| {
            let radius = ((*k as f32 + 0.5) / n as f32).sqrt() * tan;
            let (s, c) = (*k as f32 * golden).sin_cos();
            let w = (light.direction + u * (radius * c) + v * (radius * s)).normalize();
            !casters.blocked(o, w, 0.0, far)
        })
        .count();
    seen as f32 / n as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cube_maps_texels_cover_the_sphere() {
        let n = 32;
        let total: f32 = (0..6).map(|_| (0..n * n).map(|k| texel_solid_angle(n, k % n, k / n)).sum::<f32>()).sum();
        assert!((total - 4.0 * std::f32::consts::PI).abs() < 0.01 * 4.0 * std::f32::consts::PI, "{total}");
        // Each face's centre texel looks along its axis.
        for (face, axis) in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z].into_iter().enumerate() {
            assert!(texel_direction(31, face, 15, 15).dot(axis) > 0.999, "face {face}");
        }
    }

    #[test]
    fn the_fit_conserves_each_faces_energy_and_its_threshold_sets_the_light_count() {
        let map = CubeMap::sky(32, Vec3::new(0.3, 0.8, 0.2), 0.05, 500.0, 1.0);
        let total: f32 = map.energies().iter().sum();
        let mut counts = vec![];
        for t in [0.05, 0.15, 0.4] {
            let lights = fit_area_lights(&map, t);
            let fitted: f32 = lights.iter().map(|l| l.energy).sum();
            assert!((fitted - total).abs() <= 1e-3 * total, "t {t}: {fitted} of {total}");
            assert!(lights.iter().all(|l| l.direction.is_normalized() && l.solid_angle > 0.0));
            counts.push(lights.len());
        }
        assert!(counts[0] < counts[1] && counts[1] < counts[2], "light counts {counts:?}");
        // The brightest light is the sun, pointing at it.
        let lights = fit_area_lights(&map, 0.15);
        let sun = lights.iter().max_by(|a, b| a.energy.total_cmp(&b.energy)).unwrap();
        assert!(sun.direction.dot(Vec3::new(0.3, 0.8, 0.2).normalize()) > 0.99, "{sun:?}");
    }

    #[test]
    fn a_uniform_map_gives_open_irradiance_pi_times_its_radiance_on_either_side() {
        // Nothing casts: the truth is the cosine integral over the upper
        // hemisphere, π L, and the fitted lights' sum comes close to it.
        let map = CubeMap::from_fn(32, |_| 1.0);
        let scene = Scene::new(vec![]);
        let truth = EnvironmentTruth::new(&scene, &map);
        let r = WorldReceiver { position: Vec3::ZERO, normal: Vec3::Y };
        let (shadowed, open) = truth.irradiance(r);
        assert!((open - std::f32::consts::PI).abs() < 0.02, "{open}");
        assert_eq!(shadowed, open);
        // Each light shades at its centre's cosine (their §4.4): squares
        // across the horizon lose the half above it; smaller ones, less.
        let errors: Vec<f32> = [0.15, 0.4, 0.8]
            .iter()
            .map(|t| {
                let fitted = shade(&scene, &fit_area_lights(&map, *t), LightShadows::Hard, &[r], 1)[0];
                (fitted - open).abs() / open
            })
            .collect();
        println!("relative error of the fitted lights' open irradiance: {errors:?}");
        assert!(errors[2] < errors[0] && errors[2] < 0.1, "{errors:?}");
    }
}
