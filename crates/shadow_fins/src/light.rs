//! Lights with a size, and the light-space frame everything is computed in.
//!
//! Four lights (DESIGN §3):
//! - [`DiskLight`]: a planar disk with centre `c`, unit normal `n` pointing into
//!   the scene and radius `R`; maps are perspective from `c` along `n`.
//! - [`RectLight`]: a planar rectangle (Bevy's `RectLight`), half extents
//!   `(a, b)` along its tangent and bitangent; maps are perspective from its
//!   centre as for the disk. Its frame's `R` is the bounding circle
//!   `√(a² + b²)` (every conservative footprint stays right), and its
//!   [`Aperture`] says where in that circle the light actually is: the ground
//!   truth and the coverage method sample the rectangle, and a fin across an
//!   edge of map normal `d` is as wide as the rectangle's support function
//!   `h(d) = a|d_x| + b|d_y|` (the penumbra a straight edge casts spans the
//!   light's extent across the edge, `2h(d)`, scaled by eq. 3).
//! - [`SunLight`]: a disk at infinity of angular radius `θ`; maps are
//!   orthographic and penumbra widths are `tan θ · ΔL`.
//! - [`SphereLight`]: a sphere (Bevy's `PointLight`); six perspective frames,
//!   one per cube face, each with the sphere's outline as seen through it
//!   as its aperture (below, "Sphere lights").
//!
//! [`LightFrame`] maps world points into a light-aligned frame `(x, y, L)`:
//! `x, y` along the light plane, `L` the light-space depth. The subtraction of
//! the light origin is done in `f64`, so a scene offset by 1e5 loses no precision
//! in light space. Every stage after that (silhouettes, fins, layers, the oracle,
//! the ground truth) works in this frame.
//!
//! ## Sphere lights
//!
//! DESIGN §3, *point*: a sphere of radius `R` at `c`. Seen from a receiver
//! `p` its outline is a disk facing `p`; the ground truth samples exactly that
//! disk (the tangent circle: centre `c + (p − c)·R²/d²`, radius
//! `R·√(1 − R²/d²)`, `d = |p − c|`). The fin method needs planar maps, so a
//! sphere light is modelled by six perspective frames from `c`, one per cube
//! face, each the disk method's frame with one change:
//!
//! In a face's map (coordinates `m = (x/L, y/L)`), the disk facing a receiver
//! at map position `m` is not the disk in the face's plane but its oblique
//! projection along the ray `(m, 1)`: moving the light point by `q ⊥ (m, 1)`
//! moves the map projection of a point at depth `L` by `(q_xy − m q_z)/L`,
//! so the sphere is an ellipse `√(1 + |m|²)` times as wide along `m` as
//! across it. Its support function across a unit map direction `d` is
//! `R·√(1 + (d·m)²)` — what a fin's width is scaled by (eq. 3 otherwise
//! unchanged; eq. 5's refinement is a ratio of widths, so it holds as is).
//! On the face's axis it is the disk; at a cube corner, 1.73× wider radially.
//!
//! A face's maps cover its frustum `|x|, |y| ≤ L` widened by a margin
//! ([`SphereLight::face_window`]): a penumbra near a face's border is cast by
//! casters across it, as far out as the light is wide seen from the nearest
//! caster. Each receiver is shadowed by the one face whose frustum holds it
//! ([`CubeFace::of`]), so faces never double-count.

use glam::{DVec3, Vec2, Vec3};

use crate::error::LightError;

/// A planar disk light: the paper's light model (Cai et al. §3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiskLight {
    pub center: Vec3,
    /// Unit normal pointing into the scene: the side the disk emits to.
    pub normal: Vec3,
    /// Disk radius `R` in world units; 0 gives hard shadows.
    pub radius: f32,
}

impl DiskLight {
    /// Validates the light; the normal is normalised.
    pub fn new(center: Vec3, normal: Vec3, radius: f32) -> Result<Self, LightError> {
        if !center.is_finite() {
            return Err(LightError::NonFinitePosition(center.to_array()));
        }
        let normal = normal.try_normalize().ok_or(LightError::BadDirection(normal.to_array()))?;
        if !(radius >= 0.0 && radius.is_finite()) {
            return Err(LightError::BadRadius(radius));
        }
        Ok(Self { center, normal, radius })
    }
}

/// A rectangular planar light, as Bevy's `RectLight`: a `width` × `height`
/// rectangle centred at `center`, emitting along `normal` (Bevy: the
/// entity's −Z), its width along `tangent` (Bevy: local X).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectLight {
    pub center: Vec3,
    /// Unit normal pointing into the scene.
    pub normal: Vec3,
    /// Unit direction of the width, perpendicular to `normal`.
    pub tangent: Vec3,
    /// Half the width and half the height, world units; `0 × 0` gives hard shadows.
    pub half_extents: Vec2,
}

