//! More lights: Bevy `SpotLight`s, `RectLight`s, `PointLight`s and suns
//! (`DirectionalLight` with a `SunDisk`) with `FinShadows`, added beside the editor's main light,
//! each with its size, power, cone and layers edited live, removed with one
//! click; their counts come from each light's `FinLightStats`. (The main
//! light, the ground truth and the error views stay with the main light.)

use bevy::{light::SunDisk, prelude::*};
use bevy_egui::{EguiContexts, EguiPrimaryContextPass, egui};
use bevy_shadow_fins::{FinLightStats, FinShadowSettings, FinShadows, MAX_FIN_LIGHTS};

use crate::{
    scene::rect_intensity,
    state::{EditorLight, LightParams},
};

/// Marks a light the "More lights" window added.
#[derive(Component)]
pub(crate) struct ExtraLight;

pub(crate) fn build(app: &mut App) {
    app.add_systems(EguiPrimaryContextPass, lights_window);
}

/// The kinds of light the window adds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ExtraKind {
    Spot,
    Rect,
    Point,
    Sun,
}

/// Where a new light sits: beside the main one, shifted sideways by a quarter
/// of its height above the origin so its shadow differs, facing the same way.
fn new_light_transform(params: &LightParams, index: usize) -> Transform {
    let direction = params.direction.try_normalize().unwrap_or(Vec3::NEG_Y);
    let (u, v) = direction.any_orthonormal_pair();
    let a = index as f32 * 2.4;
    // At least two light radii apart, whatever the scene's scale.
    let apart = (params.position.length() * 0.25).max(params.radius.max(1e-6) * 2.0);
    let offset = (u * a.cos() + v * a.sin()) * apart;
    LightParams { position: params.position + offset, ..*params }.transform()
}

/// A new spot light beside the main one: same size and power.
fn new_light(params: &LightParams, index: usize) -> (SpotLight, Transform) {
    let spot = SpotLight {
        intensity: params.intensity.max(0.0),
        radius: params.radius.max(0.0),
        range: 1000.0,
        outer_angle: 1.0,
        inner_angle: 0.6,
        ..default()
    };
    (spot, new_light_transform(params, index))
}

/// A new rectangle light beside the main one: the main light's disk area at
/// its aspect, as bright on its axis (a millimetre at least: Bevy divides a
/// RectLight's power by its area).
fn new_rect(params: &LightParams, index: usize) -> (RectLight, Transform) {
    let (width, height) = params.rect_size();
    let rect = RectLight {
        intensity: rect_intensity(params.intensity.max(0.0)),
        range: 1000.0,
        width: width.max(1e-3),
        height: height.max(1e-3),
        ..default()
    };
    (rect, new_light_transform(params, index))
}

/// A new point light beside the main one: a sphere of its radius, same power.
fn new_point(params: &LightParams, index: usize) -> (PointLight, Transform) {
    let point = PointLight {
        intensity: params.intensity.max(0.0),
        radius: params.radius.max(0.0),
        range: 1000.0,
        shadow_maps_enabled: true,
        ..default()
    };
    (point, new_light_transform(params, index))
}

/// A new sun, tilted away from the main light's direction so its shadow differs,
/// at the main light's illuminance.
fn new_sun(params: &LightParams, index: usize) -> (DirectionalLight, SunDisk, Transform) {
    let direction = params.direction.try_normalize().unwrap_or(Vec3::NEG_Y);
    let (u, _) = direction.any_orthonormal_pair();
    let tilt = Quat::from_axis_angle(u, 0.3 + 0.2 * index as f32);
    let sun = DirectionalLight { illuminance: params.illuminance.max(0.0), shadow_maps_enabled: true, ..default() };
    // The main light's sun size (the real sun's by default), whatever the main light's kind.
    let disk = SunDisk { angular_size: 2.0 * params.sun_angular_radius(), intensity: 1.0 };
    let transform = Transform::default().looking_to(tilt * direction, direction.any_orthonormal_vector());
    (sun, disk, transform)
}

type ExtraLightItem<'a> = (
    Entity,
    Option<Mut<'a, SpotLight>>,
    Option<Mut<'a, RectLight>>,
    Option<Mut<'a, PointLight>>,
    Option<Mut<'a, DirectionalLight>>,
    Option<Mut<'a, SunDisk>>,
    Mut<'a, FinShadowSettings>,
    &'a FinLightStats,
);

