//! Fitting a sun's orthographic maps to what the fin-shadowed cameras see.
//!
//! A disk's perspective maps cover the casters it sees; a sun sees the whole
//! scene, and a scene's ground is usually far wider than the part a camera
//! looks at: maps over all of it spend their texels where nobody looks. Under
//! an orthographic projection a receiver at map point `q` is shadowed only by
//! casters whose footprint (with their penumbra) covers `q`, so the maps need
//! only cover the map footprint of what the cameras see: the union of their
//! view frusta, each cut at the far side of the scene's box, projected along
//! the sun. Casters outside the window still rasterise where they reach into
//! it. Each frustum is first cut to the scene's box (the vertices of the
//! intersection of two convex solids), since a camera looking at the ground
//! sees to the horizon through a frustum that is mostly empty air.
//!
//! The window is quantised (sizes in steps of 2^¼, centres on a grid of a
//! sixteenth of the size) so that a camera moving a little keeps the same
//! maps: no re-extraction every frame. (A step moves the texel grid by a
//! fraction of a texel, so hard-edged penumbrae may shift once per step.)
//! It is computed in the sun's axes, `(p · u, p · v)`, which depend only on
//! its direction, so it can be compared between frames before the scene is
//! collected; [`window_in_frame`] moves it into a frame's map coordinates.

use crate::casters::reach::box_corners as corners;
use bevy::{math::DVec3, prelude::*};
use shadow_fins::light::{LightFrame, SunLight};

/// What every camera sees of `scene_box`: the corners of its view frustum
/// cut to the box (the far plane first pulled in to the farthest corner of
/// the box along the camera's view); `None` when
/// some camera cannot be bounded (a custom projection, non-finite values): then
/// the maps cover the whole scene. A camera that sees nothing of the box adds
/// nothing.
pub(crate) fn view_volumes<'a>(
    views: impl Iterator<Item = (&'a GlobalTransform, &'a Projection)>,
    scene_box: (Vec3, Vec3),
) -> Option<Vec<Vec<Vec3>>> {
    let box_corners = corners(scene_box);
    let mut volumes = Vec::new();
    for (transform, projection) in views {
        let near = match projection {
            Projection::Perspective(p) => p.near,
            Projection::Orthographic(o) => o.near,
            Projection::Custom(_) => return None,
        };
        // Not `GlobalTransform::forward`: it panics (debug) on a zero scale.
        let forward = (transform.affine().matrix3 * bevy::math::Vec3A::NEG_Z).normalize_or_zero();
        let position = transform.translation();
        if !(forward.is_finite() && forward != bevy::math::Vec3A::ZERO) {
            return None;
        }
        let forward = Vec3::from(forward);
        let deepest = box_corners.iter().map(|c| (*c - position).dot(forward)).fold(f32::NEG_INFINITY, f32::max);
        let far = projection.far().min(deepest);
        if !(near.is_finite() && far.is_finite() && position.is_finite()) {
            return None;
        }
        if far <= near {
            continue;
        }
        let view = projection.get_frustum_corners(-near, -far);
        let world = view.map(|c| transform.transform_point(Vec3::from(c)));
        if !world.iter().all(|c| c.is_finite()) {
            return None;
        }
        volumes.push(clipped_to_box(&world, scene_box));
    }
    Some(volumes)
}

/// The eight corners' faces, in Bevy's order (near BR, TR, TL, BL, then far).
const FRUSTUM_FACES: [[usize; 4]; 6] =
    [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]];
const FRUSTUM_EDGES: [[usize; 2]; 12] =
    [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]];

/// Planes `(n, d)` of a convex hexahedron, `n · p ≤ d` inside. In f64: a
/// window's prism is 20 wide and 2e6 long over a wide ground, and the cross
/// product of its faces' two long, nearly parallel diagonals lost the side
/// planes' direction in f32 (a plane 1e4 off at the far end).
fn planes(corners: &[DVec3; 8]) -> Vec<(DVec3, f64)> {
    let centre = corners.iter().copied().sum::<DVec3>() / 8.0;
    FRUSTUM_FACES
        .iter()
        .filter_map(|f| {
            let (a, b, c, d) = (corners[f[0]], corners[f[1]], corners[f[2]], corners[f[3]]);
            // The diagonals' cross product: well defined even when one edge
            // has no length (a near plane shrunk to a point).
            let n = (c - a).cross(d - b).try_normalize()?;
            let n = if n.dot(centre - a) > 0.0 { -n } else { n };
            Some((n, n.dot(a)))
        })
        .collect()
}

