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
//!   into a map-space grid ([`index`]), each cell keeping only the edges
//!   that are a silhouette (C2) from some receiver it can hold, so a
//!   receiver visits the edges of its cell only — the tiled edge list a GPU
//!   walks per pixel; the raster reference count walks two short lists, the
//!   faces (each once) and the edges that come within its move of the cell.
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
pub mod reference;

use glam::{Vec2, Vec3};

use crate::{
    bvh::Bvh,
    light::Projection,
    receiver::Receiver,
    scene::{LightSpaceScene, Scene, surface_epsilon},
};

pub use edges::{CoverageEdge, potential_silhouette_edges};
pub use index::EdgeIndex;
pub use reference::{DEPTH_LIST_LENGTH, DepthLists, ReferenceCount, far_list_length};

/// Settings of the coverage method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CoverageSettings {
    /// Light samples `N` per receiver (Fibonacci spiral), 1..=4096; error
    /// against the truth falls as about `1/N` on an edge (default 256).
    pub samples: u32,
    /// Where `D(r)` comes from: a ray, or light-space depth lists (the GPU's way).
    pub reference: ReferenceCount,
}

impl Default for CoverageSettings {
    fn default() -> Self {
        Self { samples: 256, reference: ReferenceCount::Exact }
    }
}

/// The reference point `r` of (C1), in unit-disk coordinates: a generic point
/// near the centre, so that its ray does not run along a modelled edge (an
/// axis-aligned scene's edges are often exactly below the centre).
pub const REFERENCE: Vec2 = Vec2::new(1.234e-3, 0.7731e-3);

/// The most casters `D(c)` counts through depth lists: the GPU keeps each
/// sample's count in 8 bit planes (modulo 256), so the reference count
/// saturates here on both sides (a receiver behind more than 127 casters
/// along the centre ray; none in our scenes comes near).
pub const MAX_REFERENCE_COUNT: i32 = 127;

/// What one receiver cost: edges of its cell, those within its footprint
/// bound and in front of it (the culling's survivors), and those that
/// reached the sample loop (silhouettes seen from it).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CoverageWork {
    pub cell_edges: u32,
    pub reaching_edges: u32,
    pub counted_edges: u32,
}

/// One scene under one light, prepared for coverage queries.
pub struct CoverageModel<'a> {
    pub light_space: &'a LightSpaceScene,
    pub settings: CoverageSettings,
    pub edges: Vec<CoverageEdge>,
    pub index: EdgeIndex,
    /// The raster reference count's depth lists (`None` for the exact one).
    pub depth_lists: Option<DepthLists>,
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
            // u(q) = o + r (q_x e1 + q_y e2) − p
            LightShape::Outline { center, radius, e1, e2 } => {
                Line { n: Vec2::new(w.dot(e1), w.dot(e2)) * radius, c: w.dot(center - p) }
            }
        }
    }

    #[inline]
    fn positive(&self, q: Vec2) -> bool {
        self.n.dot(q) + self.c >= 0.0
    }
}

#[derive(Debug, Clone, Copy)]
enum LightShape {
    Disk {
        radius: f32,
    },
    Sun {
        tan_angle: f32,
    },
    /// A sphere's outline seen from one receiver (`light::outline_seen_from`):
    /// the disk of centre `center`, radius `radius`, spanned by `e1`, `e2`.
    Outline {
        center: Vec3,
        radius: f32,
        e1: Vec3,
        e2: Vec3,
    },
}

impl<'a> CoverageModel<'a> {
    /// Extracts the potential silhouette edges and bins them (C3, C4).
    pub fn new(scene: &Scene, light_space: &'a LightSpaceScene, settings: CoverageSettings) -> Self {
        let near = crate::oracle::near_depth(light_space);
        let edges = potential_silhouette_edges(scene, light_space, near);
        let depth_lists = match settings.reference {
            ReferenceCount::Exact => None,
            ReferenceCount::Raster { resolution, depths } => {
                Some(DepthLists::new(light_space, near, resolution, depths))
            }
        };
        // The raster reference count moves up to a texel and a half from the receiver.
        let margin = depth_lists.as_ref().map(|d| 1.5 * d.region.texel);
        let index = EdgeIndex::coverage(&edges, &light_space.frame, light_space.reference_depth, margin);
        Self {
            light_space,
            settings,
            index,
            edges,
            depth_lists,
            bvh: Bvh::new(&light_space.casters),
            samples: light_space.frame.aperture.samples(settings.samples.clamp(1, 4096)),
            near,
        }
    }

    /// The light as receiver `p` sees it; `None` when `p` is inside a
    /// sphere light (nothing can come between).
    fn shape_at(&self, p: Vec3) -> Option<LightShape> {
        if let Some(radius) = self.light_space.frame.sphere_radius() {
            let (center, radius, e1, e2) = crate::light::outline_seen_from(radius, p)?;
            return Some(LightShape::Outline { center, radius, e1, e2 });
        }
        Some(match self.light_space.frame.projection {
            Projection::Perspective { radius } => LightShape::Disk { radius },
            Projection::Orthographic { tan_angle } => LightShape::Sun { tan_angle },
        })
    }