impl RectLight {
    /// Validates the light; `tangent` is made perpendicular to `normal` and
    /// normalised (it must not be parallel to it).
    pub fn new(center: Vec3, normal: Vec3, tangent: Vec3, width: f32, height: f32) -> Result<Self, LightError> {
        if !center.is_finite() {
            return Err(LightError::NonFinitePosition(center.to_array()));
        }
        let normal = normal.try_normalize().ok_or(LightError::BadDirection(normal.to_array()))?;
        let tangent = (tangent - normal * normal.dot(tangent))
            .try_normalize()
            .filter(|_| tangent.is_finite())
            .ok_or(LightError::BadDirection(tangent.to_array()))?;
        let ok = |x: f32| x >= 0.0 && x.is_finite();
        if !(ok(width) && ok(height)) {
            return Err(LightError::BadRectSize(width, height));
        }
        Ok(Self { center, normal, tangent, half_extents: Vec2::new(width, height) * 0.5 })
    }

    /// The rectangle of the same centre, normal and area as `disk`, `aspect`
    /// (width ÷ height, > 0) times as wide as high, its width along world x
    /// (along z when the disk faces along x): the lab's and tests' way to
    /// compare a rectangle with the disk a scene was built for.
    pub fn with_area_of(disk: &DiskLight, aspect: f32) -> Result<Self, LightError> {
        if !(aspect > 0.0 && aspect.is_finite()) {
            return Err(LightError::BadRectSize(aspect, 1.0));
        }
        let (width, height) = Self::size_of_disk_area(disk.radius, aspect);
        Self::new(disk.center, disk.normal, Self::world_tangent(disk.normal), width, height)
    }

    /// The width direction the lab and tests give a rectangle facing along
    /// `normal`: world x, or z when `normal` is (nearly) along x.
    pub fn world_tangent(normal: Vec3) -> Vec3 {
        if normal.normalize_or_zero().x.abs() > 0.9 { Vec3::Z } else { Vec3::X }
    }

    /// Width and height of the rectangle of a disk of `radius`'s area,
    /// `aspect` times as wide as high (`w·h = πR²`, `w = aspect·h`).
    pub fn size_of_disk_area(radius: f32, aspect: f32) -> (f32, f32) {
        let height = radius * (std::f32::consts::PI / aspect).sqrt();
        (height * aspect, height)
    }

    /// The disk around the rectangle (its centre, normal and bounding
    /// radius): what it can reach, for culling.
    pub fn bounding_disk(&self) -> DiskLight {
        DiskLight { center: self.center, normal: self.normal, radius: self.bounding_radius() }
    }

    /// Radius of the circle around the rectangle: the frame's `R`.
    pub fn bounding_radius(&self) -> f32 {
        self.half_extents.length()
    }
}

/// Where a light is inside its bounding circle (`R` for a planar light,
/// `tan θ` for the sun), in units of that circle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Aperture {
    /// The whole circle: a disk light or the sun.
    Disk,
    /// A rectangle of these half extents along the frame's `x`, `y` axes,
    /// with `|half_extents| = 1` (its corners on the circle).
    Rect { half_extents: Vec2 },
    /// A sphere seen through one cube face's frame: at map position `m`, an
    /// ellipse `√(1 + |m|²)` times the sphere's radius along `m`, the radius
    /// across it (the module docs, "Sphere lights"). The frame's circle is the
    /// widest it gets within the face's maps, `stretch` times the radius
    /// (`√(1 + 2·window²)`); `window` is the half-width, in map units, the
    /// face's maps cover.
    Sphere { stretch: f32, window: f32 },
}

impl Aperture {
    /// The aperture of a rectangle of these half extents (any scale). A
    /// `0 × 0` rectangle is a square (the light has no size, so its shape is
    /// moot, but every function stays finite).
    pub fn rect(half_extents: Vec2) -> Self {
        let h = half_extents.abs();
        let h = if h.length() > 0.0 && h.is_finite() {
            h / h.length()
        } else {
            Vec2::splat(std::f32::consts::FRAC_1_SQRT_2)
        };
        Aperture::Rect { half_extents: h }
    }

    /// Support function `h(d) = max over the aperture of d·q` for a unit
    /// direction `d` at map position `m` (only a sphere's depends on it), in
    /// units of the bounding circle: 1 for the disk, `a|d_x| + b|d_y|` for
    /// the rectangle, `√(1 + (d·m)²)/stretch` for a sphere (all ≤ 1 within
    /// the maps).
    #[inline]
    pub fn support_at(&self, d: Vec2, m: Vec2) -> f32 {
        match *self {
            Aperture::Disk => 1.0,
            Aperture::Rect { half_extents } => half_extents.x * d.x.abs() + half_extents.y * d.y.abs(),
            Aperture::Sphere { stretch, .. } => sphere_support(d, m) / stretch,
        }
    }

