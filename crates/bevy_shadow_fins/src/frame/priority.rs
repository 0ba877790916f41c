//! Which lights get fins when more than [`MAX_FIN_LIGHTS`](super::MAX_FIN_LIGHTS)
//! ask for them: the ones that matter most to what the cameras see. The rest
//! keep Bevy's shadows (a [`FinLight`](crate::FinLight) past the limit is not
//! lit) and report [`FinDegradation::TooManyLights`](crate::FinDegradation).
//!
//! A light's priority is an estimate of the light it brings to the viewer:
//! its power (`LightSource::power`: intensity × the luminance of its colour) over the squared
//! distance to the nearest [`FinShadowView`](crate::FinShadowView) camera,
//! a tenth of that when the sphere it lights (its range) is outside every
//! camera's view cone (it matters once the camera turns, less than what is
//! in view). Suns come first. With no more lights than slots nothing is
//! ranked and the order stays the entities' (so slots are stable).

use super::lights::LightSource;
use bevy::prelude::*;
use shadow_fins::light::Light;

/// How much a light outside every view counts against one in view at the
/// same distance and power.
pub(crate) const OUT_OF_VIEW_WEIGHT: f32 = 0.1;

/// How much a light that had fins last frame counts over one that did not:
/// two lights of nearly equal priority at the cut do not swap slots (and
/// redraw their maps) every time the camera moves a little.
pub(crate) const KEPT_LIGHT_WEIGHT: f32 = 1.5;

/// A `FinShadowView` camera as the priority sees it: where it looks from and
/// the cone that holds its view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Viewer {
    pub(crate) position: Vec3,
    /// Unit length.
    pub(crate) forward: Vec3,
    /// The half-angle of a cone around `forward` holding the frustum (π for
    /// an orthographic or custom projection: everything counts as in view).
    pub(crate) half_angle: f32,
}

impl Viewer {
    /// `None` for a camera with no finite position or direction.
    pub(crate) fn new(transform: &GlobalTransform, projection: &Projection) -> Option<Self> {
        // Not `GlobalTransform::forward`: it panics (debug) on a zero scale.
        let forward = Vec3::from(transform.affine().matrix3 * bevy::math::Vec3A::NEG_Z).normalize_or_zero();
        let position = transform.translation();
        if forward == Vec3::ZERO || !forward.is_finite() || !position.is_finite() {
            return None;
        }
        let half_angle = match projection {
            // The half-diagonal of the frustum's cross-section.
            Projection::Perspective(p) => {
                let half_height = (p.fov * 0.5).tan();
                let aspect = if p.aspect_ratio.is_finite() && p.aspect_ratio > 0.0 { p.aspect_ratio } else { 1.0 };
                let angle = (half_height * (1.0 + aspect * aspect).sqrt()).atan();
                if angle.is_finite() { angle } else { std::f32::consts::PI }
            }
            _ => std::f32::consts::PI,
        };
        Some(Self { position, forward, half_angle })
    }

    /// Whether a sphere (`radius` 0: unbounded) meets the view cone.
    fn sees(&self, center: Vec3, radius: f32) -> bool {
        let to = center - self.position;
        let distance = to.length();
        if radius <= 0.0 || distance <= radius || self.half_angle >= std::f32::consts::PI {
            return true;
        }
        let angle = (to.dot(self.forward) / distance).clamp(-1.0, 1.0).acos();
        angle - (radius / distance).min(1.0).asin() <= self.half_angle
    }
}

/// The light's priority (see the module's doc; +∞ for a sun, finite and
/// ≥ 0 otherwise). With no viewer it is the light's power.
pub(crate) fn priority(source: &LightSource, viewers: &[Viewer]) -> f32 {
    let (center, size) = match &source.light {
        Light::Sun(_) => return f32::INFINITY,
        Light::Disk(d) => (d.center, d.radius),
        Light::Rect(r) => (r.center, r.half_extents.length()),
        Light::Sphere(s) => (s.center, s.radius),
    };
    let power = if source.power.is_finite() && source.power > 0.0 { source.power } else { 0.0 };
    if viewers.is_empty() {
        return power;
    }
    // The sphere the light lights (a range of 0 lights everywhere).
    let reach = if source.reach.range > 0.0 { source.reach.range + size } else { 0.0 };
    let best = viewers
        .iter()
        .map(|v| {
            // Not closer than the light's own size: a camera inside a large
            // light does not make it infinitely bright.
            let d2 = v.position.distance_squared(center).max(size * size).max(f32::MIN_POSITIVE);
            let seen = if v.sees(center, reach) { 1.0 } else { OUT_OF_VIEW_WEIGHT };
            power / d2 * seen
        })
        .fold(0.0, f32::max);
    if best.is_finite() { best } else { f32::MAX }
}

