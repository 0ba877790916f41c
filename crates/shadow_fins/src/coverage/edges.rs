//! Potential silhouette edges (C3 in [`super`]): the edges that are a
//! silhouette from some point of the light, boundary and non-manifold edges,
//! and the cuts of triangles by the near plane, in the light frame.

use glam::Vec3;

use crate::{
    light::Projection,
    mesh::NO_FACE,
    scene::{LightSpaceScene, Scene},
};

/// One potential silhouette edge: its endpoints and the third vertex of each
/// of its faces (one for a boundary edge or a near-plane cut; a non-manifold
/// edge is split into one entry per face, whose contributions add up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoverageEdge {
    pub a: Vec3,
    pub b: Vec3,
    pub third: [Vec3; 2],
    pub faces: u8,
}

impl CoverageEdge {
    /// The part of the edge with `near ≤ z < far` (the part that can lie
    /// between a receiver at depth `far` and the light), or `None`.
    #[inline]
    pub fn clipped(&self, near: f32, far: f32) -> Option<(Vec3, Vec3)> {
        let (mut a, mut b) = (self.a, self.b);
        if a.z > b.z {
            std::mem::swap(&mut a, &mut b);
        }
        // Strictly in front of the receiver: a point at its own depth projects to infinity.
        let far = far * (1.0 - 1e-6) - 1e-30;
        if !(b.z >= near && a.z < far) {
            return None;
        }
        let (a0, b0) = (a, b);
        let at = |z: f32| a0 + (b0 - a0) * ((z - a0.z) / (b0.z - a0.z));
        if a.z < near {
            a = at(near);
        }
        if b.z > far {
            b = at(far);
        }
        Some((a, b))
    }

    /// Smallest depth along the edge.
    pub fn min_depth(&self) -> f32 {
        self.a.z.min(self.b.z)
    }
}

/// How a face's plane lies relative to the whole light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Facing {
    Front,
    Back,
    /// The plane cuts the light: a silhouette from some of its points.
    Cuts,
}

fn facing(normal: Vec3, offset: f32, projection: Projection) -> Facing {
    let spread = normal.truncate().length();
    // The plane's value over the light: disk points (R q, 0); sun directions (tanθ q, −1).
    let (centre, half) = match projection {
        Projection::Perspective { radius } => (-offset, radius * spread),
        Projection::Orthographic { tan_angle } => (-normal.z, tan_angle * spread),
    };
    if centre - half > 0.0 {
        Facing::Front
    } else if centre + half < 0.0 {
        Facing::Back
    } else {
        Facing::Cuts
    }
}

