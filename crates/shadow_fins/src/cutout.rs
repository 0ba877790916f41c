//! Alpha-masked casters (glTF `alphaMode: MASK`, Bevy's `AlphaMode::Mask`):
//! where the material's alpha is below its cutoff, the caster is a hole and
//! light passes (issue 16, item 2).
//!
//! Semantics, the same for the ground truth, the CPU oracle and the GPU:
//! - the alpha at a UV is the texture's bilinear interpolation between
//!   texel centres — or, for a nearest-filtered texture ([`Filter`]), the
//!   alpha of the texel the UV falls in —, the texture read by its
//!   sampler's wrap modes (repeat, mirrored repeat, clamp), times the
//!   material's base alpha; a masked triangle blocks a ray (the ground
//!   truth's) or a texel's centre ray (a light-space map's) where that alpha
//!   is at least the cutoff (ties opaque, as Bevy's `alpha < cutoff →
//!   discard`);
//! - UVs are interpolated linearly in 3D: in a perspective map that is
//!   `Σ (bᵢ/zᵢ) uvᵢ / Σ bᵢ/zᵢ` over the map triangle's barycentrics `bᵢ`
//!   and corner depths `zᵢ` ([`crate::oracle::MapTriangle::opaque_at`]);
//! - the outline of the opaque region is geometry: per masked face, the
//!   iso-line `alpha = cutoff` by marching squares over the texel-centre
//!   grid (exact at the grid's cell edges, a chord of the bilinear curve
//!   inside a cell) — a nearest-filtered mask's, exactly, the texel borders
//!   between opaque and clear texels —, clipped to the face's UV triangle, and the opaque
//!   stretches of the face's own edges ([`Outline`]). A masked object's
//!   silhouettes (the fins') and potential silhouette edges (the coverage
//!   method's) are its outline's edges instead of its mesh edges, so a hole
//!   and a leaf's blade have penumbrae of their own;
//! - a mask larger than [`MAX_MASK_SIDE`] on a side is box-filtered down to
//!   it first (a hole smaller than 1/256 of the texture is not modelled):
//!   the outline's detail follows the mask, not the texture's resolution;
//!   the work of building it is capped per face ([`MAX_CELLS_PER_FACE`])
//!   and per mesh ([`MAX_CELLS_PER_MESH`]), past which faces are modelled
//!   by their edges' opaque stretches alone;
//! - a non-manifold edge (three or more faces) is cut per face, each face's
//!   opaque stretches a one-face edge.

use std::sync::Arc;

use glam::{Vec2, Vec3};

/// The largest mask side modelled; larger masks are box-filtered down.
pub const MAX_MASK_SIDE: u32 = 256;

/// The most grid cells one face's outline walks (a face whose UVs repeat
/// the texture thousands of times): past it the face is modelled whole
/// ([`Outline::unmodelled_faces`]).
pub const MAX_CELLS_PER_FACE: u64 = 1 << 20;

/// The most grid cells one mesh's outline walks in all (an atlas of
/// thousands of cards): the faces past it are modelled whole.
pub const MAX_CELLS_PER_MESH: u64 = 1 << 23;

/// The largest UV coordinate taken (a texture repeated a million times).
pub const MAX_UV: f32 = 1e6;

/// Why an alpha mask cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CutoutError {
    #[error("alpha mask of {width} x {height} texels holds {len} values: give width x height alphas")]
    Size { width: u32, height: u32, len: usize },
    #[error("alpha cutoff {0} is not a number: use a cutoff in [0, 1] (glTF's default is 0.5)")]
    Cutoff(f32),
    #[error("{uvs} UVs for {vertices} vertices: give one UV per mesh vertex")]
    Uvs { uvs: usize, vertices: usize },
    #[error("a UV is not finite or beyond ±{MAX_UV}: {0}")]
    BadUv(Vec2),
}

