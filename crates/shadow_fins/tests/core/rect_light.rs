//! Rectangle lights (Bevy's `RectLight`): the ground truth samples the
//! rectangle, the coverage method counts its samples, and a fin across an
//! edge of map normal `d` is as wide as the rectangle's support `a|d_x| + b|d_y|`.
//!
//! Half-plane occluders at height 3 under a light at height 5 (`L_b = 2`,
//! `L_r = 5`): an edge casts a penumbra of half-width `h(d)·(L_r − L_b)/L_b`
//! on the ground, `1.5·h(d)`, centred on the hard-shadow boundary.
//!
//! The outer-only peers (single sample, plateaus) put the whole penumbra
//! outside the hard shadow, `2h(d)` of it across each edge as the fins.
//! The wedges integrate over the rectangle and the convolution maps filter
//! over it, so behind a straight edge theirs is its box filter too.

use shadow_fins::{
    coverage::{CoverageModel, CoverageSettings},
    glam::{Vec2, Vec3},
    ground_truth::GroundTruth,
    light::{Aperture, Light, RectLight},
    oracle::{FinSettings, FinShadowModel, Method},
    peers::{PeerMethod, PeerModel},
    scene::{LightSpaceScene, Scene},
    scenes::SceneId,
};

use super::{common::*, convergence::view_receivers};

/// The outer-only peers, which take a rectangle's shape as the
/// [`LIGHT_SHAPED`] ones do.
const OUTER_ONLY: [PeerMethod; 2] = [PeerMethod::SingleSample, PeerMethod::Plateaus];

/// A `w × h` rectangle light at height 5 facing down, its width along world x.
fn rect(w: f32, h: f32) -> Light {
    Light::Rect(RectLight::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, Vec3::X, w, h).unwrap())
}

/// The half-plane `x < 0` (edge along z: normal along the width) or
/// `z < 0` (edge along x: normal along the height), at height 3.
fn half_plane(edge_along_z: bool) -> Scene {
    let occluder = if edge_along_z { quad(-40.0, 0.0, -20.0, 20.0, 3.0) } else { quad(-20.0, 20.0, -40.0, 0.0, 3.0) };
    Scene::new(vec![ground(), object("half-plane", occluder)])
}

/// Visible fraction of a rectangle of half-extent `half` across the edge at
/// offset `s` from the hard-shadow boundary: a box filter, linear.
fn box_fraction(s: f32, half: f32) -> f32 {
    ((s / half + 1.0) * 0.5).clamp(0.0, 1.0)
}

#[test]
fn rect_lights_reject_bad_sizes_and_a_tangent_along_the_normal() {
    use shadow_fins::LightError;
    let new = |n: Vec3, t: Vec3, w: f32, h: f32| RectLight::new(Vec3::ZERO, n, t, w, h);
    assert!(matches!(new(Vec3::Z, Vec3::X, -1.0, 1.0), Err(LightError::BadRectSize(..))));
    assert!(matches!(new(Vec3::Z, Vec3::X, 1.0, f32::NAN), Err(LightError::BadRectSize(..))));
    assert!(matches!(new(Vec3::Z, Vec3::X, f32::INFINITY, 1.0), Err(LightError::BadRectSize(..))));
    assert!(matches!(new(Vec3::Z, Vec3::Z * 2.0, 1.0, 1.0), Err(LightError::BadDirection(..))));
    assert!(matches!(new(Vec3::Z, Vec3::NAN, 1.0, 1.0), Err(LightError::BadDirection(..))));
    // A tangent not perpendicular to the normal is made so.
    let l = new(Vec3::Z, Vec3::new(1.0, 0.0, 1.0), 2.0, 1.0).unwrap();
    assert!(l.tangent.dot(l.normal).abs() < 1e-6 && (l.tangent.length() - 1.0).abs() < 1e-6);
    assert!(new(Vec3::Z, Vec3::X, 0.0, 0.0).is_ok());
}

