//! Caster triangles projected into light-map space.

use glam::{Vec2, Vec3};

use crate::light::LightFrame;

/// A caster triangle in map space with its light-frame plane, so the depth at
/// any covered map point is exact (what a GPU's perspective-correct depth gives
/// at a sample position).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapTriangle {
    pub corners: [Vec2; 3],
    /// Plane `normal · X = offset` in the light frame.
    pub normal: Vec3,
    pub offset: f32,
    pub min_depth: f32,
    pub max_depth: f32,
    perspective: bool,
}

impl MapTriangle {
    /// Projects a light-frame triangle, clipped to `z >= near` under perspective
    /// (a caster through the light plane keeps only its part in front of the
    /// light) and, in a sphere light's face frame, to the face's window
    /// frustum `|x|, |y| <= window·z` (`LightFrame::face_window_planes`: what lies beyond
    /// shades no receiver of the face, and a triangle through the light's
    /// plane would otherwise reach map coordinates of `1/near`, where its
    /// inside test loses every digit). Returns the fan of the clipped
    /// polygon; edge-on triangles are dropped.
    pub fn clipped(tri: &[Vec3; 3], frame: &LightFrame, near: f32, perspective: bool) -> Vec<MapTriangle> {
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let offset = normal.dot(tri[0]);
        let make = |p: [Vec3; 3]| {
            let corners = p.map(|v| frame.map(v));
            let area = (corners[1] - corners[0]).perp_dot(corners[2] - corners[0]);
            let (min_depth, max_depth) = (p[0].z.min(p[1].z).min(p[2].z), p[0].z.max(p[1].z).max(p[2].z));
            (area.abs() > 0.0 && area.is_finite()).then_some(MapTriangle {
                corners,
                normal,
                offset,
                min_depth,
                max_depth,
                perspective,
            })
        };
        let window = frame.face_window_planes();
        let inside = |p: Vec3| p.z >= near && window.iter().all(|w| w.dot(p) >= 0.0);
        if !perspective || tri.iter().all(|v| inside(*v)) {
            return make(*tri).into_iter().collect();
        }
        // Sutherland–Hodgman against z = near, then each window plane.
        let mut poly: Vec<Vec3> = tri.to_vec();
        poly = clip_polygon(&poly, |p| p.z - near);
        for w in window {
            poly = clip_polygon(&poly, |p| w.dot(p));
        }
        (1..poly.len().saturating_sub(1)).filter_map(|i| make([poly[0], poly[i], poly[i + 1]])).collect()
    }

    /// True when `q` lies inside or on the triangle.
    #[inline]
    pub fn contains(&self, q: Vec2) -> bool {
        let [a, b, c] = self.corners;
        let w0 = (b - a).perp_dot(q - a);
        let w1 = (c - b).perp_dot(q - b);
        let w2 = (a - c).perp_dot(q - c);
        (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0)
    }

    /// Light-space depth of the triangle's plane along the centre ray through `q`.
    #[inline]
    pub fn depth_at(&self, q: Vec2) -> f32 {
        let z = if self.perspective {
            self.offset / self.normal.dot(q.extend(1.0))
        } else {
            (self.offset - self.normal.x * q.x - self.normal.y * q.y) / self.normal.z
        };
        // Float error near edge-on planes: keep the depth within the triangle's own range.
        if z.is_finite() { z.clamp(self.min_depth, self.max_depth) } else { self.min_depth }
    }

    pub fn bounds(&self) -> (Vec2, Vec2) {
        let [a, b, c] = self.corners;
        (a.min(b).min(c), a.max(b).max(c))
    }
}

/// The part of a polygon where `side(p) >= 0` (Sutherland–Hodgman, one plane).
fn clip_polygon(poly: &[Vec3], side: impl Fn(Vec3) -> f32) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (sa, sb) = (side(a), side(b));
        if sa >= 0.0 {
            out.push(a);
        }
        if (sa >= 0.0) != (sb >= 0.0) {
            out.push(a + (b - a) * (sa / (sa - sb)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::light::SphereLight;

    #[test]
    fn a_cube_faces_casters_are_clipped_to_its_window_and_keep_what_lies_in_it() {
        let light = SphereLight::new(Vec3::ZERO, 0.1).unwrap();
        let frame = light.face_frame(crate::sphere_light::CubeFace::PosZ, 1.25);
        // In frame space: a big triangle through the window and the light's plane.
        let tri = [Vec3::new(-9.0, -1.0, 0.5), Vec3::new(6.0, -2.0, 3.0), Vec3::new(1.0, 8.0, -1.0)];
        let original = MapTriangle::clipped(
            &tri,
            &LightFrame::disk(&crate::light::DiskLight::new(Vec3::ZERO, Vec3::Z, 0.1).unwrap()),
            1e-3,
            true,
        );
        let clipped = MapTriangle::clipped(&tri, &frame, 1e-3, true);
        assert!(!clipped.is_empty());
        for t in &clipped {
            for c in t.corners {
                assert!(c.x.abs() <= 1.25 + 1e-4 && c.y.abs() <= 1.25 + 1e-4, "{c} outside the window");
            }
        }
        // A map point is covered by the clipped fan exactly when it is by the
        // near-clipped triangle and lies in the window.
        let mut seed = 7u32;
        for _ in 0..4000 {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            let q = glam::Vec2::new(
                (seed % 1000) as f32 / 1000.0 * 3.0 - 1.5,
                ((seed / 1000) % 1000) as f32 / 1000.0 * 3.0 - 1.5,
            );
            let inside_window = q.x.abs() < 1.249 && q.y.abs() < 1.249;
            let in_original = original.iter().any(|t| t.contains(q));
            let in_clipped = clipped.iter().any(|t| t.contains(q));
            if (q.x.abs() - 1.25).abs() > 1e-3 && (q.y.abs() - 1.25).abs() > 1e-3 {
                assert_eq!(in_clipped, in_original && inside_window, "{q}");
            }
        }
    }
}
