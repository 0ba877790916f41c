//! Single sample soft shadows (Parker, Shirley, Smits 1998; `001_…`): one
//! shadow ray per receiver, towards the light's centre, against *softened*
//! occluders.
//!
//! Each occluder is its own opaque inner object wrapped in a semi-opaque
//! outer shell. The paper sizes the shell so that the shadow's penumbra is as
//! wide as the real one (its Figure 3): at a distance `t` from the receiver,
//! along a shadow ray of length `A` to a light of diameter `D`, the shell is
//! `b = D·t/A` thick (the appendix's `b = D·t₀/‖l − o‖`). A ray passing at a
//! distance `d < b` from the object gets `τ = d/b` and the visibility
//! `s = 3τ² − 2τ³` (the Bernstein interpolant of the sinusoid a straight
//! edge gives, §3); a ray through the object gets 0. Several occluders
//! combine by thresholding, `s = min(s₁, s₂, …)`, the paper's conservative
//! choice ("never darker than they should be").
//!
//! What is ours, where the paper leaves it open (it gives spheres exactly
//! and polygons in one sentence):
//! - **the shell of a triangle**: the points seen from the receiver within
//!   `b(t)` of the triangle, perpendicular to the ray, at every depth `t`
//!   of the triangle (a "triangle with rounded corners" whose offset, seen
//!   along the ray, is `b`, as the appendix asks). Since `d/b = (d/t)·A/D`,
//!   `τ` is the tangent of the angle from the shadow ray to the nearest
//!   point of the triangle, over `D/A`: the triangle is projected centrally
//!   from the receiver onto the plane at unit distance across the ray, and
//!   `τ` is the distance of the ray from that polygon, over `D/A`;
//! - **the receiver's own surface**: triangles whose plane holds the
//!   receiver (its own surface, and any face seen edge-on from it) do not
//!   soften its ray. (The paper's receiver is a different
//!   object; without this a ground plane would darken itself under a
//!   grazing light, through its own neighbouring triangles.)
//! - **the sun**: `D/A` is the sun's angular diameter, `2 tan θ`.
//! - **a rectangle light** (`Aperture::Rect`): the shell is the triangle's
//!   Minkowski sum with the light's rectangle, seen from the receiver and
//!   doubled (the disk's `b = D·t/A` is that sum with the disk doubled:
//!   the full penumbra outside the centre's shadow). A rectangle is flat,
//!   so what the receiver sees of it is its central projection: the
//!   triangle is projected from the receiver onto the light's plane, and
//!   `τ` is the rectangle-norm distance `max(|q_x|/2a, |q_y|/2b)` of the
//!   light's centre from that polygon. Across a straight edge of normal
//!   `d` the shell is then `2h(d)` wide, `h` the rectangle's support
//!   function, as the fins' width; the disk's bounding circle (what `R`
//!   is for a rectangle) would make it `2√(a² + b²)` across every edge.
//!
//! The umbra is the hard shadow of the light's centre, so it is too large
//! wherever the real shadow has an inner penumbra (the paper says so).

use glam::{DVec2, Vec2, Vec3};

use crate::{
    bvh::{Bvh, ray_hits_box},
    light::{Aperture, Projection},
    peers::geometry::{across, clip_convex},
    receiver::Receiver,
    refine::Falloff,
    scene::{LightSpaceScene, surface_epsilon},
};

/// One scene under one light, ready for single-sample queries.
pub struct SingleSampleModel {
    bvh: Bvh,
    projection: Projection,
    aperture: Aperture,
    extent: f32,
    reference_depth: f32,
}

impl SingleSampleModel {
    pub fn new(light_space: &LightSpaceScene) -> Self {
        Self {
            bvh: Bvh::new(&light_space.casters),
            projection: light_space.frame.projection,
            aperture: light_space.frame.aperture,
            extent: light_space.extent,
            reference_depth: light_space.reference_depth,
        }
    }

