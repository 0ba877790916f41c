//! Bad geometry and extreme lights: no panic, no NaN in the visibility buffer.

use bevy_shadow_fins::{FinMethod, FinShadowSettings};
use shadow_fins::{glam::Vec3, scenes::SceneId};

use super::common::*;

/// Both methods of the plugin: fins and coverage.
fn each_method() -> [FinShadowSettings; 2] {
    [
        FinShadowSettings { method: FinMethod::MultiLayer, ..settings() },
        FinShadowSettings { method: FinMethod::Coverage, coverage_samples: 64, ..settings() },
    ]
}

#[test]
fn a_huge_light_stays_finite_and_in_range() {
    for s in each_method() {
        let mut setup = setup(SceneId::SphereGrid, s);
        setup.light = setup.light.with_size_scaled(100.0);
        let shot = render(&setup);
        assert!(shot.visibility.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)), "{:?}", s.method);
        // A light 100× the scene: the grid's shadow is a faint dimming, not black.
        let mean = shot.visibility.iter().sum::<f32>() / shot.visibility.len() as f32;
        assert!(mean > 0.5, "{:?}: mean visibility {mean}", s.method);
    }
}

#[test]
fn empty_nan_and_degenerate_meshes_are_skipped_without_panic() {
    use bevy::{
        asset::RenderAssetUsages,
        mesh::{Indices, Mesh as BevyMesh, PrimitiveTopology},
    };
    let mesh = |positions: Vec<[f32; 3]>, indices: Vec<u32>| {
        BevyMesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
            .with_inserted_attribute(BevyMesh::ATTRIBUTE_POSITION, positions)
            .with_inserted_indices(Indices::U32(indices))
    };
    for s in each_method() {
        let mut setup = setup(SceneId::BoxOverPlane, s);
        setup.extra_meshes = vec![
            // No triangles at all.
            (mesh(vec![], vec![]), Vec3::new(2.0, 1.0, 0.0)),
            // NaN positions.
            (
                mesh(vec![[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], vec![0, 1, 2]),
                Vec3::new(-2.0, 1.0, 0.0),
            ),
            // Every triangle of zero area.
            (mesh(vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], vec![0, 1, 2]), Vec3::new(0.0, 1.0, 2.0)),
        ];
        let shot = render(&setup);
        assert_not_trivial(&shot);
        assert!(shot.visibility.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
        // The bad meshes are skipped; the box and ground still cast and receive.
        assert_eq!(shot.stats.casters, 2, "{:?}", s.method);
    }
}

#[test]
fn a_camera_with_msaa_gets_it_turned_off_and_still_renders_shadows() {
    let mut setup = setup(SceneId::BoxOverPlane, settings());
    setup.msaa = bevy::prelude::Msaa::Sample4;
    // Deferred rendering has no MSAA: the plugin turns it off (with a warning)
    // instead of failing, and the shadows are those of an MSAA-less camera.
    let shot = render(&setup);
    assert_not_trivial(&shot);
    let (mad, far) = compare(&shot.visibility, &oracle(&setup, shadow_fins::oracle::Method::MultiLayer));
    assert!(mad <= 0.01 && far <= 0.03, "{mad} / {far}");
}
