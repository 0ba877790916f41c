//! Soft planar shadows using plateaus (Haines 2001; `003_…`): a soft shadow
//! texture on one receiver plane, from the hard drop shadow and, at every
//! silhouette vertex and edge, cones and sheets whose darkness is their
//! depth, so that where two overlap the darkest wins (the depth test).
//!
//! The texture (§2; the sheets' shape between unequal cones is ours, below):
//! - the plane is white; the casters' hard drop shadow (the light's centre
//!   projected through them onto the plane) is black, in front of everything;
//! - each silhouette vertex `v` at distance `a` from the plane (along the
//!   light's ray) projects to `p` and draws a cone of radius `r`: black at
//!   `p`, white at `r`; each silhouette edge joins its two cones by the sheet
//!   along their outer tangents. A point `q` of the plane at `τ = |q − p|/r`
//!   inside a cone gets `s(τ)`; the sheet of an edge reaches `q` at the
//!   smallest `τ` for which `q` lies in the convex hull of the two disks of
//!   radius `τ·r₁` and `τ·r₂` — the hull is the union of the disks between
//!   them, centre and radius interpolated linearly, so
//!   `τ = min over u ∈ [0, 1] of |q − p(u)| / r(u)`, found in closed form
//!   (Haines joins unequal cones by bilinear sheets between their tangent
//!   edges; the hull of the scaled disks is the same surface when the radii
//!   are equal, and a cone-like one between them otherwise);
//! - darkest wins: `s = min` over all cones and sheets, and 0 in the drop shadow.
//!
//! What Haines leaves as "some constant factor" we size physically, the
//! way Parker et al. (whom he follows) size their shells: the cone is as
//! wide as the whole penumbra a point at `v` makes on the plane,
//! `r = D·a/(A − a)` (`D` the light's diameter, `A − a = |v − centre|`), and
//! `r = 2 tan θ · a` under the sun. Cones are circles (his basic algorithm;
//! he suggests ellipses for lights near the horizon). The falloff is his
//! recommended sinusoid, as Parker's polynomial `3τ² − 2τ³`.
//!
//! **A rectangle light** (`Aperture::Rect`, half sides `a`, `b` along the
//! frame's axes; Haines suggests "pyramidal shapes" for rectangular lights,
//! p. 81): a point's penumbra is the light's rectangle seen through
//! it, so the cone becomes a pyramid over a parallelogram — the light's
//! axes carried onto the plane along the vertex's ray (the central
//! projection linearised at the light's centre), `2a` and `2b` long at
//! `τ = 1` as the cone is `D` wide — and the sheet is the hull of two such
//! parallelograms, `τ = min over u` of their norm `‖q − p(u)‖ / r(u)`.
//! Across an edge of normal `d` that is `2h(d)` wide, `h` the rectangle's
//! support function, as the fins; the disk of radius `R`, which for a
//! rectangle is its bounding circle `√(a² + b²)`, made it `2√(a² + b²)`
//! across every edge (the penumbra of a 4 : 1 rectangle's short side four
//! times too wide).
//!
//! **Receiver-plane restriction.** The method shades one plane: the largest
//! flat receiver facing the light ([`ReceiverPlane::largest_flat`]). Every
//! other receiver (the casters themselves, a second floor) gets the light
//! centre's hard shadow — what a renderer pairing plateaus with its shadow
//! map does — and the lab's tables score those pixels too.
//!
//! **Alpha-masked casters** ([`crate::cutout`]): the silhouettes come from
//! the fins' extractor, which draws a masked caster's from the outline of
//! its opaque region, and both ray-cast shadows (the drop shadow, the hard
//! shadow off the plane) alpha-test what they cross, so light passes through
//! the holes, as through the plugin's alpha-tested hard shadow maps.

use glam::{Mat2, Vec2, Vec3};

use crate::{
    bvh::Bvh,
    cell_grid::{CellGrid, cell_range},
    coverage::index::MAX_ENTRIES,
    cutout::caster_blocks_at,
    light::{Aperture, Projection},
    oracle::FinExtractor,
    peers::geometry::across,
    receiver::Receiver,
    refine::Falloff,
    scene::{LightSpaceScene, Scene, surface_epsilon},
};

