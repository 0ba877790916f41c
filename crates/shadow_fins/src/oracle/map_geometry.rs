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
    /// light). Returns 0, 1 or 2 triangles; edge-on ones are dropped.
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
        if !perspective || tri.iter().all(|v| v.z >= near) {
            return make(*tri).into_iter().collect();
        }
        // Sutherland–Hodgman against z = near.
        let mut poly: Vec<Vec3> = Vec::with_capacity(4);
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            let (ina, inb) = (a.z >= near, b.z >= near);
            if ina {
                poly.push(a);
            }
            if ina != inb {
                let t = (near - a.z) / (b.z - a.z);
                poly.push(a + (b - a) * t);
            }
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
