//! The outline of a mask's opaque region on a mesh: the iso-line of the
//! cutoff traced through each face's texels, clipped to the face, as the
//! silhouette edges an alpha-masked caster adds.

use super::mask::{AlphaMask, Filter};
use glam::{Vec2, Vec3};

/// The most grid cells one face's outline walks (a face whose UVs repeat
/// the texture thousands of times): past it the face is modelled whole
/// ([`Outline::unmodelled_faces`]).
pub const MAX_CELLS_PER_FACE: u64 = 1 << 20;

/// The most grid cells one mesh's outline walks in all (an atlas of
/// thousands of cards): the faces past it are modelled whole.
pub const MAX_CELLS_PER_MESH: u64 = 1 << 23;

/// The outline of a masked mesh's opaque region, object space: what its
/// silhouettes and potential silhouette edges are drawn from in place of
/// the mesh's edges. Its edges are [`crate::mesh::Edge`]s over its own
/// vertices: a two-face edge is an opaque stretch of a mesh edge whose two
/// faces are both opaque along it; a one-face edge is either an iso-line
/// segment inside a face or an opaque stretch of a mesh edge that only one
/// face is opaque along (the card's border, a seam). `forward[k]`: face `k`
/// walks the edge `vertices[0] → vertices[1]` in its winding, i.e. the
/// opaque side is on the edge's left seen from the face's front.
#[derive(Debug, Clone, Default)]
pub struct Outline {
    pub positions: Vec<Vec3>,
    /// Per vertex, the normal of a face it lies on (unnormalised).
    pub normals: Vec<Vec3>,
    /// Per vertex, that face: a pose of the mesh carries the vertex with
    /// it (the outline's vertices are points of the faces, fixed by the UVs).
    pub faces: Vec<u32>,
    pub edges: Vec<crate::mesh::Edge>,
    /// Per edge, whether it is a crease: every one-face edge is.
    pub crease: Vec<bool>,
    /// Faces whose UVs span more cells than a face's or the mesh's share
    /// ([`MAX_CELLS_PER_FACE`], [`MAX_CELLS_PER_MESH`]): modelled by their
    /// mesh edges' opaque stretches only.
    pub unmodelled_faces: usize,
    /// Dangling ends joined (see `close_dangling_ends`): 0 but where an
    /// iso-line meets a face's edge within a hair of a corner.
    pub joined_ends: usize,
}

/// A break of a face's edge `k` (from corner `k` to `k + 1`) at parameter
/// `t` where an iso-line segment leaves or enters the face: segment `seg`,
/// end `end`.
struct EdgeBreak {
    t: f32,
    seg: usize,
    end: usize,
}