    /// `count` equal-weight points of the aperture (units of the bounding
    /// circle): the disk's Fibonacci spiral, or the rectangle's R2 sequence
    /// (Roberts' generalised golden ratio: low discrepancy in every direction,
    /// so an edge of any slope sweeps the samples evenly, where a grid would
    /// step by `1/√N` on an edge parallel to it).
    ///
    /// A sphere's are the disk's, in units of the sphere's radius: the
    /// outline a receiver sees is a disk facing it, which the ground truth
    /// and the coverage method place per receiver.
    pub fn samples(&self, count: u32) -> Vec<Vec2> {
        match *self {
            Aperture::Disk | Aperture::Sphere { .. } => disk_samples(count),
            Aperture::Rect { half_extents } => {
                // The plastic number's reciprocals (Roberts 2018).
                const A1: f64 = 0.754_877_666_246_692_8;
                const A2: f64 = 0.569_840_290_998_053_3;
                (0..count.max(1))
                    .map(|i| {
                        let (u, v) = (((i as f64 + 0.5) * A1).fract(), ((i as f64 + 0.5) * A2).fract());
                        Vec2::new((2.0 * u - 1.0) as f32, (2.0 * v - 1.0) as f32) * half_extents
                    })
                    .collect()
            }
        }
    }
}

/// A distant disk light (the sun): parallel centre rays, angular radius `θ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunLight {
    /// Unit direction the light travels in (from the sun into the scene).
    pub direction: Vec3,
    /// Angular radius `θ` in radians; 0 gives hard shadows.
    pub angular_radius: f32,
}

impl SunLight {
    pub fn new(direction: Vec3, angular_radius: f32) -> Result<Self, LightError> {
        let direction = direction.try_normalize().ok_or(LightError::BadDirection(direction.to_array()))?;
        if !(0.0..=1.4).contains(&angular_radius) {
            return Err(LightError::BadAngle(angular_radius));
        }
        Ok(Self { direction, angular_radius })
    }
}

/// Any light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    Disk(DiskLight),
    Rect(RectLight),
    Sun(SunLight),
    /// A sphere: six cube-face frames (the module docs, "Sphere lights").
    Sphere(SphereLight),
}

impl Light {
    /// The light with its size set to zero (a point or a perfectly parallel light).
    pub fn with_zero_size(self) -> Self {
        match self {
            Light::Disk(d) => Light::Disk(DiskLight { radius: 0.0, ..d }),
            Light::Rect(r) => Light::Rect(RectLight { half_extents: Vec2::ZERO, ..r }),
            Light::Sun(s) => Light::Sun(SunLight { angular_radius: 0.0, ..s }),
            Light::Sphere(s) => Light::Sphere(SphereLight { radius: 0.0, ..s }),
        }
    }

    /// The same light with its size scaled by `factor` (radius or `tan θ`).
    pub fn with_size_scaled(self, factor: f32) -> Self {
        match self {
            Light::Disk(d) => Light::Disk(DiskLight { radius: d.radius * factor, ..d }),
            Light::Rect(r) => Light::Rect(RectLight { half_extents: r.half_extents * factor, ..r }),
            Light::Sun(s) => {
                let t = (s.angular_radius.tan() * factor).atan().min(1.4);
                Light::Sun(SunLight { angular_radius: t, ..s })
            }
            Light::Sphere(s) => Light::Sphere(SphereLight { radius: s.radius * factor, ..s }),
        }
    }

    /// True when the light has no size (hard shadows).
    pub fn is_zero_size(&self) -> bool {
        match self {
            Light::Disk(d) => d.radius == 0.0,
            Light::Rect(r) => r.half_extents == Vec2::ZERO,
            Light::Sun(s) => s.angular_radius == 0.0,
            Light::Sphere(s) => s.radius == 0.0,
        }
    }

    /// The centre and unit normal of a planar light (disk or rectangle);
    /// `None` for the sun and a sphere.
    pub fn planar(&self) -> Option<(Vec3, Vec3)> {
        match self {
            Light::Disk(d) => Some((d.center, d.normal)),
            Light::Rect(r) => Some((r.center, r.normal)),
            Light::Sun(_) | Light::Sphere(_) => None,
        }
    }

    /// The light's centre: a planar light's or a sphere's; `None` for the sun.
    pub fn center(&self) -> Option<Vec3> {
        match self {
            Light::Disk(d) => Some(d.center),
            Light::Rect(r) => Some(r.center),
            Light::Sphere(s) => Some(s.center),
            Light::Sun(_) => None,
        }
    }
}

/// How the light projects into its maps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Disk light: map coordinate `(x/L, y/L)`, light radius `R`.
    Perspective { radius: f32 },
    /// Sun: map coordinate `(x, y)`, `tan θ`.
    Orthographic { tan_angle: f32 },
}

/// The light-aligned frame: `(x, y)` in the light plane, `z = L` the depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightFrame {
    origin: DVec3,
    axes: [DVec3; 3],
    pub projection: Projection,
    /// Where the light is inside the circle of [`Self::size`].
    pub aperture: Aperture,
}

impl LightFrame {
    /// Frame of a disk light: origin at the centre, depth along its normal.
    pub fn disk(light: &DiskLight) -> Self {
        Self {
            origin: light.center.as_dvec3(),
            axes: orthonormal_axes(light.normal.as_dvec3()),
            projection: Projection::Perspective { radius: light.radius },
            aperture: Aperture::Disk,
        }
    }

