//! A bounding volume hierarchy over triangles, with exact ray–triangle tests.

use glam::Vec3;

#[derive(Debug, Clone, Copy)]
struct Node {
    min: Vec3,
    max: Vec3,
    /// Leaf: first triangle index; inner: index of the right child (left is next).
    index: u32,
    /// Triangles in a leaf; 0 for an inner node.
    count: u32,
}

/// A closest hit: distance along the ray, triangle index and its geometric normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub normal: Vec3,
}

/// Median-split BVH. Built once per scene; queries are read-only and thread-safe.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    triangles: Vec<[Vec3; 3]>,
    /// Index of each stored triangle in the input slice.
    original: Vec<u32>,
}

const LEAF_SIZE: usize = 4;

impl Bvh {
    pub fn new(triangles: &[[Vec3; 3]]) -> Self {
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let centroids: Vec<Vec3> = triangles.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1);
        if !triangles.is_empty() {
            build(&mut nodes, &mut order, 0, triangles, &centroids);
        }
        let tris = order.iter().map(|&i| triangles[i as usize]).collect();
        Self { nodes, triangles: tris, original: order }
    }

    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// True when the segment `origin + t·dir`, `t ∈ (t_min, t_max)`, hits any triangle.
    pub fn any_hit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> bool {
        let mut hit = false;
        self.for_each_hit(origin, dir, t_min, t_max, |_| {
            hit = true;
            true
        });
        hit
    }

    /// True when the segment crosses a triangle that `blocks(index, u, v)`
    /// says blocks at the crossing's barycentrics (an alpha-masked caster's
    /// holes let it through; `crate::scene::LightSpaceScene::blocks_at`).
    pub fn any_hit_where(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        blocks: impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        let mut hit = false;
        self.for_each_blocking_hit(origin, dir, t_min, t_max, blocks, |_| {
            hit = true;
            true
        });
        hit
    }

    /// How many triangles the segment `origin + t·dir`, `t ∈ (t_min, t_max)`,
    /// crosses: the depth complexity along it (Laine et al. 2005), which the
    /// coverage method needs at one reference point of the light.
    pub fn count_hits(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> u32 {
        let mut hits = 0;
        self.for_each_hit(origin, dir, t_min, t_max, |_| {
            hits += 1;
            false
        });
        hits
    }

    /// [`Bvh::count_hits`] counting only the crossings `blocks(index, u, v)`
    /// accepts at their barycentrics (an alpha-masked caster's opaque part).
    pub fn count_hits_where(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        blocks: impl Fn(u32, f32, f32) -> bool,
    ) -> u32 {
        let mut hits = 0;
        self.for_each_blocking_hit(origin, dir, t_min, t_max, blocks, |_| {
            hits += 1;
            false
        });
        hits
    }

    /// Calls `on_hit(index)` (index into the input slice) for every triangle
    /// the segment crosses: which occluders block one ray (the penumbra
    /// wedges' per-silhouette shadow-volume pass).
    pub fn for_each_hit_index(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32, mut on_hit: impl FnMut(u32)) {
        self.for_each_hit(origin, dir, t_min, t_max, |index| {
            on_hit(index);
            false
        });
    }

    /// [`Self::for_each_hit`] over the crossings `blocks(index, u, v)` accepts
    /// at their barycentrics.
    fn for_each_blocking_hit(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        blocks: impl Fn(u32, f32, f32) -> bool,
        mut on_hit: impl FnMut(u32) -> bool,
    ) {
        let inv = dir.recip();
        self.traverse(
            |node| slab_hit(node, origin, inv, t_min, t_max),
            |k| {
                let index = self.original[k];
                intersect_uv(&self.triangles[k], origin, dir)
                    .is_some_and(|(t, u, v)| t > t_min && t < t_max && blocks(index, u, v))
                    && on_hit(index)
            },
        );
    }

    /// Calls `on_hit(index)` for every triangle the segment crosses, until it says stop.
    fn for_each_hit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32, mut on_hit: impl FnMut(u32) -> bool) {
        let inv = dir.recip();
        self.traverse(
            |node| slab_hit(node, origin, inv, t_min, t_max),
            |k| {
                intersect(&self.triangles[k], origin, dir).is_some_and(|t| t > t_min && t < t_max)
                    && on_hit(self.original[k])
            },
        );
    }

    /// Calls `on_triangle(index, triangle)` (index into the input slice) for
    /// every triangle in a leaf whose box passes `node_test(min, max)`: a
    /// traversal for queries wider than a ray (the softened objects of
    /// single-sample soft shadows test a cone around the shadow ray).
    pub fn for_each_candidate(
        &self,
        mut node_test: impl FnMut(Vec3, Vec3) -> bool,
        mut on_triangle: impl FnMut(u32, &[Vec3; 3]),
    ) {
        self.traverse(
            |node| node_test(node.min, node.max),
            |k| {
                on_triangle(self.original[k], &self.triangles[k]);
                false
            },
        );
    }

    /// Depth-first over the nodes that pass `node_test`, calling
    /// `on_triangle(stored index)` for their leaves' triangles until it says stop.
    fn traverse(&self, mut node_test: impl FnMut(&Node) -> bool, mut on_triangle: impl FnMut(usize) -> bool) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let idx = stack[sp] as usize;
            let node = &self.nodes[idx];
            if !node_test(node) {
                continue;
            }
            if node.count > 0 {
                let s = node.index as usize;
                for k in s..s + node.count as usize {
                    if on_triangle(k) {
                        return;
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.index;
                stack[sp + 1] = idx as u32 + 1;
                sp += 2;
            }
        }
    }

    /// Nearest hit with `t > t_min`.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, t_min: f32) -> Option<Hit> {
        self.closest_hit_where(origin, dir, t_min, |_, _, _| true)
    }

    /// Nearest hit with `t > t_min` that `accept(index, u, v)` takes at its
    /// barycentrics (an alpha-masked surface's opaque part).
    pub fn closest_hit_where(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        accept: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = dir.recip();
        let mut best: Option<(f32, usize)> = None;
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let idx = stack[sp] as usize;
            let node = &self.nodes[idx];
            let t_max = best.map_or(f32::INFINITY, |b| b.0);
            if !slab_hit(node, origin, inv, t_min, t_max) {
                continue;
            }
            if node.count > 0 {
                let s = node.index as usize;
                for (k, tri) in self.triangles[s..s + node.count as usize].iter().enumerate() {
                    if let Some((t, u, v)) = intersect_uv(tri, origin, dir) {
                        if t > t_min && best.is_none_or(|b| t < b.0) && accept(self.original[s + k], u, v) {
                            best = Some((t, s + k));
                        }
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.index;
                stack[sp + 1] = idx as u32 + 1;
                sp += 2;
            }
        }
        best.map(|(t, k)| {
            let [a, b, c] = self.triangles[k];
            Hit { t, triangle: self.original[k], normal: (b - a).cross(c - a).normalize_or_zero() }
        })
    }
}