impl Outline {
    /// The outline of `topology`'s faces under `mask`, the faces' corner UVs given.
    pub fn build(mask: &AlphaMask, face_uvs: &[[Vec2; 3]], topology: &crate::mesh::Topology) -> Self {
        use crate::mesh::NO_FACE;
        let mut out = Outline::default();
        let mut welder = std::collections::HashMap::<[u32; 3], u32>::new();
        // Per face and corner edge, where iso-line segments cross it.
        let mut breaks: Vec<[Vec<EdgeBreak>; 3]> = Vec::with_capacity(face_uvs.len());
        // Segments: face, 3D ends (those on a face's edge moved once the breaks are merged).
        let mut segments: Vec<(u32, [Vec3; 2])> = Vec::new();
        let corners3 = |f: usize| topology.faces[f].map(|i| topology.positions[i as usize]);
        let mut budget = MAX_CELLS_PER_MESH;
        for (f, uv) in face_uvs.iter().enumerate() {
            let mut face_breaks: [Vec<EdgeBreak>; 3] = Default::default();
            match iso_segments(mask, uv, &mut budget) {
                None => out.unmodelled_faces += 1,
                Some(segs) => {
                    let p = corners3(f);
                    let at = |q: Vec2| {
                        let b = barycentrics_2d(uv, q);
                        p[0] * b.x + p[1] * b.y + p[2] * b.z
                    };
                    for (ends, on_edges) in segs {
                        let seg = segments.len();
                        segments.push((f as u32, [at(ends[0]), at(ends[1])]));
                        for (end, on) in on_edges.into_iter().enumerate() {
                            let count = on.iter().filter(|&&o| o).count();
                            for k in (0..3).filter(|&k| on[k]) {
                                let (a, b) = (uv[k], uv[(k + 1) % 3]);
                                let t = ((ends[end] - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                                // On two edges: at their shared corner, exactly.
                                let t = if count >= 2 {
                                    if on[(k + 1) % 3] { 1.0 } else { 0.0 }
                                } else if t < 1e-5 {
                                    0.0
                                } else if t > 1.0 - 1e-5 {
                                    1.0
                                } else {
                                    t
                                };
                                face_breaks[k].push(EdgeBreak { t, seg, end });
                            }
                        }
                    }
                }
            }
            breaks.push(face_breaks);
        }

        // The mesh's edges: opaque stretches, the iso-lines' ends on them
        // snapped to one point per crossing so both faces' pieces meet.
        let corner_of = |f: u32, v0: u32, v1: u32| -> Option<(usize, bool)> {
            let face = topology.faces[f as usize];
            (0..3).find_map(|k| {
                let (a, b) = (face[k], face[(k + 1) % 3]);
                if (a, b) == (v0, v1) {
                    Some((k, true))
                } else if (a, b) == (v1, v0) {
                    Some((k, false))
                } else {
                    None
                }
            })
        };
        let mut pending: Vec<(Vec3, Vec3, [u32; 2], [bool; 2])> = Vec::new();
        // Each mesh edge with its faces; a non-manifold edge once per face
        // (each face's opaque stretches a one-face edge of their own).
        let jobs = topology
            .edges
            .iter()
            .map(|e| {
                let faces: Vec<(u32, bool)> =
                    (0..2).filter(|&i| e.faces[i] != NO_FACE).map(|i| (e.faces[i], e.forward[i])).collect();
                (e.vertices, faces)
            })
            .chain(topology.non_manifold_edges.iter().flat_map(|e| e.faces.iter().map(|&f| (e.vertices, vec![f]))));
        for ([v0, v1], edge_faces) in jobs {
            let (p0, p1) = (topology.positions[v0 as usize], topology.positions[v1 as usize]);
            // One formula for every point of the edge, so ends meet bit for bit.
            let point_at = |s: f32| {
                if s <= 0.0 {
                    p0
                } else if s >= 1.0 {
                    p1
                } else {
                    p0.lerp(p1, s)
                }
            };
            let faces: Vec<(u32, bool, usize, bool)> = edge_faces
                .iter()
                .filter_map(|&(f, forward)| corner_of(f, v0, v1).map(|(k, same)| (f, forward, k, same)))
                .collect();
            // Breaks in the edge's own parameter s (v0 → v1), merged within
            // 1e-5: (s, face slot, opaque after it in s, segment, end).
            let mut cuts: Vec<(f32, usize, bool, usize, usize)> = Vec::new();
            for (slot, &(f, _, k, same)) in faces.iter().enumerate() {
                let uv = &face_uvs[f as usize];
                let ccw = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]) > 0.0;
                for b in &breaks[f as usize][k] {
                    // The opaque region's border, walked with it on the left,
                    // runs on along the face's edge after an iso-line arrives
                    // (end 1): forwards in t when the UV triangle turns
                    // counter-clockwise, backwards otherwise.
                    let after_t = (b.end == 1) == ccw;
                    let (s, after) = if same { (b.t, after_t) } else { (1.0 - b.t, !after_t) };
                    cuts.push((s, slot, after, b.seg, b.end));
                }
            }
            cuts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut merged_s: Vec<f32> = Vec::new();
            // Per face slot: (merged s, opaque after it), ascending.
            let mut face_breaks: [Vec<(f32, bool)>; 2] = Default::default();
            for &(s, slot, after, seg, end) in &cuts {
                let s = match merged_s.last() {
                    Some(&last) if s - last < 1e-5 => last,
                    _ => {
                        merged_s.push(s);
                        s
                    }
                };
                segments[seg].1[end] = point_at(s);
                face_breaks[slot].push((s, after));
            }
            let mut stops: Vec<f32> = vec![0.0];
            stops.extend(merged_s.iter().copied().filter(|&s| s > 0.0 && s < 1.0));
            stops.push(1.0);
            // Per face, the breaks at one point netted: an iso-line arriving
            // makes the edge opaque on, one leaving makes it clear, and a
            // pair touching the edge at a point cancels.
            let nets: Vec<Vec<(f32, i32)>> = (0..faces.len())
                .map(|slot| {
                    let mut groups: Vec<(f32, i32)> = Vec::new();
                    for &(s, after) in &face_breaks[slot] {
                        let d = if after { 1 } else { -1 };
                        match groups.last_mut() {
                            Some(g) if g.0 == s => g.1 += d,
                            _ => groups.push((s, d)),
                        }
                    }
                    groups.retain(|g| g.1 != 0);
                    groups
                })
                .collect();
            // A face is opaque along a stretch as its last net break before
            // says or, before its first, the opposite of that; with none, as
            // the iso-lines' side of the stretch's middle is.
            let opaque_on = |slot: usize, from: f32, to: f32| -> bool {
                let list = &nets[slot];
                if let Some(&(_, net)) = list.iter().rev().find(|(s, _)| *s <= from) {
                    return net > 0;
                }
                if let Some(&(_, net)) = list.first() {
                    return net < 0;
                }
                // Nudged into the face past any iso-line within a hair of its
                // edge (left out of the outline).
                let (f, _, k, same) = faces[slot];
                let uv = &face_uvs[f as usize];
                let mid = 0.5 * (from + to);
                let q = uv[k].lerp(uv[(k + 1) % 3], if same { mid } else { 1.0 - mid });
                let inward = ((uv[0] + uv[1] + uv[2]) / 3.0 - q).normalize_or_zero();
                chord_opaque(mask, q + inward * (1.5 * mask.hair()))
            };
            let flush = |from: f32, to: f32, opaque: [bool; 2], pending: &mut Vec<_>| {
                let on: Vec<usize> = (0..faces.len()).filter(|&i| opaque[i]).collect();
                if on.is_empty() || !(to > from) {
                    return;
                }
                let (a, b) = (point_at(from), point_at(to));
                let pick = |i: usize| (faces[i].0, faces[i].1);
                let (f, fw) = match on.as_slice() {
                    [i] => ([pick(*i).0, NO_FACE], [pick(*i).1, false]),
                    _ => ([pick(0).0, pick(1).0], [pick(0).1, pick(1).1]),
                };
                pending.push((a, b, f, fw));
            };
            let mut run: Option<(f32, [bool; 2])> = None;
            for w in stops.windows(2) {
                let mut opaque = [false; 2];
                for (slot, o) in opaque.iter_mut().enumerate().take(faces.len()) {
                    *o = opaque_on(slot, w[0], w[1]);
                }
                run = match run {
                    Some((from, o)) if o == opaque => Some((from, o)),
                    Some((from, o)) => {
                        flush(from, w[0], o, &mut pending);
                        Some((w[0], opaque))
                    }
                    None => Some((w[0], opaque)),
                };
            }
            if let Some((from, o)) = run {
                flush(from, 1.0, o, &mut pending);
            }
        }
        let mut vertex = |p: Vec3, face: u32, out: &mut Outline| -> u32 {
            *welder.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                out.positions.push(p);
                out.normals.push(topology.face_planes[face as usize].0);
                out.faces.push(face);
                out.positions.len() as u32 - 1
            })
        };
        for (f, [a, b]) in &segments {
            if a == b {
                continue;
            }
            let (ia, ib) = (vertex(*a, *f, &mut out), vertex(*b, *f, &mut out));
            // Opaque on the left in UV space: the face's forward direction
            // when its UV triangle turns the same way as its winding.
            let uv = &face_uvs[*f as usize];
            let turns = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]) >= 0.0;
            out.edges.push(crate::mesh::Edge { vertices: [ia, ib], faces: [*f, NO_FACE], forward: [turns, false] });
            out.crease.push(true);
        }
        for (a, b, faces, forward) in pending {
            if a == b {
                continue;
            }
            let (ia, ib) = (vertex(a, faces[0], &mut out), vertex(b, faces[0], &mut out));
            let two = faces[1] != NO_FACE;
            // A two-face stretch is a crease when its mesh edge is.
            let crease = !two || {
                let (n0, n1) = (topology.face_planes[faces[0] as usize].0, topology.face_planes[faces[1] as usize].0);
                n0.normalize_or_zero().dot(n1.normalize_or_zero()) < crate::mesh::CREASE_ANGLE_DEG.to_radians().cos()
            };
            out.edges.push(crate::mesh::Edge { vertices: [ia, ib], faces, forward });
            out.crease.push(crease);
        }
        out.close_dangling_ends(topology);
        out
    }

    /// Joins the outline's dangling ends. Where an iso-line meets a face's
    /// edge within a hair of a corner, the two faces there can decide it
    /// differently (a break on one edge or at the corner), and a chain of
    /// one-face edges ends a few ten-thousandths of a texel short of where
    /// its neighbour's goes on. Each end that more edges leave than reach
    /// is joined from the nearest end that more reach than leave, within a
    /// thousandth of the mesh's size.
    fn close_dangling_ends(&mut self, topology: &crate::mesh::Topology) {
        use crate::mesh::NO_FACE;
        let mut degree = vec![0i32; self.positions.len()];
        let mut face_at = vec![NO_FACE; self.positions.len()];
        for e in self.edges.iter().filter(|e| e.faces[1] == NO_FACE) {
            let [a, b] = if e.forward[0] { e.vertices } else { [e.vertices[1], e.vertices[0]] };
            degree[a as usize] += 1;
            degree[b as usize] -= 1;
            face_at[a as usize] = e.faces[0];
            face_at[b as usize] = e.faces[0];
        }
        if degree.iter().all(|&d| d == 0) {
            return;
        }
        let reach = (topology.bounds.1 - topology.bounds.0).length() * 1e-3;
        let mut short: Vec<u32> = (0..degree.len() as u32).filter(|&v| degree[v as usize] < 0).collect();
        for v in 0..degree.len() {
            while degree[v] > 0 {
                let p = self.positions[v];
                let nearest = short
                    .iter()
                    .enumerate()
                    .map(|(i, &w)| (i, self.positions[w as usize].distance(p)))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                let Some((i, _)) = nearest.filter(|&(_, d)| d <= reach) else { break };
                let w = short[i];
                self.edges.push(crate::mesh::Edge {
                    vertices: [w, v as u32],
                    faces: [face_at[w as usize], NO_FACE],
                    forward: [true, false],
                });
                self.crease.push(true);
                self.joined_ends += 1;
                degree[v] -= 1;
                degree[w as usize] += 1;
                if degree[w as usize] == 0 {
                    short.swap_remove(i);
                }
            }
        }
    }
}