/// How a texture coordinate outside `[0, 1]` reads the texture (glTF's
/// sampler wrap modes, Bevy's `ImageAddressMode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Address {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

impl Address {
    /// Texel index `i` of a row or column of `n` texels read this way.
    #[inline]
    fn texel(self, i: i64, n: u32) -> u32 {
        let n = n as i64;
        (match self {
            Address::Repeat => i.rem_euclid(n),
            Address::MirroredRepeat => {
                let k = i.rem_euclid(2 * n);
                if k < n { k } else { 2 * n - 1 - k }
            }
            Address::ClampToEdge => i.clamp(0, n - 1),
        }) as u32
    }
}

/// How the texture is read between texels (Bevy's sampler's magnification
/// filter, glTF's `magFilter`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Filter {
    /// Bilinear between texel centres (Bevy's default).
    #[default]
    Linear,
    /// The texel a UV falls in: a pixel-art mask's square texels.
    Nearest,
}

/// Ties go to opaque (Bevy's `alpha < cutoff → discard`): an alpha within
/// this of the cutoff counts as reaching it, everywhere alike, so that a
/// bilinear iso-line never runs exactly along a texel border (where a
/// texture's 0-to-255 steps interpolate to 0.5, glTF's default cutoff). A
/// nearest-filtered mask's outline runs along texel borders by design.
const TIE: f32 = 1.0 / 8192.0;

/// A material's alpha, texel by texel, and its cutoff.
#[derive(Debug, Clone, PartialEq)]
pub struct AlphaMask {
    width: u32,
    height: u32,
    /// Alpha per texel, row-major from the top row (`v = 0`), 0..=255.
    alpha: Vec<u8>,
    /// The alpha below which the caster is a hole, in `[0, 1]`.
    cutoff: f32,
    /// The material's base alpha, which multiplies every texel's.
    base_alpha: f32,
    /// How `u` and `v` outside `[0, 1]` read the texture.
    address: [Address; 2],
    /// How the texture is read between texels.
    filter: Filter,
}

impl AlphaMask {
    /// A mask of `width × height` alphas (row-major, first row at `v = 0`,
    /// as glTF and Bevy address textures). `base_alpha` multiplies every
    /// texel (the material's base colour alpha; not finite counts as 1); a
    /// cutoff outside `[0, 1]` is clamped, NaN is an error. An empty mask is
    /// the texture-less material: its base alpha alone. Larger than
    /// [`MAX_MASK_SIDE`] on a side, the mask is box-filtered down.
    pub fn new(width: u32, height: u32, alpha: Vec<u8>, base_alpha: f32, cutoff: f32) -> Result<Self, CutoutError> {
        if alpha.len() as u64 != width as u64 * height as u64 {
            return Err(CutoutError::Size { width, height, len: alpha.len() });
        }
        if cutoff.is_nan() {
            return Err(CutoutError::Cutoff(cutoff));
        }
        let base_alpha = if base_alpha.is_finite() { base_alpha.clamp(0.0, 1.0) } else { 1.0 };
        let (alpha, width, height) = if alpha.is_empty() { (vec![255], 1, 1) } else { (alpha, width, height) };
        let (alpha, width, height) = box_filter(alpha, width, height);
        Ok(Self {
            width,
            height,
            alpha,
            cutoff: cutoff.clamp(0.0, 1.0),
            base_alpha,
            address: [Address::Repeat; 2],
            filter: Filter::Linear,
        })
    }

    pub fn base_alpha(&self) -> f32 {
        self.base_alpha
    }

    /// True when every texel passes the cutoff: the material casts solid.
    pub fn is_solid(&self) -> bool {
        let t = self.threshold();
        self.alpha.iter().all(|&a| a as f32 / 255.0 >= t)
    }

    /// The mask read with these wrap modes for `u` and `v` (default: repeat).
    pub fn with_address(mut self, address: [Address; 2]) -> Self {
        self.address = address;
        self
    }

