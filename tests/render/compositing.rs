//! The final image: the fin light composited with Bevy's own lighting.
//!
//! Tolerances. The camera writes 8-bit sRGB; one step is at most 0.0088 in
//! linear units (at white), less below. Comparisons are made in linear units
//! with a bound of 2 steps (0.02) per pixel for what must be equal, or on the
//! mean where geometry edges can flip a pixel.

use shadow_fins::{oracle::Method, scenes::SceneId};
use shadow_fins_app::harness::Session;

use super::common::*;

fn max_channel_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter().zip(b).flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs())).fold(0.0, f32::max)
}

fn unshadowed_box_over_plane() -> shadow_fins_app::harness::Setup {
    let mut s = setup(SceneId::BoxOverPlane, settings());
    for o in &mut s.scene.objects {
        o.casts_shadows = false;
    }
    // Dim enough that nothing clips at white (clipped pixels compare equal trivially).
    s.intensity = 1.5e5;
    s
}

#[test]
fn unshadowed_fin_light_shades_like_the_equivalent_bevy_point_light() {
    let fin = unshadowed_box_over_plane();
    let mut point = fin.clone();
    point.bevy_point_light = true;
    let (fin, point) = (render(&fin), render(&point));
    save(&fin, "compositing_fin_unshadowed");
    save(&point, "compositing_point_light");
    assert!(fin.visibility.iter().all(|v| *v == 1.0));
    let (a, b) = (linear_rgb(&fin), linear_rgb(&point));
    // The light must actually light something: the lit floor is far brighter
    // than the unlit background, so the comparison is not between two blacks.
    let bright = b.iter().filter(|p| p[1] > 0.2 && p[1] < 0.95).count();
    assert!(bright > 1000, "the point light lights only {bright} pixels");
    let worst = max_channel_difference(&a, &b);
    println!("fin vs point light: worst linear difference {worst:.4}");
    assert!(worst <= 0.02, "fin light differs from Bevy's point light by {worst}");
}

#[test]
fn the_final_image_is_ambient_plus_visibility_times_the_direct_light() {
    // Tonemapping off: the output is linear in the light, so per pixel
    // shadowed = ambient + V × (lit − ambient), where `lit` is the same light
    // without shadows and `ambient` the scene with the light at zero power.
    let mut shadowed = setup(SceneId::BoxOverPlane, settings());
    // Dim enough that the floor under the light does not clip at white.
    shadowed.intensity = 1.5e5;
    let mut lit = unshadowed_box_over_plane();
    lit.bevy_point_light = true;
    lit.intensity = shadowed.intensity;
    let mut dark = shadowed.clone();
    dark.intensity = 0.0;
    let (s, l, d) = (render(&shadowed), render(&lit), render(&dark));
    assert_not_trivial(&s);
    let (sc, lc, dc) = (linear_rgb(&s), linear_rgb(&l), linear_rgb(&d));
    // Over the penumbrae on surfaces the light reaches, where V is strictly
    // between 0 and 1 (umbra and lit pixels would make the check easy).
    let errors: Vec<f32> = (0..sc.len())
        .filter(|&i| (0.05..0.95).contains(&s.visibility[i]) && lc[i][1] - dc[i][1] > 0.05)
        .filter(|&i| lc[i].iter().all(|c| *c < 0.95))
        .map(|i| {
            let expected = dc[i][1] + s.visibility[i] * (lc[i][1] - dc[i][1]);
            (sc[i][1] - expected).abs()
        })
        .collect();
    assert!(errors.len() > 100, "only {} penumbra pixels", errors.len());
    let n = errors.len();
    let (mean, p99) = mean_and_p99(errors);
    println!("composite vs ambient + V·direct: mean {mean:.4}, p99 {p99:.4} over {n} penumbra pixels");
    // 8-bit sRGB steps: ≤ 0.0088 linear each, three images.
    assert!(mean <= 0.005 && p99 <= 0.02, "mean {mean}, p99 {p99}");
    // And shadows are visible in the image, not only in the buffer.
    let umbra: Vec<usize> = (0..sc.len()).filter(|&i| s.visibility[i] < 0.02 && lc[i][1] > 0.2).collect();
    assert!(umbra.len() > 50, "no umbra on lit surfaces");
    assert!(umbra.iter().all(|&i| sc[i][1] < lc[i][1] * 0.5), "umbra pixels are not darker than lit ones");
}