    /// Frame of a rectangle light: origin at the centre, `x` along its
    /// width, `y` along its height, depth along its normal.
    pub fn rect(light: &RectLight) -> Self {
        let n = light.normal.as_dvec3().normalize();
        let u = light.tangent.as_dvec3();
        let u = (u - n * n.dot(u)).normalize();
        Self {
            origin: light.center.as_dvec3(),
            axes: [u, n.cross(u), n],
            projection: Projection::Perspective { radius: light.bounding_radius() },
            aperture: Aperture::rect(light.half_extents),
        }
    }

    /// Frame of a sun light. `scene_min`/`scene_max` bound the scene; the origin
    /// is put in front of it so every depth is positive.
    pub fn sun(light: &SunLight, scene_min: Vec3, scene_max: Vec3) -> Self {
        let n = light.direction.as_dvec3();
        let center = (scene_min.as_dvec3() + scene_max.as_dvec3()) * 0.5;
        let half = (scene_max.as_dvec3() - scene_min.as_dvec3()).length() * 0.5;
        Self {
            origin: center - n * (half * 1.01 + 1e-6 * center.length().max(1.0)),
            axes: orthonormal_axes(n),
            projection: Projection::Orthographic { tan_angle: light.angular_radius.tan() },
            aperture: Aperture::Disk,
        }
    }

    /// Frame of a sun light with its origin where the caller puts it (every
    /// depth that matters must be positive: a renderer puts it in front of
    /// the part of the scene its cameras see, so that frame coordinates stay
    /// as small as that part, not as the whole scene).
    pub fn sun_at(light: &SunLight, origin: DVec3) -> Self {
        Self {
            origin,
            axes: orthonormal_axes(light.direction.as_dvec3()),
            projection: Projection::Orthographic { tan_angle: light.angular_radius.tan() },
            aperture: Aperture::Disk,
        }
    }

    /// Frame of one cube face of a sphere light (`SphereLight::face_frame`):
    /// origin at the centre, axes the face's, `radius` the bounding circle of
    /// the sphere's outline within the face's maps.
    pub(crate) fn sphere_face(origin: DVec3, axes: [DVec3; 3], radius: f32, aperture: Aperture) -> Self {
        Self { origin, axes, projection: Projection::Perspective { radius }, aperture }
    }

    /// The frame of a light whose maps are one frame. A sphere light has six
    /// ([`SphereLight::face_frames`], [`crate::scene::LightSpaceScene::faces`]);
    /// here it gets the one of the face looking at the scene's centre, with
    /// a whole face's margin.
    pub fn new(light: &Light, scene_min: Vec3, scene_max: Vec3) -> Self {
        match light {
            Light::Disk(d) => Self::disk(d),
            Light::Rect(r) => Self::rect(r),
            Light::Sun(s) => Self::sun(s, scene_min, scene_max),
            Light::Sphere(s) => s.face_frame(CubeFace::of((scene_min + scene_max) * 0.5 - s.center), 2.0),
        }
    }

    /// The sphere's radius when this is a sphere light's face frame.
    pub fn sphere_radius(&self) -> Option<f32> {
        match (self.aperture, self.projection) {
            (Aperture::Sphere { stretch, .. }, Projection::Perspective { radius }) => Some(radius / stretch),
            _ => None,
        }
    }

    /// A sphere light's face frame as the disk of the sphere's radius in the
    /// face's plane (what the peers, which model planar lights, are given);
    /// `None` for any other frame.
    pub fn face_plane_disk(&self) -> Option<Self> {
        let radius = self.sphere_radius()?;
        Some(Self { projection: Projection::Perspective { radius }, aperture: Aperture::Disk, ..*self })
    }

    /// The planes of a sphere light's face window frustum, `n·p >= 0`
    /// inside (`|x|, |y| <= window·z`); none for any other frame.
    pub fn face_window_planes(&self) -> Vec<Vec3> {
        let Aperture::Sphere { window, .. } = self.aperture else { return Vec::new() };
        vec![
            Vec3::new(-1.0, 0.0, window),
            Vec3::new(1.0, 0.0, window),
            Vec3::new(0.0, -1.0, window),
            Vec3::new(0.0, 1.0, window),
        ]
    }

    /// True when a sphere light's face frame can leave out what spans
    /// `points` (frame space: a segment's ends, a box's corners): all beyond
    /// the same plane of the face's window frustum (`|x|, |y| ≤ window·L`),
    /// or all at or behind the light's plane. No blocker of a receiver the
    /// face shadows lies there ([`SphereLight::face_window`]), and such an
    /// edge's fins — nearly level with the light, far off the face's axis —
    /// would be hundreds of map units wide and cover the whole face. Always
    /// false for any other frame (and for no points).
    pub fn outside_face_window(&self, points: &[Vec3]) -> bool {
        if !matches!(self.aperture, Aperture::Sphere { .. }) || points.is_empty() {
            return false;
        }
        let beyond = |plane: &Vec3| points.iter().all(|p| plane.dot(*p) < 0.0);
        self.face_window_planes().iter().any(beyond) || points.iter().all(|p| p.z <= 0.0)
    }

