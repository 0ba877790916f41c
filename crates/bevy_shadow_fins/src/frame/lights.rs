//! The lights with fin shadows as the core models them: a `FinLight` or
//! `SpotLight` is a disk, a `RectLight` a rectangle, a `DirectionalLight` the
//! sun, a `PointLight` a sphere — each with its reach, settings and how it is
//! shaded.

use crate::settings::{FinLight, FinShadowSettings, FinShadows};
use crate::{casters::reach::Reach, frame::LightShading};
use bevy::{camera::visibility::RenderLayers, light::SunDisk, prelude::*, render::sync_world::RenderEntity};
use shadow_fins::light::{CubeFace, DiskLight, Light, RectLight as RectArea, SphereLight, SunLight};
use std::f32::consts::FRAC_PI_2;

/// A light asking for fin shadows, as the frame builder sees it.
pub(crate) struct LightSource {
    pub(crate) entity: Entity,
    /// A disk (`FinLight`, `SpotLight`), a rectangle (`RectLight`), the
    /// sun (`DirectionalLight`) or a sphere (`PointLight`).
    pub(crate) light: Light,
    pub(crate) reach: Reach,
    /// Intensity × colour luminance, for ranking past [`MAX_FIN_LIGHTS`](super::MAX_FIN_LIGHTS)
    /// lights (`priority.rs`; a sun's is its illuminance, and suns rank first).
    pub(crate) power: f32,
    pub(crate) settings: FinShadowSettings,
    pub(crate) shading: LightShading,
    /// A sun's maps fitted to what the cameras see (`sun_fit`), in its axes.
    pub(crate) window: Option<[f32; 4]>,
    /// The light's `RenderLayers`: only casters on a layer it shares cast
    /// for it, as in Bevy's own shadow maps.
    pub(crate) layers: RenderLayers,
}

