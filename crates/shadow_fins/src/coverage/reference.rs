//! `D(r)` of (C1) in [`super`]: how many caster triangles the segment from
//! the receiver to the light's reference point crosses. Exactly, with one ray
//! through a BVH ([`ReferenceCount::Exact`]); or as a GPU finds it
//! ([`ReferenceCount::Raster`]): per light-map texel the sorted depths of the
//! first `K` casters the centre ray through the texel centre crosses (a
//! k-buffer), counted below the receiver's depth, then corrected by the edges
//! crossed when the centre ray moves from the texel centre to the receiver —
//! (C1) again, with the light's centre as apex and silhouettes seen from it.
//! The correction makes the raster answer exact for every ray crossing at
//! most `K + K/4` casters (the near and far lists), up to
//! [`super::MAX_REFERENCE_COUNT`].

use glam::Vec2;

use crate::{
    light::LightFrame,
    oracle::{MapRegion, MapTriangle},
    scene::LightSpaceScene,
};

/// Where `D(r)` comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ReferenceCount {
    /// One ray through a BVH from the receiver to a point near the light's centre.
    #[default]
    Exact,
    /// A k-buffer of `depths` caster depths per texel at `resolution²`
    /// (the GPU's way), corrected by edges to the receiver's own map point.
    Raster { resolution: u32, depths: u32 },
}

/// The near list's length the GPU and the lab use: 24 near and 6 far depths
/// count exactly through 30 crossings, enough for the greeble tower's lit
/// faces (16 + 8 left 0.12% umbra over there); 31 words per texel keep a
/// 1024² map within a 128 MiB storage binding.
pub const DEPTH_LIST_LENGTH: u32 = 24;

/// The far list's length for a near list of `depths`: a quarter. The far
/// list only has to reach past the last caster for receivers under a dense
/// object (their count is the total); lit faces inside one are near-list
/// receivers, so the words go there.
pub const fn far_list_length(depths: u32) -> u32 {
    if depths >= 8 { depths / 4 } else { 1 }
}

/// Per texel, the nearest `depths` caster depths along the centre ray
/// through its centre (ascending, `+∞` padded), the farthest
/// [`far_list_length`]`(depths)` (descending, `−∞` padded), and how many
/// casters the ray crosses in all.
#[derive(Debug, Clone)]
pub struct DepthLists {
    pub region: MapRegion,
    pub depths: usize,
    far_depths: usize,
    lists: Vec<f32>,
    far: Vec<f32>,
    totals: Vec<u32>,
}