/// The vertices of `frustum ∩ box` (a superset: every point where an edge
/// of one solid crosses a face plane of the other, or a corner of one lies
/// in the other, kept when inside both). Empty when they do not meet.
fn clipped_to_box(frustum: &[Vec3; 8], scene_box: (Vec3, Vec3)) -> Vec<Vec3> {
    let frustum = frustum.map(|p| p.as_dvec3());
    let boxed = hexahedron(scene_box).map(|p| p.as_dvec3());
    let (fp, bp) = (planes(&frustum), planes(&boxed));
    // The corners' own f32 rounding, with room.
    let magnitude = frustum.iter().chain(&boxed).map(|p| p.abs().max_element()).fold(1.0, f64::max);
    let tolerance = 1e-6 * magnitude;
    let inside = |p: DVec3| fp.iter().chain(&bp).all(|(n, d)| n.dot(p) <= d + tolerance);
    let mut points: Vec<DVec3> = frustum.iter().chain(&boxed).copied().filter(|p| inside(*p)).collect();
    let mut cross = |solid: &[DVec3; 8], other: &[(DVec3, f64)]| {
        for [i, j] in FRUSTUM_EDGES {
            let (a, b) = (solid[i], solid[j]);
            for (n, d) in other {
                let (da, db) = (n.dot(a) - d, n.dot(b) - d);
                if (da < 0.0) != (db < 0.0) {
                    let p = a + (b - a) * (da / (da - db));
                    if inside(p) {
                        points.push(p);
                    }
                }
            }
        }
    };
    cross(&frustum, &bp);
    cross(&boxed, &fp);
    points.into_iter().map(|p| p.as_vec3()).collect()
}

/// The map window of `sun` over `volumes`, in the sun's axes
/// `[min u, min v, max u, max v]`, cut to the scene box's own footprint and
/// quantised; `None` when no camera sees the scene.
///
/// Hysteresis: the `previous` window stays while it still covers what the
/// cameras see and is at most two size steps (2^½) wider than a new one
/// would be; a camera bobbing across a step boundary keeps its maps.
pub(crate) fn sun_window(
    volumes: &[Vec<Vec3>],
    scene_box: (Vec3, Vec3),
    sun: &SunLight,
    previous: Option<[f32; 4]>,
) -> Option<[f32; 4]> {
    let [u, v, _] = LightFrame::sun(sun, Vec3::ZERO, Vec3::ONE).axes();
    let footprint = |points: &mut dyn Iterator<Item = Vec3>| {
        points.fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), p| {
            let q = Vec2::new(p.dot(u), p.dot(v));
            (lo.min(q), hi.max(q))
        })
    };
    let (view_lo, view_hi) = footprint(&mut volumes.iter().flatten().copied());
    let (box_lo, box_hi) = footprint(&mut corners(scene_box).into_iter());
    let (lo, hi) = (view_lo.max(box_lo), view_hi.min(box_hi));
    if !(lo.x <= hi.x && lo.y <= hi.y) {
        return None;
    }
    let (x0, x1) = quantised(lo.x, hi.x);
    let (y0, y1) = quantised(lo.y, hi.y);
    let fresh = [x0, y0, x1, y1];
    let keep = previous.filter(|p| {
        let covers = p[0] <= lo.x && p[1] <= lo.y && p[2] >= hi.x && p[3] >= hi.y;
        let side = |w: &[f32; 4]| (w[2] - w[0]).max(w[3] - w[1]);
        covers && side(p) <= side(&fresh) * std::f32::consts::SQRT_2 * 1.001
    });
    Some(keep.unwrap_or(fresh))
}

/// `[lo, hi]` widened to a size of a power of 2^¼ and a centre on a grid of
/// a sixteenth of that size, still covering `[lo, hi]`.
fn quantised(lo: f32, hi: f32) -> (f32, f32) {
    let size = (hi - lo).max(1e-6 * lo.abs().max(hi.abs()).max(1e-30));
    let step_size = 2f32.powf((4.0 * (size * 1.02).log2()).ceil() / 4.0);
    let grid = step_size / 16.0;
    let centre = ((lo + hi) * 0.5 / grid).round() * grid;
    // The centre moved by at most half a grid step: widen by that.
    let half = step_size * 0.5 + grid * 0.5;
    (centre - half, centre + half)
}