/// The receiver plane, light frame: points `x` with `(x − point)·normal = 0`,
/// `normal` towards the light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiverPlane {
    pub point: Vec3,
    pub normal: Vec3,
}

impl ReceiverPlane {
    /// The flat receiving object of largest area whose front faces the
    /// light's centre; without one, the plane across the light's axis at
    /// the deepest receiver (`L0`).
    pub fn largest_flat(scene: &Scene, light_space: &LightSpaceScene) -> Self {
        let perspective = light_space.frame.is_perspective();
        let mut best: Option<(f32, ReceiverPlane)> = None;
        for (object, to_frame) in scene.objects.iter().zip(&light_space.object_frames) {
            if !object.receives_shadows {
                continue;
            }
            let pts: Vec<Vec3> = object.topology.positions.iter().map(|&p| to_frame.point(p)).collect();
            let mut area = 0.0f32;
            let mut normal = Vec3::ZERO;
            for f in &object.topology.faces {
                let [a, b, c] = f.map(|i| pts[i as usize]);
                let n = (b - a).cross(c - a);
                area += n.length() * 0.5;
                // Faces of one plane share a normal up to sign (windings may differ).
                normal += if normal.dot(n) < 0.0 { -n } else { n };
            }
            let Some(normal) = normal.try_normalize() else { continue };
            let Some(&point) = pts.first() else { continue };
            let (lo, hi) = pts.iter().fold((point, point), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
            let tolerance = 1e-4 * (hi - lo).length().max(1e-30);
            if pts.iter().any(|p| (*p - point).dot(normal).abs() > tolerance) {
                continue;
            }
            // Towards the light: its centre (perspective) or against its rays (sun).
            let toward = if perspective { -point } else { Vec3::NEG_Z };
            let normal = if normal.dot(toward) < 0.0 { -normal } else { normal };
            if normal.dot(toward) <= 0.0 {
                continue;
            }
            if best.is_none_or(|(a, _)| area > a) {
                best = Some((area, ReceiverPlane { point, normal }));
            }
        }
        best.map(|(_, p)| p)
            .unwrap_or(ReceiverPlane { point: Vec3::new(0.0, 0.0, light_space.reference_depth), normal: Vec3::NEG_Z })
    }

    fn height(&self, p: Vec3) -> f32 {
        (p - self.point).dot(self.normal)
    }
}

/// A silhouette edge drawn into the texture: the centres (plane coordinates)
/// and radii of its two cones.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sheet {
    p1: Vec2,
    p2: Vec2,
    r1: f32,
    r2: f32,
    /// The cones' cross-section: a circle of radius 1, or a parallelogram.
    shape: Footprint,
}

/// The cross-section of a cone of radius 1: what a point's penumbra on the
/// plane looks like, up to its size.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Footprint {
    /// A disk light or the sun: Haines' circles.
    Circle,
    /// A rectangle light: the parallelogram of half axes `k₁`, `k₂` (plane
    /// coordinates), kept as the matrix that takes an offset `x` to its
    /// coordinates `c` in `x = c₁k₁ + c₂k₂` (the norm is `max |cᵢ|`), and
    /// the half size of its bounding box.
    Parallelogram { to_axes: Mat2, half_box: Vec2 },
}

impl Footprint {
    /// Half the size of the bounding box of the radius-1 cross-section.
    fn half_box(&self) -> Vec2 {
        match *self {
            Footprint::Circle => Vec2::ONE,
            Footprint::Parallelogram { half_box, .. } => half_box,
        }
    }
}

