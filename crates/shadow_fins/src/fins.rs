//! Fin construction (Cai et al. §3.1, fig. 4) in light-map space.
//!
//! Each silhouette edge gets an *outer* quad (pointing away from the occluder's
//! projected interior, adds shadow) and an *inner* quad (pointing into it,
//! removes shadow). Its width at depth `L_b` is the penumbra half-width that the
//! edge casts on the reference plane `L0`: world `B0 = R(L0 − L_b)/L0` (eq. 3),
//! i.e. `R(1/L_b − 1/L0)` in map units for a disk light. For a rectangle
//! light (beyond the paper) `R` is its support function across the fin,
//! `h(d) = a|d_x| + b|d_y|` ([`crate::light::Aperture::support`]); the falloff
//! across the fin stays the disk's (a rectangle's exact profile depends on the
//! edge's slope: linear for an edge along a side, quadratic at the ends for a
//! diagonal one), an approximation measured in `BENCHMARKS.md`.
//!
//! Fins are kept in map space, where the oracle and the GPU look them up, and
//! carry their own geometry so that `t` (eq. 1) is exact:
//! - a quad spans the projected edge `m0 → m1` and its far boundary
//!   `m0 + w0 d0 → m1 + w1 d1`. A point is `lerp(m0, m1, α) + t · lerp(w0 d0, w1 d1, α)`
//!   (inverse bilinear), with weight from `t` and depth `L_b` of the edge point at
//!   `α` (`1/L` is linear in `α` under perspective). On a crease `d0 = d1` is the
//!   edge's normal and the quad is the paper's trapezoid with `t = β / w(α)`;
//! - a fan is a circular sector of radius `w` around a silhouette vertex, with
//!   radial `t = r/w` and the vertex's depth.
//!
//! **Smooth silhouettes (beyond the paper).** A tessellated smooth surface has a
//! staircase silhouette: its edges turn by up to 90° at every facet, and with
//! per-edge normals the fins of neighbouring steps fan out in all directions;
//! the min/max rules then pick the worst of them (measured: the ring and sphere
//! shadows came out far too dark). Where both silhouette edges at a vertex are
//! facet edges of a smooth surface (dihedral below
//! [`crate::mesh::CREASE_ANGLE_DEG`]), both quads use the projected vertex
//! normal there instead, so the fins form one smooth band with no fan. Creases
//! keep the paper's construction.
//!
//! Fans close the gap on the outer side of convex turns and on the inner side of
//! concave turns. Where three or more silhouette edges meet (or the loop is not
//! simple there), sectors join each edge's fin to the direction of the projected
//! averaged vertex normal (paper §3.1 after Chan & Durand). A vertex where an
//! open silhouette chain ends gets an outer half-disk cap.

use glam::Vec2;

use crate::{light::LightFrame, silhouette::SilhouetteEdge};

/// Which side of the silhouette a fin lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FinSide {
    /// Inside the hard shadow: removes shadow (its weight is added to visibility).
    Inner,
    /// Outside the hard shadow: adds shadow (its weight is subtracted).
    Outer,
}

/// A fin's shape in map space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FinShape {
    /// Quad on a silhouette edge.
    Quad {
        m0: Vec2,
        m1: Vec2,
        /// Unit directions across the fin at `m0` and `m1`.
        d0: Vec2,
        d1: Vec2,
        /// Fin widths (map units) at `m0` and `m1`.
        w0: f32,
        w1: f32,
        /// Light-space depths of the edge endpoints.
        z0: f32,
        z1: f32,
    },
    /// Circular sector around a silhouette vertex, from `from` to `to` (unit
    /// vectors, short arc, less than π apart).
    Sector { center: Vec2, radius: f32, from: Vec2, to: Vec2, depth: f32 },
}

/// One fin: shape, side, and the patch (occluder) it softens.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fin {
    pub shape: FinShape,
    pub side: FinSide,
    /// The patch of its silhouette edge: the fin goes into that patch's layer.
    pub patch: u32,
}