    /// Visibility of the light from a receiver (light frame), in `[0, 1]`.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let eps = surface_epsilon(receiver.position, self.extent);
        let o = receiver.position + receiver.normal * eps;
        if !o.is_finite() {
            return 0.0;
        }
        // The shadow ray (unit direction `v`, length `a` to the light's
        // centre) and `D/A`, the shell's thickness per unit of distance.
        let (v, a, spread) = match self.projection {
            Projection::Perspective { radius } => {
                // At or behind the one-sided light's plane: unlit, as the ground truth says.
                if !(o.z > self.reference_depth * 1e-5) {
                    return 0.0;
                }
                let a = o.length();
                (-o / a, a, 2.0 * radius / a)
            }
            Projection::Orthographic { tan_angle } => (Vec3::NEG_Z, self.extent * 4.0 + o.z.abs(), 2.0 * tan_angle),
        };
        let t_min = eps;
        if self.bvh.any_hit(o, v, t_min, a) {
            return 0.0;
        }
        if !(spread > 0.0) || !spread.is_finite() {
            return 1.0;
        }
        let perspective = matches!(self.projection, Projection::Perspective { .. });
        if let Aperture::Rect { half_extents } = self.aperture {
            return self.rect_visibility(o, v, a, t_min, half_extents);
        }
        let (e1, e2) = across(v);
        // Shared by the box test (which narrows the search as `τ` falls) and the triangle test.
        let tau = std::cell::Cell::new(1.0f32);
        let inv_v = v.recip();
        self.bvh.for_each_candidate(
            |lo, hi| {
                // The farthest a box reaches along the ray bounds the shell's
                // radius over it; a box expanded by that radius that the ray
                // misses holds no point within the shell.
                let corners = box_corners(lo, hi);
                let t_far = corners.iter().map(|c| (*c - o).dot(v)).fold(f32::NEG_INFINITY, f32::max);
                if t_far <= t_min || (perspective && hi.z <= 0.0) {
                    return false;
                }
                let r = t_far.min(a) * spread * tau.get();
                ray_hits_box(lo - Vec3::splat(r), hi + Vec3::splat(r), o, inv_v, 0.0, t_far.min(a))
            },
            |_, tri| {
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                let len = n.length();
                // The receiver's own plane: no softening of its own ray.
                if !(len > 0.0) || ((o - tri[0]).dot(n) / len).abs() <= 2.0 * eps {
                    return;
                }
                if let Some(d) = angular_distance(tri, o, v, e1, e2, t_min, perspective) {
                    tau.set(tau.get().min(d / spread));
                }
            },
        );
        Falloff::Bernstein.apply(tau.get())
    }

    /// The shell of a rectangle light (`half_extents` in units of the
    /// bounding circle, the frame's axes): `τ` is the smallest rectangle-norm
    /// distance, in light-size units over the doubled rectangle, from the
    /// light's centre to where a line from the receiver `o` through a
    /// triangle meets the light (the triangle's shadow cast from `o` onto
    /// the light's plane, or onto the sun's directions). The centre's hard
    /// shadow has already been traced.
    fn rect_visibility(&self, o: Vec3, v: Vec3, a: f32, t_min: f32, half_extents: Vec2) -> f32 {
        let perspective = matches!(self.projection, Projection::Perspective { .. });
        let size = match self.projection {
            Projection::Perspective { radius } => radius,
            Projection::Orthographic { tan_angle } => tan_angle,
        };
        // The doubled rectangle, in light-size units; a zero side (a line
        // light) kept finite: its norm is then huge off the line, not NaN.
        let shell = (2.0 * size * half_extents).max(Vec2::splat(1e-6 * size)).as_dvec2();
        let inv_v = v.recip();
        let tau = std::cell::Cell::new(1.0f32);
        self.bvh.for_each_candidate(
            |lo, hi| {
                // A point of norm below `τ` lies within `τ` times the
                // doubled bounding circle at its depth (the rectangle is
                // inside it) of the ray's point at that depth: `2τR·s` at
                // `s = (L_o − L_p)/L_o` of the way to a planar light, `t = A·s`
                // along the ray; `2τ tan θ·t` at `t = L_o − L_p` under the sun.
                if lo.z >= o.z || (perspective && hi.z <= 0.0) {
                    return false;
                }
                let (r, t_hi) = if perspective {
                    let s = ((o.z - lo.z.max(0.0)) / o.z).min(1.0);
                    (2.0 * size * s, a * s)
                } else {
                    let t = (o.z - lo.z).min(a);
                    (2.0 * size * t, t)
                };
                let r = r * tau.get();
                ray_hits_box(lo - Vec3::splat(r), hi + Vec3::splat(r), o, inv_v, 0.0, t_hi)
            },
            |_, tri| {
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                let len = n.length();
                // The receiver's own plane (`t_min` is its lift): as for the disk.
                if !(len > 0.0) || ((o - tri[0]).dot(n) / len).abs() <= 2.0 * t_min {
                    return;
                }
                // Between the receiver's depth and the light's plane: where a
                // point can stand between the receiver and some of the light.
                let mut poly: Vec<Vec3> = clip_convex(tri, |p| o.z - p.z - t_min);
                if perspective {
                    poly = clip_convex(&poly, |p| p.z);
                }
                if poly.len() < 3 {
                    return;
                }
                let projected: Vec<DVec2> =
                    poly.iter().map(|p| light_plane_point(o, *p, perspective).as_dvec2() / shell).collect();
                tau.set(tau.get().min(chebyshev_distance_to_convex_polygon(&projected)));
            },
        );
        Falloff::Bernstein.apply(tau.get())
    }
}