    pub fn address(&self) -> [Address; 2] {
        self.address
    }

    /// The mask read with this filter (default: linear). A mask box-filtered
    /// down from a larger texture ([`MAX_MASK_SIDE`]) is read nearest from
    /// the filtered texels.
    pub fn with_filter(mut self, filter: Filter) -> Self {
        self.filter = filter;
        self
    }

    pub fn filter(&self) -> Filter {
        self.filter
    }

    /// How close to a face's edge an iso-line counts as on it, in UV: a
    /// thousandth of a texel (the iso-lines [`TIE`] moves off a texel
    /// border are a tenth of that from it).
    #[inline]
    fn hair(&self) -> f32 {
        1e-3 / self.width.max(self.height) as f32 + 1e-6
    }

    /// What the texture's own alpha (before the base alpha) is compared
    /// with: `alpha · base ≥ cutoff` as `alpha ≥ cutoff / base`, less
    /// [`TIE`] (no rounding of `alpha · base` into 8 bits, which Bevy does
    /// not do either). A base of 0 passes nothing but a cutoff of 0.
    #[inline]
    pub fn threshold(&self) -> f32 {
        if self.base_alpha > 0.0 {
            self.cutoff / self.base_alpha - TIE
        } else if self.cutoff <= 0.0 {
            -TIE
        } else {
            f32::INFINITY
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texture's alphas, row-major, before the base alpha (what a GPU
    /// copy uploads, with [`AlphaMask::threshold`]).
    pub fn alpha(&self) -> &[u8] {
        &self.alpha
    }

    pub fn cutoff(&self) -> f32 {
        self.cutoff
    }

    /// The alpha at texel `(x, y)` of the texture read by its wrap modes, in `[0, 1]`.
    #[inline]
    fn texel(&self, x: i64, y: i64) -> f32 {
        let (x, y) = (self.address[0].texel(x, self.width), self.address[1].texel(y, self.height));
        self.alpha[(y * self.width + x) as usize] as f32 * (1.0 / 255.0)
    }

    /// The texture's alpha at `uv` (before the base alpha): bilinear between
    /// texel centres, or the texel's own under [`Filter::Nearest`], read by
    /// the wrap modes.
    #[inline]
    pub fn alpha_at(&self, uv: Vec2) -> f32 {
        if self.filter == Filter::Nearest {
            let (i, j) = self.texel_of(uv);
            return self.texel(i, j);
        }
        let x = uv.x as f64 * self.width as f64 - 0.5;
        let y = uv.y as f64 * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (i, j) = (x0 as i64, y0 as i64);
        let top = self.texel(i, j) * (1.0 - fx) + self.texel(i + 1, j) * fx;
        let bottom = self.texel(i, j + 1) * (1.0 - fx) + self.texel(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The texel `uv` falls in (before wrapping): texel `i` spans
    /// `[i/w, (i+1)/w)`.
    #[inline]
    fn texel_of(&self, uv: Vec2) -> (i64, i64) {
        ((uv.x as f64 * self.width as f64).floor() as i64, (uv.y as f64 * self.height as f64).floor() as i64)
    }

    /// True when the caster blocks light at `uv`: the alpha there is at
    /// least the cutoff. A non-finite UV blocks.
    #[inline]
    pub fn opaque(&self, uv: Vec2) -> bool {
        !uv.is_finite() || self.alpha_at(uv) >= self.threshold()
    }
}

/// `alpha` box-filtered down to at most [`MAX_MASK_SIDE`] a side, each new
/// texel the mean of the source texels under it (source ranges split in
/// proportion, so the filtered mask stays aligned with the texture).
fn box_filter(alpha: Vec<u8>, width: u32, height: u32) -> (Vec<u8>, u32, u32) {
    if width <= MAX_MASK_SIDE && height <= MAX_MASK_SIDE {
        return (alpha, width, height);
    }
    let factor = width.max(height).div_ceil(MAX_MASK_SIDE);
    let (w, h) = (width.div_ceil(factor), height.div_ceil(factor));
    let span = |i: u32, n: u32, to: u32| {
        let (a, b) = ((i as u64 * n as u64 / to as u64) as u32, ((i as u64 + 1) * n as u64 / to as u64) as u32);
        a..b.max(a + 1).min(n)
    };
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (mut sum, mut n) = (0u32, 0u32);
            for sy in span(y, height, h) {
                for sx in span(x, width, w) {
                    sum += alpha[(sy * width + sx) as usize] as u32;
                    n += 1;
                }
            }
            out.push((sum as f32 / n.max(1) as f32).round() as u8);
        }
    }
    (out, w, h)
}

/// The cut-outs of one mesh under one mask: per face of its topology
/// (`Topology::faces` order), the UVs of the face's corners, and the
/// outline of the opaque region. Built once per (mesh, mask) and shared by
/// every instance.
#[derive(Debug, Clone)]
pub struct Cutout {
    pub mask: Arc<AlphaMask>,
    /// One UV per mesh vertex, as given.
    pub vertex_uvs: Arc<Vec<Vec2>>,
    pub face_uvs: Arc<Vec<[Vec2; 3]>>,
    pub outline: Arc<Outline>,
}

impl Cutout {
    /// The cut-outs of `mesh` with one UV per mesh vertex.
    pub fn new(
        mask: Arc<AlphaMask>,
        uvs: &[Vec2],
        mesh: &crate::mesh::Mesh,
        topology: &crate::mesh::Topology,
    ) -> Result<Self, CutoutError> {
        if uvs.len() != mesh.positions().len() {
            return Err(CutoutError::Uvs { uvs: uvs.len(), vertices: mesh.positions().len() });
        }
        if let Some(bad) = uvs.iter().find(|uv| !uv.is_finite() || uv.abs().max_element() > MAX_UV) {
            return Err(CutoutError::BadUv(*bad));
        }
        let face_uvs: Vec<[Vec2; 3]> = topology
            .source_triangles
            .iter()
            .map(|&t| {
                let i = &mesh.indices()[t as usize * 3..t as usize * 3 + 3];
                [uvs[i[0] as usize], uvs[i[1] as usize], uvs[i[2] as usize]]
            })
            .collect();
        let outline = Outline::build(&mask, &face_uvs, topology);
        Ok(Self { mask, vertex_uvs: Arc::new(uvs.to_vec()), face_uvs: Arc::new(face_uvs), outline: Arc::new(outline) })
    }
}

/// One caster triangle's cut-out: its mask (an index into the scene's masks)
/// and the UVs of its corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CasterCutout {
    pub mask: u32,
    pub uvs: [Vec2; 3],
}

/// Whether caster `k` blocks light at its barycentric point `(u, v)`, given
/// every caster's cut-out (`cutouts`, empty when none is masked; see
/// [`crate::scene::caster_cutouts`]) and the masks they index: always for a
/// solid caster.
#[inline]
pub fn caster_blocks_at(cutouts: &[Option<CasterCutout>], masks: &[Arc<AlphaMask>], k: usize, u: f32, v: f32) -> bool {
    cutouts.get(k).copied().flatten().is_none_or(|c| c.blocks_at(masks, u, v))
}

impl CasterCutout {
    /// True where the triangle is opaque at its barycentric point `(u, v)`
    /// (weights `1 − u − v`, `u`, `v` of its corners), reading `masks`.
    #[inline]
    pub fn blocks_at(&self, masks: &[Arc<AlphaMask>], u: f32, v: f32) -> bool {
        masks[self.mask as usize].opaque(self.uvs[0] * (1.0 - u - v) + self.uvs[1] * u + self.uvs[2] * v)
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Mesh, NO_FACE, Topology};