#[test]
fn a_rectangle_with_the_area_of_a_disk_keeps_its_area_centre_and_aspect() {
    use shadow_fins::{LightError, light::DiskLight};
    let disk = DiskLight::new(Vec3::new(1.0, 5.0, 2.0), Vec3::NEG_Y, 0.7).unwrap();
    for aspect in [0.25, 1.0, 4.0] {
        let r = RectLight::with_area_of(&disk, aspect).unwrap();
        let (w, h) = (2.0 * r.half_extents.x, 2.0 * r.half_extents.y);
        let area = std::f32::consts::PI * 0.7 * 0.7;
        assert!((w * h - area).abs() < 1e-5 * area && (w / h - aspect).abs() < 1e-5 * aspect, "{w} × {h}");
        assert_eq!((r.center, r.normal, r.tangent), (disk.center, disk.normal, Vec3::X));
    }
    // Facing along x, the width lies along z (x is no tangent then).
    let side = DiskLight::new(Vec3::ZERO, Vec3::X, 1.0).unwrap();
    assert_eq!(RectLight::with_area_of(&side, 2.0).unwrap().tangent, Vec3::Z);
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(matches!(RectLight::with_area_of(&disk, bad), Err(LightError::BadRectSize(..))), "{bad}");
    }
}

#[test]
fn the_ground_truth_of_a_rectangle_behind_a_straight_edge_is_a_box_filter() {
    // Width 2 (a = 1) across the edge along z, height 0.4 (b = 0.2) across
    // the edge along x: the same light gives penumbrae five times apart.
    let light = rect(2.0, 0.4);
    for (edge_along_z, half) in [(true, 1.5 * 1.0), (false, 1.5 * 0.2)] {
        let scene = half_plane(edge_along_z);
        let points: Vec<Vec3> = (-24..=24)
            .map(|i| {
                let s = i as f32 / 20.0 * half;
                if edge_along_z { Vec3::new(s, 0.0, 0.3) } else { Vec3::new(0.3, 0.0, s) }
            })
            .collect();
        let gt = ground_truth(&scene, light, 4096, &points);
        for (p, g) in points.iter().zip(&gt) {
            let s = if edge_along_z { p.x } else { p.z };
            let exact = box_fraction(s, half);
            assert!((g - exact).abs() < 0.01, "edge along z {edge_along_z}, s {s}: truth {g} vs box {exact}");
        }
    }
}

#[test]
fn fins_are_as_wide_as_the_rectangle_across_each_edge() {
    // Where the fins' visibility first reaches 1 (outer edge of the penumbra)
    // and last leaves 0 (inner edge): 1.5·a across the width, 1.5·b across
    // the height, within 2% (the disk's own test's tolerance).
    let light = rect(2.0, 0.4);
    for (edge_along_z, half) in [(true, 1.5f32), (false, 0.3f32)] {
        let scene = half_plane(edge_along_z);
        let at = |s: f32| {
            let p = if edge_along_z { Vec3::new(s, 0.0, 0.3) } else { Vec3::new(0.3, 0.0, s) };
            method_visibility(&scene, light, Method::MultiLayer, linear(), &[p])[0]
        };
        let bisect = |lo: f32, hi: f32, pred: &dyn Fn(f32) -> bool| {
            let (mut a, mut b) = (lo, hi);
            for _ in 0..40 {
                let m = 0.5 * (a + b);
                if pred(at(m)) { b = m } else { a = m }
            }
            b
        };
        let outer = bisect(0.0, 4.0, &|v| v >= 1.0);
        let inner = -bisect(-4.0, 0.0, &|v| v > 0.0);
        for (name, w) in [("outer", outer), ("inner", inner)] {
            assert!(
                (w - half).abs() < 0.02 * half,
                "edge along z {edge_along_z}: {name} half-width {w}, expected {half}"
            );
        }
        assert!((at(0.0) - 0.5).abs() < 1e-3, "V on the hard-shadow boundary {}", at(0.0));
    }
}