/// Where the line from the receiver `o` through `p` (nearer the light,
/// `p.z < o.z`) meets the light: the point of the plane `z = 0`
/// (perspective), or the ray's tangent `(x, y)/(−z)` (the sun).
///
/// As `o + (p − o)·o.z/(o.z − p.z)`: the difference `p − o` is small and
/// exact where the occluder is near the receiver, and only that offset is
/// scaled. The equal `(p·o.z − o·p.z)/(o.z − p.z)` cancels two products of
/// size `|o|·o.z` and divides their rounding by the small gap: a receiver
/// 1e4 along the light's plane, 20 under it and 0.3 under an edge got 0.033
/// wrong in visibility, against 7e-4 now
/// (`the_single_sample_penumbra_is_the_same_1e4_along_the_lights_plane`).
#[inline]
fn light_plane_point(o: Vec3, p: Vec3, perspective: bool) -> Vec2 {
    let (oxy, d) = (Vec2::new(o.x, o.y), Vec2::new(p.x - o.x, p.y - o.y));
    let gap = o.z - p.z;
    if perspective { oxy + d * (o.z / gap) } else { d / gap }
}

fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// The tangent of the smallest angle between the ray `o + t·v` and a point
/// of the triangle in front of the receiver (`t > t_min`) and, for a disk
/// light, in front of the light's plane (`z > 0`); `None` when no part of
/// the triangle is there.
fn angular_distance(
    tri: &[Vec3; 3],
    o: Vec3,
    v: Vec3,
    e1: Vec3,
    e2: Vec3,
    t_min: f32,
    perspective: bool,
) -> Option<f32> {
    let mut poly: Vec<Vec3> = tri.to_vec();
    poly = clip_convex(&poly, |p| (p - o).dot(v) - t_min);
    if perspective {
        poly = clip_convex(&poly, |p| p.z);
    }
    if poly.len() < 3 {
        return None;
    }
    // Central projection from the receiver onto the plane at unit distance:
    // convex, since every point is in front of the receiver.
    let projected: Vec<Vec2> = poly
        .iter()
        .map(|p| {
            let d = *p - o;
            Vec2::new(d.dot(e1), d.dot(e2)) / d.dot(v)
        })
        .collect();
    Some(distance_to_convex_polygon(&projected))
}

