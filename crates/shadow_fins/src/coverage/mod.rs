//! # Exact coverage with occluder fusion (beyond the paper)
//!
//! The fraction of the light a receiver sees, counted over `N` light samples,
//! from the scene's *potential silhouette edges* alone, with occluders fused
//! exactly. Fins soften each occluder's own outline and then combine
//! occluders by a rule (min, product); on real assets made of many
//! overlapping, interpenetrating parts no rule is right, because the
//! silhouette of a union is not the union of the silhouettes. Here nothing is
//! combined by a rule: per light sample `s`, the *depth complexity* `D(s)` —
//! how many caster triangles the segment from the receiver `p` to `s`
//! crosses — is counted, and the sample is visible iff `D(s) = 0`.
//!
//! The count comes from edges, not triangles (Laine, Aila, Assarsson,
//! Lehtinen, Akenine-Möller, *Soft Shadow Volumes for Ray Tracing*, 2005):
//!
//! - **(C1)** `D(s) = D(r) + Σ_e σ_e(p) · χ_e(s)`, where `r` is one reference
//!   point of the light whose `D(r)` is found by one ray (through a BVH here,
//!   from a light-space depth list on the GPU), `χ_e(s) = ±1` when the
//!   segment `r → s` on the light crosses the edge `e` projected from `p`
//!   onto the light (`+1` crossing to the side of the edge's positive plane
//!   normal, `−1` back), else 0;
//! - **(C2)** `σ_e(p) = Σ_F side(F)`: per face `F` of the edge, `±1` as `F`
//!   lies on the positive or negative side of the plane through `p` and `e`.
//!   An edge whose two faces lie on opposite sides (not a silhouette seen
//!   from `p`) cancels; a fold seen from `p` counts twice; a boundary edge of
//!   an open mesh once. This is exact for any triangle soup: open sheets,
//!   non-manifold edges, interpenetrating closed parts;
//! - **(C3)** only *potential silhouette edges* can have `χ ≠ 0`: edges that
//!   are silhouettes from some point of the light (a face's plane cuts the
//!   light, or its two faces face it differently), boundary edges and
//!   non-manifold edges. Where the segment `p → s` passes through an edge the
//!   edge's silhouette status from `p` and from `s` agree, so an edge that is
//!   a silhouette from no light point never contributes. They are extracted
//!   once per light ([`edges`]), the paper's silhouette pass with the disk's
//!   extent instead of its centre (Laine et al.'s PSE);
//! - **(C4)** an edge at depth `z` can reach a receiver at depth `z_p` only
//!   within map distance `R(1/z − 1/z_p)` of it (the cross-section of the cone
//!   from the receiver to the disk); the edges are binned by that footprint
//!   into a map-space grid ([`index`]), so a receiver visits the edges of its
//!   cell only — the tiled edge list a GPU walks per pixel.
//!
//! Every test is a sign of a 3×3 determinant of light-frame vectors (a plane
//! through `p`), so no division by a depth and no projection to infinity: an
//! edge is clipped to the part in front of the receiver and behind the near
//! plane, and triangles cut by the near plane add their cut as a boundary.
//! Radius 0 is the hard shadow exactly (every sample is the centre). The
//! light's part below the receiver's tangent plane is not counted, as in the
//! ground truth.

pub mod edges;
pub mod index;

use glam::{Vec2, Vec3};

use crate::{
    bvh::Bvh,
    ground_truth::disk_samples,
    light::Projection,
    oracle::Receiver,
    scene::{LightSpaceScene, Scene, surface_epsilon},
};

pub use edges::{CoverageEdge, potential_silhouette_edges};
pub use index::EdgeIndex;

/// Settings of the coverage method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CoverageSettings {
    /// Light samples `N` per receiver (Fibonacci spiral), 1..=4096; error
    /// against the truth falls as about `1/N` on an edge (default 256).
    pub samples: u32,
}

impl Default for CoverageSettings {
    fn default() -> Self {
        Self { samples: 256 }
    }
}

/// The reference point `r` of (C1), in unit-disk coordinates: a generic point
/// near the centre, so that its ray does not run along a modelled edge (an
/// axis-aligned scene's edges are often exactly below the centre).
pub const REFERENCE: Vec2 = Vec2::new(1.234e-3, 0.7731e-3);

/// What one receiver cost: edges of its cell, and those that reached the
/// sample loop (silhouettes seen from it, in front of it).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CoverageWork {
    pub cell_edges: u32,
    pub counted_edges: u32,
}

/// One scene under one light, prepared for coverage queries.
pub struct CoverageModel<'a> {
    pub light_space: &'a LightSpaceScene,
    pub settings: CoverageSettings,
    pub edges: Vec<CoverageEdge>,
    pub index: EdgeIndex,
    bvh: Bvh,
    /// Unit-disk sample points.
    samples: Vec<Vec2>,
    near: f32,
}

/// A 2D line in unit-disk coordinates: `value(q) = n · q + c`.
#[derive(Debug, Clone, Copy)]
struct Line {
    n: Vec2,
    c: f32,
}

