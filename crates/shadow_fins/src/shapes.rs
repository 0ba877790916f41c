//! Procedural meshes with outward (counter-clockwise) winding.

use std::f32::consts::{PI, TAU};

use glam::Vec3;

use crate::mesh::Mesh;

/// Collects triangles and builds a validated [`Mesh`].
#[derive(Default)]
struct Builder {
    positions: Vec<Vec3>,
    indices: Vec<u32>,
}

impl Builder {
    fn vertex(&mut self, p: Vec3) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }

    /// Quad `a b c d`, counter-clockwise seen from outside.
    fn quad(&mut self, a: u32, b: u32, c: u32, d: u32) {
        self.indices.extend([a, b, c, a, c, d]);
    }

    fn finish(self) -> Mesh {
        Mesh::new(self.positions, self.indices).expect("procedural meshes are valid by construction")
    }
}

/// Axis-aligned box centred at the origin.
pub fn cuboid(half: Vec3) -> Mesh {
    let mut b = Builder::default();
    let v: Vec<u32> = (0..8)
        .map(|i| {
            let s = Vec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            );
            b.vertex(s * half)
        })
        .collect();
    // Faces as (corner indices) counter-clockwise from outside.
    for [a, bb, c, d] in [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]] {
        b.quad(v[a], v[bb], v[c], v[d]);
    }
    b.finish()
}

/// Square plane in XZ facing +Y, `size` wide, split into `cells²` quads.
pub fn plane(size: f32, cells: u32) -> Mesh {
    let cells = cells.max(1);
    let mut b = Builder::default();
    let n = cells + 1;
    for z in 0..n {
        for x in 0..n {
            let f = |i: u32| (i as f32 / cells as f32 - 0.5) * size;
            b.vertex(Vec3::new(f(x), 0.0, f(z)));
        }
    }
    for z in 0..cells {
        for x in 0..cells {
            let i = z * n + x;
            b.quad(i, i + n, i + n + 1, i + 1);
        }
    }
    b.finish()
}

/// UV sphere (poles welded; their degenerate triangles are skipped by the topology).
pub fn uv_sphere(radius: f32, rings: u32, segments: u32) -> Mesh {
    displaced_sphere(rings, segments, |_, _| radius)
}

/// UV sphere with radius `r(θ, φ)`; `θ` from the +Y pole, `φ` around Y.
pub fn displaced_sphere(rings: u32, segments: u32, radius: impl Fn(f32, f32) -> f32) -> Mesh {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let mut b = Builder::default();
    for i in 0..=rings {
        let theta = PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = TAU * j as f32 / segments as f32;
            // Poles exactly on the axis, so their copies weld (sin π ≠ 0 in f32).
            let p = if i == 0 {
                Vec3::Y * radius(0.0, 0.0)
            } else if i == rings {
                Vec3::NEG_Y * radius(PI, 0.0)
            } else {
                Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * radius(theta, phi)
            };
            b.vertex(p);
        }
    }
    for i in 0..rings {
        for j in 0..segments {
            let k = (j + 1) % segments;
            let (a, bb, c, d) = (i * segments + j, (i + 1) * segments + j, (i + 1) * segments + k, i * segments + k);
            b.quad(a, d, c, bb);
        }
    }
    b.finish()
}

/// Torus around the Y axis.
pub fn torus(major: f32, minor: f32, major_segments: u32, minor_segments: u32) -> Mesh {
    let (nu, nv) = (major_segments.max(3), minor_segments.max(3));
    let mut b = Builder::default();
    for i in 0..nu {
        let u = TAU * i as f32 / nu as f32;
        for j in 0..nv {
            let v = TAU * j as f32 / nv as f32;
            let ring = major + minor * v.cos();
            b.vertex(Vec3::new(ring * u.cos(), minor * v.sin(), ring * u.sin()));
        }
    }
    for i in 0..nu {
        for j in 0..nv {
            let (i1, j1) = ((i + 1) % nu, (j + 1) % nv);
            b.quad(i * nv + j, i * nv + j1, i1 * nv + j1, i1 * nv + j);
        }
    }
    b.finish()
}