#[test]
fn a_diagonal_edge_sees_the_support_function_of_the_rectangle() {
    // Edge along the diagonal x = z under a square 2 × 2 light: the support
    // across it is (|d_x| + |d_y|)·1 = √2 of the half side, so the
    // penumbra is √2 times as wide as under an edge along a side.
    let occluder = shadow_fins::mesh::Mesh::new(
        vec![Vec3::new(-40.0, 3.0, -40.0), Vec3::new(40.0, 3.0, 40.0), Vec3::new(-40.0, 3.0, 40.0)],
        vec![0, 2, 1],
    )
    .unwrap();
    let scene = Scene::new(vec![ground(), object("half-plane", occluder)]);
    let light = rect(2.0, 2.0);
    // Across the edge: along (1, 0, −1)/√2 from the point (0.3, 0, 0.3).
    let across = Vec3::new(1.0, 0.0, -1.0).normalize();
    let at = |s: f32| {
        method_visibility(&scene, light, Method::MultiLayer, linear(), &[Vec3::new(0.3, 0.0, 0.3) + across * s])[0]
    };
    let expected = 1.5 * std::f32::consts::SQRT_2;
    let first_lit = (0..=400).map(|i| i as f32 * 0.01).find(|&s| at(s) >= 1.0).unwrap_or(f32::NAN);
    assert!((first_lit - expected).abs() < 0.03 * expected, "outer half-width {first_lit}, expected {expected}");
    // The truth agrees on where the penumbra ends (it is a tent there, not a box).
    let truth = ground_truth(&scene, light, 4096, &[Vec3::new(0.3, 0.0, 0.3) + across * (expected * 0.9)])[0];
    assert!(truth > 0.98 && truth < 1.0, "truth just inside the penumbra's end {truth}");
}

#[test]
fn zero_size_rectangles_give_exactly_the_hard_shadow() {
    for id in [SceneId::BoxOverPlane, SceneId::StarPrism, SceneId::NearContact] {
        let s = id.build();
        let (center, normal) = s.light.planar().unwrap();
        let light = Light::Rect(RectLight::new(center, normal, Vec3::X, 0.0, 0.0).unwrap());
        let (ls, receivers) = view_receivers(&s.scene, light, &s.camera, 64, 48);
        let hard = FinShadowModel::new(&s.scene, &ls, Method::Hard, FinSettings::default());
        let fins = FinShadowModel::new(&s.scene, &ls, Method::MultiLayer, FinSettings::default());
        let coverage = CoverageModel::new(&s.scene, &ls, CoverageSettings::default());
        let gt = GroundTruth::new(&ls, 64);
        let (h, f) = (hard.analytic(), fins.analytic());
        let mut shadowed = 0;
        for r in &receivers {
            let v = h.visibility(*r);
            shadowed += (v == 0.0) as u32;
            assert_eq!(f.visibility(*r), v, "{id:?}: fins at {:?}", r.position);
            assert_eq!(coverage.visibility(*r), v, "{id:?}: coverage at {:?}", r.position);
            assert_eq!(gt.visibility(*r), v, "{id:?}: truth at {:?}", r.position);
        }
        assert!(shadowed > 20, "{id:?}: the view must hold a shadow ({shadowed} px)");
    }
}

#[test]
fn coverage_of_a_rectangle_light_matches_its_ground_truth_on_built_in_scenes() {
    // 1024 coverage samples against 4096 truth samples: ≤ 0.01 mean.
    for id in [SceneId::BoxOverPlane, SceneId::StarPrism, SceneId::SphereGrid] {
        let s = id.build();
        let (center, normal) = s.light.planar().unwrap();
        let size = match s.light {
            Light::Disk(d) => d.radius * 2.0,
            _ => unreachable!("built-in scenes have disk lights"),
        };
        let light =
            Light::Rect(RectLight::new(center, normal, Vec3::new(1.0, 0.0, 0.4), size * 2.0, size * 0.5).unwrap());
        let (ls, receivers) = view_receivers(&s.scene, light, &s.camera, 48, 36);
        let coverage = CoverageModel::new(&s.scene, &ls, CoverageSettings { samples: 1024, ..Default::default() });
        let gt = GroundTruth::new(&ls, 4096);
        let (c, g): (Vec<f32>, Vec<f32>) =
            receivers.iter().map(|r| (coverage.visibility(*r), gt.visibility(*r))).unzip();
        let penumbra = g.iter().filter(|v| **v > 0.02 && **v < 0.98).count();
        assert!(penumbra > 30, "{id:?}: the view must hold penumbra ({penumbra} px)");
        let mae = mean_abs_diff(&c, &g);
        assert!(mae <= 0.01, "{id:?}: coverage vs truth {mae}");
    }
}

