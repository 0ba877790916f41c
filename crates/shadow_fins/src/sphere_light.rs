//! Sphere lights (Bevy's `PointLight` with a `radius`): six cube-face frames.
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

use crate::{
    error::LightError,
    light::{Aperture, LightFrame},
};

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