/// Prism over a star polygon (`points` tips) in XZ, from y = 0 to `height`.
pub fn star_prism(points: u32, inner: f32, outer: f32, height: f32) -> Mesh {
    let n = points.max(2) * 2;
    let mut b = Builder::default();
    let ring = |b: &mut Builder, y: f32| -> Vec<u32> {
        (0..n)
            .map(|i| {
                let a = TAU * i as f32 / n as f32;
                let r = if i % 2 == 0 { outer } else { inner };
                b.vertex(Vec3::new(r * a.cos(), y, r * a.sin()))
            })
            .collect()
    };
    let bottom = ring(&mut b, 0.0);
    let top = ring(&mut b, height);
    let (cb, ct) = (b.vertex(Vec3::ZERO), b.vertex(Vec3::Y * height));
    for i in 0..n as usize {
        let k = (i + 1) % n as usize;
        b.indices.extend([ct, top[k], top[i]]);
        b.indices.extend([cb, bottom[i], bottom[k]]);
        b.quad(bottom[i], top[i], top[k], bottom[k]);
    }
    b.finish()
}

/// An open sheet (one layer of triangles, with a boundary): `width × height`,
/// bent around the Y axis by `bend` radians over its width, `cells²` quads,
/// facing +Z at its middle. Real assets are full of such open parts (leaves,
/// cloth, panels without a back).
pub fn open_sheet(width: f32, height: f32, bend: f32, cells: u32) -> Mesh {
    let cells = cells.max(1);
    let n = cells + 1;
    let mut b = Builder::default();
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (i as f32 / cells as f32 - 0.5, j as f32 / cells as f32 - 0.5);
            let p = if bend.abs() < 1e-4 {
                Vec3::new(u * width, v * height, 0.0)
            } else {
                // An arc of length `width` on a circle of radius width / bend.
                let r = width / bend;
                let a = u * bend;
                Vec3::new(r * a.sin(), v * height, r * (1.0 - a.cos()))
            };
            b.vertex(p);
        }
    }
    for j in 0..cells {
        for i in 0..cells {
            let k = j * n + i;
            b.quad(k, k + 1, k + n + 1, k + n);
        }
    }
    b.finish()
}

/// A bumpy closed blob of about `triangles` triangles (≥ 1k): the scaling mesh.
pub fn bumpy_blob(triangles: u32) -> Mesh {
    // A UV sphere with s segments and s/2 rings has s² triangles (poles included).
    let segments = ((triangles.max(1000) as f32).sqrt().ceil() as u32).max(8);
    displaced_sphere(segments / 2, segments, |t, p| {
        1.0 + 0.08 * (7.0 * t).sin() * (9.0 * p).sin() + 0.04 * (23.0 * t).cos()
    })
}

/// Signed volume (positive when faces wind outward); for tests.
pub fn signed_volume(mesh: &Mesh) -> f32 {
    mesh.triangles().map(|[a, b, c]| a.dot(b.cross(c)) / 6.0).sum()
}

/// The leaf's three holes: centre `(u, v)` in the texture and radius in
/// texels at 128².
pub const LEAF_HOLES: [(f32, f32, f32); 3] = [(0.35, 0.4, 7.0), (0.62, 0.55, 6.0), (0.52, 0.28, 5.0)];

/// A `size`² alpha mask of a leaf, tip at the top (`v = 0`) and stem at the
/// bottom: 255 on the blade and the stem, 0 outside it and in three round
/// holes ([`LEAF_HOLES`]). Row-major from `v = 0`: the alpha channel of
/// `assets/leaf-cards.gltf`'s leaf texture and of the `leaf-cards` scene.
pub fn leaf_alpha(size: u32) -> Vec<u8> {
    let scale = size as f32 / 128.0;
    (0..size * size)
        .map(|i| {
            let (u, v) = (((i % size) as f32 + 0.5) / size as f32, ((i / size) as f32 + 0.5) / size as f32);
            let x = (u - 0.5) * 2.0;
            // The blade from v = 0.05 to 0.9, widest in its middle; then the stem.
            let s = (v - 0.05) / 0.85;
            let blade = (0.0..=1.0).contains(&s) && x.abs() < 0.9 * 4.0 * s * (1.0 - s);
            let stem = v > 0.85 && x.abs() < 0.05;
            let hole = LEAF_HOLES.iter().any(|&(cu, cv, r)| {
                let (dx, dy) = ((u - cu) * size as f32, (v - cv) * size as f32);
                dx * dx + dy * dy < (r * scale) * (r * scale)
            });
            if (blade || stem) && !hole { 255 } else { 0 }
        })
        .collect()
}