/// Distance from the origin to a convex polygon (0 inside).
fn distance_to_convex_polygon(poly: &[Vec2]) -> f32 {
    if contains_origin(poly) {
        return 0.0;
    }
    let n = poly.len();
    let mut best = f32::INFINITY;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let e = b - a;
        let t = if e.length_squared() > 0.0 { ((-a).dot(e) / e.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
        best = best.min((a + e * t).length());
    }
    best
}

/// `max(|x|, |y|)` distance from the origin to a convex polygon (0
/// inside): the rectangle norm once each axis is divided by its half side.
/// In f64: a line light's zero side, kept a sliver of 1e-6, makes `x` a
/// million times `y`, and where an edge crosses `x = 0` the f32 `a + e·t`
/// kept ulps of 1e6 of `x` — τ came out in steps of 1/8 (a NaN-blind test
/// passed it; `zero_size_or_line_rectangles_stay_hard_or_finite` compares
/// it with a thin rectangle's now).
fn chebyshev_distance_to_convex_polygon(poly: &[DVec2]) -> f32 {
    if contains_origin(poly) {
        return 0.0;
    }
    let n = poly.len();
    let norm = |p: DVec2| p.x.abs().max(p.y.abs());
    let mut best = f64::INFINITY;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let e = b - a;
        best = best.min(norm(a));
        // `max(|x|, |y|)` along the edge is convex and piecewise linear:
        // its minimum is at an end or where `x`, `y` or `|x| − |y|` is 0.
        for (num, den) in [(-a.x, e.x), (-a.y, e.y), (a.y - a.x, e.x - e.y), (-a.x - a.y, e.x + e.y)] {
            if den != 0.0 {
                let t = num / den;
                if (0.0..=1.0).contains(&t) {
                    best = best.min(norm(a + e * t));
                }
            }
        }
    }
    best as f32
}

/// True when the origin is inside a convex polygon (either winding), the
/// cross products in f64.
fn contains_origin<P: Copy + Into<DVec2>>(poly: &[P]) -> bool {
    let n = poly.len();
    let mut inside_sign = 0.0f64;
    for i in 0..n {
        let (a, b): (DVec2, DVec2) = (poly[i].into(), poly[(i + 1) % n].into());
        let cross = (b - a).perp_dot(-a);
        if cross != 0.0 {
            if inside_sign == 0.0 {
                inside_sign = cross.signum();
            } else if cross.signum() != inside_sign {
                return false;
            }
        }
    }
    inside_sign != 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polygon_around_the_origin_is_at_distance_zero_and_one_beside_it_at_its_gap() {
        let square = [Vec2::new(-1.0, -1.0), Vec2::new(1.0, -1.0), Vec2::new(1.0, 1.0), Vec2::new(-1.0, 1.0)];
        assert_eq!(distance_to_convex_polygon(&square), 0.0);
        let right: Vec<Vec2> = square.iter().map(|p| *p + Vec2::new(3.0, 0.0)).collect();
        assert!((distance_to_convex_polygon(&right) - 2.0).abs() < 1e-6);
        // A corner is the nearest point: rounded corners, as the paper's outer triangle.
        let corner: Vec<Vec2> = square.iter().map(|p| *p + Vec2::new(4.0, 5.0)).collect();
        assert!((distance_to_convex_polygon(&corner) - 5.0).abs() < 1e-5);
    }

    #[test]
    fn the_rectangle_norm_distance_is_the_larger_axis_gap() {
        let square = [Vec2::new(-1.0, -1.0), Vec2::new(1.0, -1.0), Vec2::new(1.0, 1.0), Vec2::new(-1.0, 1.0)];
        let square = square.map(|p| p.as_dvec2());
        assert_eq!(chebyshev_distance_to_convex_polygon(&square), 0.0);
        let shifted = |d: DVec2| -> Vec<DVec2> { square.iter().map(|p| *p + d).collect() };
        // Beside it: the gap across; off a corner: the larger of the two gaps.
        assert!((chebyshev_distance_to_convex_polygon(&shifted(DVec2::new(3.0, 0.5))) - 2.0).abs() < 1e-6);
        assert!((chebyshev_distance_to_convex_polygon(&shifted(DVec2::new(4.0, 5.0))) - 4.0).abs() < 1e-6);
        // A diagonal edge x + y = 2: nearest where |x| = |y|, at (1, 1).
        let diagonal = [DVec2::new(2.0, 0.0), DVec2::new(0.0, 2.0), DVec2::new(3.0, 3.0)];
        assert!((chebyshev_distance_to_convex_polygon(&diagonal) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn clipping_keeps_the_part_in_front() {
        let tri = [Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)];
        let front = clip_convex(&tri, |p| p.z);
        assert_eq!(front.len(), 4);
        assert!(front.iter().all(|p| p.z >= -1e-6));
    }
}
