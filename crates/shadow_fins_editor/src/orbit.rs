//! Orbit camera: drag to turn around the focus, wheel to zoom, right-drag to
//! pan. Input over the panels belongs to the panels.

use bevy::{
    input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll},
    prelude::*,
};
use bevy_egui::input::EguiWantsInput;

/// An orbit around `focus` at `distance`, angles in radians.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    pub focus: Vec3,
    pub distance: f32,
    pub yaw: f32,
    pub pitch: f32,
}

impl OrbitCamera {
    /// The orbit that puts the camera at `position` looking at `focus`.
    pub fn looking_at(position: Vec3, focus: Vec3) -> Self {
        let offset = position - focus;
        let distance = offset.length().max(1e-3);
        Self { focus, distance, yaw: offset.x.atan2(offset.z), pitch: (offset.y / distance).clamp(-1.0, 1.0).asin() }
    }

    pub fn transform(&self) -> Transform {
        let offset = Vec3::new(self.yaw.sin() * self.pitch.cos(), self.pitch.sin(), self.yaw.cos() * self.pitch.cos())
            * self.distance;
        Transform::from_translation(self.focus + offset).looking_at(self.focus, Vec3::Y)
    }
}

pub(crate) fn build(app: &mut App) {
    app.add_systems(Update, (orbit_input, apply_orbit).chain());
}

fn orbit_input(
    buttons: Res<ButtonInput<MouseButton>>,
    keys: Res<ButtonInput<KeyCode>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    egui_input: Res<EguiWantsInput>,
    mut cameras: Query<(&mut OrbitCamera, &Transform)>,
) {
    if egui_input.wants_any_pointer_input() {
        return;
    }
    // Shift + drag belongs to the light gizmo.
    let shift = keys.any_pressed([KeyCode::ShiftLeft, KeyCode::ShiftRight]);
    for (mut orbit, transform) in &mut cameras {
        if buttons.pressed(MouseButton::Left) && !shift && motion.delta != Vec2::ZERO {
            orbit.yaw -= motion.delta.x * 0.005;
            orbit.pitch = (orbit.pitch + motion.delta.y * 0.005).clamp(-1.5, 1.5);
        }
        if buttons.pressed(MouseButton::Right) && motion.delta != Vec2::ZERO {
            let scale = orbit.distance * 0.0015;
            let pan = transform.right().as_vec3() * -motion.delta.x + transform.up().as_vec3() * motion.delta.y;
            orbit.focus += pan * scale;
        }
        if scroll.delta.y != 0.0 {
            orbit.distance = (orbit.distance * (1.0 - scroll.delta.y.clamp(-5.0, 5.0) * 0.1)).clamp(1e-3, 1e5);
        }
    }
}

fn apply_orbit(mut cameras: Query<(&OrbitCamera, &mut Transform), Changed<OrbitCamera>>) {
    for (orbit, mut transform) in &mut cameras {
        *transform = orbit.transform();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn looking_at_round_trips_the_camera_position() {
        let (position, focus) = (Vec3::new(3.0, 4.0, 4.5), Vec3::new(0.0, 0.3, 0.0));
        let orbit = OrbitCamera::looking_at(position, focus);
        assert!(orbit.transform().translation.distance(position) < 1e-4);
    }
}