    /// World point → frame point `(x, y, L)`.
    pub fn to_frame(&self, p: Vec3) -> Vec3 {
        self.to_frame_f64(p.as_dvec3())
    }

    /// World point (in f64) → frame point.
    pub fn to_frame_f64(&self, p: DVec3) -> Vec3 {
        let d = p - self.origin;
        Vec3::new(d.dot(self.axes[0]) as f32, d.dot(self.axes[1]) as f32, d.dot(self.axes[2]) as f32)
    }

    /// World direction → frame direction.
    pub fn dir_to_frame(&self, d: Vec3) -> Vec3 {
        let d = d.as_dvec3();
        Vec3::new(d.dot(self.axes[0]) as f32, d.dot(self.axes[1]) as f32, d.dot(self.axes[2]) as f32)
    }

    /// Frame direction → world direction.
    pub fn dir_to_world(&self, d: Vec3) -> Vec3 {
        let d = d.as_dvec3();
        (self.axes[0] * d.x + self.axes[1] * d.y + self.axes[2] * d.z).as_vec3()
    }

    /// Frame point → world point.
    pub fn to_world(&self, p: Vec3) -> Vec3 {
        let p = p.as_dvec3();
        (self.origin + self.axes[0] * p.x + self.axes[1] * p.y + self.axes[2] * p.z).as_vec3()
    }

    /// World-space light origin (disk centre) and the frame axes `(u, v, n)`.
    pub fn origin(&self) -> DVec3 {
        self.origin
    }

    pub fn axes(&self) -> [Vec3; 3] {
        self.axes.map(|a| a.as_vec3())
    }

    /// The frame axes `(u, v, n)` in f64, for composing transforms into the
    /// frame without losing what the f64 origin keeps.
    pub fn axes_f64(&self) -> [DVec3; 3] {
        self.axes
    }

    /// Light size: `R` for a disk, `tan θ` for the sun.
    pub fn size(&self) -> f32 {
        match self.projection {
            Projection::Perspective { radius } => radius,
            Projection::Orthographic { tan_angle } => tan_angle,
        }
    }

    /// Map coordinate of a frame point (the centre ray's direction, or position).
    #[inline]
    pub fn map(&self, p: Vec3) -> Vec2 {
        match self.projection {
            Projection::Perspective { .. } => Vec2::new(p.x, p.y) / p.z,
            Projection::Orthographic { .. } => Vec2::new(p.x, p.y),
        }
    }

    /// Map-space direction in which a frame point `p` moves when displaced along
    /// the frame direction `d` (used to project junction normals).
    pub fn map_direction(&self, p: Vec3, d: Vec3) -> Vec2 {
        match self.projection {
            Projection::Perspective { .. } => (Vec2::new(d.x, d.y) - Vec2::new(p.x, p.y) / p.z * d.z) / p.z,
            Projection::Orthographic { .. } => Vec2::new(d.x, d.y),
        }
    }

    /// Half-width of the penumbra, in map units, that an edge at depth `edge_depth`
    /// casts on a receiver at depth `receiver_depth` (0 when the receiver is not
    /// behind the edge).
    ///
    /// Disk: the world width `B_r = R(L_r − L_b)/L_r` of eq. 3 at the edge's depth
    /// is `R(1/L_b − 1/L_r)` in map units, computed as `R((L_r − L_b)/L_b)/L_r`:
    /// the difference of two reciprocals cancels catastrophically when the
    /// receiver is just behind the edge far from the light (at `L ≈ 1e4` a gap of
    /// 1e-2 kept one significant digit), while `L_r − L_b` of two nearby floats is
    /// exact. Sun: `tan θ (L_r − L_b)`.
    #[inline]
    pub fn penumbra_half_width(&self, edge_depth: f32, receiver_depth: f32) -> f32 {
        let w = match self.projection {
            Projection::Perspective { radius } => {
                radius * ((receiver_depth - edge_depth) / edge_depth) / receiver_depth
            }
            Projection::Orthographic { tan_angle } => tan_angle * (receiver_depth - edge_depth),
        };
        if w > 0.0 { w } else { 0.0 }
    }

    /// World-space fin width `B0` at depth `L_b` for reference plane `L0` (eq. 3):
    /// `R(L0 − L_b)/L0` (disk) or `tan θ (L0 − L_b)` (sun). This is what a GPU
    /// builds its fins with; the oracle works with [`Self::penumbra_half_width`].
    pub fn fin_world_width(&self, edge_depth: f32, reference_depth: f32) -> f32 {
        let w = match self.projection {
            Projection::Perspective { radius } => radius * (reference_depth - edge_depth) / reference_depth,
            Projection::Orthographic { tan_angle } => tan_angle * (reference_depth - edge_depth),
        };
        w.max(0.0)
    }

    /// True when the frame is a perspective one (disk light).
    pub fn is_perspective(&self) -> bool {
        matches!(self.projection, Projection::Perspective { .. })
    }