/// What a fin says at a map point: weight `s0 = (1 − t)/2` (eq. 1) and depth `L_b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FinSample {
    pub weight: f32,
    pub depth: f32,
}

impl Fin {
    /// The fin's weight and depth at map point `q`, or `None` outside it.
    #[inline]
    pub fn sample(&self, q: Vec2, perspective: bool) -> Option<FinSample> {
        match self.shape {
            FinShape::Quad { m0, m1, d0, d1, w0, w1, z0, z1 } => {
                let (alpha, t) = quad_coordinates(q, m0, m1, d0 * w0, d1 * w1)?;
                // The edge line itself belongs to the inner fin only: there the
                // caster blocks (base 0) and visibility must come out as 1/2.
                if t == 0.0 && self.side == FinSide::Outer {
                    return None;
                }
                let depth =
                    if perspective { 1.0 / (1.0 / z0 + (1.0 / z1 - 1.0 / z0) * alpha) } else { z0 + (z1 - z0) * alpha };
                Some(FinSample { weight: 0.5 * (1.0 - t), depth })
            }
            FinShape::Sector { center, radius, from, to, depth } => {
                let rel = q - center;
                let r2 = rel.length_squared();
                if !(r2 <= radius * radius) || (r2 == 0.0 && self.side == FinSide::Outer) {
                    return None;
                }
                let s = sector_orientation(from, to);
                if from.perp_dot(rel) * s < 0.0 || rel.perp_dot(to) * s < 0.0 {
                    return None;
                }
                let t = r2.sqrt() / radius;
                Some(FinSample { weight: 0.5 * (1.0 - t), depth })
            }
        }
    }

    /// Map-space bounding box `(min, max)`.
    pub fn bounds(&self) -> (Vec2, Vec2) {
        match self.shape {
            FinShape::Quad { m0, m1, d0, d1, w0, w1, .. } => {
                let (p2, p3) = (m0 + d0 * w0, m1 + d1 * w1);
                (m0.min(m1).min(p2).min(p3), m0.max(m1).max(p2).max(p3))
            }
            FinShape::Sector { center, radius, .. } => (center - Vec2::splat(radius), center + Vec2::splat(radius)),
        }
    }
}

/// The turning sense of a sector from `from` to `to`: `+1` counter-clockwise,
/// `−1` clockwise.
///
/// When the bounds are exactly opposite (`from × to = 0`, ±0 included) the
/// sector is the half disk counter-clockwise from `from`. Spelled out because
/// `f32::signum(0.0)` is 1 and `signum(-0.0)` is −1 in Rust while WGSL's
/// `sign(0.0)` is 0, which made such a sector the whole disk on the GPU and
/// half of it on the CPU; `maps.wgsl` implements this same rule.
#[inline]
pub fn sector_orientation(from: Vec2, to: Vec2) -> f32 {
    if from.perp_dot(to) >= 0.0 { 1.0 } else { -1.0 }
}

