//! Property tests of welding, adjacency and silhouettes on random closed meshes.

use proptest::prelude::*;
use shadow_fins::{
    glam::{Affine3A, Mat3, Vec3},
    light::{DiskLight, Light, SunLight},
    mesh::{Mesh, Topology},
    oracle::FinExtractor,
    scene::{LightSpaceScene, Scene, SceneObject},
    shapes,
    silhouette::trace_loops,
};

/// Splits every vertex per triangle (as flat-shaded exports do).
fn unwelded(mesh: &Mesh) -> Mesh {
    let positions: Vec<Vec3> = mesh.triangles().flatten().collect();
    let indices = (0..positions.len() as u32).collect();
    Mesh::new(positions, indices).unwrap()
}

fn silhouettes(mesh: Mesh, transform: Affine3A, light: Light) -> Vec<shadow_fins::silhouette::SilhouetteEdge> {
    let scene = Scene::new(vec![SceneObject::new("m", mesh, transform).unwrap()]);
    let ls = LightSpaceScene::new(&scene, light);
    let mut ex = FinExtractor::default();
    ex.extract(&scene, &ls, 16, 1024);
    ex.silhouettes
}

fn arb_light(distance: f32) -> impl Strategy<Value = Light> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0, any::<bool>()).prop_filter_map(
        "non-zero direction",
        move |(x, y, z, sun)| {
            let d = Vec3::new(x, y, z).try_normalize()?;
            Some(if sun {
                Light::Sun(SunLight::new(d, 0.05).ok()?)
            } else {
                Light::Disk(DiskLight::new(-d * distance, d, 0.3).ok()?)
            })
        },
    )
}

/// A random linear map with a healthy determinant (mirrors included).
fn arb_linear() -> impl Strategy<Value = Mat3> {
    proptest::array::uniform9(-1.5f32..1.5).prop_filter_map("well conditioned", |m| {
        let m = Mat3::from_cols_array(&m);
        (m.determinant().abs() > 0.2).then_some(m)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn welding_restores_the_topology_of_split_meshes(rings in 3u32..10, segs in 3u32..14, bump in 0.0f32..0.4) {
        let mesh = shapes::displaced_sphere(rings, segs, |t, p| 1.0 + bump * (3.0 * t).sin() * (2.0 * p).cos());
        let a = Topology::build(&mesh);
        let b = Topology::build(&unwelded(&mesh));
        prop_assert_eq!(a.positions.len(), b.positions.len());
        prop_assert_eq!(a.edges.len(), b.edges.len());
        prop_assert!(b.is_closed_manifold());
        // Euler characteristic of a sphere: V − E + F = 2.
        prop_assert_eq!(a.positions.len() as i64 - a.edges.len() as i64 + a.faces.len() as i64, 2);
    }

    #[test]
    fn silhouette_loops_of_closed_meshes_always_close(
        rings in 3u32..12, segs in 3u32..16, bump in 0.0f32..0.5,
        linear in arb_linear(), light in arb_light(12.0),
    ) {
        // Star-shaped (possibly non-convex) closed mesh under a random affine map.
        let mesh = shapes::displaced_sphere(rings, segs, |t, p| 1.0 + bump * (4.0 * t).cos() * (3.0 * p).sin());
        let edges = silhouettes(mesh, Affine3A::from_mat3(linear), light);
        let (_loops, open) = trace_loops(&edges);
        prop_assert!(open.is_empty(), "{} silhouette edges do not close into loops", open.len());
        // Every vertex has as many silhouette edges in as out.
        let mut balance = std::collections::HashMap::<u32, i32>::new();
        for e in &edges {
            *balance.entry(e.vertex_a).or_default() += 1;
            *balance.entry(e.vertex_b).or_default() -= 1;
        }
        prop_assert!(balance.values().all(|b| *b == 0));
    }

    #[test]
    fn a_convex_mesh_has_exactly_one_silhouette_loop(
        rings in 3u32..12, segs in 4u32..16, linear in arb_linear(), light in arb_light(30.0),
    ) {
        // An affine image of a sphere tessellation is convex.
        let edges = silhouettes(shapes::uv_sphere(1.0, rings, segs), Affine3A::from_mat3(linear), light);
        let (loops, open) = trace_loops(&edges);
        prop_assert!(open.is_empty());
        prop_assert_eq!(loops.len(), 1, "{} loops", loops.len());
    }
}

#[test]
fn a_box_lit_from_above_has_its_top_rim_as_silhouette_and_fins_point_outward() {
    use shadow_fins::fins::{FinShape, FinSide};
    let light = Light::Disk(DiskLight::new(Vec3::new(0.1, 5.0, 0.05), Vec3::NEG_Y, 0.5).unwrap());
    let scene =
        Scene::new(vec![SceneObject::new("box", shapes::cuboid(Vec3::splat(0.5)), Affine3A::IDENTITY).unwrap()]);
    let ls = LightSpaceScene::new(&scene, light);
    let mut ex = FinExtractor::default();
    ex.extract(&scene, &ls, 16, 1024);
    assert_eq!(ex.silhouettes.len(), 4);
    assert!(ex.silhouettes.iter().all(|e| (ls.frame.to_world(e.a).y - 0.5).abs() < 1e-5));
    let centre = ls.frame.map(ls.frame.to_frame(Vec3::new(0.0, 0.5, 0.0)));
    for f in &ex.fins {
        if let FinShape::Quad { m0, m1, d0: dir, .. } = f.shape {
            let mid = (m0 + m1) * 0.5;
            let outward = (mid - centre).dot(dir) > 0.0;
            assert_eq!(outward, f.side == FinSide::Outer, "fin side and direction disagree");
        }
    }
    let fans = ex.fins.iter().filter(|f| matches!(f.shape, FinShape::Sector { .. })).count();
    assert_eq!(fans, 4, "one outer fan per convex corner");
}

#[test]
fn non_manifold_and_degenerate_meshes_do_not_crash() {
    // Three fins sharing one edge, plus a zero-area triangle.
    let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.5, -1.0, 0.3), Vec3::X * 2.0];
    let mesh = Mesh::new(p, vec![0, 1, 2, 1, 0, 3, 0, 1, 4, 0, 1, 5]).unwrap();
    let t = Topology::build(&mesh);
    assert_eq!(t.non_manifold_edges.len(), 1);
    assert_eq!(t.degenerate_faces, 1);
    let light = Light::Disk(DiskLight::new(Vec3::new(0.3, 3.0, 0.2), Vec3::NEG_Y, 0.4).unwrap());
    let edges = silhouettes(mesh, Affine3A::IDENTITY, light);
    assert!(edges.iter().all(|e| e.a.is_finite() && e.b.is_finite()));
}