    /// The vector from the receiver `p` towards light sample `q` (unit-disk
    /// coordinates): to the point `(R q, 0)` of the disk, or along the
    /// direction `(tanθ q, −1)` to the sun.
    #[inline]
    fn sample_vector(shape: LightShape, p: Vec3, q: Vec2) -> Vec3 {
        match shape {
            LightShape::Disk { radius } => (q * radius).extend(0.0) - p,
            LightShape::Sun { tan_angle } => (q * tan_angle).extend(-1.0),
            LightShape::Outline { center, radius, e1, e2 } => center + (e1 * q.x + e2 * q.y) * radius - p,
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
        let (p, eps) = self.lifted(receiver);
        if !p.is_finite() {
            return (0.0, work);
        }
        // Inside a sphere light nothing comes between (before the near
        // plane's test, as the GPU pass orders them).
        let Some(shape) = self.shape_at(p) else { return (1.0, work) };
        if ls.frame.is_perspective() && !(p.z > self.near) {
            return (0.0, work);
        }
        // The light's part above the receiver's horizon.
        let n = receiver.normal;
        let above: Vec<bool> = self.samples.iter().map(|&q| n.dot(Self::sample_vector(shape, p, q)) >= 0.0).collect();
        let total = above.iter().filter(|a| **a).count();
        if total == 0 {
            return (0.0, work);
        }
        let (reference, reference_count) = match &self.depth_lists {
            None => {
                let u_r = Self::sample_vector(shape, p, REFERENCE);
                let count = self.count_to_light(shape, p, u_r, eps);
                (REFERENCE, count as i32)
            }
            Some(lists) => (Vec2::ZERO, self.raster_reference_count(lists, p, receiver.normal, None)),
        };
        let u_r = Self::sample_vector(shape, p, reference);
        let mut depth = vec![reference_count; self.samples.len()];
        for &id in self.index.cell(ls.frame.map(p)) {
            work.cell_edges += 1;
            let e = &self.edges[id as usize];
            if !self.index.may_reach(id, e, p, &ls.frame) {
                continue;
            }
            // The part of the edge between the near plane and the receiver.
            let Some((a, b)) = e.clipped(self.near, p.z) else { continue };
            work.reaching_edges += 1;
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
            let r_side = edge_line.positive(reference);
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

    /// The receiver lifted off its surface by the core's `surface_epsilon`
    /// (the point every query starts from), and that lift.
    fn lifted(&self, receiver: Receiver) -> (Vec3, f32) {
        let eps = surface_epsilon(receiver.position, self.light_space.extent);
        (receiver.position + receiver.normal * eps, eps)
    }

    /// `D(c)` both ways at a receiver (exact ray, depth lists): what the
    /// raster reference count is tested against.
    #[doc(hidden)]
    pub fn reference_counts(&self, receiver: Receiver) -> Option<(i32, i32)> {
        let lists = self.depth_lists.as_ref()?;
        let (p, eps) = self.lifted(receiver);
        let shape = self.shape_at(p)?;
        let u = Self::sample_vector(shape, p, Vec2::ZERO);
        let exact = self.count_to_light(shape, p, u, eps) as i32;
        Some((exact, self.raster_reference_count(lists, p, receiver.normal, None)))
    }

    /// The raster reference count at a receiver through the cell's reference
    /// lists and through every face and edge: equal unless the lists left
    /// out one the move passes (what the lists are tested against).
    #[doc(hidden)]
    pub fn reference_lists_against_all(&self, receiver: Receiver) -> Option<(i32, i32)> {
        let lists = self.depth_lists.as_ref()?;
        let (p, _) = self.lifted(receiver);
        self.shape_at(p)?;
        let faces: Vec<u32> = (0..self.index.faces().len() as u32).collect();
        let edges: Vec<u32> = (0..self.edges.len() as u32).collect();
        let all = self.raster_reference_count(lists, p, receiver.normal, Some((&faces, &edges)));
        Some((self.raster_reference_count(lists, p, receiver.normal, None), all))
    }

    /// Faces crossed from the receiver `p` along `u` to the light: up to
    /// the light point (a disk or a sphere's outline), or out of the scene
    /// (the sun).
    fn count_to_light(&self, shape: LightShape, p: Vec3, u: Vec3, eps: f32) -> u32 {
        let (t_min, t_max) = match shape {
            LightShape::Disk { .. } | LightShape::Outline { .. } => (eps / u.length().max(eps), 1.0),
            LightShape::Sun { .. } => (eps, self.light_space.extent * 4.0 + p.z.abs()),
        };
        let ls = self.light_space;
        if ls.caster_cutouts.is_empty() {
            self.bvh.count_hits(p, u, t_min, t_max)
        } else {
            self.bvh.count_hits_where(p, u, t_min, t_max, |k, a, b| ls.blocks_at(k as usize, a, b))
        }
    }

    /// `D(c)` from the depth lists: the count along a texel centre's ray up to
    /// the receiver's depth, then (C1) with the light's centre as apex along
    /// the move, at that depth, from the texel centre's ray to the receiver:
    /// each edge crossed in front of the receiver adds its faces' sides of the
    /// plane through the centre ray and it.
    ///
    /// The move runs at the receiver's depth, so its end can pass through a
    /// face — where an object stands on the receiver's surface — and a face
    /// passed through toggles whether it lies between the light and the
    /// moving point with no edge crossed. So the reference list's faces are
    /// tested against the move too (each once: `EdgeIndex::reference_faces`):
    /// a face crossed counts `−1` when the move leaves its light side, `+1`
    /// when it enters it. The
    /// receiver's own surface is kept out of the way by taking, of the four
    /// texel centres around the receiver, the one whose ray passes furthest in
    /// front of the receiver's tangent plane (a plane through the receiver has
    /// texel centres on both its sides), so the receiver needs no texel-sized
    /// lift, which cost accuracy at every contact. Exact up to faces with no
    /// potential silhouette edge (the inside of a large flat region) passed
    /// through within a texel of the receiver, and to the lists' length.
    ///
    /// `walk`: the (faces, edges) to test instead of the cell's reference lists.
    fn raster_reference_count(&self, lists: &DepthLists, p: Vec3, normal: Vec3, walk: Option<(&[u32], &[u32])>) -> i32 {
        let frame = &self.light_space.frame;
        let region = &lists.region;
        let m_p = frame.map(p);
        let at_depth = |m: Vec2| if frame.is_perspective() { (m * p.z).extend(p.z) } else { m.extend(p.z) };
        let corner = ((m_p - region.min) / region.texel - 0.5).floor();
        let mut candidates: Vec<((u32, u32), Vec3, f32)> = Vec::with_capacity(4);
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let (x, y) = (corner.x + dx, corner.y + dy);
            let r = region.resolution as f32;
            if x >= 0.0 && y >= 0.0 && x < r && y < r {
                let texel = (x as u32, y as u32);
                let p_t = at_depth(region.texel_center(texel.0, texel.1));
                candidates.push((texel, p_t, normal.dot(p_t - p)));
            }
        }
        // The first of the best (the GPU's order: ties, as on a flat ground, pick alike).
        let Some(&(texel, p_t, _)) =
            candidates.iter().fold(None, |best: Option<&((u32, u32), Vec3, f32)>, c| match best {
                Some(b) if !(c.2 > b.2) => Some(b),
                _ => Some(c),
            })
        else {
            return 0;
        };
        let (faces, edges) = walk.unwrap_or((self.index.reference_faces(m_p), self.index.reference_edges(m_p)));
        let mut count = lists.count_before(texel, p.z) as i32;
        count += self.faces_passed(faces, p_t, p);
        for &id in edges {
            let e = &self.edges[id as usize];
            let Some((a, b)) = e.clipped(self.near, p.z) else { continue };
            // The plane through the centre ray and the edge: through the
            // light's centre (disk), or containing its direction (sun).
            let n = if frame.is_perspective() { a.cross(b) } else { (b - a).cross(Vec3::Z) };
            let side = |x: Vec3| n.dot(x - a) >= 0.0;
            let (from, to) = (side(p_t), side(p));
            if from == to {
                continue;
            }
            // The edge's ends on either side of the swept plane (the centre
            // rays through the move): one plane test for both edges at a
            // shared vertex, so a move through it counts once.
            let m = if frame.is_perspective() { p_t.cross(p) } else { (p - p_t).cross(Vec3::Z) };
            if (m.dot(a - p_t) >= 0.0) == (m.dot(b - p_t) >= 0.0) {
                continue;
            }
            let sigma: i32 = e.third[..e.faces as usize].iter().map(|v| if side(*v) { 1 } else { -1 }).sum();
            count += if to { sigma } else { -sigma };
        }
        count.clamp(0, MAX_REFERENCE_COUNT)
    }

    /// The change in how many faces lie between the light's centre and a
    /// point moving from `from` to `to` through the faces it passes: the
    /// reference list's faces (`EdgeIndex::reference_faces`, each face once).
    fn faces_passed(&self, cell: &[u32], from: Vec3, to: Vec3) -> i32 {
        let frame = &self.light_space.frame;
        // The light's side of a face: towards the centre (disk) or up the sun.
        let light_side = |n: Vec3, a: Vec3| if frame.is_perspective() { n.dot(-a) } else { -n.z };
        let mut change = 0;
        for &id in cell {
            let [a, b, c] = self.index.faces()[id as usize];
            let n = (b - a).cross(c - a);
            let (fa, fb) = (n.dot(from - a), n.dot(to - a));
            if (fa >= 0.0) == (fb >= 0.0) {
                continue;
            }
            // Where the move meets the face's plane, inside the triangle?
            let x = from + (to - from) * (fa / (fa - fb));
            let inside = |p: Vec3, q: Vec3| n.dot((q - p).cross(x - p)) >= 0.0;
            if !(inside(a, b) && inside(b, c) && inside(c, a)) {
                continue;
            }
            // Leaving the light's side puts the face between light and point.
            let leaves = (fa >= 0.0) == (light_side(n, a) >= 0.0);
            change += if leaves { 1 } else { -1 };
        }
        change
    }
}