    /// How far from the axis map coordinates are kept: a perspective map's
    /// coordinates are tangents of the angle off the light's axis, clamped
    /// to `perspective_limit` (geometry beyond is seen edge-on); the sun's are
    /// world units, never clamped (a 200-wide scene is 200 map units wide).
    ///
    /// A sphere's face frame keeps its face's window.
    pub fn map_limit(&self, perspective_limit: f32) -> f32 {
        match (self.is_perspective(), self.aperture) {
            (true, Aperture::Sphere { window, .. }) => perspective_limit.min(window),
            (true, _) => perspective_limit,
            (false, _) => f32::INFINITY,
        }
    }
}

/// A right-handed orthonormal frame `(u, v, n)` with `u × v = n`.
fn orthonormal_axes(n: DVec3) -> [DVec3; 3] {
    let n = n.normalize();
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let u = helper.cross(n).normalize();
    let v = n.cross(u);
    [u, v, n]
}

/// `count` points on the unit disk on a Fibonacci (sunflower) spiral: equal area
/// per point, deterministic, no clumping.
pub fn disk_samples(count: u32) -> Vec<Vec2> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..count.max(1))
        .map(|i| {
            let r = ((i as f32 + 0.5) / count.max(1) as f32).sqrt();
            let a = i as f32 * golden;
            Vec2::new(r * a.cos(), r * a.sin())
        })
        .collect()
}

/// A spherical light: Bevy's `PointLight` of `radius` at `center`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereLight {
    pub center: Vec3,
    /// Sphere radius `R`, world units; 0 gives hard shadows.
    pub radius: f32,
}

impl SphereLight {
    /// Validates the light.
    pub fn new(center: Vec3, radius: f32) -> Result<Self, LightError> {
        if !center.is_finite() {
            return Err(LightError::NonFinitePosition(center.to_array()));
        }
        if !(radius >= 0.0 && radius.is_finite()) {
            return Err(LightError::BadRadius(radius));
        }
        Ok(Self { center, radius })
    }

    /// The half-width, in map units (tangent of the angle off the face's
    /// axis), of what each face's maps cover: the face itself (1) and a margin
    /// for the casters across its borders whose penumbrae reach into it.
    ///
    /// A blocker at distance ≥ `nearest_caster` from the centre that shades a
    /// receiver inside the face lies at most `R·√3·√3 / nearest_caster` map
    /// units outside it (the sphere's support at a face corner, `R√3`, over
    /// the blocker's depth, ≥ its distance / √3). The margin is kept in
    /// `[1/64, 1]`: at least a sliver, so a fin on a border is drawn on both
    /// sides of it; at most one face again (a caster nearer than `3R` to the
    /// centre may lose the part of its penumbra that lies beyond that).
    pub fn face_window(&self, nearest_caster: f32) -> f32 {
        const LEAST: f32 = 1.0 / 64.0;
        if self.radius == 0.0 {
            return 1.0 + LEAST;
        }
        let margin = 3.0 * self.radius / nearest_caster;
        // No distance known (NaN) or a caster at the centre: a whole face's margin.
        1.0 + if margin.is_finite() && nearest_caster > 0.0 { margin.clamp(LEAST, 1.0) } else { 1.0 }
    }

    /// The frame of one cube face whose maps cover `window` (see
    /// [`Self::face_window`]; clamped to `[1, 2]`).
    pub fn face_frame(&self, face: CubeFace, window: f32) -> LightFrame {
        let window = if window.is_finite() { window.clamp(1.0, 2.0) } else { 2.0 };
        // The widest the sphere gets inside the window: at its corner, |m|² = 2w².
        let stretch = (1.0 + 2.0 * window * window).sqrt();
        LightFrame::sphere_face(
            self.center.as_dvec3(),
            face.axes(),
            self.radius * stretch,
            Aperture::Sphere { stretch, window },
        )
    }

    /// The six face frames, in [`CubeFace::ALL`] order.
    pub fn face_frames(&self, window: f32) -> [LightFrame; 6] {
        CubeFace::ALL.map(|face| self.face_frame(face, window))
    }

    /// The disk of the sphere that a point `p` sees (its outline), as its
    /// centre, radius and two unit axes spanning it; `None` when `p` is
    /// inside the sphere or at its centre (nothing can come between).
    pub fn outline_seen_from(&self, p: Vec3) -> Option<(Vec3, f32, Vec3, Vec3)> {
        outline_seen_from(self.radius, p - self.center).map(|(c, r, e1, e2)| (self.center + c, r, e1, e2))
    }
}

/// The outline of a sphere of `radius` at the origin seen from `p`: the
/// tangent circle's centre `p·R²/d²`, radius `R√(1 − R²/d²)` and axes
/// perpendicular to `p`; `None` when `p` is inside the sphere.
pub fn outline_seen_from(radius: f32, p: Vec3) -> Option<(Vec3, f32, Vec3, Vec3)> {
    let d2 = p.length_squared();
    let r2 = radius * radius;
    if !(d2 > r2) || !d2.is_finite() {
        return None;
    }
    let axis = p / d2.sqrt();
    let (e1, e2) = axis.any_orthonormal_pair();
    Some((p * (r2 / d2), (r2 * (1.0 - r2 / d2)).max(0.0).sqrt(), e1, e2))
}

