//! Alpha-masked casters (`shadow_fins::cutout`): light passes through the
//! holes for the ground truth, the coverage method and the fins alike, and
//! the masked outline gives the holes and the blade penumbrae of their own.

use std::sync::Arc;

use shadow_fins::{
    coverage::{CoverageModel, CoverageSettings, ReferenceCount},
    cutout::{AlphaMask, Cutout, CutoutError},
    glam::{Affine3A, Quat, Vec2, Vec3},
    ground_truth::GroundTruth,
    mesh::Topology,
    metrics::ErrorMetrics,
    oracle::{FinSettings, FinShadowModel, Method, Receiver},
    scene::{LightSpaceScene, Scene, SceneObject},
    scenes::SceneId,
    shapes,
};

use super::{
    common::{down_light, ground, ground_receivers},
    convergence::view_receivers,
};

/// A 64² mask, opaque but for a round hole of radius 0.25 (in UV) at its centre.
fn holed_mask() -> AlphaMask {
    let alpha = (0..64 * 64)
        .map(|i| {
            let q = Vec2::new((i % 64) as f32 + 0.5, (i / 64) as f32 + 0.5) / 64.0 - 0.5;
            if q.length() < 0.25 { 0 } else { 255 }
        })
        .collect();
    AlphaMask::new(64, 64, alpha, 1.0, 0.5).unwrap()
}

/// A 2 × 2 card lying flat at height 1 (facing down when `flipped`), its
/// mask `mask` (solid when `None`), over the ground.
fn card_scene(mask: Option<AlphaMask>, flipped: bool) -> Scene {
    let (mesh, uvs) = shapes::card(2.0, 2.0);
    let topology = Topology::build(&mesh);
    // Stand the card's XY plane on the ground's XZ plane, centred at the origin.
    let turn = if flipped {
        Quat::from_rotation_x(std::f32::consts::FRAC_PI_2)
    } else {
        Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)
    };
    let z = if flipped { -1.0 } else { 1.0 };
    let t = Affine3A::from_rotation_translation(turn, Vec3::new(0.0, 1.0, z));
    let mut card = SceneObject::new("card", mesh.clone(), t).unwrap();
    if let Some(mask) = mask {
        card.cutout = Some(Cutout::new(Arc::new(mask), &uvs, &mesh, &topology).unwrap());
    }
    Scene::new(vec![ground(), card])
}

#[test]
fn light_passes_through_a_hole_for_the_truth_coverage_and_fins() {
    let light = down_light(Vec3::new(0.0, 4.0, 0.0), 0.05);
    let holed = card_scene(Some(holed_mask()), false);
    let solid = card_scene(None, false);
    // Under the hole's centre, under the card's opaque rim, and outside the card.
    let points = [Vec3::ZERO, Vec3::new(0.8, 0.0, 0.1), Vec3::new(3.0, 0.0, 0.0)];
    for (scene, expected) in [(&holed, [1.0, 0.0, 1.0]), (&solid, [0.0, 0.0, 1.0])] {
        let ls = LightSpaceScene::new(scene, light);
        let receivers = ground_receivers(&ls, &points);
        let truth = GroundTruth::new(&ls, 1024);
        let coverage = CoverageModel::new(scene, &ls, CoverageSettings::default());
        let fins = FinShadowModel::new(scene, &ls, Method::MultiLayer, FinSettings::default());
        let (exact, maps) = (fins.analytic(), fins.raster(512));
        // The plateaus peer: its drop shadow alpha-tested, its cones and
        // sheets from the outline.
        let plateaus = shadow_fins::peers::PlateauModel::new(scene, &ls);
        for (r, want) in receivers.iter().zip(expected) {
            let got = [
                truth.visibility(*r),
                coverage.visibility(*r),
                exact.visibility(*r),
                maps.visibility(*r),
                plateaus.visibility(*r),
            ];
            for (what, v) in ["truth", "coverage", "fins", "fins maps", "plateaus"].iter().zip(got) {
                assert!((v - want).abs() < 0.02, "{what} at {:?}: {v}, wanted {want}", r.position);
            }
        }
    }
}