/// `(α, t)` of `q` in the quad `lerp(m0, m1, α) + t · lerp(a0, a1, α)`, both in
/// `[0, 1]`, or `None` outside. Exact for the trapezoid (`a0 ∥ a1`) and an
/// inverse bilinear map otherwise.
#[inline]
pub fn quad_coordinates(q: Vec2, m0: Vec2, m1: Vec2, a0: Vec2, a1: Vec2) -> Option<(f32, f32)> {
    let e = m1 - m0;
    let h = q - m0;
    let g = a1 - a0;
    // q − m0 = α e + t a0 + α t g, so (h − t a0) × (e + t g) = 0:
    // k2 t² + k1 t + k0 = 0.
    let k2 = g.perp_dot(a0);
    let k1 = e.perp_dot(a0) + h.perp_dot(g);
    let k0 = h.perp_dot(e);
    let scale = e.length_squared().max(a0.length_squared()).max(a1.length_squared());
    let solve_alpha = |t: f32| {
        let dir = e + g * t;
        let len2 = dir.length_squared();
        (len2 > 0.0).then(|| (h - a0 * t).dot(dir) / len2)
    };
    // A little slack on α so that two quads sharing an end ray leave no crack.
    let inside = |alpha: f32, t: f32| (-1e-5..=1.0 + 1e-5).contains(&alpha) && (0.0..=1.0 + 1e-5).contains(&t);
    // Snap float noise on the edge line (t = 0) so the inner/outer split is exact.
    let snap = |t: f32| if t.abs() <= 1e-6 { 0.0 } else { t };
    if k2.abs() <= 1e-7 * scale * scale {
        // Parallel directions: linear in t.
        if k1 == 0.0 {
            return None;
        }
        let t = snap(-k0 / k1);
        let alpha = solve_alpha(t)?;
        let back = m0 + e * alpha + (a0 + g * alpha) * t;
        return (inside(alpha, t) && (back - q).length_squared() <= 1e-8 * scale)
            .then_some((alpha.clamp(0.0, 1.0), t.min(1.0)));
    }
    let disc = k1 * k1 - 4.0 * k0 * k2;
    if disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    // Numerically stable roots.
    let qq = -0.5 * (k1 + root.copysign(k1));
    let candidates = [qq / k2, if qq != 0.0 { k0 / qq } else { f32::NAN }];
    candidates.into_iter().filter(|t| t.is_finite()).map(snap).find_map(|t| {
        let alpha = solve_alpha(t)?;
        // Guard against a root that does not reproduce q (near-degenerate quads).
        let back = m0 + e * alpha + (a0 + g * alpha) * t;
        (inside(alpha, t) && (back - q).length_squared() <= 1e-8 * scale).then_some((alpha.clamp(0.0, 1.0), t.min(1.0)))
    })
}

/// Builds every fin of a set of silhouette edges, reusing its buffers.
///
/// `reference_depth` is `L0`. Fins of zero width (radius 0, or an edge on the
/// reference plane) are not emitted, so radius 0 reproduces hard shadows exactly.
#[derive(Debug, Default)]
pub struct FinBuilder {
    incidences: Vec<(u32, u32, bool)>,
    /// Per edge: projected endpoints and its unit normal (NaN when degenerate).
    mapped: Vec<(Vec2, Vec2, Vec2)>,
    /// Per edge: fin directions at its two ends.
    end_dirs: Vec<[Vec2; 2]>,
}