impl DepthLists {
    /// Rasterises every caster triangle (both sides: every crossing counts)
    /// at texel centres, clipped at the near plane like the fins' maps.
    pub fn new(light_space: &LightSpaceScene, near: f32, resolution: u32, depths: u32) -> Self {
        let frame = &light_space.frame;
        let depths = depths.clamp(1, 64) as usize;
        let triangles = map_triangles(light_space, near);
        let region = covering_region(&triangles, resolution, frame);
        let resolution = region.resolution;
        let far_depths = far_list_length(depths as u32) as usize;
        let mut lists = vec![f32::INFINITY; (resolution * resolution) as usize * depths];
        let mut far = vec![f32::NEG_INFINITY; (resolution * resolution) as usize * far_depths];
        let mut totals = vec![0u32; (resolution * resolution) as usize];
        let res = resolution as usize;
        for t in &triangles {
            let (a, b) = t.bounds();
            let Some((x0, x1, y0, y1)) = region.texel_range(a, b) else { continue };
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let q = region.texel_center(x, y);
                    if !owns(&t.corners, q) || !t.opaque_at(q, &light_space.masks) {
                        continue;
                    }
                    let d = t.depth_at(q);
                    if d > near {
                        let texel = y as usize * res + x as usize;
                        insert_sorted(&mut lists[texel * depths..(texel + 1) * depths], d);
                        // The far list keeps the largest, as a k-buffer of −depth.
                        let f = &mut far[texel * far_depths..(texel + 1) * far_depths];
                        f.iter_mut().for_each(|x| *x = -*x);
                        insert_sorted(f, -d);
                        f.iter_mut().for_each(|x| *x = -*x);
                        totals[texel] += 1;
                    }
                }
            }
        }
        Self { region, depths, far_depths, lists, far, totals }
    }

    /// The texel centre nearest to map point `q`, or `None` outside the maps.
    pub fn texel_of(&self, q: Vec2) -> Option<(u32, u32)> {
        self.region.texel_of(q)
    }

    /// How many casters texel `(x, y)`'s centre ray crosses before depth `z`.
    /// Exact when `z` falls within the near list, or within or beyond the far
    /// list (the total less what lies behind `z`): every ray crossing no more
    /// than `depths + far_list_length(depths)` casters, and every receiver in front of the near
    /// ones or behind the far ones (the ground under a dense object). Between
    /// the two lists the count is unknown: the upper bound is taken (such a
    /// receiver is deep inside a dense object, where erring towards shadow is
    /// invisible and erring towards light would leak).
    pub fn count_before(&self, (x, y): (u32, u32), z: f32) -> u32 {
        let texel = (y * self.region.resolution + x) as usize;
        let list = &self.lists[texel * self.depths..(texel + 1) * self.depths];
        let n = list.partition_point(|&d| d < z);
        if n < self.depths {
            return n as u32;
        }
        // The far list, descending: how many of the farthest lie at or behind z.
        let far = &self.far[texel * self.far_depths..(texel + 1) * self.far_depths];
        let behind = far.partition_point(|&d| d >= z) as u32;
        self.totals[texel] - behind.min(self.totals[texel])
    }

    /// Bytes the lists take (what a GPU would hold for them).
    pub fn memory_bytes(&self) -> usize {
        (self.lists.len() + self.far.len() + self.totals.len()) * 4
    }
}

/// Every caster triangle, both sides, in map space, clipped at the near plane
/// (what the depth lists rasterise, on the CPU and on the GPU).
pub fn map_triangles(light_space: &LightSpaceScene, near: f32) -> Vec<MapTriangle> {
    let frame = &light_space.frame;
    let perspective = frame.is_perspective();
    light_space
        .casters
        .iter()
        .enumerate()
        .flat_map(|(k, t)| MapTriangle::clipped_with_cutout(t, light_space.cutout(k), frame, near, perspective))
        .collect()
}

/// The square of map space the depth lists cover: every caster, a perspective
/// one clamped to ±83° off the light's axis.
pub fn covering_region(triangles: &[MapTriangle], resolution: u32, frame: &LightFrame) -> MapRegion {
    let limit = frame.map_limit(crate::oracle::RASTER_MAP_LIMIT);
    MapRegion::covering(triangles.iter().map(MapTriangle::bounds), resolution.clamp(1, 8192), limit)
}

/// Whether the map triangle `c` owns point `q`: inside, or on an edge by the
/// top-left rule. A point on an edge two triangles share belongs to exactly
/// one of them (and a shared vertex to one of the triangles around it), so
/// every crossing is counted once — an inclusive test counts a texel centre
/// on a shared edge twice (seen: a sphere's pole under the light's centre).
/// The edge function is evaluated with its ends in a fixed order, so that the
/// two triangles of an edge get exactly opposite values.
pub fn owns(c: &[Vec2; 3], q: Vec2) -> bool {
    let area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
    if !(area != 0.0) {
        return false;
    }
    let orient = if area > 0.0 { 1.0 } else { -1.0 };
    (0..3).all(|i| {
        let (a, b) = (c[i], c[(i + 1) % 3]);
        // The edge a → b of a counter-clockwise (after `orient`) triangle.
        let (lo, hi, sign) = if (a.x, a.y) < (b.x, b.y) { (a, b, 1.0) } else { (b, a, -1.0) };
        let w = (hi - lo).perp_dot(q - lo) * sign * orient;
        let e = (b - a) * orient;
        w > 0.0 || (w == 0.0 && (e.y > 0.0 || (e.y == 0.0 && e.x < 0.0)))
    })
}

