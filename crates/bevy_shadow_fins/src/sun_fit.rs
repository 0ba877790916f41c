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
//! maps, texel for texel: no shimmering edges, no re-extraction every frame.
//! It is computed in the sun's axes, `(p · u, p · v)`, which depend only on
//! its direction, so it can be compared between frames before the scene is
//! collected; [`window_in_frame`] moves it into a frame's map coordinates.

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
        let (position, forward) = (transform.translation(), transform.forward().as_vec3());
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

/// Planes `(n, d)` of a convex hexahedron, `n · p ≤ d` inside.
fn planes(corners: &[Vec3; 8]) -> Vec<(Vec3, f32)> {
    let centre = corners.iter().copied().sum::<Vec3>() / 8.0;
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
    let boxed = corners(scene_box);
    let (fp, bp) = (planes(frustum), planes(&boxed));
    let size = (scene_box.1 - scene_box.0).length().max(frustum[0].distance(frustum[6]));
    let tolerance = 1e-5 * size.max(scene_box.0.abs().max(scene_box.1.abs()).max_element());
    let inside = |p: Vec3| fp.iter().chain(&bp).all(|(n, d)| n.dot(p) <= d + tolerance);
    let mut points: Vec<Vec3> = frustum.iter().chain(&boxed).copied().filter(|p| inside(*p)).collect();
    let mut cross = |solid: &[Vec3; 8], other: &[(Vec3, f32)]| {
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
    cross(frustum, &bp);
    cross(&boxed, &fp);
    points
}

/// The map window of `sun` over `volumes`, in the sun's axes
/// `[min u, min v, max u, max v]`, cut to the scene box's own footprint and
/// quantised; `None` when no camera sees the scene.
pub(crate) fn sun_window(volumes: &[Vec<Vec3>], scene_box: (Vec3, Vec3), sun: &SunLight) -> Option<[f32; 4]> {
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
    Some([x0, y0, x1, y1])
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

fn corners((a, b): (Vec3, Vec3)) -> [Vec3; 8] {
    std::array::from_fn(|k| {
        Vec3::new(
            if k & 1 == 0 { a.x } else { b.x },
            if k & 2 == 0 { a.y } else { b.y },
            if k & 4 == 0 { a.z } else { b.z },
        )
    })
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
        let w = sun_window(&volumes, scene, &sun).unwrap();
        let (width, height) = (w[2] - w[0], w[3] - w[1]);
        assert!(width < 20.0 && height < 20.0, "window {w:?} is not fitted to the view");
        // It covers what the camera sees: the point it looks at, in the sun's axes.
        let [u, v, _] = LightFrame::sun(&sun, Vec3::ZERO, Vec3::ONE).axes();
        let target = Vec3::new(80.0, 0.0, 80.0);
        let q = Vec2::new(target.dot(u), target.dot(v));
        assert!(q.x > w[0] && q.x < w[2] && q.y > w[1] && q.y < w[3], "{q} outside {w:?}");
    }

    #[test]
    fn a_small_camera_move_keeps_the_window_and_a_large_one_moves_it() {
        let scene = (Vec3::new(-100.0, 0.0, -100.0), Vec3::new(100.0, 2.0, 100.0));
        let sun = SunLight::new(Vec3::new(0.3, -1.0, 0.2), 0.01).unwrap();
        let window = |x: f32| {
            let (t, p) = camera(Vec3::new(x, 5.0, 8.0), Vec3::new(x, 0.0, 0.0));
            sun_window(&view_volumes(std::iter::once((&t, &p)), scene).unwrap(), scene, &sun).unwrap()
        };
        assert_eq!(window(0.0), window(0.01), "a 1 cm move re-fitted the maps");
        assert_ne!(window(0.0), window(30.0), "a 30 m move kept the maps where they were");
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
        assert_eq!(sun_window(&volumes, scene, &sun), None);
    }
}