impl FinBuilder {
    pub fn build(
        &mut self,
        edges: &[SilhouetteEdge],
        frame: &LightFrame,
        reference_depth: f32,
        near: f32,
        out: &mut Vec<Fin>,
    ) {
        out.clear();
        if frame.size() <= 0.0 {
            return;
        }
        let width = |z: f32| frame.penumbra_half_width(z, reference_depth);
        let mapped = &mut self.mapped;
        mapped.clear();
        mapped.extend(edges.iter().map(|e| {
            let (m0, m1) = (frame.map(e.a), frame.map(e.b));
            let dir = Vec2::new(m0.y - m1.y, m1.x - m0.x).normalize_or(Vec2::NAN);
            (m0, m1, dir)
        }));
        let mapped = &*mapped;
        self.end_dirs.clear();
        self.end_dirs.extend(mapped.iter().map(|m| [m.2, m.2]));

        // Vertex incidences: (vertex id, edge index, edge starts here).
        let inc = &mut self.incidences;
        inc.clear();
        for (i, e) in edges.iter().enumerate() {
            inc.push((e.vertex_a, i as u32, true));
            inc.push((e.vertex_b, i as u32, false));
        }
        inc.sort_unstable_by_key(|&(v, i, s)| (v as u64) << 33 | (i as u64) << 1 | s as u64);
        let mut k = 0;
        while k < inc.len() {
            let v = inc[k].0;
            let end = k + inc[k..].iter().take_while(|x| x.0 == v).count();
            let group = &inc[k..end];
            k = end;
            let (first_edge, first_starts) = (group[0].1 as usize, group[0].2);
            let pos = if first_starts { edges[first_edge].a } else { edges[first_edge].b };
            if pos.z <= near {
                continue;
            }
            let ends = |starts: bool| group.iter().filter(move |x| x.2 == starts).map(|x| x.1 as usize);
            let (n_in, n_out) = (ends(false).count(), ends(true).count());
            let (first_in, first_out) = (ends(false).next(), ends(true).next());
            let normal = if first_starts { edges[first_edge].normal_a } else { edges[first_edge].normal_b };
            // Smooth vertex: one edge in, one out, both facet edges of a smooth surface.
            if let (1, 1, Some(a), Some(b)) = (n_in, n_out, first_in, first_out) {
                if !edges[a].crease && !edges[b].crease {
                    let (da, db) = (mapped[a].2, mapped[b].2);
                    let mut d = frame.map_direction(pos, normal).normalize_or(Vec2::NAN);
                    // The projected normal must point out of the occluder, between the edges' normals.
                    let mid = (da + db).normalize_or(Vec2::NAN);
                    if !(d.dot(da) > 0.05 && d.dot(db) > 0.05) {
                        d = mid;
                    }
                    if !d.is_nan() {
                        self.end_dirs[a][1] = d;
                        self.end_dirs[b][0] = d;
                        continue;
                    }
                }
            }
            let full = width(pos.z);
            if !(full > 0.0) {
                continue;
            }
            let center = frame.map(pos);
            // The smallest patch id among the vertex's silhouettes: a rule of
            // the geometry (the GPU's threads meet here in no fixed order).
            let patch = group.iter().map(|&(_, i, _)| edges[i as usize].patch).min().unwrap_or(edges[first_edge].patch);
            let mut sector = |from: Vec2, to: Vec2, side: FinSide| {
                // Skip empty or degenerate sectors (collinear fins need no fan).
                if from.is_nan() || to.is_nan() || from.perp_dot(to).abs() < 1e-6 && from.dot(to) > 0.0 {
                    return;
                }
                // A rectangle light's fan is a circle as wide as the light
                // across the sector's middle (a sphere's, at the vertex) (its bounding circle would
                // reach past both quads; the disk's is exactly its width).
                let mid = (from + to).normalize_or(from.perp());
                let radius = full * frame.aperture.support_at(mid, center);
                out.push(Fin { shape: FinShape::Sector { center, radius, from, to, depth: pos.z }, side, patch });
            };
            match (n_in, n_out, first_in, first_out) {
                (1, 1, Some(a), Some(b)) => {
                    let (ea, eb) = (mapped[a].1 - mapped[a].0, mapped[b].1 - mapped[b].0);
                    let (da, db) = (mapped[a].2, mapped[b].2);
                    // Interior is on the right: a right turn (negative cross) is convex.
                    let turn = ea.perp_dot(eb);
                    if turn < 0.0 {
                        sector(da, db, FinSide::Outer);
                    } else if turn > 0.0 {
                        sector(-da, -db, FinSide::Inner);
                    }
                }
                (1, 0, Some(a), _) | (0, 1, _, Some(a)) => {
                    // Open chain end: outer half-disk cap around the edge's extension.
                    let (m0, m1, d) = mapped[a];
                    let along = (m1 - m0).normalize_or(Vec2::NAN);
                    let ext = if n_in == 0 { -along } else { along };
                    sector(d, ext, FinSide::Outer);
                    sector(ext, -d, FinSide::Outer);
                }
                _ => {
                    // Junction: sectors from each fin to the projected averaged normal.
                    let avg = frame.map_direction(pos, normal).normalize_or(Vec2::NAN);
                    for &(_, i, _) in group {
                        let d = mapped[i as usize].2;
                        if d.dot(avg) > -0.999 {
                            sector(d, avg, FinSide::Outer);
                            sector(-d, -avg, FinSide::Inner);
                        }
                    }
                }
            }
        }

        for ((e, &(m0, m1, dir)), &[d0, d1]) in edges.iter().zip(mapped).zip(&self.end_dirs) {
            if e.a.z <= near || e.b.z <= near || dir.is_nan() {
                continue;
            }
            let (w0, w1) =
                (width(e.a.z) * frame.aperture.support_at(d0, m0), width(e.b.z) * frame.aperture.support_at(d1, m1));
            if !(w0 > 0.0 || w1 > 0.0) {
                continue;
            }
            // A staircase step almost along the fin direction spans no area; its
            // neighbours' fins meet across it.
            let along = (m1 - m0).normalize_or(Vec2::ZERO);
            if along.perp_dot(d0).abs() < 0.05 || along.perp_dot(d1).abs() < 0.05 {
                continue;
            }
            for (side, sign) in [(FinSide::Outer, 1.0), (FinSide::Inner, -1.0)] {
                let shape = FinShape::Quad { m0, m1, d0: d0 * sign, d1: d1 * sign, w0, w1, z0: e.a.z, z1: e.b.z };
                out.push(Fin { shape, side, patch: e.patch });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_coordinates_are_distance_over_local_width() {
        let (m0, m1) = (Vec2::ZERO, Vec2::new(2.0, 0.0));
        let d = Vec2::Y;
        let (alpha, t) = quad_coordinates(Vec2::new(0.5, 0.3), m0, m1, d * 1.0, d * 2.0).unwrap();
        assert!((alpha - 0.25).abs() < 1e-6);
        assert!((t - 0.3 / 1.25).abs() < 1e-6);
        assert!(quad_coordinates(Vec2::new(0.5, -0.1), m0, m1, d, d * 2.0).is_none());
        assert!(quad_coordinates(Vec2::new(2.5, 0.1), m0, m1, d, d * 2.0).is_none());
        assert_eq!(quad_coordinates(Vec2::new(1.0, 0.0), m0, m1, d, d).map(|x| x.1), Some(0.0));
    }

    #[test]
    fn a_sector_with_opposite_bounds_is_the_half_disk_counter_clockwise_from_its_start() {
        let sector = |from: Vec2, to: Vec2| Fin {
            shape: FinShape::Sector { center: Vec2::ZERO, radius: 1.0, from, to, depth: 1.0 },
            side: FinSide::Outer,
            patch: 0,
        };
        // Exactly opposite bounds, with +0 and −0 cross products.
        let cases = [(Vec2::X, Vec2::NEG_X), (Vec2::Y, Vec2::NEG_Y)];
        assert!(
            cases[0].0.perp_dot(cases[0].1).is_sign_positive() && cases[1].0.perp_dot(cases[1].1).is_sign_negative()
        );
        for (from, to) in cases {
            assert_eq!(from.perp_dot(to), 0.0);
            let f = sector(from, to);
            let left = from.perp() * 0.5;
            assert!(f.sample(left, true).is_some(), "{from:?}→{to:?}: the counter-clockwise half is in");
            assert!(f.sample(-left, true).is_none(), "{from:?}→{to:?}: the other half is out");
        }
        assert_eq!(sector_orientation(Vec2::X, Vec2::Y), 1.0);
        assert_eq!(sector_orientation(Vec2::Y, Vec2::X), -1.0);
    }

    #[test]
    fn bilinear_coordinates_invert_the_quad() {
        let (m0, m1) = (Vec2::new(0.1, 0.2), Vec2::new(1.3, -0.1));
        let (a0, a1) = (Vec2::new(-0.3, 0.9), Vec2::new(0.4, 1.1));
        for i in 0..=10 {
            for j in 0..=10 {
                let (alpha, t) = (i as f32 / 10.0, j as f32 / 10.0);
                let q = m0.lerp(m1, alpha) + a0.lerp(a1, alpha) * t;
                let Some((ra, rt)) = quad_coordinates(q, m0, m1, a0, a1) else { panic!("({alpha},{t}) not found") };
                assert!((ra - alpha).abs() < 1e-4 && (rt - t).abs() < 1e-4, "({alpha},{t}) -> ({ra},{rt})");
            }
        }
    }
}