#[test]
fn aperture_samples_are_inside_and_evenly_spread() {
    // Inside the rectangle, mean at its centre, and every quarter holds a
    // quarter of them (±2%): what equal weights need.
    let ap = Aperture::rect(Vec2::new(3.0, 0.5));
    let Aperture::Rect { half_extents } = ap else { unreachable!() };
    assert!((half_extents.length() - 1.0).abs() < 1e-6);
    let samples = ap.samples(4096);
    assert_eq!(samples.len(), 4096);
    let mean = samples.iter().copied().sum::<Vec2>() / 4096.0;
    assert!(mean.length() < 1e-3 * half_extents.length(), "mean {mean}");
    for q in &samples {
        assert!(q.x.abs() <= half_extents.x && q.y.abs() <= half_extents.y, "{q} outside {half_extents}");
    }
    for (sx, sy) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
        let n = samples.iter().filter(|q| q.x * sx > 0.0 && q.y * sy > 0.0).count();
        assert!((n as f32 / 4096.0 - 0.25).abs() < 0.02, "quadrant {sx},{sy}: {n}");
    }
    // The support function is the rectangle's: h(d) = a|dx| + b|dy|.
    let d = Vec2::new(0.6, -0.8);
    let support = samples.iter().map(|q| q.dot(d)).fold(f32::MIN, f32::max);
    assert!(
        support <= ap.support_at(d, Vec2::ZERO) + 1e-6 && support > ap.support_at(d, Vec2::ZERO) * 0.97,
        "{support} vs {}",
        ap.support_at(d, Vec2::ZERO)
    );
    // Degenerate sizes stay finite.
    for h in [Vec2::ZERO, Vec2::new(1.0, 0.0), Vec2::new(f32::NAN, 1.0)] {
        let a = Aperture::rect(h);
        assert!(a.support_at(Vec2::X, Vec2::ZERO).is_finite() && a.samples(16).iter().all(|q| q.is_finite()), "{h}");
    }
}

#[test]
fn outer_only_peers_are_as_wide_as_the_rectangle_across_each_edge() {
    // The whole penumbra outside the hard shadow (both papers' umbra is the
    // centre's hard shadow): from the hard edge to `2·1.5·h(d)`, 3a across
    // the width and 3b across the height, half the light at half the way
    // (Bernstein's `3τ² − 2τ³` at τ = ½). The bounding circle made both 3√(a² + b²).
    let light = rect(2.0, 0.4);
    for (edge_along_z, width) in [(true, 3.0f32), (false, 0.6f32)] {
        let scene = half_plane(edge_along_z);
        let ls = LightSpaceScene::new(&scene, light);
        for method in OUTER_ONLY {
            let model = PeerModel::new(method, &scene, &ls);
            let at = |s: f32| {
                let p = if edge_along_z { Vec3::new(s, 0.0, 0.3) } else { Vec3::new(0.3, 0.0, s) };
                model.visibility(ground_receivers(&ls, &[p])[0])
            };
            let lit = (1..=4000).map(|i| i as f32 * 1e-3 * width).find(|&s| at(s) >= 1.0).unwrap_or(f32::INFINITY);
            assert!(
                (lit - width).abs() <= 0.02 * width,
                "{} edge along z {edge_along_z}: lit from {lit}, expected {width}",
                method.name()
            );
            assert!((at(0.5 * width) - 0.5).abs() < 0.03, "{}: half-way {}", method.name(), at(0.5 * width));
            assert_eq!(at(-0.01 * width), 0.0, "{}: light inside the hard shadow", method.name());
        }
    }
}

/// Total absolute error of `method` over a view against `samples` of ground
/// truth, per pixel of the true shadow (`V < 0.999`): unlike the lab's MAE,
/// whose region is the union of both shadows, a penumbra drawn too wide
/// cannot dilute its own error.
fn error_per_shadowed_pixel(id: SceneId, light: Light, method: PeerMethod, samples: u32) -> f32 {
    let s = id.build();
    let (ls, receivers) = view_receivers(&s.scene, light, &s.camera, 64, 48);
    let receivers: Vec<_> = receivers.into_iter().filter(|r| r.faces_light(&ls.frame)).collect();
    let model = PeerModel::new(method, &s.scene, &ls);
    let gt = GroundTruth::new(&ls, samples);
    let (v, g): (Vec<f32>, Vec<f32>) = receivers.iter().map(|r| (model.visibility(*r), gt.visibility(*r))).unzip();
    let shadowed = g.iter().filter(|g| **g < 0.999).count();
    assert!(shadowed > 50, "{id:?}: the view must hold a shadow ({shadowed} px)");
    v.iter().zip(&g).map(|(v, g)| (v - g).abs()).sum::<f32>() / shadowed as f32
}

