//! Caster triangles projected into light-map space.

use glam::{Vec2, Vec3};

use crate::cutout::{AlphaMask, CasterCutout};
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
    /// An alpha-masked caster's holes ([`crate::cutout`]).
    pub cutout: Option<MapCutout>,
}

/// The cut-out of one map triangle: its mask (an index into the scene's
/// masks), the UVs at its own corners and the corners' light-frame depths,
/// which perspective-correct interpolation needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapCutout {
    pub mask: u32,
    pub uvs: [Vec2; 3],
    pub depths: [f32; 3],
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
        Self::clipped_with_cutout(tri, None, frame, near, perspective)
    }

    /// [`MapTriangle::clipped`] for a caster that may have a cut-out: each
    /// piece carries the UVs at its own corners (a clipped corner's by its
    /// barycentrics in the original triangle, which it lies on).
    pub fn clipped_with_cutout(
        tri: &[Vec3; 3],
        cutout: Option<CasterCutout>,
        frame: &LightFrame,
        near: f32,
        perspective: bool,
    ) -> Vec<MapTriangle> {
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let offset = normal.dot(tri[0]);
        let uv_at = |c: &CasterCutout, p: Vec3| {
            let b = barycentrics_3d(tri, p);
            c.uvs[0] * b.x + c.uvs[1] * b.y + c.uvs[2] * b.z
        };
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
                cutout: cutout.map(|c| MapCutout {
                    mask: c.mask,
                    uvs: p.map(|v| uv_at(&c, v)),
                    depths: p.map(|v| v.z),
                }),
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

    /// True when the triangle blocks light at the covered map point `q`:
    /// always for a solid caster; for a masked one where the alpha at the
    /// UV interpolated perspective-correctly, `Σ (bᵢ/zᵢ) uvᵢ / Σ bᵢ/zᵢ`
    /// over `q`'s barycentrics `bᵢ` (linearly under an orthographic map),
    /// passes the cutoff.
    #[inline]
    pub fn opaque_at(&self, q: Vec2, masks: &[std::sync::Arc<AlphaMask>]) -> bool {
        let Some(c) = self.cutout else {
            return true;
        };
        let [a, b, d] = self.corners;
        let area = (b - a).perp_dot(d - a);
        let mut w = Vec3::new((d - b).perp_dot(q - b), (a - d).perp_dot(q - d), (b - a).perp_dot(q - a)) / area;
        if self.perspective {
            w /= Vec3::from(c.depths).max(Vec3::splat(f32::MIN_POSITIVE));
        }
        let uv = (c.uvs[0] * w.x + c.uvs[1] * w.y + c.uvs[2] * w.z) / (w.x + w.y + w.z);
        masks.get(c.mask as usize).is_none_or(|m| m.opaque(uv))
    }

    pub fn bounds(&self) -> (Vec2, Vec2) {
        let [a, b, c] = self.corners;
        (a.min(b).min(c), a.max(b).max(c))
    }
}

/// Barycentric weights of `p` (on the triangle's plane) for its corners.
fn barycentrics_3d(tri: &[Vec3; 3], p: Vec3) -> Vec3 {
    let (e1, e2, ep) = (tri[1] - tri[0], tri[2] - tri[0], p - tri[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (dp1, dp2) = (ep.dot(e1), ep.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if !(det.abs() > 0.0) {
        return Vec3::new(1.0, 0.0, 0.0);
    }
    let v = (d22 * dp1 - d12 * dp2) / det;
    let w = (d11 * dp2 - d12 * dp1) / det;
    Vec3::new(1.0 - v - w, v, w)
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
        let frame = light.face_frame(crate::light::CubeFace::PosZ, 1.25);
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