/// A `width × height` card in the XY plane facing +Z, its bottom edge's
/// middle at the origin, with the UVs of a texture standing on it (`v = 0`
/// at the top): positions, indices and one UV per vertex.
pub fn card(width: f32, height: f32) -> (Mesh, Vec<glam::Vec2>) {
    let h = width / 2.0;
    let positions =
        vec![Vec3::new(-h, 0.0, 0.0), Vec3::new(h, 0.0, 0.0), Vec3::new(h, height, 0.0), Vec3::new(-h, height, 0.0)];
    let uvs = vec![glam::Vec2::new(0.0, 1.0), glam::Vec2::new(1.0, 1.0), glam::Vec2::new(1.0, 0.0), glam::Vec2::ZERO];
    let mesh = Mesh::new(positions, vec![0, 1, 2, 0, 2, 3]).expect("a card is valid by construction");
    (mesh, uvs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Topology;

    #[test]
    fn an_open_sheet_has_a_boundary_all_around() {
        let t = crate::mesh::Topology::build(&open_sheet(2.0, 1.0, 1.0, 4));
        assert_eq!(t.boundary_edge_count(), 16);
        assert!(!t.is_closed_manifold());
    }

    #[test]
    fn closed_shapes_wind_outward_and_are_manifold() {
        let shapes = [
            ("cuboid", cuboid(Vec3::new(1.0, 2.0, 3.0)), 48.0),
            ("sphere", uv_sphere(1.0, 32, 64), 4.0 / 3.0 * PI),
            ("torus", torus(2.0, 0.5, 64, 32), 2.0 * PI * PI * 2.0 * 0.25),
            ("star", star_prism(5, 0.4, 1.0, 0.5), 0.0),
            ("blob", bumpy_blob(4000), 0.0),
        ];
        for (name, mesh, volume) in shapes {
            let v = signed_volume(&mesh);
            assert!(v > 0.0, "{name} winds inward");
            if volume > 0.0 {
                assert!((v - volume).abs() < 0.02 * volume, "{name} volume {v} vs {volume}");
            }
            let t = Topology::build(&mesh);
            assert!(t.is_closed_manifold(), "{name} is not a closed manifold");
        }
    }

    #[test]
    fn plane_faces_up_and_blob_reaches_its_size() {
        let p = plane(2.0, 3);
        assert!(p.triangles().all(|[a, b, c]| (b - a).cross(c - a).y > 0.0));
        assert!(bumpy_blob(100_000).triangle_count() >= 100_000);
    }

    #[test]
    fn points_inside_a_closed_mesh_are_found_by_ray_parity() {
        let cube = Topology::build(&cuboid(Vec3::splat(0.5)));
        assert!(cube.is_closed_manifold());
        for p in [Vec3::ZERO, Vec3::splat(0.45), Vec3::new(-0.49, 0.0, 0.3), Vec3::new(0.0, 0.25, 0.0)] {
            assert!(cube.contains_point(p), "{p:?} is inside");
        }
        for p in [Vec3::splat(0.51), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, -0.7, 0.0)] {
            assert!(!cube.contains_point(p), "{p:?} is outside");
        }
        // Just off the centre, where the diagonal ray would graze edges.
        assert!(cube.contains_point(Vec3::new(1e-12, 1e-12, 1e-12)));
        let sphere = Topology::build(&uv_sphere(1.0, 24, 12));
        assert!(sphere.contains_point(Vec3::new(0.1, -0.2, 0.3)));
        assert!(!sphere.contains_point(Vec3::new(0.8, 0.8, 0.0)));
        // An open quad has no inside.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let quad = Topology::build(&crate::mesh::Mesh::new(p, vec![0, 1, 2, 0, 2, 3]).unwrap());
        assert!(!quad.contains_point(Vec3::new(0.5, 0.5, 0.0)));
    }
}