#[test]
fn outer_only_peers_err_under_a_rectangle_about_as_under_the_disk_of_its_area() {
    // Outer-only methods err by their whole outer penumbra, whose width
    // across an edge is the light's extent across it. A 4 : 1 rectangle of
    // the disk's area (a = 1.77R, b = 0.44R) spans (a + b)/2 = 1.11R on
    // average over a box's two edge directions, against the disk's R; its
    // bounding circle, 1.83R. So ≈ 1.1× the disk's error, and 1.35× (about
    // halfway, geometrically, to 1.8×) is where the rectangle's shape was lost.
    for id in [SceneId::BoxOverPlane, SceneId::TiltedReceiver, SceneId::StarPrism] {
        let disk = id.build().light;
        let Light::Disk(d) = disk else { unreachable!("built-in scenes have disk lights") };
        let rect = Light::Rect(RectLight::with_area_of(&d, 4.0).unwrap());
        for method in OUTER_ONLY {
            let (e_rect, e_disk) =
                (error_per_shadowed_pixel(id, rect, method, 1024), error_per_shadowed_pixel(id, disk, method, 1024));
            assert!(
                e_rect <= 1.35 * e_disk,
                "{id:?} {}: error {e_rect} under the rectangle, {e_disk} under the disk ({:.2}×)",
                method.name(),
                e_rect / e_disk
            );
        }
    }
}

#[test]
fn outer_only_peers_under_zero_size_or_line_rectangles_stay_hard_or_finite() {
    zero_size_or_line_rectangles_stay_hard_or_finite(&OUTER_ONLY);
}

/// 0 × 0 is exactly each method's hard shadow: what it gives in the same
/// frame as a disk of radius 0 (both take the zero-size shortcut, before
/// any rectangle code). A square a millionth of the scene wide does run the
/// rectangle's code and must give that hard shadow too (the convolution
/// maps: their filtered test before the point lookup's rounding), at all
/// but 1 in 500 receivers. Line lights (one side 0) are the limit of thin
/// rectangles: within 0.02 of a `2 × 2e-4` one at all but 1 in 500. Both
/// are compared by differences, which a NaN fails — the models map a NaN
/// to 0 or drop it in a `min`, so "finite in [0, 1]" alone passed whatever
/// the line light's own code computed. A 1000 × 1 one stays finite in [0, 1].
fn zero_size_or_line_rectangles_stay_hard_or_finite(methods: &[PeerMethod]) {
    for id in [SceneId::BoxOverPlane, SceneId::TiltedReceiver, SceneId::NearContact] {
        let s = id.build();
        let (center, normal) = s.light.planar().unwrap();
        let with = |w: f32, h: f32| Light::Rect(RectLight::new(center, normal, Vec3::X, w, h).unwrap());
        let (ls, receivers) = view_receivers(&s.scene, with(0.0, 0.0), &s.camera, 48, 36);
        let mut ls_disk = LightSpaceScene::new(&s.scene, with(0.0, 0.0));
        ls_disk.frame.aperture = Aperture::Disk;
        let (lo, hi) = s.scene.bounds().unwrap();
        let tiny = 1e-6 * (hi - lo).length();
        let ls_tiny = LightSpaceScene::new(&s.scene, with(tiny, tiny));
        let allowed = receivers.len() / 500;
        for method in methods.iter().copied() {
            let (zero, point) = (PeerModel::new(method, &s.scene, &ls), PeerModel::new(method, &s.scene, &ls_disk));
            let small = PeerModel::new(method, &s.scene, &ls_tiny);
            let filtered = matches!(method, PeerMethod::Convolution | PeerMethod::ConvolutionMipmap);
            let (mut shadowed, mut off_hard) = (0, 0);
            for r in &receivers {
                let v = zero.visibility(*r);
                shadowed += (v == 0.0) as u32;
                assert!(v == 0.0 || v == 1.0, "{id:?} {}: 0 × 0 gives {v} at {:?}", method.name(), r.position);
                assert_eq!(v, point.visibility(*r), "{id:?} {}: 0 × 0 at {:?}", method.name(), r.position);
                let t = small.unclamped_visibility(*r);
                // The point lookup's rounding, NaN kept.
                let t = if filtered && !t.is_nan() { (t >= 0.5) as u32 as f32 } else { t };
                off_hard += !((t - v).abs() <= 1e-3) as usize;
            }
            assert!(shadowed > 20, "{id:?}: the view must hold a shadow ({shadowed} px)");
            assert!(
                off_hard <= allowed,
                "{id:?} {}: {off_hard} of {} receivers under the {tiny} square are off the hard shadow",
                method.name(),
                receivers.len()
            );
            for ((w, h), thin) in [((2.0, 0.0), (2.0, 2e-4)), ((0.0, 2.0), (2e-4, 2.0))] {
                let line = PeerModel::new(method, &s.scene, &LightSpaceScene::new(&s.scene, with(w, h)));
                let thin = PeerModel::new(method, &s.scene, &LightSpaceScene::new(&s.scene, with(thin.0, thin.1)));
                let (mut apart, mut soft) = (0, 0);
                for r in &receivers {
                    let (v, t) = (line.unclamped_visibility(*r), thin.unclamped_visibility(*r));
                    apart += !((v - t).abs() <= 0.02) as usize;
                    soft += (v > 0.0 && v < 1.0) as usize;
                }
                assert!(
                    apart <= allowed,
                    "{id:?} {} {w} × {h}: {apart} of {} receivers off the thin rectangle's",
                    method.name(),
                    receivers.len()
                );
                assert!(soft > 5, "{id:?} {} {w} × {h}: no penumbra ({soft} px)", method.name());
            }
            let ls = LightSpaceScene::new(&s.scene, with(1e3, 1.0));
            let model = PeerModel::new(method, &s.scene, &ls);
            for r in &receivers {
                let v = model.unclamped_visibility(*r);
                assert!((0.0..=1.0).contains(&v), "{id:?} {} 1000 × 1: {v}", method.name());
            }
        }
    }
}