/// The lights with fin shadows: `FinLight`s, and Bevy `SpotLight`s,
/// `DirectionalLight`s, `RectLight`s and `PointLight`s with [`FinShadows`],
/// by entity order; and the entities of those whose position or direction
/// is not finite (they shadow nothing).
pub(crate) fn light_sources(
    fin_lights: &Query<(Entity, &FinLight, &FinShadowSettings, &GlobalTransform)>,
    spot_lights: &SpotLights,
    directional_lights: &DirectionalLights,
    others: &OtherLights,
) -> (Vec<LightSource>, Vec<Entity>) {
    let rect_lights = &others.rects;
    // Not `GlobalTransform::forward`: it panics (debug) on a zero scale; the
    // core's lights reject a direction of no length instead.
    let forward = |t: &GlobalTransform| Vec3::from(t.affine().matrix3 * bevy::math::Vec3A::NEG_Z);
    let disk = |t: &GlobalTransform, radius: f32| DiskLight::new(t.translation(), forward(t), radius);
    let finite = |x: f32| if x.is_finite() && x > 0.0 { x } else { 0.0 };
    let own = fin_lights.iter().map(|(entity, light, settings, transform)| {
        let source = |disk| LightSource {
            entity,
            light: Light::Disk(disk),
            reach: Reach { range: finite(light.range), cone: None },
            power: light_power(light.intensity, light.color),
            settings: settings.clamped(),
            shading: LightShading::Own { light: *light, transform: *transform },
            window: None,
            layers: RenderLayers::default(),
        };
        disk(transform, light.effective_radius()).map(source).map_err(|_| entity)
    });
    // An entity with both a FinLight and a SpotLight is the FinLight (one slot).
    let spots = spot_lights.iter().filter(|l| l.5 && !fin_lights.contains(l.0)).filter_map(
        |(entity, spot, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let source = |disk| LightSource {
                entity,
                light: Light::Disk(disk),
                // Bevy lights nothing past the outer angle (its spot attenuation).
                reach: Reach { range: finite(spot.range), cone: Some(spot.outer_angle.clamp(0.0, FRAC_PI_2)) },
                power: light_power(spot.intensity, spot.color),
                settings,
                shading: LightShading::Bevy { render_entity: render.id() },
                window: None,
                layers: RenderLayers::default(),
            };
            Some(disk(transform, finite(spot.radius)).map(source).map_err(|_| entity))
        },
    );
    let suns = directional_lights.iter().filter(|l| l.6 && !fin_lights.contains(l.0)).filter_map(
        |(entity, sun_light, sun_disk, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let sun = SunLight::new(forward(transform), sun_angular_radius(sun_disk)).map_err(|_| entity);
            Some(sun.map(|sun| LightSource {
                entity,
                light: Light::Sun(sun),
                reach: Reach { range: 0.0, cone: None },
                power: light_power(sun_light.illuminance, sun_light.color),
                settings,
                shading: LightShading::Bevy { render_entity: render.id() },
                window: None,
                layers: RenderLayers::default(),
            }))
        },
    );
    // Bevy's rectangle spans its local X (width) and Y (height), scaled as
    // Bevy scales it (`ExtractedRectLight`), and faces local −Z.
    let rects = rect_lights.iter().filter(|l| l.5 && !fin_lights.contains(l.0)).filter_map(
        |(entity, rect, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let m = transform.affine().matrix3;
            let size = |s: f32, axis: bevy::math::Vec3A| finite(s) * axis.length();
            if !(size(rect.width, m.x_axis) * size(rect.height, m.y_axis) > 0.0) {
                // Fin shadows of a 0 × 0 rectangle are the hard shadow; Bevy's
                // own shading divides the light's power by its area.
                warn_once!(
                    "fin shadows: a RectLight of zero area: Bevy shades it as infinitely bright (NaN on screen); \
                     give it a width and height > 0"
                );
            }
            let area = RectArea::new(
                transform.translation(),
                forward(transform),
                Vec3::from(m.x_axis),
                size(rect.width, m.x_axis),
                size(rect.height, m.y_axis),
            );
            Some(
                area.map(|area| LightSource {
                    entity,
                    light: Light::Rect(area),
                    reach: Reach { range: finite(rect.range), cone: None },
                    power: light_power(rect.intensity, rect.color),
                    settings,
                    shading: LightShading::Bevy { render_entity: render.id() },
                    window: None,
                    layers: RenderLayers::default(),
                })
                .map_err(|_| entity),
            )
        },
    );
    // A point light is a sphere of its radius at its position (Bevy shades
    // it so: `PointLight::radius`, its representative-point specular).
    let points = others.points.iter().filter(|l| l.5 && !fin_lights.contains(l.0)).filter_map(
        |(entity, point, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let sphere = SphereLight::new(transform.translation(), finite(point.radius)).map_err(|_| entity);
            Some(sphere.map(|sphere| LightSource {
                entity,
                light: Light::Sphere(sphere),
                reach: Reach { range: finite(point.range), cone: None },
                power: light_power(point.intensity, point.color),
                settings,
                shading: LightShading::Bevy { render_entity: render.id() },
                window: None,
                layers: RenderLayers::default(),
            }))
        },
    );
    let (mut sources, mut invalid) = (Vec::new(), Vec::new());
    for light in own.chain(spots).chain(suns).chain(rects).chain(points) {
        match light {
            Ok(source) => sources.push(source),
            Err(entity) => invalid.push(entity),
        }
    }
    sources.sort_by_key(|s| s.entity);
    (sources, invalid)
}

/// A light's power for ranking lights (`priority.rs`): its intensity times
/// the luminance of its colour (0 for anything not finite or negative).
pub(crate) fn light_power(intensity: f32, color: Color) -> f32 {
    use bevy::color::Luminance;
    let p = intensity * color.luminance();
    if p.is_finite() && p > 0.0 { p } else { 0.0 }
}

/// The sun's angular radius `θ` from Bevy's `SunDisk::angular_size` (a
/// diameter): half of it, `SunDisk::EARTH` (what Bevy draws) when the light
/// has none, clamped to `[0, 1.4]` rad (the core's `SunLight` range; 80°,
/// far past any sun), 0 for NaN. (`SunDisk::OFF`, size 0, gives the hard
/// shadow.)
pub(crate) fn sun_angular_radius(sun_disk: Option<&SunDisk>) -> f32 {
    let size = sun_disk.map_or(SunDisk::EARTH.angular_size, |d| d.angular_size);
    // +∞ is "as wide as there is"; NaN is no size.
    if size.is_nan() { 0.0 } else { (size * 0.5).clamp(0.0, 1.4) }
}