    #[test]
    fn alpha_is_bilinear_between_texel_centres_repeated_and_bad_input_is_an_error() {
        // 2 × 2: a hole at the top left texel.
        let m = AlphaMask::new(2, 2, vec![0, 255, 255, 255], 1.0, 0.5).unwrap();
        // At texel centres, the texel.
        assert!(!m.opaque(Vec2::new(0.25, 0.25)));
        assert!(m.opaque(Vec2::new(0.75, 0.25)) && m.opaque(Vec2::new(0.25, 0.75)));
        // Half way between the hole and its right neighbour: 0.5.
        assert!((m.alpha_at(Vec2::new(0.5, 0.25)) - 0.5).abs() < 1e-6);
        // Repeated: 1.25 and −0.75 are 0.25; the wrap joins the last texel to the first.
        assert!(!m.opaque(Vec2::new(1.25, -0.75)));
        assert!((m.alpha_at(Vec2::new(0.0, 0.25)) - 0.5).abs() < 1e-6);
        assert!(m.opaque(Vec2::NAN));
        // The base alpha scales every texel: at 0.4, nothing reaches 0.5.
        let faded = AlphaMask::new(2, 2, vec![0, 255, 255, 255], 0.4, 0.5).unwrap();
        assert!(!faded.opaque(Vec2::new(0.75, 0.75)));
        // No texture: the base alpha alone.
        assert!(AlphaMask::new(0, 0, vec![], 1.0, 0.5).unwrap().opaque(Vec2::new(0.3, 0.9)));
        assert!(matches!(AlphaMask::new(2, 2, vec![0; 3], 1.0, 0.5), Err(CutoutError::Size { .. })));
        assert!(matches!(AlphaMask::new(1, 1, vec![0], 1.0, f32::NAN), Err(CutoutError::Cutoff(_))));
        assert_eq!(AlphaMask::new(1, 1, vec![0], 1.0, 7.0).unwrap().cutoff(), 1.0);
        // A big mask is box-filtered to MAX_MASK_SIDE, its alpha kept.
        let big = AlphaMask::new(
            1024,
            512,
            (0..1024 * 512).map(|i| if i % 1024 < 512 { 0 } else { 255 }).collect(),
            1.0,
            0.5,
        )
        .unwrap();
        assert_eq!((big.width(), big.height()), (256, 128));
        assert!(!big.opaque(Vec2::new(0.2, 0.5)) && big.opaque(Vec2::new(0.8, 0.5)));
    }