/// The peers that integrate or filter over the light (Forest et al.'s
/// wedges, Annen et al.'s convolution maps), which take a rectangle's shape.
const LIGHT_SHAPED: [PeerMethod; 4] =
    [PeerMethod::PenumbraWedges, PeerMethod::WedgeBlending, PeerMethod::Convolution, PeerMethod::ConvolutionMipmap];

#[test]
fn penumbra_wedges_behind_a_straight_edge_are_the_rectangles_box_filter() {
    // One edge, one convex silhouette: the wedges' integral over the
    // rectangle is exact (their Figure 4), a linear ramp `1.5·a` or `1.5·b`
    // either side of the hard edge; the bounding circle made both `1.5·√(a² + b²)`.
    let light = rect(2.0, 0.4);
    for (edge_along_z, half) in [(true, 1.5f32), (false, 0.3f32)] {
        let scene = half_plane(edge_along_z);
        let ls = LightSpaceScene::new(&scene, light);
        for method in [PeerMethod::PenumbraWedges, PeerMethod::WedgeBlending] {
            let model = PeerModel::new(method, &scene, &ls);
            // Off the hard edge itself, where the centre's ray grazes it.
            for i in -24..24 {
                let s = (i as f32 + 0.5) / 20.0 * half;
                let p = if edge_along_z { Vec3::new(s, 0.0, 0.3) } else { Vec3::new(0.3, 0.0, s) };
                let v = model.visibility(ground_receivers(&ls, &[p])[0]);
                let exact = box_fraction(s, half);
                assert!(
                    (v - exact).abs() < 0.01,
                    "{} edge along z {edge_along_z}, s {s}: {v} vs {exact}",
                    method.name()
                );
            }
        }
    }
}

#[test]
fn convolution_penumbrae_follow_the_rectangles_sides() {
    // The filter box is the rectangle seen through the receiver: the ramp
    // across the edge along z (normal along the width, a = 1) is five times
    // the one across the edge along x (b = 0.2). Measured 10%–90%, which
    // the ringing scale α and the texels change alike for both; the square
    // of the bounding circle made the ratio 1.
    let light = rect(2.0, 0.4);
    let mut widths = vec![];
    for edge_along_z in [true, false] {
        let scene = half_plane(edge_along_z);
        let ls = LightSpaceScene::new(&scene, light);
        let model = PeerModel::new(PeerMethod::Convolution, &scene, &ls);
        let at = |s: f32| {
            let p = if edge_along_z { Vec3::new(s, 0.0, 0.3) } else { Vec3::new(0.3, 0.0, s) };
            model.visibility(ground_receivers(&ls, &[p])[0])
        };
        let s: Vec<f32> = (-3000..=3000).map(|i| i as f32 * 1e-3).collect();
        let first = |t: f32| s.iter().copied().find(|&x| at(x) >= t).unwrap_or(f32::NAN);
        widths.push(first(0.9) - first(0.1));
    }
    let ratio = widths[0] / widths[1];
    assert!((3.5..=7.0).contains(&ratio), "10–90% widths {widths:?}: ratio {ratio}, the rectangle's 5");
}