#[test]
fn a_card_facing_away_from_the_light_casts_what_it_casts_facing_it() {
    // An open mesh's back faces are in the maps: their boundary is their
    // outline, with fins, as the front's is.
    let light = down_light(Vec3::new(0.3, 4.0, 0.2), 0.6);
    let points: Vec<Vec3> = (0..40).map(|i| Vec3::new(-2.0 + i as f32 * 0.1, 0.0, 0.37)).collect();
    for mask in [None, Some(holed_mask())] {
        let v: Vec<Vec<f32>> = [false, true]
            .iter()
            .map(|&flipped| {
                let scene = card_scene(mask.clone(), flipped);
                let ls = LightSpaceScene::new(&scene, light);
                let model = FinShadowModel::new(&scene, &ls, Method::MultiLayer, FinSettings::default());
                assert!(!model.silhouettes.is_empty(), "flipped {flipped}: the card has an outline");
                let index = model.analytic();
                ground_receivers(&ls, &points).into_iter().map(|r| index.visibility(r)).collect()
            })
            .collect();
        let worst = v[0].iter().zip(&v[1]).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 1e-3, "mask {}: front and back differ by {worst}", mask.is_some());
        assert!(v[0].iter().any(|&x| x > 0.05 && x < 0.95), "the shadow is soft");
    }
}

/// The acceptance target against a 4096-sample truth on the alpha-masked
/// leaf cards: MAE ≤ 0.01 for the coverage method; modelled solid, the same
/// cards are off by an order of magnitude more.
#[test]
fn coverage_meets_the_accuracy_target_on_alpha_masked_leaf_cards() {
    let s = SceneId::LeafCards.build();
    let (ls, receivers) = view_receivers(&s.scene, s.light, &s.camera, 96, 72);
    let lit: Vec<Receiver> = receivers.into_iter().filter(|r| r.faces_light(&ls.frame)).collect();
    let truth = GroundTruth::new(&ls, 4096);
    let t: Vec<f32> = lit.iter().map(|r| truth.visibility(*r)).collect();
    let model = CoverageModel::new(&s.scene, &ls, CoverageSettings::default());
    let m = ErrorMetrics::compute(&lit.iter().map(|r| model.visibility(*r)).collect::<Vec<_>>(), &t);
    println!("leaf-cards coverage: MAE {:.4}, p99 {:.4} on {} px", m.mae, m.p99, m.count);
    assert!(m.count > 100, "the view has a shadow");
    assert!(m.mae <= 0.01 && m.p99 <= 0.08, "{m:?}");
    // The same cards solid.
    let mut solid = s.scene.clone();
    solid.objects.iter_mut().for_each(|o| o.cutout = None);
    let solid_ls = LightSpaceScene::new(&solid, s.light);
    let solid_model = CoverageModel::new(&solid, &solid_ls, CoverageSettings::default());
    let v: Vec<f32> = lit.iter().map(|r| solid_model.visibility(*r)).collect();
    let m_solid = ErrorMetrics::compute(&v, &t);
    assert!(m_solid.mae > 10.0 * m.mae, "solid cards: {m_solid:?}, masked {m:?}");
}

#[test]
fn depth_lists_count_only_the_opaque_crossings() {
    // The GPU's reference count: its lists alpha-test as the exact ray does.
    let s = SceneId::LeafCards.build();
    let (ls, receivers) = view_receivers(&s.scene, s.light, &s.camera, 48, 36);
    let settings =
        CoverageSettings { reference: ReferenceCount::Raster { resolution: 512, depths: 24 }, ..Default::default() };
    let model = CoverageModel::new(&s.scene, &ls, settings);
    let (mut same, mut under_a_card) = (0, 0);
    for r in &receivers {
        let (exact, raster) = model.reference_counts(*r).expect("raster reference");
        same += (exact == raster) as usize;
        under_a_card += (exact > 0) as usize;
    }
    assert!(under_a_card > 20, "some receivers are under a card");
    assert!(same * 100 >= receivers.len() * 99, "{same} of {} counts agree", receivers.len());
}