/// Every potential silhouette edge of every casting object, light frame; an
/// alpha-masked object's from its outline ([`crate::cutout::Outline`]),
/// whose one-face edges stand for the border of its opaque region.
/// `near` clips disk-light casters at the light's plane; its cuts become
/// boundary edges.
pub fn potential_silhouette_edges(scene: &Scene, light_space: &LightSpaceScene, near: f32) -> Vec<CoverageEdge> {
    let projection = light_space.frame.projection;
    let perspective = light_space.frame.is_perspective();
    let mut out = Vec::new();
    for (object, to_frame) in scene.objects.iter().zip(&light_space.object_frames) {
        if !object.casts_shadows {
            continue;
        }
        let t = &object.topology;
        let pts: Vec<Vec3> = t.positions.iter().map(|&p| to_frame.point(p)).collect();
        let planes: Vec<(Vec3, f32)> = t
            .faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| pts[i as usize]);
                let n = (b - a).cross(c - a);
                (n, n.dot(a))
            })
            .collect();
        let facings: Vec<Facing> = planes.iter().map(|&(n, d)| facing(n, d, projection)).collect();
        let third = |face: u32, v0: u32, v1: u32| {
            let f = t.faces[face as usize];
            let v = f.into_iter().find(|&v| v != v0 && v != v1).unwrap_or(f[0]);
            pts[v as usize]
        };
        if let Some(cutout) = object.fitting_cutout() {
            // An alpha-masked object: its outline's edges ([`crate::cutout`]).
            let o = &cutout.outline;
            for e in &o.edges {
                let [v0, v1] = e.vertices;
                let (pa, pb) = (o.positions[v0 as usize], o.positions[v1 as usize]);
                let (a, b) = (to_frame.point(pa), to_frame.point(pb));
                if e.faces[1] == NO_FACE {
                    // A point of its face's plane on the opaque side: left of
                    // the edge walked the face's way, seen from the face's front.
                    let (n, _) = t.face_planes[e.faces[0] as usize];
                    let walk = if e.forward[0] { pb - pa } else { pa - pb };
                    let side = n.normalize_or_zero().cross(walk.normalize_or_zero()) * n.length().sqrt();
                    let inside = to_frame.point(0.5 * (pa + pb) + side);
                    out.push(CoverageEdge { a, b, third: [inside, Vec3::ZERO], faces: 1 });
                    continue;
                }
                let (f0, f1) = (facings[e.faces[0] as usize], facings[e.faces[1] as usize]);
                if f0 == f1 && f0 != Facing::Cuts {
                    continue;
                }
                // The faces' own third corners: off the mesh edge the stretch lies on.
                let third_of = |face: u32| {
                    let f = t.faces[face as usize];
                    let [x, y, z] = f.map(|i| pts[i as usize]);
                    // The corner farthest from the stretch's line.
                    let d = |p: Vec3| (p - a).cross(b - a).length_squared();
                    if d(x) >= d(y) && d(x) >= d(z) {
                        x
                    } else if d(y) >= d(z) {
                        y
                    } else {
                        z
                    }
                };
                out.push(CoverageEdge { a, b, third: [third_of(e.faces[0]), third_of(e.faces[1])], faces: 2 });
            }
        } else {
            for e in &t.edges {
                let [v0, v1] = e.vertices;
                let (a, b) = (pts[v0 as usize], pts[v1 as usize]);
                if e.faces[1] == NO_FACE {
                    out.push(CoverageEdge { a, b, third: [third(e.faces[0], v0, v1), Vec3::ZERO], faces: 1 });
                    continue;
                }
                let (f0, f1) = (facings[e.faces[0] as usize], facings[e.faces[1] as usize]);
                if f0 == f1 && f0 != Facing::Cuts {
                    continue;
                }
                let third = [third(e.faces[0], v0, v1), third(e.faces[1], v0, v1)];
                out.push(CoverageEdge { a, b, third, faces: 2 });
            }
            // A masked object's outline already cuts its non-manifold edges per face.
            for e in &t.non_manifold_edges {
                let [v0, v1] = e.vertices;
                let (a, b) = (pts[v0 as usize], pts[v1 as usize]);
                for &(face, _) in &e.faces {
                    out.push(CoverageEdge { a, b, third: [third(face, v0, v1), Vec3::ZERO], faces: 1 });
                }
            }
        }
        if perspective {
            // Triangles cut by the near plane: the cut bounds what is left of them.
            for f in &t.faces {
                let [a, b, c] = f.map(|i| pts[i as usize]);
                if let Some(cut) = near_cut([a, b, c], near) {
                    out.push(cut);
                }
            }
        }
    }
    out
}

/// The segment where the plane `z = near` cuts a triangle, as a boundary edge
/// of its part in front (its third point a point of that part), or `None`.
fn near_cut(tri: [Vec3; 3], near: f32) -> Option<CoverageEdge> {
    let front: Vec<Vec3> = tri.iter().copied().filter(|v| v.z > near).collect();
    if front.is_empty() || front.len() == 3 {
        return None;
    }
    let mut cut = Vec::with_capacity(2);
    for i in 0..3 {
        let (p, q) = (tri[i], tri[(i + 1) % 3]);
        if (p.z > near) != (q.z > near) {
            cut.push(p + (q - p) * ((near - p.z) / (q.z - p.z)));
        }
    }
    let inside = front.iter().copied().sum::<Vec3>() / front.len() as f32;
    (cut.len() == 2).then(|| CoverageEdge { a: cut[0], b: cut[1], third: [inside, Vec3::ZERO], faces: 1 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_the_part_between_the_near_plane_and_the_receiver() {
        let e =
            CoverageEdge { a: Vec3::new(0.0, 0.0, -1.0), b: Vec3::new(0.0, 0.0, 3.0), third: [Vec3::X; 2], faces: 2 };
        let (a, b) = e.clipped(0.5, 2.0).unwrap();
        assert!((a.z - 0.5).abs() < 1e-6 && b.z < 2.0 && b.z > 1.99);
        assert!(e.clipped(4.0, 5.0).is_none(), "behind the near plane");
        assert!(e.clipped(-2.0, -1.5).is_none(), "beyond the receiver");
    }

    #[test]
    fn a_face_whose_plane_cuts_the_disk_is_neither_front_nor_back() {
        let disk = Projection::Perspective { radius: 1.0 };
        // A plane z = 2 facing the light (normal −z): the whole disk is in front.
        assert_eq!(facing(Vec3::NEG_Z, -2.0, disk), Facing::Front);
        assert_eq!(facing(Vec3::Z, 2.0, disk), Facing::Back);
        // A plane through the disk's middle (x = 0.5): it cuts the disk.
        assert_eq!(facing(Vec3::X, 0.5, disk), Facing::Cuts);
        assert_eq!(facing(Vec3::X, 1.5, disk), Facing::Back);
    }
}