/// The cube faces a light's frames are made for: one frame (`None`) for a
/// disk, rectangle or sun, six for a sphere.
pub(crate) fn faces_of(light: &Light) -> Vec<Option<CubeFace>> {
    match light {
        Light::Sphere(_) => CubeFace::ALL.map(Some).to_vec(),
        _ => vec![None],
    }
}

/// The numbers a light's frame depends on.
pub(crate) fn light_key(light: &Light) -> [f32; 12] {
    // The first entry is the kind, so that no two kinds share a key.
    match light {
        Light::Disk(d) => {
            let (c, n) = (d.center, d.normal);
            [0.0, c.x, c.y, c.z, n.x, n.y, n.z, d.radius, 0.0, 0.0, 0.0, 0.0]
        }
        Light::Rect(r) => {
            let (c, n, t, h) = (r.center, r.normal, r.tangent, r.half_extents);
            [1.0, c.x, c.y, c.z, n.x, n.y, n.z, h.x, h.y, t.x, t.y, t.z]
        }
        Light::Sun(s) => {
            let d = s.direction;
            [2.0, 0.0, 0.0, 0.0, d.x, d.y, d.z, s.angular_radius, 0.0, 0.0, 0.0, 0.0]
        }
        Light::Sphere(s) => {
            let c = s.center;
            [3.0, c.x, c.y, c.z, 0.0, 0.0, 0.0, s.radius, 0.0, 0.0, 0.0, 0.0]
        }
    }
}

/// Every `SpotLight`, fin-shadowed (`FinShadows`) or not: mutable, so that
/// one that stops being fin-shadowed can be marked changed.
pub(crate) type SpotLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut SpotLight,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Every `DirectionalLight`, as [`SpotLights`].
pub(crate) type DirectionalLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut DirectionalLight,
        Option<&'static SunDisk>,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Every `RectLight` (Bevy has no shadow map for it to turn off).
pub(crate) type RectLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static bevy::light::RectLight,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Every `PointLight`, as [`SpotLights`].
pub(crate) type PointLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut PointLight,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Rectangle and point lights (one parameter: a system takes at most sixteen).
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct OtherLights<'w, 's> {
    pub(crate) rects: RectLights<'w, 's>,
    pub(crate) points: PointLights<'w, 's>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lights_power_is_its_intensity_times_its_luminance_and_never_nonsense() {
        assert_eq!(light_power(f32::NAN, Color::WHITE), 0.0);
        assert_eq!(light_power(-1.0, Color::WHITE), 0.0);
        assert_eq!(light_power(f32::INFINITY, Color::WHITE), 0.0);
        assert_eq!(light_power(10.0, Color::BLACK), 0.0);
        assert!((light_power(10.0, Color::WHITE) - 10.0).abs() < 1e-4);
        assert!(light_power(10.0, Color::srgb(0.0, 1.0, 0.0)) > light_power(10.0, Color::srgb(0.0, 0.0, 1.0)));
    }

    #[test]
    fn the_suns_angular_radius_is_half_its_sun_disk_clamped_and_earths_without_one() {
        let radius = |angular_size| sun_angular_radius(Some(&SunDisk { angular_size, intensity: 1.0 }));
        assert_eq!(sun_angular_radius(None), SunDisk::EARTH.angular_size * 0.5);
        assert_eq!(radius(0.2), 0.1);
        assert_eq!(radius(0.0), 0.0);
        assert_eq!(radius(-1.0), 0.0);
        assert_eq!(radius(f32::NAN), 0.0);
        assert_eq!(radius(f32::INFINITY), 1.4);
        assert_eq!(radius(f32::NEG_INFINITY), 0.0);
        assert_eq!(radius(10.0), 1.4);
        // Every clamped value is a valid core sun.
        for size in [0.0, 0.2, -1.0, f32::NAN, 10.0, f32::INFINITY] {
            assert!(SunLight::new(Vec3::NEG_Y, radius(size)).is_ok(), "{size}");
        }
    }
}