/// A face of the cube around a sphere light: the maps of one face see the
/// directions whose largest component is along its axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CubeFace {
    PosX,
    NegX,
    PosY,
    NegY,
    PosZ,
    NegZ,
}

impl CubeFace {
    pub const ALL: [CubeFace; 6] =
        [CubeFace::PosX, CubeFace::NegX, CubeFace::PosY, CubeFace::NegY, CubeFace::PosZ, CubeFace::NegZ];

    /// The face's index in [`Self::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The face's outward axis.
    pub fn axis(self) -> Vec3 {
        match self {
            CubeFace::PosX => Vec3::X,
            CubeFace::NegX => Vec3::NEG_X,
            CubeFace::PosY => Vec3::Y,
            CubeFace::NegY => Vec3::NEG_Y,
            CubeFace::PosZ => Vec3::Z,
            CubeFace::NegZ => Vec3::NEG_Z,
        }
    }

    /// The face frame's axes `(u, v, n)`: `n` the face's axis, `u` and `v`
    /// along the cube's other two axes (so the face's frustum is
    /// `|x|, |y| ≤ L` in the frame), right-handed.
    pub fn axes(self) -> [DVec3; 3] {
        let n = self.axis().as_dvec3();
        let u = match self {
            CubeFace::PosX | CubeFace::NegX => DVec3::Z,
            CubeFace::PosY | CubeFace::NegY => DVec3::X,
            CubeFace::PosZ | CubeFace::NegZ => DVec3::Y,
        };
        [u, n.cross(u), n]
    }

    /// The face whose frustum holds direction `d`: its largest component
    /// (ties to the first of x, y, z; a zero or non-finite direction is +Y's,
    /// an arbitrary but fixed choice).
    pub fn of(d: Vec3) -> CubeFace {
        let a = d.abs();
        if !d.is_finite() || a.max_element() == 0.0 {
            return CubeFace::PosY;
        }
        if a.x >= a.y && a.x >= a.z {
            if d.x >= 0.0 { CubeFace::PosX } else { CubeFace::NegX }
        } else if a.y >= a.z {
            if d.y >= 0.0 { CubeFace::PosY } else { CubeFace::NegY }
        } else if d.z >= 0.0 {
            CubeFace::PosZ
        } else {
            CubeFace::NegZ
        }
    }
}