/// The sun's frame for a window from [`sun_window`], and its reference depth
/// `L0`: the origin at the window's centre, just in front of where the
/// window's prism (the window extruded along the sun) meets the scene's box,
/// `L0` at that solid's deepest point. Frame coordinates are then as small as
/// what the cameras see, not as the whole scene: on a ground 2e6 wide the
/// scene-wide origin put visible points 1.4e6 away (f32 depths 0.125 apart,
/// a receiver lift of 14). Every receiver in the window lies within the
/// solid, so none is beyond `L0` or in front of the origin; casters outside
/// the prism may be (negative depths), and only reach texels outside the
/// window. `None` when the prism misses the box.
pub(crate) fn window_frame(window: [f32; 4], scene_box: (Vec3, Vec3), sun: &SunLight) -> Option<(LightFrame, f32)> {
    let [u, v, n] = LightFrame::sun(sun, Vec3::ZERO, Vec3::ONE).axes_f64();
    let box_depths = corners(scene_box).map(|c| c.as_dvec3().dot(n));
    let (zlo, zhi) = box_depths.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), z| (a.min(*z), b.max(*z)));
    let at = |x: f32, y: f32, z: f64| (u * x as f64 + v * y as f64 + n * z).as_vec3();
    let [x0, y0, x1, y1] = window;
    let prism = [
        at(x1, y0, zlo),
        at(x1, y1, zlo),
        at(x0, y1, zlo),
        at(x0, y0, zlo),
        at(x1, y0, zhi),
        at(x1, y1, zhi),
        at(x0, y1, zhi),
        at(x0, y0, zhi),
    ];
    let inside = clipped_to_box(&prism, scene_box);
    let depths = inside.iter().map(|p| p.as_dvec3().dot(n));
    let (near, far) = depths.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), z| (a.min(z), b.max(z)));
    if !(near <= far) {
        return None;
    }
    // A margin on both sides, at least a receiver's lift off its surface
    // (a texel — a hundredth of the window covers maps of ≥ 100 texels — plus
    // the surface epsilon, whose floor is 1e-7 of the scene) and the f32
    // rounding of the solid's points.
    let side = ((x1 - x0).max(y1 - y0)) as f64;
    let diagonal = (scene_box.1 - scene_box.0).length() as f64;
    let margin = 1e-3 * (far - near) + 1e-2 * side + 1e-6 * diagonal + 1e-6 * near.abs().max(far.abs()).max(1.0);
    let centre = (x0 as f64 + x1 as f64) * 0.5 * u + (y0 as f64 + y1 as f64) * 0.5 * v;
    let frame = LightFrame::sun_at(sun, centre + n * (near - margin));
    Some((frame, (far - near + 2.0 * margin) as f32))
}

/// A window from [`sun_window`] in `frame`'s map coordinates (the sun's
/// frame's `x, y` are the axes' minus its origin's, in f64).
pub(crate) fn window_in_frame(window: [f32; 4], frame: &LightFrame) -> (Vec2, Vec2) {
    let [u, v, _] = frame.axes_f64();
    let origin = frame.origin();
    let offset = |axis: DVec3| origin.dot(axis);
    let (ou, ov) = (offset(u), offset(v));
    let at = |a: f32, o: f64| (a as f64 - o) as f32;
    (Vec2::new(at(window[0], ou), at(window[1], ov)), Vec2::new(at(window[2], ou), at(window[3], ov)))
}