/// One scene under one light, as a plateau texture on its receiver plane.
pub struct PlateauModel {
    /// The cones and sheets: the texture beside the drop shadow.
    pub texture: PlateauTexture,
    /// Casters off the plane, for the drop shadow.
    drop: Bvh,
    /// The caster index of each of `drop`'s triangles.
    off_plane: Vec<u32>,
    /// Every caster, for the hard shadow of receivers off the plane.
    hard: Bvh,
    /// Each caster's cut-out (empty when none is masked) and the masks.
    cutouts: Vec<Option<crate::cutout::CasterCutout>>,
    masks: Vec<std::sync::Arc<crate::cutout::AlphaMask>>,
    projection: Projection,
    reference_depth: f32,
}

/// The soft part of the plateau texture on one plane: every silhouette
/// edge's sheet between its two cones, binned by footprint, evaluated where
/// it is read (the renderer's texture, drawn at the receivers' own points).
/// The drop shadow is the caller's: a ray cast ([`PlateauModel`]) or a shadow
/// map (the plugin's `FinMethod::Plateaus`).
pub struct PlateauTexture {
    pub plane: ReceiverPlane,
    sheets: Vec<Sheet>,
    grid: CellGrid,
    axes: (Vec3, Vec3),
    extent: f32,
}

/// One sheet as the plugin's GPU reads it (`Sheet` in `plateaus.wgsl`):
/// `ends` the two cones' centres (plane coordinates), `radii` their radii
/// and the cross-section (`z` 0 circle, 1 parallelogram), `to_axes` the
/// parallelogram's matrix by columns.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetRecord {
    pub ends: [f32; 4],
    pub radii: [f32; 4],
    pub to_axes: [f32; 4],
}

impl PlateauModel {
    pub fn new(scene: &Scene, light_space: &LightSpaceScene) -> Self {
        Self::on_plane(scene, light_space, ReceiverPlane::largest_flat(scene, light_space))
    }

    /// The texture on a given plane.
    pub fn on_plane(scene: &Scene, light_space: &LightSpaceScene, plane: ReceiverPlane) -> Self {
        let texture = PlateauTexture::on_plane(scene, light_space, plane);
        let on_plane_tolerance = 1e-5 * light_space.extent.max(1e-30);
        let plane = texture.plane;
        let off_plane: Vec<u32> = (0..light_space.casters.len() as u32)
            .filter(|&k| light_space.casters[k as usize].iter().any(|p| plane.height(*p).abs() > on_plane_tolerance))
            .collect();
        let drop_triangles: Vec<[Vec3; 3]> = off_plane.iter().map(|&k| light_space.casters[k as usize]).collect();
        Self {
            texture,
            drop: Bvh::new(&drop_triangles),
            off_plane,
            hard: Bvh::new(&light_space.casters),
            cutouts: light_space.caster_cutouts.clone(),
            masks: light_space.masks.clone(),
            projection: light_space.frame.projection,
            reference_depth: light_space.reference_depth,
        }
    }

    /// Number of silhouette edges drawn as sheets.
    pub fn sheet_count(&self) -> usize {
        self.texture.sheets.len()
    }

    /// Visibility of the light from a receiver (light frame), in `[0, 1]`:
    /// the texture on the plane, the hard shadow elsewhere.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let eps = surface_epsilon(receiver.position, self.texture.extent);
        let p = receiver.position;
        let on_plane = self.texture.holds(p);
        let o = if on_plane { p + self.texture.plane.normal * eps } else { p + receiver.normal * eps };
        if !o.is_finite() {
            return 0.0;
        }
        let (dir, t_max) = match self.projection {
            Projection::Perspective { .. } => {
                if !(o.z > self.reference_depth * 1e-5) {
                    return 0.0;
                }
                (-o, 1.0)
            }
            Projection::Orthographic { .. } => (Vec3::NEG_Z, self.texture.extent * 4.0 + o.z.abs()),
        };
        let t_min = eps / dir.length().max(eps);
        // Both shadows alpha-test masked casters (their holes let the light
        // through), as the cones and sheets come from their outlines.
        let blocks = |k: u32, u: f32, v: f32| caster_blocks_at(&self.cutouts, &self.masks, k as usize, u, v);
        if !on_plane {
            return if self.hard.any_hit_where(o, dir, t_min, t_max, blocks) { 0.0 } else { 1.0 };
        }
        if self.drop.any_hit_where(o, dir, t_min, t_max, |k, u, v| blocks(self.off_plane[k as usize], u, v)) {
            return 0.0;
        }
        self.texture.value(p)
    }
}