#[test]
fn bad_masks_and_uvs_are_typed_errors() {
    let (mesh, uvs) = shapes::card(1.0, 1.0);
    let topology = Topology::build(&mesh);
    let mask = Arc::new(AlphaMask::new(1, 1, vec![255], 1.0, 0.5).unwrap());
    assert!(matches!(
        Cutout::new(mask.clone(), &uvs[..3], &mesh, &topology),
        Err(CutoutError::Uvs { uvs: 3, vertices: 4 })
    ));
    let mut nan = uvs.clone();
    nan[2] = Vec2::new(f32::NAN, 0.0);
    assert!(matches!(Cutout::new(mask, &nan, &mesh, &topology), Err(CutoutError::BadUv(_))));
    assert!(matches!(AlphaMask::new(4, 4, vec![0; 15], 1.0, 0.5), Err(CutoutError::Size { .. })));
}

/// A 64² mask, opaque but for its top-left quarter (u < 0.5, v < 0.5): where
/// it lands in the world pins the mask's row order and axes.
fn quarter_hole_mask() -> AlphaMask {
    let alpha = (0..64 * 64).map(|i| if i % 64 < 32 && i / 64 < 32 { 0 } else { 255 }).collect();
    AlphaMask::new(64, 64, alpha, 1.0, 0.5).unwrap()
}

#[test]
fn the_hole_lands_where_its_texels_are() {
    // `card_scene` lays the card flat: u along +x (x = 2u − 1), v along +z
    // (z = 2v − 1). The hole (u, v < 0.5) is over x, z < 0.
    let scene = card_scene(Some(quarter_hole_mask()), false);
    let light = down_light(Vec3::new(0.0, 6.0, 0.0), 0.02);
    let ls = LightSpaceScene::new(&scene, light);
    let points =
        [Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 0.0, -0.5), Vec3::new(-0.5, 0.0, 0.5), Vec3::new(0.5, 0.0, 0.5)];
    let receivers = ground_receivers(&ls, &points);
    let truth = GroundTruth::new(&ls, 256);
    let coverage = CoverageModel::new(&scene, &ls, CoverageSettings::default());
    let maps = FinShadowModel::new(&scene, &ls, Method::MultiLayer, FinSettings::default());
    let maps = maps.raster(256);
    // The convolution peer filters an alpha-tested shadow map (its
    // approximation's own error is larger, hence the wider tolerance).
    let csm = shadow_fins::peers::ConvolutionModel::new(&ls, Default::default());
    for (r, want) in receivers.iter().zip([1.0, 0.0, 0.0, 0.0]) {
        for (what, v, tolerance) in [
            ("truth", truth.visibility(*r), 0.02),
            ("coverage", coverage.visibility(*r), 0.02),
            ("maps", maps.visibility(*r), 0.02),
            ("convolution peer", csm.visibility(*r), 0.05),
        ] {
            let at = ls.frame.to_world(r.position);
            assert!((v - want).abs() < tolerance, "{what} at {at:?}: {v}, wanted {want}");
        }
    }
}