impl Line {
    /// The plane test `w · u(q)` as a line in `q`, for the light's sample
    /// vector `u(q)` (see [`CoverageModel::sample_vector`]).
    #[inline]
    fn of(w: Vec3, shape: LightShape, p: Vec3) -> Self {
        match shape {
            // u(q) = (R q, 0) − p
            LightShape::Disk { radius } => Line { n: Vec2::new(w.x, w.y) * radius, c: -w.dot(p) },
            // u(q) = (tanθ q, −1)
            LightShape::Sun { tan_angle } => Line { n: Vec2::new(w.x, w.y) * tan_angle, c: -w.z },
        }
    }

    #[inline]
    fn positive(&self, q: Vec2) -> bool {
        self.n.dot(q) + self.c >= 0.0
    }
}

#[derive(Debug, Clone, Copy)]
enum LightShape {
    Disk { radius: f32 },
    Sun { tan_angle: f32 },
}

impl<'a> CoverageModel<'a> {
    /// Extracts the potential silhouette edges and bins them (C3, C4).
    pub fn new(scene: &Scene, light_space: &'a LightSpaceScene, settings: CoverageSettings) -> Self {
        let near = crate::oracle::near_depth(light_space);
        let edges = potential_silhouette_edges(scene, light_space, near);
        let index = EdgeIndex::new(&edges, &light_space.frame, light_space.reference_depth);
        Self {
            light_space,
            settings,
            index,
            edges,
            bvh: Bvh::new(&light_space.casters),
            samples: disk_samples(settings.samples.clamp(1, 4096)),
            near,
        }
    }

    fn shape(&self) -> LightShape {
        match self.light_space.frame.projection {
            Projection::Perspective { radius } => LightShape::Disk { radius },
            Projection::Orthographic { tan_angle } => LightShape::Sun { tan_angle },
        }
    }

    /// The vector from the receiver `p` towards light sample `q` (unit-disk
    /// coordinates): to the point `(R q, 0)` of the disk, or along the
    /// direction `(tanθ q, −1)` to the sun.
    #[inline]
    fn sample_vector(shape: LightShape, p: Vec3, q: Vec2) -> Vec3 {
        match shape {
            LightShape::Disk { radius } => (q * radius).extend(0.0) - p,
            LightShape::Sun { tan_angle } => (q * tan_angle).extend(-1.0),
        }
    }

    /// Visibility of the light from a receiver, `V ∈ [0, 1]`.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        self.visibility_and_work(receiver).0
    }

    /// [`Self::visibility`] and what it cost.
    pub fn visibility_and_work(&self, receiver: Receiver) -> (f32, CoverageWork) {
        let mut work = CoverageWork::default();
        let ls = self.light_space;
        let eps = surface_epsilon(receiver.position, ls.extent);
        let p = receiver.position + receiver.normal * eps;
        if !p.is_finite() || (ls.frame.is_perspective() && !(p.z > self.near)) {
            return (0.0, work);
        }
        let shape = self.shape();
        // The light's part above the receiver's horizon.
        let n = receiver.normal;
        let above: Vec<bool> = self.samples.iter().map(|&q| n.dot(Self::sample_vector(shape, p, q)) >= 0.0).collect();
        let total = above.iter().filter(|a| **a).count();
        if total == 0 {
            return (0.0, work);
        }
        let u_r = Self::sample_vector(shape, p, REFERENCE);
        let reference_count = match shape {
            LightShape::Disk { .. } => self.bvh.count_hits(p, u_r, eps / u_r.length().max(eps), 1.0),
            LightShape::Sun { .. } => self.bvh.count_hits(p, u_r, eps, ls.extent * 4.0 + p.z.abs()),
        } as i32;
        let mut depth = vec![reference_count; self.samples.len()];
        for &id in self.index.cell(ls.frame.map(p)) {
            work.cell_edges += 1;
            let e = &self.edges[id as usize];
            if !self.index.may_reach(id, e, p, &ls.frame) {
                continue;
            }
            // The part of the edge between the near plane and the receiver.
            let Some((a, b)) = e.clipped(self.near, p.z) else { continue };
            let (da, db) = (a - p, b - p);
            let normal = da.cross(db);
            // (C2): the faces' sides of the plane through p and the edge.
            let sigma: i32 =
                e.third[..e.faces as usize].iter().map(|v| if normal.dot(*v - p) >= 0.0 { 1 } else { -1 }).sum();
            if sigma == 0 {
                continue;
            }
            work.counted_edges += 1;
            let edge_line = Line::of(normal, shape, p);
            let r_side = edge_line.positive(REFERENCE);
            // Planes through p, the reference ray and each end (C1's crossing test).
            let line_a = Line::of(da.cross(u_r), shape, p);
            let line_b = Line::of(db.cross(u_r), shape, p);
            let step = if r_side { -sigma } else { sigma };
            for (k, &q) in self.samples.iter().enumerate() {
                if edge_line.positive(q) != r_side && line_a.positive(q) != line_b.positive(q) {
                    depth[k] += step;
                }
            }
        }
        let visible = depth.iter().zip(&above).filter(|(d, a)| **a && **d == 0).count();
        (visible as f32 / total as f32, work)
    }
}