    #[test]
    fn a_nearest_filtered_mask_is_its_texels_squares() {
        let m = AlphaMask::new(2, 2, vec![0, 255, 255, 255], 1.0, 0.5).unwrap().with_filter(Filter::Nearest);
        // Up to the texel border the hole's alpha, from it on the neighbour's (bilinear: 0.5 there).
        assert_eq!(m.alpha_at(Vec2::new(0.499, 0.25)), 0.0);
        assert_eq!(m.alpha_at(Vec2::new(0.5, 0.25)), 1.0);
        assert!(!m.opaque(Vec2::new(0.01, 0.49)) && m.opaque(Vec2::new(0.01, 0.51)));
        // Wrapped as the linear mask is: −0.25 repeats to 0.75.
        assert!(m.opaque(Vec2::new(-0.25, 0.25)) && !m.opaque(Vec2::new(1.25, 0.25)));
        // Its outline is the hole's two inner sides on a card (u, v in [0, 1]):
        // a 0.5 × 0.5 square hole, the rest of the card opaque.
        let (_, c) = card_cutout(m, 0.0, false);
        assert!(unbalanced_vertices(&c.outline).is_empty());
        assert!((enclosed_area(&c.outline) - 0.54 * 0.75).abs() < 1e-5, "{}", enclosed_area(&c.outline));
    }

