//! Fin construction (Cai et al. §3.1, fig. 4) in light-map space.
//!
//! Each silhouette edge gets an *outer* quad (pointing away from the occluder's
//! projected interior, adds shadow) and an *inner* quad (pointing into it,
//! removes shadow). Its width at depth `L_b` is the penumbra half-width that the
//! edge casts on the reference plane `L0`: world `B0 = R(L0 − L_b)/L0` (eq. 3),
//! i.e. `R(1/L_b − 1/L0)` in map units for a disk light.
//!
//! Fins are kept in map space, where the oracle and the GPU look them up, and
//! carry their own geometry so that `t` (eq. 1) is exact:
//! - a quad is the map trapezoid between the projected edge `m0 → m1` and its
//!   offset by `w0, w1` along the edge's unit normal `d`; a point
//!   `m0 + α(m1 − m0) + β d` has `t = β / lerp(w0, w1, α)` and depth `L_b` of the
//!   edge point at `α` (`1/L` is linear in `α` under perspective);
//! - a fan is a circular sector of radius `w` around a silhouette vertex, with
//!   radial `t = r/w` and the vertex's depth.
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
    /// Trapezoid on a silhouette edge.
    Quad {
        m0: Vec2,
        m1: Vec2,
        /// Unit map-space normal of the edge, pointing across the fin.
        dir: Vec2,
        /// Fin widths (map units) at `m0` and `m1`.
        w0: f32,
        w1: f32,
        /// Light-space depths of the edge endpoints.
        z0: f32,
        z1: f32,
    },
    /// Circular sector around a silhouette vertex, from `from` to `to` (unit
    /// vectors, short arc, less than π apart).
    Sector {
        center: Vec2,
        radius: f32,
        from: Vec2,
        to: Vec2,
        depth: f32,
    },
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
            FinShape::Quad {
                m0,
                m1,
                dir,
                w0,
                w1,
                z0,
                z1,
            } => {
                let e = m1 - m0;
                let rel = q - m0;
                let alpha = rel.dot(e) / e.length_squared();
                if !(0.0..=1.0).contains(&alpha) {
                    return None;
                }
                let beta = rel.dot(dir);
                let width = w0 + (w1 - w0) * alpha;
                // The edge line itself belongs to the inner fin only: there the
                // caster blocks (base 0) and visibility must come out as 1/2.
                let on_edge_ok = self.side == FinSide::Inner;
                if !((beta > 0.0 || (beta == 0.0 && on_edge_ok)) && beta <= width && width > 0.0) {
                    return None;
                }
                let t = beta / width;
                let depth = if perspective {
                    1.0 / (1.0 / z0 + (1.0 / z1 - 1.0 / z0) * alpha)
                } else {
                    z0 + (z1 - z0) * alpha
                };
                Some(FinSample {
                    weight: 0.5 * (1.0 - t),
                    depth,
                })
            }
            FinShape::Sector {
                center,
                radius,
                from,
                to,
                depth,
            } => {
                let rel = q - center;
                let r2 = rel.length_squared();
                if !(r2 <= radius * radius) || (r2 == 0.0 && self.side == FinSide::Outer) {
                    return None;
                }
                let s = from.perp_dot(to).signum();
                if from.perp_dot(rel) * s < 0.0 || rel.perp_dot(to) * s < 0.0 {
                    return None;
                }
                let t = r2.sqrt() / radius;
                Some(FinSample {
                    weight: 0.5 * (1.0 - t),
                    depth,
                })
            }
        }
    }

    /// Map-space bounding box `(min, max)`.
    pub fn bounds(&self) -> (Vec2, Vec2) {
        match self.shape {
            FinShape::Quad {
                m0,
                m1,
                dir,
                w0,
                w1,
                ..
            } => {
                let (p2, p3) = (m0 + dir * w0, m1 + dir * w1);
                (m0.min(m1).min(p2).min(p3), m0.max(m1).max(p2).max(p3))
            }
            FinShape::Sector { center, radius, .. } => {
                (center - Vec2::splat(radius), center + Vec2::splat(radius))
            }
        }
    }
}

