//! Orbit camera: drag to turn around the focus, wheel to zoom, right-drag to
//! pan, W/A/S/D (and Q/E down/up) to walk the focus — into a room and
//! around it. Input over the panels belongs to the panels.

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
    /// The scene's size: zoom is clamped to `[10⁻⁴, 10²]` of it and walking
    /// covers a tenth of it per second at least, so a millimetre model and a
    /// kilometre terrain handle alike.
    pub scale: f32,
}

impl OrbitCamera {
    /// The orbit that puts the camera at `position` looking at `focus`.
    pub fn looking_at(position: Vec3, focus: Vec3) -> Self {
        let offset = position - focus;
        let distance = offset.length().max(1e-3);
        Self {
            focus,
            distance,
            yaw: offset.x.atan2(offset.z),
            pitch: (offset.y / distance).clamp(-1.0, 1.0).asin(),
            scale: distance,
        }
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
    time: Res<Time>,
    buttons: Res<ButtonInput<MouseButton>>,
    keys: Res<ButtonInput<KeyCode>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    egui_input: Res<EguiWantsInput>,
    mut cameras: Query<(&mut OrbitCamera, &Transform)>,
) {
    if !egui_input.wants_any_keyboard_input() {
        for (mut orbit, transform) in &mut cameras {
            let step = walk(&keys, transform) * orbit.walking_speed() * time.delta_secs();
            if step != Vec3::ZERO {
                orbit.focus += step;
            }
        }
    }
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
            let (near, far) = orbit.zoom_range();
            orbit.distance = (orbit.distance * (1.0 - scroll.delta.y.clamp(-5.0, 5.0) * 0.1)).clamp(near, far);
        }
    }
}

impl OrbitCamera {
    /// The closest and farthest the camera may zoom.
    pub fn zoom_range(&self) -> (f32, f32) {
        let scale = if self.scale.is_finite() && self.scale > 0.0 { self.scale } else { 1.0 };
        (scale * 1e-4, scale * 1e2)
    }

    /// Focus speed of the walking keys, units per second: the orbit's
    /// distance (a close look walks slowly), at least a tenth of the scene.
    pub fn walking_speed(&self) -> f32 {
        self.distance.max(self.scale * 0.1)
    }
}

/// The walking direction the held keys ask for, in the camera's frame
/// flattened onto the ground (W/S forward and back, A/D sideways, Q/E down
/// and up), of length 1 or 0.
fn walk(keys: &ButtonInput<KeyCode>, camera: &Transform) -> Vec3 {
    let forward = camera.forward().as_vec3().with_y(0.0).normalize_or_zero();
    let right = camera.right().as_vec3().with_y(0.0).normalize_or_zero();
    let mut d = Vec3::ZERO;
    for (key, dir) in [
        (KeyCode::KeyW, forward),
        (KeyCode::KeyS, -forward),
        (KeyCode::KeyD, right),
        (KeyCode::KeyA, -right),
        (KeyCode::KeyE, Vec3::Y),
        (KeyCode::KeyQ, Vec3::NEG_Y),
    ] {
        if keys.pressed(key) {
            d += dir;
        }
    }
    d.normalize_or_zero()
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

    #[test]
    fn zoom_and_walking_follow_the_scenes_scale() {
        for scale in [1e-3_f32, 1.0, 1e3] {
            let orbit = OrbitCamera { scale, ..OrbitCamera::looking_at(Vec3::splat(scale), Vec3::ZERO) };
            let (near, far) = orbit.zoom_range();
            assert!((near / scale - 1e-4).abs() < 1e-9 && (far / scale - 1e2).abs() < 1e-4, "{scale}: {near} {far}");
            assert!(orbit.walking_speed() >= scale * 0.1);
        }
        let broken = OrbitCamera { scale: f32::NAN, ..OrbitCamera::looking_at(Vec3::ONE, Vec3::ZERO) };
        assert_eq!(broken.zoom_range(), (1e-4, 1e2));
    }

    #[test]
    fn walking_keys_move_on_the_ground_plane_and_up() {
        let camera = Transform::from_xyz(0.0, 5.0, 5.0).looking_at(Vec3::ZERO, Vec3::Y);
        let mut keys = ButtonInput::<KeyCode>::default();
        keys.press(KeyCode::KeyW);
        assert!(walk(&keys, &camera).distance(Vec3::NEG_Z) < 1e-5, "W walks forward, level");
        keys.press(KeyCode::KeyS);
        assert_eq!(walk(&keys, &camera), Vec3::ZERO, "W and S cancel");
        keys.release_all();
        keys.press(KeyCode::KeyE);
        assert_eq!(walk(&keys, &camera), Vec3::Y);
    }
}