    /// A 0.6 × 0.9 card with its UVs turned by `uv_turn` about the
    /// texture's centre, and mirrored in u when `mirror` (the UV triangles
    /// then turn the way the faces wind; unmirrored, against it).
    fn card_cutout(mask: AlphaMask, uv_turn: f32, mirror: bool) -> (Topology, Cutout) {
        let (mesh, uvs) = crate::shapes::card(0.6, 0.9);
        let rot = glam::Mat2::from_angle(uv_turn);
        let flip = |uv: Vec2| if mirror { Vec2::new(1.0 - uv.x, uv.y) } else { uv };
        let uvs: Vec<Vec2> = uvs.iter().map(|&uv| rot * (flip(uv) - 0.5) + 0.5).collect();
        let topology = Topology::build(&mesh);
        let cutout = Cutout::new(Arc::new(mask), &uvs, &mesh, &topology).unwrap();
        (topology, cutout)
    }

    /// The vertices where one-face edges leaving, each walked the way its
    /// face winds, do not match those entering (none on closed outlines),
    /// with the edges there.
    fn unbalanced_vertices(o: &Outline) -> Vec<String> {
        let mut degree = vec![0i32; o.positions.len()];
        for e in o.edges.iter().filter(|e| e.faces[1] == NO_FACE) {
            let [a, b] = if e.forward[0] { e.vertices } else { [e.vertices[1], e.vertices[0]] };
            degree[a as usize] += 1;
            degree[b as usize] -= 1;
        }
        (0..degree.len())
            .filter(|&i| degree[i] != 0)
            .map(|i| {
                let at: Vec<String> = o
                    .edges
                    .iter()
                    .filter(|e| e.vertices.contains(&(i as u32)))
                    .map(|e| {
                        format!(
                            "{:?}: {} → {}",
                            e, o.positions[e.vertices[0] as usize], o.positions[e.vertices[1] as usize]
                        )
                    })
                    .collect();
                format!("{} at {}: {}", degree[i], o.positions[i], at.join("; "))
            })
            .collect()
    }

    /// The area the one-face edges enclose, in the card's plane (z = 0, seen from +z).
    fn enclosed_area(o: &Outline) -> f32 {
        o.edges
            .iter()
            .filter(|e| e.faces[1] == NO_FACE)
            .map(|e| {
                let [a, b] = if e.forward[0] { e.vertices } else { [e.vertices[1], e.vertices[0]] };
                let (a, b) = (o.positions[a as usize], o.positions[b as usize]);
                0.5 * a.truncate().perp_dot(b.truncate())
            })
            .sum()
    }

    #[test]
    fn an_opaque_card_is_outlined_by_its_border_and_a_clear_one_by_nothing() {
        let (_, solid) = card_cutout(AlphaMask::new(4, 4, vec![255; 16], 1.0, 0.5).unwrap(), 0.0, false);
        let o = &solid.outline;
        let border: f32 = o
            .edges
            .iter()
            .filter(|e| e.faces[1] == NO_FACE)
            .map(|e| o.positions[e.vertices[0] as usize].distance(o.positions[e.vertices[1] as usize]))
            .sum();
        assert!((border - 3.0).abs() < 1e-5, "border {border}, the card's perimeter is 3");
        assert!((enclosed_area(o) - 0.54).abs() < 1e-5);
        // The diagonal, both faces opaque: one two-face edge.
        assert_eq!(o.edges.iter().filter(|e| e.faces[1] != NO_FACE).count(), 1);
        assert!(unbalanced_vertices(o).is_empty());
        let (_, clear) = card_cutout(AlphaMask::new(4, 4, vec![0; 16], 1.0, 0.5).unwrap(), 0.0, false);
        assert!(clear.outline.edges.is_empty());
    }