/// Keeps the `list.len()` smallest values, ascending (a k-buffer insert).
fn insert_sorted(list: &mut [f32], d: f32) {
    let at = list.partition_point(|&x| x <= d);
    if at < list.len() {
        list.copy_within(at..list.len() - 1, at + 1);
        list[at] = d;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn a_point_on_a_shared_edge_or_vertex_belongs_to_exactly_one_triangle() {
        // A fan of triangles around the origin, both windings, and points on
        // their shared edges and at the shared centre.
        let ring: Vec<Vec2> = (0..6).map(|k| Vec2::from_angle(k as f32 * 1.047_197_6)).collect();
        let fan: Vec<[Vec2; 3]> = (0..6)
            .map(|k| {
                if k % 2 == 0 {
                    [Vec2::ZERO, ring[k], ring[(k + 1) % 6]]
                } else {
                    [ring[(k + 1) % 6], ring[k], Vec2::ZERO]
                }
            })
            .collect();
        let mut points = vec![Vec2::ZERO];
        points.extend(ring.iter().map(|r| *r * 0.5));
        points.extend([Vec2::new(0.3, 0.0), Vec2::new(-0.2, 0.0)]);
        for q in points {
            let owners = fan.iter().filter(|t| owns(t, q)).count();
            assert_eq!(owners, 1, "{q:?} has {owners} owners");
        }
    }

    /// 35 stacked squares over the light's axis, at depths 0.25..=8.75, against
    /// lists of 24 near and 6 far depths: the count before `z` is exact in
    /// the near list, in the far list and beyond it, and the upper bound
    /// (the total less the far list) in the gap between them.
    #[test]
    fn counts_are_exact_in_both_lists_and_bounded_between_them() {
        use crate::light::{DiskLight, LightFrame};
        let light = DiskLight::new(Vec3::ZERO, Vec3::NEG_Y, 0.5).unwrap();
        let frame = LightFrame::disk(&light);
        let square = |z: f32| {
            let (a, b, c, d) = (Vec3::new(-z, -z, z), Vec3::new(z, -z, z), Vec3::new(z, z, z), Vec3::new(-z, z, z));
            [[a, b, c], [a, c, d]]
        };
        let casters: Vec<[Vec3; 3]> = (1..=35).flat_map(|k| square(k as f32 * 0.25)).collect();
        let ls = LightSpaceScene {
            light: crate::light::Light::Disk(light),
            frame,
            casters,
            object_frames: Vec::new(),
            reference_depth: 10.0,
            caster_cutouts: Vec::new(),
            masks: Vec::new(),
            extent: 20.0,
        };
        let lists = DepthLists::new(&ls, 0.01, 16, DEPTH_LIST_LENGTH);
        assert_eq!((lists.depths, far_list_length(DEPTH_LIST_LENGTH)), (24, 6));
        let texel = lists.texel_of(Vec2::new(0.013, 0.007)).unwrap();
        for k in 0..=36u32 {
            // Just behind the k-th square (depth 0.25 k), in front of the next.
            let z = k as f32 * 0.25 + 0.1;
            let expected = match k {
                0..=23 => k,       // the near list (a 24th could hide more behind it)
                24..=28 => 35 - 6, // between the lists: the upper bound
                _ => k.min(35),    // the far list and beyond it
            };
            assert_eq!(lists.count_before(texel, z), expected, "behind square {k}");
        }
    }

    #[test]
    fn the_k_buffer_keeps_the_nearest_depths_in_order() {
        let mut list = [f32::INFINITY; 3];
        for d in [5.0, 1.0, 4.0, 2.0, 9.0, 3.0] {
            insert_sorted(&mut list, d);
        }
        assert_eq!(list, [1.0, 2.0, 3.0]);
    }
}