#[test]
fn hdr_on_and_off_give_the_same_image() {
    let off = setup(SceneId::RingPlate, settings());
    let mut on = off.clone();
    on.hdr = true;
    let (off, on) = (render(&off), render(&on));
    assert_not_trivial(&on);
    assert_eq!(off.visibility, on.visibility);
    let (a, b) = (linear_rgb(&off), linear_rgb(&on));
    let mean = a.iter().zip(&b).map(|(p, q)| (p[1] - q[1]).abs()).sum::<f32>() / a.len() as f32;
    let worst = max_channel_difference(&a, &b);
    println!("HDR on vs off: mean {mean:.4}, worst {worst:.4}");
    // Only quantisation and deband dithering differ (HDR dithers after a
    // 16-bit float target, non-HDR inside the lighting shader).
    assert!(mean <= 0.005 && worst <= 0.03, "mean {mean}, worst {worst}");
}

#[test]
fn two_cameras_each_get_their_own_shadows() {
    let mut s = setup(SceneId::BoxOverPlane, settings());
    let mut side = s.camera;
    side.position = shadow_fins::glam::Vec3::new(-s.camera.position.x - 2.0, s.camera.position.y, s.camera.position.z);
    s.extra_cameras = vec![side];
    let shot = render(&s);
    for (name, visibility, camera) in
        [("first", &shot.visibility, &s.camera), ("second", &shot.extra_views[0].visibility, &side)]
    {
        assert_visibility_not_trivial(visibility);
        let (mad, far) = compare(visibility, &oracle_for(&s, camera, Method::MultiLayer));
        println!("{name} camera: mean |gpu − oracle| {mad:.5}, > 0.1: {:.2}%", far * 100.0);
        assert!(mad <= 0.01 && far <= 0.03, "{name} camera: {mad} / {far}");
    }
    assert_ne!(shot.visibility, shot.extra_views[0].visibility, "the cameras see the scene from different places");
}

#[test]
fn a_mesh_that_does_not_receive_is_lit_as_if_unshadowed() {
    let mut s = setup(SceneId::BoxOverPlane, settings());
    // The ground receives nothing; the box still casts onto it in the buffer.
    for o in &mut s.scene.objects {
        o.receives_shadows = o.name != "ground";
    }
    let mut unshadowed = unshadowed_box_over_plane();
    s.intensity = unshadowed.intensity;
    unshadowed.scene = s.scene.clone();
    for o in &mut unshadowed.scene.objects {
        o.casts_shadows = false;
    }
    let (shot, reference) = (render(&s), render(&unshadowed));
    assert_not_trivial(&shot);
    let worst = max_channel_difference(&linear_rgb(&shot), &linear_rgb(&reference));
    assert!(worst <= 0.02, "a non-receiving ground shows a shadow: {worst}");
}

#[test]
fn pass_times_are_recorded_as_render_diagnostics() {
    const PASSES: [&str; 4] = ["extraction", "penumbra_maps", "visibility", "composite"];
    let mut session = Session::new(&setup(SceneId::BoxOverPlane, settings()));
    session.settle(6).expect("headless render");
    // The maps are drawn once and then reused, and a pass's GPU time comes
    // back a few frames after it ran: on a busy machine the one frame that
    // drew them can be that recent. A few more frames, never a redraw.
    let missing = |times: &[(String, f64)]| {
        PASSES
            .into_iter()
            .find(|pass| !times.iter().any(|(n, _)| n.starts_with(&format!("render/fin_shadows/{pass}/"))))
    };
    let mut times = shadow_fins_app::harness::pass_times(session.app.world());
    for _ in 0..30 {
        if missing(&times).is_none() {
            break;
        }
        session.update();
        times = shadow_fins_app::harness::pass_times(session.app.world());
    }
    println!("{times:?}");
    // The maps' passes run in the root render graph, outside any camera's.
    assert_eq!(missing(&times), None, "a pass without a diagnostic in {times:?}");
    assert!(times.iter().all(|(_, ms)| ms.is_finite() && *ms >= 0.0));
}
