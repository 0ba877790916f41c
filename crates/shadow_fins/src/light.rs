//! Lights with a size, and the light-space frame everything is computed in.
//!
//! Two lights (DESIGN §3):
//! - [`DiskLight`]: a planar disk with centre `c`, unit normal `n` pointing into
//!   the scene and radius `R`; maps are perspective from `c` along `n`.
//! - [`SunLight`]: a disk at infinity of angular radius `θ`; maps are
//!   orthographic and penumbra widths are `tan θ · ΔL`.
//!
//! [`LightFrame`] maps world points into a light-aligned frame `(x, y, L)`:
//! `x, y` along the light plane, `L` the light-space depth. The subtraction of
//! the light origin is done in `f64`, so a scene offset by 1e5 loses no precision
//! in light space. Every stage after that (silhouettes, fins, layers, the oracle,
//! the ground truth) works in this frame.

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

/// Either light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    Disk(DiskLight),
    Sun(SunLight),
}

impl Light {
    /// The light with its size set to zero (a point or a perfectly parallel light).
    pub fn with_zero_size(self) -> Self {
        match self {
            Light::Disk(d) => Light::Disk(DiskLight { radius: 0.0, ..d }),
            Light::Sun(s) => Light::Sun(SunLight { angular_radius: 0.0, ..s }),
        }
    }

    /// The same light with its size scaled by `factor` (radius or `tan θ`).
    pub fn with_size_scaled(self, factor: f32) -> Self {
        match self {
            Light::Disk(d) => Light::Disk(DiskLight { radius: d.radius * factor, ..d }),
            Light::Sun(s) => {
                let t = (s.angular_radius.tan() * factor).atan().min(1.4);
                Light::Sun(SunLight { angular_radius: t, ..s })
            }
        }
    }

    /// True when the light has no size (hard shadows).
    pub fn is_zero_size(&self) -> bool {
        match self {
            Light::Disk(d) => d.radius == 0.0,
            Light::Sun(s) => s.angular_radius == 0.0,
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
}

impl LightFrame {
    /// Frame of a disk light: origin at the centre, depth along its normal.
    pub fn disk(light: &DiskLight) -> Self {
        Self {
            origin: light.center.as_dvec3(),
            axes: orthonormal_axes(light.normal.as_dvec3()),
            projection: Projection::Perspective { radius: light.radius },
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
        }
    }

    pub fn new(light: &Light, scene_min: Vec3, scene_max: Vec3) -> Self {
        match light {
            Light::Disk(d) => Self::disk(d),
            Light::Sun(s) => Self::sun(s, scene_min, scene_max),
        }
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
    pub fn map_limit(&self, perspective_limit: f32) -> f32 {
        if self.is_perspective() { perspective_limit } else { f32::INFINITY }
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