/// The support of a sphere light seen through a face's map at map position
/// `m`, across unit map direction `d`, in units of the sphere's radius:
/// `√(1 + (d·m)²)` (module docs).
#[inline]
pub fn sphere_support(d: Vec2, m: Vec2) -> f32 {
    let dm = d.dot(m);
    (1.0 + dm * dm).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lights_reject_bad_input() {
        assert!(matches!(DiskLight::new(Vec3::ZERO, Vec3::Z, -1.0), Err(LightError::BadRadius(_))));
        assert!(matches!(DiskLight::new(Vec3::ZERO, Vec3::Z, f32::NAN), Err(LightError::BadRadius(_))));
        assert!(matches!(DiskLight::new(Vec3::ZERO, Vec3::ZERO, 1.0), Err(LightError::BadDirection(_))));
        assert!(matches!(DiskLight::new(Vec3::splat(f32::INFINITY), Vec3::Z, 1.0), Err(_)));
        assert!(matches!(SunLight::new(Vec3::Z, -0.1), Err(LightError::BadAngle(_))));
        assert!(DiskLight::new(Vec3::ZERO, Vec3::Z, 0.0).is_ok());
    }

    #[test]
    fn frame_is_right_handed_and_round_trips() {
        let light = DiskLight::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.3, -1.0, 0.2), 0.5).unwrap();
        let f = LightFrame::disk(&light);
        let [u, v, n] = f.axes();
        assert!((u.cross(v) - n).length() < 1e-6);
        let p = Vec3::new(-2.0, -5.0, 4.0);
        assert!((f.to_world(f.to_frame(p)) - p).length() < 1e-5);
        assert!((f.to_frame(light.center)).length() < 1e-6);
    }

    #[test]
    fn penumbra_width_matches_similar_triangles() {
        // Edge at depth 1, receiver at depth 3, R = 0.5: world half-width on the
        // receiver is R (Lr − Lb)/Lb = 1.0, i.e. 1/3 in map units.
        let f = LightFrame::disk(&DiskLight::new(Vec3::ZERO, Vec3::Z, 0.5).unwrap());
        assert!((f.penumbra_half_width(1.0, 3.0) - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(f.penumbra_half_width(3.0, 1.0), 0.0);
    }

    #[test]
    fn penumbra_width_keeps_its_digits_for_a_small_gap_far_from_the_light() {
        // 1/L_b − 1/L_r in f32 at L ≈ 1e4 keeps about one digit of a 1e-2 gap.
        let f = LightFrame::disk(&DiskLight::new(Vec3::ZERO, Vec3::Z, 1.0).unwrap());
        for (lb, gap) in [(1e4f32, 1e-2f32), (1e3, 1e-3), (5e4, 0.5), (1.0, 1e-6)] {
            let lr = lb + gap;
            let exact = (lr as f64 - lb as f64) / (lb as f64 * lr as f64);
            let w = f.penumbra_half_width(lb, lr) as f64;
            assert!((w - exact).abs() <= 1e-5 * exact, "L_b {lb}, gap {gap}: {w} vs {exact}");
        }
    }
}

#[cfg(test)]
mod sphere_tests {
    use super::*;

    #[test]
    fn every_direction_has_one_face_and_the_face_frustum_holds_it() {
        let mut seed = 0x2545_f491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        let light = SphereLight::new(Vec3::new(1.0, -2.0, 3.0), 0.5).unwrap();
        for _ in 0..2000 {
            let d = Vec3::new(next(), next(), next());
            let face = CubeFace::of(d);
            let frame = light.face_frame(face, 1.0);
            let p = frame.to_frame(light.center + d * 3.0);
            assert!(
                p.z > 0.0 && p.x.abs() <= p.z * (1.0 + 1e-5) && p.y.abs() <= p.z * (1.0 + 1e-5),
                "{d} {face:?} {p}"
            );
        }
    }

    #[test]
    fn face_frames_are_right_handed_and_aligned_with_the_cube() {
        for face in CubeFace::ALL {
            let [u, v, n] = face.axes();
            assert!((u.cross(v) - n).length() < 1e-12, "{face:?}");
            for a in [u, v, n] {
                assert_eq!(a.abs().max_element(), 1.0, "{face:?} axis {a} is a cube axis");
            }
        }
    }

    #[test]
    fn the_outline_is_the_tangent_circle() {
        // From distance 2R the tangent points are at 60°: centre R/2 towards p, radius R√3/2.
        let (c, r, e1, e2) = outline_seen_from(1.0, Vec3::new(0.0, 2.0, 0.0)).unwrap();
        assert!((c - Vec3::new(0.0, 0.5, 0.0)).length() < 1e-6);
        assert!((r - 3f32.sqrt() / 2.0).abs() < 1e-6);
        assert!(e1.dot(Vec3::Y).abs() < 1e-6 && e2.dot(Vec3::Y).abs() < 1e-6 && e1.dot(e2).abs() < 1e-6);
        // A tangent point is on the sphere, and the line from p to it touches it.
        let t = c + e1 * r;
        assert!((t.length() - 1.0).abs() < 1e-5);
        assert!((t - Vec3::new(0.0, 2.0, 0.0)).dot(t).abs() < 1e-5);
        assert!(outline_seen_from(1.0, Vec3::new(0.0, 0.5, 0.0)).is_none());
        assert!(outline_seen_from(1.0, Vec3::NAN).is_none());
        // A point light: the outline is the centre, of no size.
        let (c, r, ..) = outline_seen_from(0.0, Vec3::X).unwrap();
        assert_eq!((c, r), (Vec3::ZERO, 0.0));
    }

    #[test]
    fn the_support_is_the_projected_disks_extent() {
        // Brute force: the disk of radius 1 perpendicular to the ray (m, 1),
        // projected along the ray onto the plane z = 0, spans √(1 + (d·m)²) across d.
        for m in [Vec2::ZERO, Vec2::new(0.7, -0.2), Vec2::new(1.0, 1.0), Vec2::new(-1.9, 0.4)] {
            let ray = m.extend(1.0).normalize();
            let (e1, e2) = ray.any_orthonormal_pair();
            for angle in [0.0f32, 0.4, 1.3, 2.5] {
                let d = Vec2::from_angle(angle);
                let extent = (0..3600)
                    .map(|k| {
                        let a = k as f32 / 3600.0 * std::f32::consts::TAU;
                        let q = e1 * a.cos() + e2 * a.sin();
                        (q.truncate() - m * q.z).dot(d)
                    })
                    .fold(f32::MIN, f32::max);
                assert!((extent - sphere_support(d, m)).abs() < 1e-3, "{m} {d}: {extent}");
            }
        }
    }

    #[test]
    fn the_face_window_grows_near_the_light_within_bounds() {
        let light = SphereLight::new(Vec3::ZERO, 0.1).unwrap();
        assert!((light.face_window(10.0) - 1.03).abs() < 1e-6);
        assert_eq!(light.face_window(30.0), 1.0 + 1.0 / 64.0);
        assert_eq!(light.face_window(1e9), 1.0 + 1.0 / 64.0);
        assert_eq!(light.face_window(0.05), 2.0);
        assert_eq!(light.face_window(0.0), 2.0);
        assert_eq!(light.face_window(f32::NAN), 2.0);
        let point = SphereLight::new(Vec3::ZERO, 0.0).unwrap();
        assert_eq!(point.face_window(0.0), 1.0 + 1.0 / 64.0);
    }
}