    #[test]
    fn the_leafs_outline_is_closed_and_encloses_its_opaque_area_at_any_uv_rotation() {
        let alpha = crate::shapes::leaf_alpha(128);
        // The opaque area by the mask's test on a fine grid, against the
        // area the outline encloses; bilinear and nearest (whose texel
        // corners the card's diagonal runs through, unturned).
        let cases = [(0.0, false), (0.3, false), (1.9, false), (0.0, true), (0.7, true)];
        for ((turn, mirror), filter) in cases.into_iter().flat_map(|c| [(c, Filter::Linear), (c, Filter::Nearest)]) {
            let mask = AlphaMask::new(128, 128, alpha.clone(), 1.0, 0.5).unwrap().with_filter(filter);
            let (_, c) = card_cutout(mask, turn, mirror);
            let o = &c.outline;
            let open = unbalanced_vertices(o);
            assert!(open.is_empty(), "turn {turn}, mirror {mirror}, {filter:?}: open outline: {open:#?}");
            assert_eq!(o.joined_ends, 0, "turn {turn}, mirror {mirror}, {filter:?}: closed without joining ends");
            let n = 600;
            let mut opaque = 0;
            for y in 0..n {
                for x in 0..n {
                    let q = Vec2::new((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
                    // The card's UV at its point (u, 1 − y) mirrored and turned like its corners'.
                    let q = if mirror { Vec2::new(1.0 - q.x, q.y) } else { q };
                    let uv = glam::Mat2::from_angle(turn) * (q - 0.5) + 0.5;
                    opaque += c.mask.opaque(uv) as u32;
                }
            }
            let sampled = opaque as f32 / (n * n) as f32 * 0.54;
            let area = enclosed_area(o);
            assert!(
                (area - sampled).abs() < 0.01 * 0.54,
                "turn {turn}, mirror {mirror}, {filter:?}: outline encloses {area}, opaque {sampled}"
            );
            // Holes and blade: many more edges than the card's four.
            assert!(o.edges.len() > 100, "{}", o.edges.len());
        }
    }

    #[test]
    fn a_bent_strip_of_random_masks_keeps_a_closed_outline() {
        // A strip of 8 faces folded along its rungs, UVs continuous, a noisy
        // mask at any cutoff: every outline closes.
        let mut seed = 12345u32;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        let mut joined = 0;
        for k in 0..2000 {
            let alpha: Vec<u8> = (0..64).map(|_| (rnd() % 256) as u8).collect();
            let cutoff = (rnd() % 100) as f32 / 100.0;
            let filter = if k % 2 == 0 { Filter::Linear } else { Filter::Nearest };
            let mask = AlphaMask::new(8, 8, alpha, 1.0, cutoff).unwrap().with_filter(filter);
            let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
            for i in 0..5u32 {
                let x = i as f32 * 0.25;
                let z = if i % 2 == 1 { 0.1 } else { 0.0 };
                positions.extend([Vec3::new(x, 0.0, z), Vec3::new(x, 1.0, z)]);
                let u = i as f32 * 0.17 + (rnd() % 100) as f32 * 1e-4;
                uvs.extend([Vec2::new(u, 0.9), Vec2::new(u, 0.05)]);
                if i > 0 {
                    let b = 2 * (i - 1);
                    indices.extend([b, b + 2, b + 3, b, b + 3, b + 1]);
                }
            }
            let mesh = Mesh::new(positions, indices).unwrap();
            let topology = Topology::build(&mesh);
            let c = Cutout::new(Arc::new(mask), &uvs, &mesh, &topology).unwrap();
            let open = unbalanced_vertices(&c.outline);
            assert!(open.is_empty(), "open outline: {open:#?}");
            joined += c.outline.joined_ends;
            for e in &c.outline.edges {
                let (a, b) = (c.outline.positions[e.vertices[0] as usize], c.outline.positions[e.vertices[1] as usize]);
                assert!(a.is_finite() && b.is_finite() && a != b);
            }
        }
        // Joins mend the rare corner case only (a few in 16 000 faces).
        assert!(joined <= 40, "{joined} dangling ends joined");
    }
}