impl PlateauTexture {
    /// Whether `p` (light frame) lies on the texture's plane: within ten
    /// surface epsilons of it.
    pub fn holds(&self, p: Vec3) -> bool {
        self.plane.height(p).abs() <= 10.0 * surface_epsilon(p, self.extent)
    }

    /// Plane coordinates of `p`: from the plane's point along its two axes.
    pub fn coordinates(&self, p: Vec3) -> Vec2 {
        Vec2::new((p - self.plane.point).dot(self.axes.0), (p - self.plane.point).dot(self.axes.1))
    }

    /// The texture's value at `p` on the plane outside the drop shadow: the
    /// darkest cone or sheet there, through Haines' falloff (1 where none reaches).
    pub fn value(&self, p: Vec3) -> f32 {
        let q = self.coordinates(p);
        let tau = self.grid.cell(q).iter().fold(1.0f32, |t, &i| t.min(sheet_tau(&self.sheets[i as usize], q)));
        Falloff::Bernstein.apply(tau)
    }

    /// The plane's two in-plane axes (light frame).
    pub fn axes(&self) -> (Vec3, Vec3) {
        self.axes
    }

    /// The sheets for a GPU copy, in the grid's item order.
    pub fn sheet_records(&self) -> Vec<SheetRecord> {
        self.sheets
            .iter()
            .map(|s| {
                let (kind, m) = match s.shape {
                    Footprint::Circle => (0.0, Mat2::IDENTITY),
                    Footprint::Parallelogram { to_axes, .. } => (1.0, to_axes),
                };
                SheetRecord {
                    ends: [s.p1.x, s.p1.y, s.p2.x, s.p2.y],
                    radii: [s.r1, s.r2, kind, 0.0],
                    to_axes: [m.x_axis.x, m.x_axis.y, m.y_axis.x, m.y_axis.y],
                }
            })
            .collect()
    }

    /// The sheets' footprint grid (for a GPU copy).
    pub fn grid(&self) -> &CellGrid {
        &self.grid
    }