/// Barycentric weights of `q` in the 2D triangle `t` (corner 0, 1, 2).
fn barycentrics_2d(t: &[Vec2; 3], q: Vec2) -> Vec3 {
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    if !(area.abs() > 0.0) {
        return Vec3::new(1.0, 0.0, 0.0);
    }
    let w1 = (q - t[0]).perp_dot(t[2] - t[0]) / area;
    let w2 = (t[1] - t[0]).perp_dot(q - t[0]) / area;
    Vec3::new(1.0 - w1 - w2, w1, w2)
}

/// The iso-line `alpha = cutoff` inside the UV triangle `uv`: segments with
/// the opaque side on their left (in `(u, v)` with the usual orientation),
/// and per end the triangle edges it ends on. `None` when the triangle
/// spans more than [`MAX_CELLS_PER_FACE`] cells or more than the mesh's
/// `budget` of cells left (which it takes from).
#[allow(clippy::type_complexity)]
fn iso_segments(mask: &AlphaMask, uv: &[Vec2; 3], budget: &mut u64) -> Option<Vec<([Vec2; 2], [[bool; 3]; 2])>> {
    let (w, h) = (mask.width as f64, mask.height as f64);
    let lo = uv[0].min(uv[1]).min(uv[2]);
    let hi = uv[0].max(uv[1]).max(uv[2]);
    // Cells: between texel centres (linear), or the texels themselves (nearest).
    let shift = if mask.filter == Filter::Nearest { 0.0 } else { 0.5 };
    let (i0, i1) = ((lo.x as f64 * w - shift).floor() as i64, (hi.x as f64 * w - shift).floor() as i64);
    let (j0, j1) = ((lo.y as f64 * h - shift).floor() as i64, (hi.y as f64 * h - shift).floor() as i64);
    let cells = ((i1 - i0 + 1) as u64).saturating_mul((j1 - j0 + 1) as u64);
    if cells > MAX_CELLS_PER_FACE || cells > *budget {
        return None;
    }
    *budget -= cells;
    let area = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]);
    if !(area.abs() > 0.0) {
        return Some(Vec::new());
    }
    let sign = area.signum();
    let mut out = Vec::new();
    for j in j0..=j1 {
        for i in i0..=i1 {
            for (p, q) in cell_chords(mask, i, j) {
                if let Some(seg) = clip_to_triangle(p, q, uv, sign, mask.hair()) {
                    out.push(seg);
                }
            }
        }
    }
    Some(out)
}

