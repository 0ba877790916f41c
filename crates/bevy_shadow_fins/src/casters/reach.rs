//! What a light can shadow: a caster's box culled by the light's range,
//! cone and plane, or by a point light's cube-face frustum.

use bevy::{
    camera::{primitives::Aabb, visibility::RenderLayers},
    prelude::*,
};
use shadow_fins::light::{DiskLight, LightFrame};

/// What a light's shadow sees of the scene: where it lights and its layers.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LightSees<'a> {
    pub reach: Reach,
    pub layers: &'a RenderLayers,
}

/// Where a light can light: its range (0: unbounded) and, for a spot, the
/// outer half-angle of its cone around the disk's normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Reach {
    pub range: f32,
    pub cone: Option<f32>,
}

/// True when a box (its world corners) cannot shadow anything this light
/// lights: all of it behind the disk's plane, all of it beyond the range from
/// the centre, or all of it outside the cone widened by what the disk and the
/// box subtend (a blocker of a lit receiver lies on a segment from a disk
/// point to the receiver, within `asin(R / d)` of the cone seen from the
/// centre).
pub(crate) fn out_of_reach(corners: &[Vec3; 8], disk: &DiskLight, reach: Reach) -> bool {
    let behind = corners.iter().all(|p| (*p - disk.center).dot(disk.normal) < 0.0);
    let (lo, hi) = corners.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let nearest = disk.center.clamp(lo, hi);
    let beyond = reach.range > 0.0 && nearest.distance(disk.center) > reach.range + disk.radius;
    let outside_cone = reach.cone.is_some_and(|cone| {
        let (middle, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
        let to_box = middle - disk.center;
        let distance = to_box.length();
        let margin = radius + disk.radius;
        distance > margin && {
            let angle = (to_box.dot(disk.normal) / distance).clamp(-1.0, 1.0).acos();
            angle - (margin / distance).min(1.0).asin() > cone
        }
    });
    behind || beyond || outside_cone
}

/// The distance from `point` to a box given by its corners (0 inside it).
pub(crate) fn nearest_distance(corners: &[Vec3; 8], point: Vec3) -> f32 {
    let (lo, hi) = corners.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    point.clamp(lo, hi).distance(point)
}

/// True when a box (its world corners) lies wholly outside a point light's
/// cube-face window frustum (`LightFrame::outside_face_window`); false for
/// any other frame.
pub(crate) fn outside_face(corners: &[Vec3; 8], frame: &LightFrame) -> bool {
    frame.outside_face_window(&corners.map(|c| frame.to_frame(c)))
}

/// The eight world-space corners of an entity's bounding box.
pub(crate) fn world_corners(aabb: &Aabb, transform: &GlobalTransform) -> [Vec3; 8] {
    let (c, h) = (Vec3::from(aabb.center), Vec3::from(aabb.half_extents));
    std::array::from_fn(|k| {
        let s = Vec3::new(
            if k & 1 == 0 { -1.0 } else { 1.0 },
            if k & 2 == 0 { -1.0 } else { 1.0 },
            if k & 4 == 0 { -1.0 } else { 1.0 },
        );
        transform.transform_point(c + h * s)
    })
}

/// The box's corners in bit order (x, y, z): for projecting it.
pub(crate) fn box_corners((a, b): (Vec3, Vec3)) -> [Vec3; 8] {
    std::array::from_fn(|k| {
        Vec3::new(
            if k & 1 == 0 { a.x } else { b.x },
            if k & 2 == 0 { a.y } else { b.y },
            if k & 4 == 0 { a.z } else { b.z },
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small_box_at(p: Vec3) -> [Vec3; 8] {
        std::array::from_fn(|k| {
            p + Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32) * 0.2 - Vec3::splat(0.1)
        })
    }

    #[test]
    fn casters_out_of_a_lights_reach_are_culled_and_none_in_it() {
        let disk = DiskLight::new(Vec3::ZERO, Vec3::NEG_Y, 0.5).unwrap();
        let spot = Reach { range: 10.0, cone: Some(0.5) };
        // On the axis, and just outside the cone but within what the disk subtends: kept.
        assert!(!out_of_reach(&small_box_at(Vec3::new(0.0, -3.0, 0.0)), &disk, spot));
        let edge = Vec3::new(0.6_f32.tan() * 3.0, -3.0, 0.0);
        assert!(!out_of_reach(&small_box_at(edge), &disk, spot));
        // Far outside the cone, behind the disk, beyond the range: culled.
        assert!(out_of_reach(&small_box_at(Vec3::new(3.0, -1.0, 0.0)), &disk, spot));
        assert!(out_of_reach(&small_box_at(Vec3::new(0.0, 2.0, 0.0)), &disk, spot));
        assert!(out_of_reach(&small_box_at(Vec3::new(0.0, -20.0, 0.0)), &disk, spot));
        // No cone, no range: only what is behind the disk goes.
        let everywhere = Reach { range: 0.0, cone: None };
        assert!(!out_of_reach(&small_box_at(Vec3::new(3.0, -1.0, 0.0)), &disk, everywhere));
        assert!(!out_of_reach(&small_box_at(Vec3::new(0.0, -1e6, 0.0)), &disk, everywhere));
        // A box around the light itself is never culled.
        assert!(!out_of_reach(&small_box_at(Vec3::ZERO), &disk, spot));
    }
}