#[allow(clippy::type_complexity)]
fn lights_window(
    mut contexts: EguiContexts,
    mut commands: Commands,
    params: Res<LightParams>,
    main: Query<&FinShadowSettings, (With<EditorLight>, Without<ExtraLight>)>,
    mut extras: Query<
        (
            Entity,
            Option<&mut SpotLight>,
            Option<&mut RectLight>,
            Option<&mut PointLight>,
            Option<&mut DirectionalLight>,
            Option<&mut SunDisk>,
            &mut FinShadowSettings,
            &FinLightStats,
        ),
        With<ExtraLight>,
    >,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    // Anchored at the bottom of the 3D view, clear of the side panels (whose
    // width follows their content) and of what the view shows near its top.
    let window = egui::Window::new("More lights").default_open(false);
    window.anchor(egui::Align2::CENTER_BOTTOM, egui::vec2(0.0, -8.0)).show(&ctx, |ui| {
        ui.small("Bevy lights with FinShadows, shadowed together with the main light.");
        let count = extras.iter().count();
        let room = count + 1 < MAX_FIN_LIGHTS;
        let settings = main.single().copied().unwrap_or_default();
        ui.horizontal(|ui| {
            for (kind, label) in [
                (ExtraKind::Spot, "add a spot"),
                (ExtraKind::Rect, "add a rect"),
                (ExtraKind::Point, "add a point"),
                (ExtraKind::Sun, "add a sun"),
            ] {
                if !ui.add_enabled(room, egui::Button::new(label)).clicked() {
                    continue;
                }
                let mut e = commands.spawn((ExtraLight, FinShadows, settings));
                match kind {
                    ExtraKind::Spot => e.insert((new_light(&params, count), Name::new("extra spot light"))),
                    ExtraKind::Rect => e.insert((new_rect(&params, count), Name::new("extra rect light"))),
                    ExtraKind::Point => e.insert((new_point(&params, count), Name::new("extra point light"))),
                    ExtraKind::Sun => e.insert((new_sun(&params, count), Name::new("extra sun"))),
                };
            }
        });
        let mut lights: Vec<ExtraLightItem> = extras.iter_mut().collect();
        lights.sort_by_key(|l| l.0);
        for (k, (entity, spot, rect, point, sun, disk, mut settings, stats)) in lights.into_iter().enumerate() {
            ui.separator();
            let kind = if spot.is_some() {
                "spot"
            } else if rect.is_some() {
                "rect"
            } else if point.is_some() {
                "point"
            } else {
                "sun"
            };
            ui.horizontal(|ui| {
                ui.label(format!("{kind} {}", k + 1));
                if ui.button("remove").clicked() {
                    commands.entity(entity).despawn();
                }
            });
            if let Some(spot) = spot {
                spot_controls(ui, spot);
            }
            if let Some(rect) = rect {
                rect_controls(ui, rect);
            }
            if let Some(point) = point {
                point_controls(ui, point);
            }
            if let (Some(sun), Some(disk)) = (sun, disk) {
                sun_controls(ui, sun, disk);
            }
            let mut layers = settings.layers;
            ui.add(egui::Slider::new(&mut layers, 1..=32).text("layers"));
            if layers != settings.layers {
                settings.layers = layers;
            }
            let st = stats.0;
            ui.small(format!(
                "{} silhouettes, {} fins, {} layers at {}², {} on the GPU",
                st.silhouettes,
                st.fins,
                st.layers,
                st.map_resolution,
                bevy_shadow_fins::ByteSize(st.gpu_bytes)
            ));
            for why in st.degraded.iter() {
                ui.colored_label(egui::Color32::YELLOW, why.to_string());
            }
        }
    });
    Ok(())
}

/// Radius, power and cone; written back only when edited (change detection
/// rebuilds the light's frame).
fn spot_controls(ui: &mut egui::Ui, mut spot: Mut<SpotLight>) {
    let mut s = *spot;
    ui.add(egui::Slider::new(&mut s.radius, 0.0..=5.0).text("radius").logarithmic(true).smallest_positive(1e-3));
    ui.add(egui::Slider::new(&mut s.intensity, 0.0..=1e8).text("intensity (lm)").logarithmic(true));
    ui.add(egui::Slider::new(&mut s.outer_angle, 0.05..=1.5).text("cone (rad)"));
    s.inner_angle = s.inner_angle.min(s.outer_angle);
    if (s.radius, s.intensity, s.outer_angle, s.inner_angle)
        != (spot.radius, spot.intensity, spot.outer_angle, spot.inner_angle)
    {
        *spot = s;
    }
}

/// Radius and power.
fn point_controls(ui: &mut egui::Ui, mut point: Mut<PointLight>) {
    let mut p = *point;
    ui.add(egui::Slider::new(&mut p.radius, 0.0..=5.0).text("radius").logarithmic(true).smallest_positive(1e-3));
    ui.add(egui::Slider::new(&mut p.intensity, 0.0..=1e8).text("intensity (lm)").logarithmic(true));
    if (p.radius, p.intensity) != (point.radius, point.intensity) {
        *point = p;
    }
}