/// The iso-line's chords in grid cell `(i, j)` (between texel centres `i`,
/// `i + 1` and `j`, `j + 1`), opaque side on the left: marching squares.
/// Under [`Filter::Nearest`] the cell is texel `(i, j)` and its chords the
/// sides it shares with a texel of the other state, if it is opaque.
fn cell_chords(mask: &AlphaMask, i: i64, j: i64) -> impl Iterator<Item = (Vec2, Vec2)> {
    if mask.filter == Filter::Nearest {
        return texel_border_chords(mask, i, j).into_iter();
    }
    let (w, h) = (mask.width as f64, mask.height as f64);
    let cutoff = mask.threshold();
    let at = |i: i64, j: i64| Vec2::new(((i as f64 + 0.5) / w) as f32, ((j as f64 + 0.5) / h) as f32);
    // The crossing on the grid edge between samples (i, j) and (k, l),
    // always computed from its lower sample so both cells agree bit for bit.
    let crossing = |(i, j): (i64, i64), (k, l): (i64, i64)| {
        let ((i, j), (k, l)) = if (i, j) <= (k, l) { ((i, j), (k, l)) } else { ((k, l), (i, j)) };
        let (a, b) = (mask.texel(i, j), mask.texel(k, l));
        let t = ((cutoff - a) / (b - a)).clamp(0.0, 1.0);
        at(i, j).lerp(at(k, l), t)
    };
    // Corners counter-clockwise in (u, v): (0,0), (1,0), (1,1), (0,1).
    let c = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
    let a = c.map(|(x, y)| mask.texel(x, y));
    let inside = a.map(|v| v >= cutoff);
    // Crossings walking the cell's border counter-clockwise: (point, leaves the opaque side).
    let mut xs: Vec<(Vec2, bool)> = Vec::with_capacity(4);
    for k in 0..4 {
        if inside[k] != inside[(k + 1) % 4] {
            xs.push((crossing(c[k], c[(k + 1) % 4]), inside[k]));
        }
    }
    // Each exit joins the next entry (opaque corners joined through the
    // cell's middle) or, at a saddle whose middle is clear, the previous.
    let joined = a.iter().sum::<f32>() * 0.25 >= cutoff;
    let n = xs.len();
    let chords: Vec<(Vec2, Vec2)> = (0..n)
        .filter(|&k| xs[k].1)
        .map(|k| {
            let m = (1..n)
                .map(|d| if joined || n == 2 { (k + d) % n } else { (k + n - d) % n })
                .find(|&m| !xs[m].1)
                .unwrap_or(k);
            (xs[k].0, xs[m].0)
        })
        .collect();
    chords.into_iter()
}