/// Keeps the `max` lights of highest priority in `sources` (in the order
/// they came) and returns the rest. `had_fins` tells a light that had a slot
/// last frame (weighted by [`KEPT_LIGHT_WEIGHT`]); ties go to the lower entity.
pub(crate) fn keep_most_important(
    sources: &mut Vec<LightSource>,
    viewers: &[Viewer],
    max: usize,
    had_fins: impl Fn(Entity) -> bool,
) -> Vec<LightSource> {
    if sources.len() <= max {
        return vec![];
    }
    let score = |s: &LightSource| {
        let p = priority(s, viewers);
        if had_fins(s.entity) { p * KEPT_LIGHT_WEIGHT } else { p }
    };
    let mut ranked: Vec<(f32, Entity)> = sources.iter().map(|s| (score(s), s.entity)).collect();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let kept: Vec<Entity> = ranked.iter().take(max).map(|(_, e)| *e).collect();
    let (keep, cut): (Vec<LightSource>, Vec<LightSource>) =
        std::mem::take(sources).into_iter().partition(|s| kept.contains(&s.entity));
    *sources = keep;
    cut
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{casters::reach::Reach, frame::LightShading, settings::FinShadowSettings};
    use bevy::camera::visibility::RenderLayers;
    use shadow_fins::light::{DiskLight, SunLight};

    fn spot(index: u32, at: Vec3, power: f32, range: f32) -> LightSource {
        LightSource {
            entity: Entity::from_raw_u32(index + 1).unwrap(),
            light: Light::Disk(DiskLight::new(at, Vec3::NEG_Y, 0.1).unwrap()),
            reach: Reach { range, cone: None },
            power,
            settings: FinShadowSettings::default(),
            shading: LightShading::Bevy { render_entity: Entity::PLACEHOLDER },
            window: None,
            layers: RenderLayers::default(),
        }
    }

    fn camera_at_origin_looking_down_z() -> Viewer {
        let transform = GlobalTransform::from(Transform::from_xyz(0.0, 0.0, 0.0).looking_to(Vec3::NEG_Z, Vec3::Y));
        Viewer::new(&transform, &Projection::Perspective(PerspectiveProjection::default())).unwrap()
    }

    fn entities(sources: &[LightSource]) -> Vec<u32> {
        sources.iter().map(|s| s.entity.index_u32() - 1).collect()
    }

    #[test]
    fn with_no_more_lights_than_slots_nothing_moves() {
        let mut sources: Vec<LightSource> =
            (0..4).map(|i| spot(i, Vec3::new(0.0, 0.0, -100.0 * i as f32 - 1.0), 1.0, 10.0)).collect();
        let cut = keep_most_important(&mut sources, &[camera_at_origin_looking_down_z()], 4, |_| false);
        assert!(cut.is_empty());
        assert_eq!(entities(&sources), vec![0, 1, 2, 3]);
    }

    #[test]
    fn the_nearest_lights_in_view_are_kept_in_their_order() {
        // Twenty equal lights along the view axis, shuffled in entity order.
        let distance = |i: u32| 1.0 + ((i * 7) % 20) as f32;
        let mut sources: Vec<LightSource> =
            (0..20).map(|i| spot(i, Vec3::new(0.0, 0.0, -distance(i)), 1000.0, 5.0)).collect();
        let cut = keep_most_important(&mut sources, &[camera_at_origin_looking_down_z()], 16, |_| false);
        assert_eq!(sources.len(), 16);
        let order = entities(&sources);
        assert!(order.windows(2).all(|w| w[0] < w[1]), "the kept ones stay in their order: {order:?}");
        let farthest_kept = sources.iter().map(|s| distance(s.entity.index_u32() - 1)).fold(0.0, f32::max);
        let nearest_cut = cut.iter().map(|s| distance(s.entity.index_u32() - 1)).fold(f32::INFINITY, f32::min);
        assert!(farthest_kept < nearest_cut, "{farthest_kept} kept, {nearest_cut} cut");
        assert_eq!(cut.len(), 4);
    }

    #[test]
    fn power_distance_and_view_decide_and_suns_come_first() {
        let viewer = [camera_at_origin_looking_down_z()];
        let at = |z: f32| Vec3::new(0.0, 0.0, z);
        // 4× the power at 2× the distance: the same light at the camera.
        let near = priority(&spot(0, at(-1.0), 1.0, 1.0), &viewer);
        let far_bright = priority(&spot(1, at(-2.0), 4.0, 1.0), &viewer);
        assert!((near - far_bright).abs() <= 1e-6 * near, "{near} vs {far_bright}");
        // Behind the camera, its range well away from the view: a tenth.
        let behind = priority(&spot(2, at(10.0), 100.0, 1.0), &viewer);
        let ahead = priority(&spot(3, at(-10.0), 100.0, 1.0), &viewer);
        assert!((behind - ahead * OUT_OF_VIEW_WEIGHT).abs() <= 1e-6 * ahead, "{behind} vs {ahead}");
        // Behind but lighting the camera's surroundings (a range that reaches
        // into the view): counts in full; unbounded range too.
        assert_eq!(priority(&spot(4, at(3.0), 100.0, 5.0), &viewer), priority(&spot(5, at(-3.0), 100.0, 5.0), &viewer));
        assert_eq!(priority(&spot(6, at(10.0), 100.0, 0.0), &viewer), ahead);
        let mut sun = spot(7, at(0.0), 0.0, 0.0);
        sun.light = Light::Sun(SunLight::new(Vec3::NEG_Y, 0.01).unwrap());
        assert_eq!(priority(&sun, &viewer), f32::INFINITY);
        let mut sources: Vec<LightSource> = (0..3).map(|i| spot(i, at(-1.0), 1e6, 1.0)).collect();
        sources.push(sun);
        let cut = keep_most_important(&mut sources, &viewer, 1, |_| false);
        assert_eq!(entities(&sources), vec![7]);
        assert_eq!(cut.len(), 3);
    }

    #[test]
    fn a_light_that_had_fins_keeps_them_against_one_barely_brighter() {
        let viewer = [camera_at_origin_looking_down_z()];
        let kept = Entity::from_raw_u32(2).unwrap();
        let make = || vec![spot(0, Vec3::new(0.0, 0.0, -2.0), 1.2, 1.0), spot(1, Vec3::new(0.0, 0.0, -2.0), 1.0, 1.0)];
        let mut sources = make();
        keep_most_important(&mut sources, &viewer, 1, |e| e == kept);
        assert_eq!(entities(&sources), vec![1], "20% brighter does not take the slot");
        let mut sources = make();
        keep_most_important(&mut sources, &viewer, 1, |_| false);
        assert_eq!(entities(&sources), vec![0], "with no history the brighter one wins");
    }

    #[test]
    fn nonsense_ranks_last_and_never_panics() {
        let viewer = [camera_at_origin_looking_down_z()];
        for power in [f32::NAN, f32::INFINITY, -5.0, 0.0] {
            let p = priority(&spot(0, Vec3::new(0.0, 0.0, -1.0), power, 1.0), &viewer);
            assert!(p.is_finite() && p >= 0.0, "{power}: {p}");
        }
        // A light at the camera is as bright as one its own size away.
        let at_camera = priority(&spot(0, Vec3::ZERO, 1.0, 1.0), &viewer);
        assert!(at_camera.is_finite() && at_camera > 0.0);
        // A camera with a degenerate transform is no viewer.
        let squashed = GlobalTransform::from(Transform::from_scale(Vec3::ZERO));
        assert_eq!(Viewer::new(&squashed, &Projection::default()), None);
        let nan = GlobalTransform::from(Transform::from_xyz(f32::NAN, 0.0, 0.0));
        assert_eq!(Viewer::new(&nan, &Projection::default()), None);
    }
}
