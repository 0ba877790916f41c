//! More lights: Bevy `SpotLight`s with `FinShadows` added beside the editor's
//! main light, each with its radius, intensity, cone and layers edited live,
//! removed with one click; their counts come from each light's
//! `FinLightStats`. (The main light, the ground truth and the error views stay
//! with the main light.)

use bevy::prelude::*;
use bevy_egui::{EguiContexts, EguiPrimaryContextPass, egui};
use bevy_shadow_fins::{FinLightStats, FinShadowSettings, FinShadows, MAX_FIN_LIGHTS};

use crate::scene::{EditorLight, LightParams};

/// Marks a light the "More lights" window added.
#[derive(Component)]
pub(crate) struct ExtraLight;

pub(crate) fn build(app: &mut App) {
    app.add_systems(EguiPrimaryContextPass, lights_window);
}

/// A new spot light beside the main one: same size and power, shifted
/// sideways by a quarter of its height above the origin so its shadow differs.
fn new_light(params: &LightParams, index: usize) -> (SpotLight, Transform) {
    let direction = params.direction.try_normalize().unwrap_or(Vec3::NEG_Y);
    let (u, v) = direction.any_orthonormal_pair();
    let a = index as f32 * 2.4;
    let offset = (u * a.cos() + v * a.sin()) * (params.position.length() * 0.25).max(0.5);
    let spot = SpotLight {
        intensity: params.intensity.max(0.0),
        radius: params.radius.max(0.0),
        range: 1000.0,
        outer_angle: 1.0,
        inner_angle: 0.6,
        ..default()
    };
    (spot, LightParams { position: params.position + offset, ..*params }.transform())
}

#[allow(clippy::type_complexity)]
fn lights_window(
    mut contexts: EguiContexts,
    mut commands: Commands,
    params: Res<LightParams>,
    main: Query<&FinShadowSettings, (With<EditorLight>, Without<ExtraLight>)>,
    mut extras: Query<(Entity, &mut SpotLight, &mut FinShadowSettings, &FinLightStats), With<ExtraLight>>,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    // Over the 3D view, clear of the side panels.
    egui::Window::new("More lights").default_open(false).default_pos(egui::pos2(300.0, 12.0)).show(&ctx, |ui| {
        ui.small("Bevy SpotLights with FinShadows, shadowed together with the main light.");
        let count = extras.iter().count();
        let room = count + 1 < MAX_FIN_LIGHTS;
        if ui.add_enabled(room, egui::Button::new("add a spot light")).clicked() {
            let (spot, transform) = new_light(&params, count);
            let settings = main.single().copied().unwrap_or_default();
            commands.spawn((ExtraLight, spot, FinShadows, settings, transform, Name::new("extra spot light")));
        }
        let mut lights: Vec<_> = extras.iter_mut().collect();
        lights.sort_by_key(|l| l.0);
        for (k, (entity, mut spot, mut settings, stats)) in lights.into_iter().enumerate() {
            ui.separator();
            ui.horizontal(|ui| {
                ui.label(format!("spot {}", k + 1));
                if ui.button("remove").clicked() {
                    commands.entity(entity).despawn();
                }
            });
            let mut s = *spot;
            ui.add(
                egui::Slider::new(&mut s.radius, 0.0..=5.0).text("radius").logarithmic(true).smallest_positive(1e-3),
            );
            ui.add(egui::Slider::new(&mut s.intensity, 0.0..=1e8).text("intensity (lm)").logarithmic(true));
            ui.add(egui::Slider::new(&mut s.outer_angle, 0.05..=1.5).text("cone (rad)"));
            s.inner_angle = s.inner_angle.min(s.outer_angle);
            let edited = (s.radius, s.intensity, s.outer_angle, s.inner_angle);
            if edited != (spot.radius, spot.intensity, spot.outer_angle, spot.inner_angle) {
                *spot = s;
            }
            let mut layers = settings.layers;
            ui.add(egui::Slider::new(&mut layers, 1..=32).text("layers"));
            if layers != settings.layers {
                settings.layers = layers;
            }
            let st = stats.0;
            ui.small(format!(
                "{} silhouettes, {} fins, {} layers at {}²",
                st.silhouettes, st.fins, st.layers, st.map_resolution
            ));
            if let Some(why) = st.degraded {
                ui.colored_label(egui::Color32::YELLOW, why.to_string());
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_lights_sit_apart_facing_like_the_main_light_and_stay_finite() {
        let params = LightParams {
            position: Vec3::new(0.0, 4.0, 0.0),
            direction: Vec3::NEG_Y,
            radius: 0.5,
            intensity: 1e6,
            color: [1.0; 3],
            method: Default::default(),
            kind: crate::scene::LightKind::FinLight,
            sun_angle: crate::scene::DEFAULT_SUN_ANGLE,
            illuminance: crate::scene::DEFAULT_ILLUMINANCE,
            rect_aspect: crate::scene::DEFAULT_RECT_ASPECT,
        };
        let (a, ta) = new_light(&params, 0);
        let (_, tb) = new_light(&params, 1);
        assert!(ta.translation.distance(params.position) >= 0.5 && ta.translation.distance(tb.translation) > 0.1);
        assert!((ta.forward().as_vec3() - Vec3::NEG_Y).length() < 1e-5);
        assert_eq!((a.radius, a.intensity), (0.5, 1e6));
        // A degenerate main light (zero direction, NaN-free but zero) still gives a finite light.
        let (_, t) = new_light(&LightParams { direction: Vec3::ZERO, radius: -1.0, ..params }, 3);
        assert!(t.translation.is_finite() && t.rotation.is_finite());
    }
}