/// An opaque texel's sides facing a clear texel, counter-clockwise in
/// `(u, v)` (the opaque texel on their left): the nearest-filtered mask's
/// outline, each border drawn once (by its opaque texel).
fn texel_border_chords(mask: &AlphaMask, i: i64, j: i64) -> Vec<(Vec2, Vec2)> {
    let t = mask.threshold();
    if mask.texel(i, j) < t {
        return Vec::new();
    }
    let (w, h) = (mask.width as f64, mask.height as f64);
    let at = |i: i64, j: i64| Vec2::new((i as f64 / w) as f32, (j as f64 / h) as f32);
    let corners = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
    // Across each side (bottom, right, top, left): the neighbour it borders.
    let across = [(i, j - 1), (i + 1, j), (i, j + 1), (i - 1, j)];
    (0..4).filter(|&k| mask.texel(across[k].0, across[k].1) < t).map(|k| (corners[k], corners[(k + 1) % 4])).collect()
}

/// Whether `uv` lies in the opaque region the iso-line's chords bound (the
/// outline's own region, a hair from the bilinear test's near the line):
/// the side of the nearest chord of its cell, or its cell's state.
fn chord_opaque(mask: &AlphaMask, uv: Vec2) -> bool {
    if mask.filter == Filter::Nearest {
        // The outline runs along texel borders: the region is the texels'.
        return mask.opaque(uv);
    }
    let i = (uv.x as f64 * mask.width as f64 - 0.5).floor() as i64;
    let j = (uv.y as f64 * mask.height as f64 - 0.5).floor() as i64;
    let nearest = cell_chords(mask, i, j)
        .map(|(p, q)| {
            let d = q - p;
            let t = ((uv - p).dot(d) / d.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
            ((p + d * t).distance_squared(uv), d.perp_dot(uv - p) >= 0.0)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0));
    match nearest {
        Some((_, left)) => left,
        None => mask.texel(i, j) >= mask.threshold(),
    }
}

/// The part of segment `a → b` inside the triangle (`sign`: its turn), and
/// per end the triangle edges it ends on: the edge that cut it, and any it
/// already ended within a hair of (an iso-line through a texel border the
/// face's edge runs along; both edges at a corner), so that its chain goes
/// on along the edge. A segment along an edge is left to the edge's stretches.
#[allow(clippy::type_complexity)]
fn clip_to_triangle(a: Vec2, b: Vec2, t: &[Vec2; 3], sign: f32, hair: f32) -> Option<([Vec2; 2], [[bool; 3]; 2])> {
    let hair = hair + 1e-6 * a.abs().max(b.abs()).max_element();
    let mut g = [(0.0f32, 0.0f32); 3];
    for k in 0..3 {
        let (p, q) = (t[k], t[(k + 1) % 3]);
        let len = (q - p).length();
        if !(len > 0.0) {
            return None;
        }
        let f = |x: Vec2| sign * (q - p).perp_dot(x - p) / len;
        g[k] = (f(a), f(b));
    }
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    let mut on = [[false; 3]; 2];
    for &(ga, gb) in &g {
        if ga <= hair && gb <= hair {
            return None;
        }
        if ga < -hair {
            t0 = t0.max(ga / (ga - gb));
        }
        if gb < -hair {
            t1 = t1.min(ga / (ga - gb));
        }
    }
    if !(t1 > t0) {
        return None;
    }
    // Which edges each end lies on, by its distance to them (the clipped end too).
    for (end, s) in [t0, t1].into_iter().enumerate() {
        for (k, &(ga, gb)) in g.iter().enumerate() {
            on[end][k] = (ga + (gb - ga) * s).abs() <= hair;
        }
    }
    // What is left runs along an edge: the edge's stretches have it.
    if (0..3).any(|k| on[0][k] && on[1][k]) {
        return None;
    }
    Some(([a.lerp(b, t0), a.lerp(b, t1)], on))
}