/// Width, height (a millimetre at least) and power.
fn rect_controls(ui: &mut egui::Ui, mut rect: Mut<RectLight>) {
    let mut r = *rect;
    ui.add(egui::Slider::new(&mut r.width, 1e-3..=10.0).text("width").logarithmic(true));
    ui.add(egui::Slider::new(&mut r.height, 1e-3..=10.0).text("height").logarithmic(true));
    ui.add(egui::Slider::new(&mut r.intensity, 0.0..=1e8).text("intensity (lm)").logarithmic(true));
    (r.width, r.height) = (r.width.max(1e-3), r.height.max(1e-3));
    if (r.width, r.height, r.intensity) != (rect.width, rect.height, rect.intensity) {
        *rect = r;
    }
}

/// Angular size (degrees on the slider) and illuminance.
fn sun_controls(ui: &mut egui::Ui, mut sun: Mut<DirectionalLight>, mut disk: Mut<SunDisk>) {
    let mut degrees = disk.angular_size.to_degrees();
    ui.add(egui::Slider::new(&mut degrees, 0.0..=20.0).text("angular size (°)"));
    if degrees.to_radians() != disk.angular_size {
        disk.angular_size = degrees.to_radians();
    }
    let mut lux = sun.illuminance;
    ui.add(egui::Slider::new(&mut lux, 0.0..=1e5).text("illuminance (lx)").logarithmic(true));
    if lux != sun.illuminance {
        sun.illuminance = lux;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disk light 4 units above the origin, facing down.
    fn main_light() -> LightParams {
        LightParams {
            position: Vec3::new(0.0, 4.0, 0.0),
            direction: Vec3::NEG_Y,
            radius: 0.5,
            intensity: 1e6,
            color: [1.0; 3],
            method: Default::default(),
            kind: crate::state::LightKind::FinLight,
            sun_angle: crate::state::DEFAULT_SUN_ANGLE,
            illuminance: crate::state::DEFAULT_ILLUMINANCE,
            rect_aspect: crate::state::DEFAULT_RECT_ASPECT,
        }
    }

    #[test]
    fn new_lights_sit_apart_facing_like_the_main_light_and_stay_finite() {
        let params = main_light();
        let (a, ta) = new_light(&params, 0);
        let (_, tb) = new_light(&params, 1);
        assert!(ta.translation.distance(params.position) >= 0.5 && ta.translation.distance(tb.translation) > 0.1);
        assert!((ta.forward().as_vec3() - Vec3::NEG_Y).length() < 1e-5);
        assert_eq!((a.radius, a.intensity), (0.5, 1e6));
        // A degenerate main light (zero direction, NaN-free but zero) still gives a finite light.
        let (_, t) = new_light(&LightParams { direction: Vec3::ZERO, radius: -1.0, ..params }, 3);
        assert!(t.translation.is_finite() && t.rotation.is_finite());
    }

    #[test]
    fn new_point_lights_are_spheres_of_the_main_lights_radius_and_power_apart_from_it() {
        let params = main_light();
        let (p, t) = new_point(&params, 0);
        assert_eq!((p.radius, p.intensity), (0.5, 1e6));
        assert!(p.shadow_maps_enabled, "the user's own setting: fin shadows turn the cube map off, not the light");
        assert!(t.translation.distance(params.position) >= 0.5 && t.translation.is_finite());
        let (bad, t) = new_point(&LightParams { radius: -1.0, intensity: f32::NEG_INFINITY, ..params }, 2);
        assert!(bad.radius == 0.0 && bad.intensity == 0.0 && t.translation.is_finite());
    }

    #[test]
    fn new_rects_and_suns_are_valid_bevy_lights_for_any_main_light() {
        let params = LightParams { rect_aspect: 4.0, ..main_light() };
        let (rect, t) = new_rect(&params, 0);
        // The main disk's area at 4 : 1, a quarter of its power (as bright on its axis).
        let area = std::f32::consts::PI * 0.25;
        assert!((rect.width * rect.height - area).abs() < 1e-4 && (rect.width / rect.height - 4.0).abs() < 1e-3);
        assert_eq!(rect.intensity, 2.5e5);
        assert!((t.forward().as_vec3() - Vec3::NEG_Y).length() < 1e-5);
        // A zero-size main light: still a millimetre (Bevy divides by the area).
        let (tiny, _) = new_rect(&LightParams { radius: 0.0, ..params }, 1);
        assert!(tiny.width >= 1e-3 && tiny.height >= 1e-3);
        let (sun, disk, t) = new_sun(&params, 0);
        assert_eq!(sun.illuminance, crate::state::DEFAULT_ILLUMINANCE);
        assert!((disk.angular_size - crate::state::DEFAULT_SUN_ANGLE).abs() < 1e-7);
        // Tilted from the main light, still shining downwards.
        let down = t.forward().as_vec3();
        assert!(down.y < -0.8 && (down - Vec3::NEG_Y).length() > 0.1, "{down}");
        let (_, bad_disk, bad) = new_sun(&LightParams { direction: Vec3::ZERO, sun_angle: f32::NAN, ..params }, 2);
        assert!(bad.rotation.is_finite() && bad_disk.angular_size == 0.0);
    }
}