#[test]
fn a_closed_masked_mesh_keeps_its_back_faces_in_the_maps() {
    // A closed box whose top is cut by a hole and whose bottom is opaque (its
    // vertices' UVs sit in the mask's opaque corner): light through the hole
    // meets the bottom, which a closed mesh's culled back faces would miss.
    let (lo, hi) = (Vec3::new(-1.0, 1.0, -1.0), Vec3::new(1.0, 1.5, 1.0));
    let p = |x: f32, y: f32, z: f32| {
        Vec3::new(
            if x > 0.0 { hi.x } else { lo.x },
            if y > 0.0 { hi.y } else { lo.y },
            if z > 0.0 { hi.z } else { lo.z },
        )
    };
    let positions = vec![
        p(-1., -1., -1.),
        p(1., -1., -1.),
        p(1., -1., 1.),
        p(-1., -1., 1.),
        p(-1., 1., -1.),
        p(1., 1., -1.),
        p(1., 1., 1.),
        p(-1., 1., 1.),
    ];
    // Top corners over the whole texture (hole in its middle), bottom ones at an opaque texel.
    let uvs = vec![Vec2::splat(0.95); 4]
        .into_iter()
        .chain([Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)])
        .collect::<Vec<_>>();
    let indices = vec![
        0, 1, 2, 0, 2, 3, // bottom, facing down
        4, 6, 5, 4, 7, 6, // top, facing up
        0, 4, 5, 0, 5, 1, 1, 5, 6, 1, 6, 2, 2, 6, 7, 2, 7, 3, 3, 7, 4, 3, 4, 0,
    ];
    let mesh = shadow_fins::mesh::Mesh::new(positions, indices).unwrap();
    let topology = Topology::build(&mesh);
    assert!(topology.is_closed_manifold());
    let mut boxed = SceneObject::new("box", mesh.clone(), Affine3A::IDENTITY).unwrap();
    boxed.cutout = Some(Cutout::new(Arc::new(holed_mask()), &uvs, &mesh, &topology).unwrap());
    let scene = Scene::new(vec![ground(), boxed]);
    let light = down_light(Vec3::new(0.0, 6.0, 0.0), 0.02);
    let ls = LightSpaceScene::new(&scene, light);
    let under = ground_receivers(&ls, &[Vec3::ZERO])[0];
    let truth = GroundTruth::new(&ls, 256).visibility(under);
    let coverage = CoverageModel::new(&scene, &ls, CoverageSettings::default()).visibility(under);
    let model = FinShadowModel::new(&scene, &ls, Method::MultiLayer, FinSettings::default());
    let (exact, maps) = (model.analytic().visibility(under), model.raster(256).visibility(under));
    assert!(truth < 0.02, "the truth sees the bottom: {truth}");
    for (what, v) in [("coverage", coverage), ("fins", exact), ("fins maps", maps)] {
        assert!(v < 0.02, "{what}: {v} under the hole, the bottom blocks it");
    }
}

#[test]
fn the_environment_lab_alpha_tests_its_rays_as_the_ground_truth_does() {
    // The environment lab's hard, exact and truth paths cast rays in world
    // space; through a leaf card's holes they must see the light, as the
    // (alpha-tested) ground truth does — and as its CSM maps do.
    use shadow_fins::{
        light::{Light, SunLight},
        peers::environment::{EnvLight, LightShadows, WorldReceiver, shade},
    };
    let s = SceneId::LeafCards.build();
    let up = EnvLight { direction: Vec3::Y, solid_angle: 1e-6, energy: 1.0, face: 2, square: (0, 0, 1) };
    let receivers: Vec<WorldReceiver> = (0..48 * 48)
        .map(|k| {
            let (i, j) = ((k % 48) as f32, (k / 48) as f32);
            WorldReceiver { position: Vec3::new(-1.2 + i * 0.05, 0.0, -1.2 + j * 0.05), normal: Vec3::Y }
        })
        .collect();
    let hard = shade(&s.scene, &[up], LightShadows::Hard, &receivers, 2);
    let sun = Light::Sun(SunLight::new(Vec3::NEG_Y, 1e-6).unwrap());
    let ls = LightSpaceScene::new(&s.scene, sun);
    let truth = GroundTruth::new(&ls, 16);
    let expected: Vec<f32> = receivers
        .iter()
        .map(|r| {
            truth.visibility(Receiver {
                position: ls.frame.to_frame(r.position),
                normal: ls.frame.dir_to_frame(r.normal),
            })
        })
        .collect();
    let agree = hard.iter().zip(&expected).filter(|(h, e)| (*h - *e).abs() < 0.5).count();
    let mut solid = s.scene.clone();
    solid.objects.iter_mut().for_each(|o| o.cutout = None);
    let solid_hard = shade(&solid, &[up], LightShadows::Hard, &receivers, 2);
    let through_holes = hard.iter().zip(&solid_hard).filter(|(m, s)| **m > 0.5 && **s < 0.5).count();
    println!("{agree} of {} agree with the truth; {through_holes} lit only through the holes", receivers.len());
    assert!(through_holes > 20, "no receiver is lit through a card's holes ({through_holes})");
    assert!(agree * 1000 >= receivers.len() * 995, "{agree} of {} agree", receivers.len());
}