    /// The cones and sheets of `scene`'s silhouette edges on `plane`.
    pub fn on_plane(scene: &Scene, light_space: &LightSpaceScene, plane: ReceiverPlane) -> Self {
        // Plane coordinates from the foot of the light's axis on it (the
        // frame origin's nearest point), where the frame keeps its digits: from
        // a corner of a 60-wide ground they were f32 at 30, 2e-6 apart.
        let plane = ReceiverPlane { point: plane.normal * plane.point.dot(plane.normal), ..plane };
        let extent = light_space.extent;
        let projection = light_space.frame.projection;
        let spread = match projection {
            Projection::Perspective { radius } => 2.0 * radius,
            Projection::Orthographic { tan_angle } => 2.0 * tan_angle,
        };
        let axes = across(plane.normal);
        let footprint = |v: Vec3| footprint(light_space.frame.aperture, projection, plane, axes, v);
        let mut ex = FinExtractor::default();
        ex.extract_silhouettes(scene, light_space);
        // Each silhouette vertex's cone: its drop-shadow point on the plane and radius.
        let cone = |v: Vec3| -> Option<(Vec2, f32)> {
            let h = plane.height(v);
            let (p, along) = match projection {
                Projection::Perspective { .. } => {
                    // Along the ray from the light's centre (the frame origin) through `v`.
                    let denom = v.dot(plane.normal);
                    let to_plane = plane.point.dot(plane.normal);
                    // A vertex level with or behind the light has no drop shadow on the plane.
                    if !(denom < 0.0) || !(to_plane < 0.0) {
                        return None;
                    }
                    let p = v * (to_plane / denom);
                    let a = (p - v).length();
                    (p, if h > 0.0 { a / v.length().max(1e-30) } else { 0.0 })
                }
                Projection::Orthographic { .. } => {
                    let d_n = Vec3::Z.dot(plane.normal);
                    if !(d_n < 0.0) {
                        return None;
                    }
                    let p = v + Vec3::Z * (-h / d_n);
                    (p, if h > 0.0 { (p - v).length() } else { 0.0 })
                }
            };
            let q = Vec2::new((p - plane.point).dot(axes.0), (p - plane.point).dot(axes.1));
            let r = spread * along;
            (q.is_finite() && r.is_finite()).then_some((q, r))
        };
        let sheets: Vec<Sheet> = ex
            .silhouettes
            .iter()
            .filter_map(|e| {
                let ((p1, r1), (p2, r2)) = (cone(e.a)?, cone(e.b)?);
                // One parallelogram per sheet, carried along the ray through
                // the edge's midpoint (the same for every ray when the plane
                // is parallel to the light).
                let shape = footprint((e.a + e.b) * 0.5);
                (r1 > 0.0 || r2 > 0.0).then_some(Sheet { p1, p2, r1, r2, shape })
            })
            .collect();
        let bounds: Vec<Option<(Vec2, Vec2)>> = sheets
            .iter()
            .map(|s| {
                let k = s.shape.half_box();
                Some(((s.p1 - k * s.r1).min(s.p2 - k * s.r2), (s.p1 + k * s.r1).max(s.p2 + k * s.r2)))
            })
            .collect();
        let (lo, hi) = bounds
            .iter()
            .flatten()
            .fold((Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)), |(lo, hi), (a, b)| {
                (lo.min(*a), hi.max(*b))
            });
        let (lo, size) = if lo.x <= hi.x { (lo, (hi - lo).max(Vec2::splat(1e-20))) } else { (Vec2::ZERO, Vec2::ONE) };
        // Padded by 1e-3 of its size: a sheet on the grid's border whose
        // reach is below the f32 steps of `lo` and `size` (a light a
        // millionth of the scene) fell outside `CellGrid::cell`'s range.
        let (lo, size) = (lo - size * 1e-3, size * (1.0 + 2e-3));
        let mut side = ((sheets.len() as f32).sqrt() * 2.0).clamp(1.0, 512.0) as usize;
        // Wide sheets (a large light) cover many cells: coarser cells until
        // the lists fit, as the coverage index does.
        loop {
            let entries: usize = bounds
                .iter()
                .flatten()
                .map(|(a, b)| {
                    let (x0, x1, y0, y1) = cell_range(lo, size, [side, side], *a, *b);
                    (x1 - x0 + 1) * (y1 - y0 + 1)
                })
                .sum();
            if entries <= MAX_ENTRIES || side == 1 {
                break;
            }
            side = (side / 2).max(1);
        }
        let grid = CellGrid::build(lo, size, [side, side], &bounds);
        Self { plane, sheets, grid, axes, extent }
    }
}

/// The cross-section of a rectangle light's cones on `plane` (plane
/// coordinates along `axes`), for a vertex at `v`: the light's half sides
/// `a·x̂`, `b·ŷ` (units of its bounding circle, the cone's radius) carried
/// onto the plane along the ray through `v`, `l − w (l·n)/(w·n)` — the
/// derivative of where a light point's ray through `v` meets the plane,
/// up to the cone's scale `|p − v|/|v|` (which [`PlateauModel::on_plane`]
/// puts in `r`). The disk and the sun keep Haines' circles.
fn footprint(
    aperture: Aperture,
    projection: Projection,
    plane: ReceiverPlane,
    axes: (Vec3, Vec3),
    v: Vec3,
) -> Footprint {
    let Aperture::Rect { half_extents } = aperture else { return Footprint::Circle };
    let w = match projection {
        Projection::Perspective { .. } => v.normalize_or_zero(),
        Projection::Orthographic { .. } => Vec3::Z,
    };
    let w_n = w.dot(plane.normal);
    let carry = |l: Vec3| {
        let k = l - w * (l.dot(plane.normal) / w_n);
        Vec2::new(k.dot(axes.0), k.dot(axes.1))
    };
    // A zero side (a line light) kept a sliver, so the matrix inverts.
    let h = half_extents.max(Vec2::splat(1e-6));
    let (k1, k2) = (carry(Vec3::X) * h.x, carry(Vec3::Y) * h.y);
    let to_axes = Mat2::from_cols(k1, k2).inverse();
    if !(w_n < 0.0) || !to_axes.is_finite() {
        return Footprint::Circle;
    }
    Footprint::Parallelogram { to_axes, half_box: k1.abs() + k2.abs() }
}