/// Builds every fin of a set of silhouette edges, reusing `out`.
///
/// `reference_depth` is `L0`. Fins of zero width (radius 0, or an edge on the
/// reference plane) are not emitted, so radius 0 reproduces hard shadows exactly.
#[derive(Debug, Default)]
pub struct FinBuilder {
    incidences: Vec<(u32, u32, bool)>,
    mapped: Vec<(Vec2, Vec2, Vec2)>,
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
        // Per edge: projected endpoints and outward normal; NaN normal = degenerate.
        let mapped = &mut self.mapped;
        mapped.clear();
        mapped.extend(edges.iter().map(|e| {
            let (m0, m1) = (frame.map(e.a), frame.map(e.b));
            let dir = Vec2::new(m0.y - m1.y, m1.x - m0.x).normalize_or(Vec2::NAN);
            (m0, m1, dir)
        }));
        let mapped = &*mapped;
        for (e, &(m0, m1, dir)) in edges.iter().zip(mapped) {
            if e.a.z <= near || e.b.z <= near || dir.is_nan() {
                continue;
            }
            let (w0, w1) = (width(e.a.z), width(e.b.z));
            if !(w0 > 0.0 || w1 > 0.0) {
                continue;
            }
            for (side, d) in [(FinSide::Outer, dir), (FinSide::Inner, -dir)] {
                let shape = FinShape::Quad {
                    m0,
                    m1,
                    dir: d,
                    w0,
                    w1,
                    z0: e.a.z,
                    z1: e.b.z,
                };
                out.push(Fin {
                    shape,
                    side,
                    patch: e.patch,
                });
            }
        }

        // Vertex incidences: (vertex id, edge index, edge starts here).
        let inc = &mut self.incidences;
        inc.clear();
        for (i, e) in edges.iter().enumerate() {
            inc.push((e.vertex_a, i as u32, true));
            inc.push((e.vertex_b, i as u32, false));
        }
        inc.sort_unstable_by_key(|&(v, i, s)| (v, i, s));
        let mut k = 0;
        while k < inc.len() {
            let v = inc[k].0;
            let end = k + inc[k..].iter().take_while(|x| x.0 == v).count();
            let group = &inc[k..end];
            k = end;
            let (first_edge, first_starts) = (group[0].1 as usize, group[0].2);
            let pos = if first_starts {
                edges[first_edge].a
            } else {
                edges[first_edge].b
            };
            if pos.z <= near {
                continue;
            }
            let radius = width(pos.z);
            if !(radius > 0.0) {
                continue;
            }
            let center = frame.map(pos);
            let patch = edges[first_edge].patch;
            let mut sector = |from: Vec2, to: Vec2, side: FinSide| {
                // Skip empty or degenerate sectors (collinear fins need no fan).
                if from.is_nan()
                    || to.is_nan()
                    || from.perp_dot(to).abs() < 1e-6 && from.dot(to) > 0.0
                {
                    return;
                }
                out.push(Fin {
                    shape: FinShape::Sector {
                        center,
                        radius,
                        from,
                        to,
                        depth: pos.z,
                    },
                    side,
                    patch,
                });
            };
            let ends = |starts: bool| {
                group
                    .iter()
                    .filter(move |x| x.2 == starts)
                    .map(|x| x.1 as usize)
            };
            let (n_in, n_out) = (ends(false).count(), ends(true).count());
            let (first_in, first_out) = (ends(false).next(), ends(true).next());
            match (n_in, n_out, first_in, first_out) {
                (1, 1, Some(a), Some(b)) => {
                    let (a, b) = (&a, &b);
                    let (ea, eb) = (mapped[*a].1 - mapped[*a].0, mapped[*b].1 - mapped[*b].0);
                    let (da, db) = (mapped[*a].2, mapped[*b].2);
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
                    let normal: glam::Vec3 = group
                        .iter()
                        .map(|&(_, i, s)| {
                            if s {
                                edges[i as usize].normal_a
                            } else {
                                edges[i as usize].normal_b
                            }
                        })
                        .next()
                        .unwrap_or_default();
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
    }
}