#[test]
fn light_shaped_peers_err_under_a_rectangle_about_as_under_its_disk() {
    // Both methods integrate or filter over the light, so a rectangle taken
    // as its own shape errs as a disk of its size does; taken as its
    // bounding circle (√(a² + b²)) it blurred every edge to the diagonal's
    // width and erred 2.3–3.9× (convolution) and 19–26× (wedges) the
    // same-area disk's. Measured now: the square of the disk's area errs
    // 0.9–1.1× the disk (both methods); a 4 : 1 rectangle under convolution
    // 1.1–1.4× (the box filter is exact across either side, but CSM's one
    // blocker depth per kernel errs more over the long side, 1.77R, than
    // over the disk's R), and under the wedges 0.85–1.05× the disk whose
    // radius is the long half side a: their silhouette seen from the centre
    // (their assumption) is off by as much as the light's longest extent.
    let tol = 1.25;
    for id in [SceneId::BoxOverPlane, SceneId::TiltedReceiver, SceneId::StarPrism] {
        let disk = id.build().light;
        let Light::Disk(d) = disk else { unreachable!("built-in scenes have disk lights") };
        let (square, long) = (RectLight::with_area_of(&d, 1.0).unwrap(), RectLight::with_area_of(&d, 4.0).unwrap());
        let as_long = Light::Disk(shadow_fins::light::DiskLight { radius: long.half_extents.x, ..d });
        for method in [PeerMethod::WedgeBlending, PeerMethod::Convolution] {
            let e = |light: Light| error_per_shadowed_pixel(id, light, method, 1024);
            let (e_disk, e_square, e_long) = (e(disk), e(Light::Rect(square)), e(Light::Rect(long)));
            assert!(
                e_square <= tol * e_disk,
                "{id:?} {}: error {e_square} under the square, {e_disk} under the disk ({:.2}×)",
                method.name(),
                e_square / e_disk
            );
            let (reference, name, factor) = match method {
                PeerMethod::Convolution => (e_disk, "the disk", 1.6),
                _ => (e(as_long), "the disk of radius a", tol),
            };
            assert!(
                e_long <= factor * reference,
                "{id:?} {}: error {e_long} under the 4 : 1 rectangle, {reference} under {name} ({:.2}×)",
                method.name(),
                e_long / reference
            );
        }
    }
}

#[test]
fn light_shaped_peers_under_zero_size_or_line_rectangles_stay_hard_or_finite() {
    zero_size_or_line_rectangles_stay_hard_or_finite(&LIGHT_SHAPED);
}