/// The smallest `τ` at which `q` is in the hull of the sheet's two cones'
/// cross-sections of radii `τ·r₁`, `τ·r₂`: `min over u` of
/// `‖q − p(u)‖ / r(u)`. Circles: setting the derivative of its square to
/// zero is linear in `u`, so the minimum is at that root or at an end.
/// Parallelograms: the norm along the segment is convex and piecewise
/// linear, and a linear function over the positive linear `r(u)` is
/// monotone, so the minimum is at an end or a kink (where a coordinate
/// `cᵢ(u)` or `|c₁| − |c₂|` is 0).
fn sheet_tau(s: &Sheet, q: Vec2) -> f32 {
    // In f64: a line light's zero side, kept a sliver of 1e-6, and a light a
    // millionth of its edges' length put `c` at 1e6–1e7 while `τ` is about
    // 1, and where the kinks cancel it, f32 kept τ to steps of 1/8 or worse.
    let d = q.as_dvec2() - s.p1.as_dvec2();
    let e = s.p2.as_dvec2() - s.p1.as_dvec2();
    let (r1, dr) = (s.r1 as f64, s.r2 as f64 - s.r1 as f64);
    if let Footprint::Parallelogram { to_axes, .. } = s.shape {
        let to_axes = to_axes.as_dmat2();
        let (c0, ce) = (to_axes * d, to_axes * e);
        let at = |u: f64| {
            let r = r1 + u * dr;
            let c = c0 - ce * u;
            if r > 0.0 { c.x.abs().max(c.y.abs()) / r } else { f64::INFINITY }
        };
        let mut best = at(0.0).min(at(1.0));
        for (num, den) in [(c0.x, ce.x), (c0.y, ce.y), (c0.x - c0.y, ce.x - ce.y), (c0.x + c0.y, ce.x + ce.y)] {
            if den != 0.0 {
                let u = num / den;
                if (0.0..=1.0).contains(&u) {
                    best = best.min(at(u));
                }
            }
        }
        return best as f32;
    }
    let at = |u: f64| {
        let r = r1 + u * dr;
        if r > 0.0 { (d - e * u).length() / r } else { f64::INFINITY }
    };
    let mut best = at(0.0).min(at(1.0));
    let denom = r1 * e.length_squared() + dr * d.dot(e);
    if denom != 0.0 {
        let u = (r1 * d.dot(e) + dr * d.length_squared()) / denom;
        if (0.0..=1.0).contains(&u) {
            best = best.min(at(u));
        }
    }
    best as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers in [0, 1] from a xorshift32 generator seeded with `seed`.
    fn xorshift(mut seed: u32) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        }
    }

    /// Brute force over `u`: the closed form finds the same minimum.
    #[test]
    fn the_sheet_minimum_in_closed_form_matches_a_dense_search() {
        let mut rnd = xorshift(7);
        for _ in 0..500 {
            let s = Sheet {
                p1: Vec2::new(rnd(), rnd()) * 4.0,
                p2: Vec2::new(rnd(), rnd()) * 4.0,
                r1: rnd() * 2.0,
                r2: rnd() * 2.0 + 1e-3,
                shape: Footprint::Circle,
            };
            let q = Vec2::new(rnd(), rnd()) * 6.0 - Vec2::ONE;
            let dense = (0..=20000)
                .map(|i| {
                    let u = i as f32 / 20000.0;
                    let r = s.r1 + u * (s.r2 - s.r1);
                    if r > 0.0 { (q - s.p1.lerp(s.p2, u)).length() / r } else { f32::INFINITY }
                })
                .fold(f32::INFINITY, f32::min);
            let closed = sheet_tau(&s, q);
            assert!(
                (closed - dense).abs() <= 1e-3 * dense.max(1.0),
                "closed {closed} vs dense {dense} for {s:?} at {q}"
            );
        }
    }

    /// The same for parallelogram cones: the ends and kinks hold the minimum.
    #[test]
    fn the_parallelogram_sheet_minimum_at_ends_and_kinks_matches_a_dense_search() {
        let mut rnd = xorshift(11);
        for _ in 0..500 {
            // Sheared and unequal, but far from flat (det ≥ 0.25), so the
            // dense search's steps stay fine against the norm's slope.
            let (k1, k2) = (Vec2::new(rnd() + 1.0, rnd() - 0.5), Vec2::new(rnd() - 0.5, rnd() + 0.5));
            let to_axes = Mat2::from_cols(k1, k2).inverse();
            let s = Sheet {
                p1: Vec2::new(rnd(), rnd()) * 4.0,
                p2: Vec2::new(rnd(), rnd()) * 4.0,
                r1: rnd() * 2.0,
                r2: rnd() * 2.0 + 1e-3,
                shape: Footprint::Parallelogram { to_axes, half_box: k1.abs() + k2.abs() },
            };
            let q = Vec2::new(rnd(), rnd()) * 6.0 - Vec2::ONE;
            let dense = (0..=20000)
                .map(|i| {
                    let u = i as f32 / 20000.0;
                    let r = s.r1 + u * (s.r2 - s.r1);
                    let c = to_axes * (q - s.p1.lerp(s.p2, u));
                    if r > 0.0 { c.x.abs().max(c.y.abs()) / r } else { f32::INFINITY }
                })
                .fold(f32::INFINITY, f32::min);
            let closed = sheet_tau(&s, q);
            assert!(closed <= dense + 1e-4 * dense.max(1.0), "kinks {closed} above dense {dense} for {s:?} at {q}");
            assert!(closed >= dense - 1e-3 * dense.max(1.0), "kinks {closed} below dense {dense} for {s:?} at {q}");
        }
    }

    #[test]
    fn a_rectangle_over_a_parallel_plane_keeps_its_sides() {
        // Plane across the light's axis: the footprint's half axes are the
        // rectangle's, whatever the vertex (no carrying along the ray).
        let plane = ReceiverPlane { point: Vec3::new(0.0, 0.0, 5.0), normal: Vec3::NEG_Z };
        let axes = (Vec3::X, Vec3::Y);
        let ap = Aperture::rect(Vec2::new(4.0, 1.0));
        let Aperture::Rect { half_extents } = ap else { unreachable!() };
        for v in [Vec3::new(0.0, 0.0, 3.0), Vec3::new(2.0, -1.0, 2.0)] {
            let Footprint::Parallelogram { to_axes, half_box } =
                footprint(ap, Projection::Perspective { radius: 1.0 }, plane, axes, v)
            else {
                panic!("a rectangle's footprint is a parallelogram")
            };
            assert!((half_box - half_extents).abs().max_element() < 1e-6, "{half_box} vs {half_extents}");
            assert!((to_axes * Vec2::new(half_extents.x, 0.0) - Vec2::X).length() < 1e-5);
        }
        assert_eq!(
            footprint(Aperture::Disk, Projection::Perspective { radius: 1.0 }, plane, axes, Vec3::Z),
            Footprint::Circle
        );
    }

    #[test]
    fn equal_cones_make_a_flat_band_of_their_radius() {
        let s = Sheet { p1: Vec2::new(0.0, 0.0), p2: Vec2::new(4.0, 0.0), r1: 1.0, r2: 1.0, shape: Footprint::Circle };
        assert!((sheet_tau(&s, Vec2::new(2.0, 0.5)) - 0.5).abs() < 1e-6);
        assert!((sheet_tau(&s, Vec2::new(5.0, 0.0)) - 1.0).abs() < 1e-6);
    }
}