/// A box's corners in the frusta's cyclic order (`FRUSTUM_FACES`): its
/// `z = min` face, then its `z = max` face, each turning the same way. (In
/// [`corners`]' bit order two "faces" were bow-ties and two were diagonal
/// planes through the centre: the clip kept a wedge of the box.)
fn hexahedron((a, b): (Vec3, Vec3)) -> [Vec3; 8] {
    let face =
        |z: f32| [Vec3::new(b.x, a.y, z), Vec3::new(b.x, b.y, z), Vec3::new(a.x, b.y, z), Vec3::new(a.x, a.y, z)];
    let (near, far) = (face(a.z), face(b.z));
    [near[0], near[1], near[2], near[3], far[0], far[1], far[2], far[3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(at: Vec3, target: Vec3) -> (GlobalTransform, Projection) {
        let transform = GlobalTransform::from(Transform::from_translation(at).looking_at(target, Vec3::Y));
        (transform, Projection::Perspective(PerspectiveProjection { near: 0.1, far: 1000.0, ..default() }))
    }

    #[test]
    fn a_camera_looking_at_a_corner_of_a_wide_ground_gets_a_window_over_that_corner_only() {
        // A 200 × 200 ground, the sun straight down; a camera 3 above the
        // ground looking down at (80, 0, 80) sees a few units of it.
        let scene = (Vec3::new(-100.0, 0.0, -100.0), Vec3::new(100.0, 2.0, 100.0));
        let sun = SunLight::new(Vec3::NEG_Y, 0.01).unwrap();
        let (t, p) = camera(Vec3::new(80.0, 3.0, 83.0), Vec3::new(80.0, 0.0, 80.0));
        let volumes = view_volumes(std::iter::once((&t, &p)), scene).unwrap();
        let w = sun_window(&volumes, scene, &sun, None).unwrap();
        let (width, height) = (w[2] - w[0], w[3] - w[1]);
        assert!(width < 20.0 && height < 20.0, "window {w:?} is not fitted to the view");
        // It covers what the camera sees: the point it looks at, in the sun's axes.
        let [u, v, _] = LightFrame::sun(&sun, Vec3::ZERO, Vec3::ONE).axes();
        let target = Vec3::new(80.0, 0.0, 80.0);
        let q = Vec2::new(target.dot(u), target.dot(v));
        assert!(q.x > w[0] && q.x < w[2] && q.y > w[1] && q.y < w[3], "{q} outside {w:?}");
    }

    #[test]
    fn a_frustum_around_the_box_keeps_all_of_it_and_one_seeing_its_top_keeps_the_top() {
        // A box 20 wide and 10 tall. A camera far away sees all of it: the
        // clip keeps the eight corners.
        let scene = (Vec3::new(-10.0, 0.0, -10.0), Vec3::new(10.0, 10.0, 10.0));
        let (t, p) = camera(Vec3::new(0.0, 20.0, 100.0), Vec3::ZERO);
        let all = view_volumes(std::iter::once((&t, &p)), scene).unwrap().remove(0);
        for c in corners(scene) {
            assert!(all.iter().any(|q| q.distance(c) < 1e-3), "corner {c} lost: {all:?}");
        }
        // A camera seeing only the upper part of the box's front, under a
        // slanted sun: the window covers the point it looks at.
        let sun = SunLight::new(Vec3::new(0.6, -1.0, 0.3), 0.01).unwrap();
        let (t, p) = camera(Vec3::new(0.0, 9.0, 30.0), Vec3::new(0.0, 9.0, 10.0));
        let volumes = view_volumes(std::iter::once((&t, &p)), scene).unwrap();
        let w = sun_window(&volumes, scene, &sun, None).unwrap();
        let [u, v, _] = LightFrame::sun(&sun, Vec3::ZERO, Vec3::ONE).axes();
        let seen = Vec3::new(0.0, 9.0, 10.0);
        let q = Vec2::new(seen.dot(u), seen.dot(v));
        assert!(q.x >= w[0] && q.x <= w[2] && q.y >= w[1] && q.y <= w[3], "{q} outside {w:?}");
    }

    #[test]
    fn a_camera_with_a_zero_scale_gives_up_the_window_instead_of_panicking() {
        let scene = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let t = GlobalTransform::from(Transform::from_scale(Vec3::ZERO));
        let p = Projection::Perspective(PerspectiveProjection::default());
        assert!(view_volumes(std::iter::once((&t, &p)), scene).is_none());
    }

    #[test]
    fn a_small_camera_move_keeps_the_window_and_a_large_one_moves_it() {
        let scene = (Vec3::new(-100.0, 0.0, -100.0), Vec3::new(100.0, 2.0, 100.0));
        let sun = SunLight::new(Vec3::new(0.3, -1.0, 0.2), 0.01).unwrap();
        let window = |x: f32| {
            let (t, p) = camera(Vec3::new(x, 5.0, 8.0), Vec3::new(x, 0.0, 0.0));
            sun_window(&view_volumes(std::iter::once((&t, &p)), scene).unwrap(), scene, &sun, None).unwrap()
        };
        assert_eq!(window(0.0), window(0.01), "a 1 cm move re-fitted the maps");
        assert_ne!(window(0.0), window(30.0), "a 30 m move kept the maps where they were");
    }

    #[test]
    fn a_window_frame_sits_at_what_the_window_shows_however_wide_the_ground() {
        // A box 2 tall on grounds up to 2e6 wide, the sun slanted: the frame's
        // origin is just in front of the box's top inside the window, and L0
        // about the window's depth there — not the ground's far corners (in
        // f32 the window's long prism lost its side planes at 2e6: the origin
        // came out 6e5 away).
        let sun = SunLight::new(Vec3::new(0.3, -1.0, 0.2), 0.1).unwrap();
        for half in [1e1f32, 1e4, 1e6] {
            let scene = (Vec3::new(-half, 0.0, -half), Vec3::new(half, 2.0, half));
            let (t, p) = camera(Vec3::new(3.0, 4.0, 4.5), Vec3::new(0.0, 0.3, 0.0));
            let volumes = view_volumes(std::iter::once((&t, &p)), scene).unwrap();
            let window = sun_window(&volumes, scene, &sun, None).unwrap();
            let (frame, l0) = window_frame(window, scene, &sun).unwrap();
            let origin = frame.origin().as_vec3();
            assert!(origin.length() < 50.0, "{half}: origin {origin} far from the view");
            assert!(l0 > 0.0 && l0 < 60.0, "{half}: L0 {l0}");
            // The point the camera looks at is in front of the origin and
            // not beyond L0.
            let target = frame.to_frame(Vec3::new(0.0, 0.0, 0.0));
            assert!(target.z > 0.0 && target.z <= l0, "{half}: target depth {} vs L0 {l0}", target.z);
        }
    }

    #[test]
    fn a_window_is_kept_while_it_covers_the_view_and_is_not_much_too_big() {
        let scene = (Vec3::new(-100.0, 0.0, -100.0), Vec3::new(100.0, 2.0, 100.0));
        let sun = SunLight::new(Vec3::NEG_Y, 0.01).unwrap();
        let window = |height: f32, previous| {
            let (t, p) = camera(Vec3::new(0.0, height, 0.01), Vec3::ZERO);
            sun_window(&view_volumes(std::iter::once((&t, &p)), scene).unwrap(), scene, &sun, previous).unwrap()
        };
        // Find two heights whose fresh windows differ by a size step.
        let a = window(5.0, None);
        let b = (1..200).map(|k| 5.0 + k as f32 * 0.01).map(|h| (h, window(h, None))).find(|(_, w)| *w != a);
        let (h, b) = b.expect("a size step between 5 and 7");
        // Bobbing back below the boundary keeps the bigger window; growing past it takes a new one.
        assert_eq!(window(5.0, Some(b)), b, "the wider window covers the lower view: kept");
        // 10% higher the view is past the smaller window's margin (a sixteenth plus 2%).
        assert_eq!(window(h * 1.1, Some(a)), window(h * 1.1, None), "the smaller window does not cover: replaced");
        // A window far too big (the camera came much closer) is replaced.
        let far = window(40.0, None);
        assert_eq!(window(5.0, Some(far)), a, "a window 8× too wide is not kept");
    }

    #[test]
    fn quantised_windows_cover_their_input_and_waste_little() {
        for (lo, hi) in [(0.0, 1.0), (-3.7, 12.2), (1e5, 1e5 + 3.0), (-0.001, 0.0004), (5.0, 5.0)] {
            let (a, b) = quantised(lo, hi);
            assert!(a <= lo && b >= hi, "[{a}, {b}] does not cover [{lo}, {hi}]");
            let size = (hi - lo).max(1e-3);
            assert!(b - a <= 1.3 * size + 1e-3 * hi.abs().max(1.0), "[{a}, {b}] wastes too much around [{lo}, {hi}]");
        }
    }

    #[test]
    fn no_camera_seeing_the_scene_gives_no_window() {
        let scene = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let sun = SunLight::new(Vec3::NEG_Y, 0.01).unwrap();
        // Looking away from the scene.
        let (t, p) = camera(Vec3::new(0.0, 0.0, 10.0), Vec3::new(0.0, 0.0, 20.0));
        let volumes = view_volumes(std::iter::once((&t, &p)), scene).unwrap();
        assert!(volumes.iter().all(|v| v.is_empty()));
        assert_eq!(sun_window(&volumes, scene, &sun, None), None);
    }
}