fn build(nodes: &mut Vec<Node>, order: &mut [u32], first: usize, tris: &[[Vec3; 3]], centroids: &[Vec3]) -> usize {
    let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let (mut cmin, mut cmax) = (min, max);
    for &i in order.iter() {
        for v in tris[i as usize] {
            min = min.min(v);
            max = max.max(v);
        }
        cmin = cmin.min(centroids[i as usize]);
        cmax = cmax.max(centroids[i as usize]);
    }
    let me = nodes.len();
    nodes.push(Node { min, max, index: first as u32, count: order.len() as u32 });
    let extent = cmax - cmin;
    if order.len() <= LEAF_SIZE || extent.max_element() <= 0.0 {
        return me;
    }
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis]));
    let (left, right) = order.split_at_mut(mid);
    build(nodes, left, first, tris, centroids);
    let r = build(nodes, right, first + mid, tris, centroids);
    nodes[me].index = r as u32;
    nodes[me].count = 0;
    me
}

#[inline]
fn slab_hit(node: &Node, origin: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> bool {
    ray_hits_box(node.min, node.max, origin, inv, t_min, t_max)
}

/// Slab test: does the ray `origin + t·dir`, `t ∈ [t_min, t_max]`, meet the
/// box `[min, max]`? `inv` is `dir.recip()`.
#[inline]
pub fn ray_hits_box(min: Vec3, max: Vec3, origin: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> bool {
    let t0 = (min - origin) * inv;
    let t1 = (max - origin) * inv;
    // NaN (0 · ∞ on a slab boundary) must not reject: min/max ignore NaN operands.
    let near = t0.min(t1).max_element().max(t_min);
    let far = t0.max(t1).min_element().min(t_max);
    near <= far
}

/// Möller–Trumbore; returns the ray parameter of the hit.
#[inline]
pub fn intersect(tri: &[Vec3; 3], origin: Vec3, dir: Vec3) -> Option<f32> {
    intersect_uv(tri, origin, dir).map(|(t, _, _)| t)
}

/// Möller–Trumbore; returns the ray parameter of the hit and its
/// barycentrics `(u, v)` (weights `1 − u − v`, `u`, `v` of the corners).
#[inline]
pub fn intersect_uv(tri: &[Vec3; 3], origin: Vec3, dir: Vec3) -> Option<(f32, f32, f32)> {
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = origin - tri[0];
    let u = s.dot(p) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv_det;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    Some((e2.dot(q) * inv_det, u, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_any(tris: &[[Vec3; 3]], o: Vec3, d: Vec3, t0: f32, t1: f32) -> bool {
        tris.iter().any(|t| intersect(t, o, d).is_some_and(|t| t > t0 && t < t1))
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        // A deterministic cloud of small triangles.
        let mut s = 12345u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s as f32 / u32::MAX as f32) * 2.0 - 1.0
        };
        let tris: Vec<[Vec3; 3]> = (0..300)
            .map(|_| {
                let c = Vec3::new(rnd(), rnd(), rnd()) * 3.0;
                [c, c + Vec3::new(rnd(), rnd(), rnd()) * 0.4, c + Vec3::new(rnd(), rnd(), rnd()) * 0.4]
            })
            .collect();
        let bvh = Bvh::new(&tris);
        for _ in 0..2000 {
            let o = Vec3::new(rnd(), rnd(), rnd()) * 4.0;
            let d = Vec3::new(rnd(), rnd(), rnd());
            assert_eq!(bvh.any_hit(o, d, 1e-4, 2.0), brute_any(&tris, o, d, 1e-4, 2.0));
            let count = tris.iter().filter(|t| intersect(t, o, d).is_some_and(|t| t > 1e-4 && t < 2.0)).count();
            assert_eq!(bvh.count_hits(o, d, 1e-4, 2.0) as usize, count);
            let brute =
                tris.iter().filter_map(|t| intersect(t, o, d).filter(|&t| t > 1e-4)).fold(f32::INFINITY, f32::min);
            match bvh.closest_hit(o, d, 1e-4) {
                Some(h) => assert!((h.t - brute).abs() <= 1e-6 * brute.max(1.0)),
                None => assert!(brute.is_infinite()),
            }
        }
    }
}