#[test]
fn peers_under_a_line_light_soften_an_edge_only_across_its_length() {
    // A 2 × 0 light (and 0 × 2): across the edge its length crosses, each
    // peer's penumbra is the 2 × 0.4 rectangle's (whose sides the tests
    // above pin: `2h(d)` wide for the outer-only ones, the box filter for
    // the wedges, the box for the summed-area maps); across the edge along
    // it, the hard shadow's step. Compared as differences, which a NaN the
    // models turned into 0 or 1 would fail as well as a NaN itself. Mipmaps
    // choose their level by the light's area, so only their step is checked.
    for (w, h) in [(2.0f32, 0.0f32), (0.0, 2.0)] {
        let (line, rectangle) = (rect(w, h), rect(w.max(0.4), h.max(0.4)));
        for (edge_along_z, soft) in [(true, w > 0.0), (false, h > 0.0)] {
            let scene = half_plane(edge_along_z);
            let at_edge = |s: f32| if edge_along_z { Vec3::new(s, 0.0, 0.3) } else { Vec3::new(0.3, 0.0, s) };
            let (ls, ls_rect) = (LightSpaceScene::new(&scene, line), LightSpaceScene::new(&scene, rectangle));
            for method in OUTER_ONLY.into_iter().chain(LIGHT_SHAPED) {
                let model = PeerModel::new(method, &scene, &ls);
                let at = |s: f32| model.unclamped_visibility(ground_receivers(&ls, &[at_edge(s)])[0]);
                let name = format!("{} {w} × {h}, edge along z {edge_along_z}", method.name());
                if soft {
                    if method == PeerMethod::ConvolutionMipmap {
                        // Its level from the light's area (a sliver) blurs
                        // it by less: a ramp about 1 wide (the box's is 3).
                        assert!(at(-1.6) == 0.0 && at(1.6) == 1.0, "{name}: {} and {} off the ramp", at(-1.6), at(1.6));
                        assert!((at(0.0) - 0.5).abs() < 0.1, "{name}: {} at the hard edge", at(0.0));
                        continue;
                    }
                    let reference = PeerModel::new(method, &scene, &ls_rect);
                    for i in -40..=80 {
                        let s = (i as f32 + 0.5) * 0.05;
                        let (v, r) = (at(s), reference.visibility(ground_receivers(&ls_rect, &[at_edge(s)])[0]));
                        assert!((v - r).abs() <= 0.01, "{name}, s {s}: {v}, the 2 × 0.4 rectangle's {r}");
                    }
                } else {
                    // A hard step: exact for the ray-traced and wedge peers,
                    // within two texels (0.16 each) for the maps.
                    let d = if LIGHT_SHAPED[2..].contains(&method) { 0.35 } else { 0.01 };
                    assert!(at(-d) == 0.0 && at(d) == 1.0, "{name}: {} and {} either side", at(-d), at(d));
                }
            }
        }
    }
}

#[test]
fn peers_behind_a_straight_edge_keep_the_rectangles_shape_at_a_millionth_of_its_size() {
    // The 2 × 0.4 light scaled by 1e-6: the rectangle's own code at the
    // degenerate limit (a 0 × 0 light never reaches it). The outer-only
    // peers' penumbra is then the disk's of the same support across the
    // edge (radius a across the width, b across the height), `2h(d)` wide;
    // the wedges' is the rectangle's box filter. Both within 0.01, as at
    // full size. The wedges at 1e-5: at 1e-6 the edge index they share
    // with the coverage method (`EdgeIndex::may_reach`, an f32 distance
    // from the receiver to an edge 10 map units long, ulps of 1e-6 against
    // a reach of 3e-7) drops the edge for the outer tenth of the penumbra.
    // (The maps' texels cannot hold it: their hard step is in the built-in
    // scenes' millionth square above.)
    for (scale, methods) in [(1e-6f32, &OUTER_ONLY[..]), (1e-5, &LIGHT_SHAPED[..2])] {
        let light = rect(2.0 * scale, 0.4 * scale);
        for (edge_along_z, half) in [(true, 1.0 * scale), (false, 0.2 * scale)] {
            let scene = half_plane(edge_along_z);
            let at_edge = |s: f32| if edge_along_z { Vec3::new(s, 0.0, 0.3) } else { Vec3::new(0.3, 0.0, s) };
            let ls = LightSpaceScene::new(&scene, light);
            let disk = LightSpaceScene::new(&scene, down_light(Vec3::new(0.0, 5.0, 0.0), half));
            for method in methods.iter().copied() {
                let model = PeerModel::new(method, &scene, &ls);
                let same_support = PeerModel::new(method, &scene, &disk);
                let mut soft = 0;
                for i in -40..=80 {
                    let s = (i as f32 + 0.5) / 20.0 * 1.5 * half;
                    let v = model.unclamped_visibility(ground_receivers(&ls, &[at_edge(s)])[0]);
                    let expected = if OUTER_ONLY.contains(&method) {
                        same_support.visibility(ground_receivers(&disk, &[at_edge(s)])[0])
                    } else {
                        box_fraction(s, 1.5 * half)
                    };
                    soft += (v > 0.05 && v < 0.95) as u32;
                    assert!(
                        (v - expected).abs() <= 0.01,
                        "{} at {scale}, edge along z {edge_along_z}, s {s}: {v}, expected {expected}",
                        method.name()
                    );
                }
                assert!(soft > 10, "{} at {scale}: {soft} points in the penumbra", method.name());
            }
        }
    }
}
