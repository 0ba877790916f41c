//! Clicking into the scene: Ctrl + click drops the light over the surface
//! clicked (facing it, under a ceiling when it is one), Alt + click makes
//! the clicked point the orbit's focus (to look around inside a room).
//! Rays are traced against the loaded scene's triangles — what the ground
//! truth traces — through the core's BVH, built once per scene.

use std::sync::Arc;

use bevy::{prelude::*, window::PrimaryWindow};
use bevy_egui::input::EguiWantsInput;
use shadow_fins::bvh::Bvh;

use crate::{
    orbit::OrbitCamera,
    state::{EditorCamera, LightParams, LoadedScene},
};

pub(crate) fn build(app: &mut App) {
    app.add_systems(Update, pick);
}

/// The loaded scene's world triangles and their BVH.
struct Picker {
    generation: u64,
    bvh: Arc<Bvh>,
}

impl Picker {
    fn new(scene: &LoadedScene) -> Self {
        let triangles: Vec<[Vec3; 3]> = scene
            .scene
            .objects
            .iter()
            .flat_map(|o| o.mesh.triangles().map(|t| t.map(|p| o.transform.transform_point3(p))))
            .collect();
        let bvh = Arc::new(Bvh::new(&triangles));
        Self { generation: scene.generation, bvh }
    }

    /// The first surface along the ray: its point and its normal, turned to
    /// face the ray's origin.
    fn hit(&self, origin: Vec3, dir: Vec3) -> Option<(Vec3, Vec3)> {
        let hit = self.bvh.closest_hit(origin, dir, 0.0)?;
        let n = hit.normal.try_normalize()?;
        Some((origin + dir * hit.t, if n.dot(dir) > 0.0 { -n } else { n }))
    }
}

/// Where a light dropped on the surface at `point` with normal `normal`
/// goes: off the surface by a quarter of the scene's size, or half the free
/// space in front of it if that is less (under a ceiling, inside a room),
/// facing the surface.
pub(crate) fn dropped_light(picker_free: Option<f32>, point: Vec3, normal: Vec3, extent: f32) -> (Vec3, Vec3) {
    let quarter = extent * 0.25;
    let height = picker_free.map_or(quarter, |free| (free * 0.5).min(quarter));
    (point + normal * height, -normal)
}

#[allow(clippy::too_many_arguments)]
fn pick(
    buttons: Res<ButtonInput<MouseButton>>,
    keys: Res<ButtonInput<KeyCode>>,
    egui_input: Res<EguiWantsInput>,
    window: Query<&Window, With<PrimaryWindow>>,
    mut camera: Query<(&Camera, &GlobalTransform, &mut OrbitCamera), With<EditorCamera>>,
    scene: Option<Res<LoadedScene>>,
    mut params: ResMut<LightParams>,
    mut picker: Local<Option<Picker>>,
) {
    let ctrl = keys.any_pressed([KeyCode::ControlLeft, KeyCode::ControlRight]);
    let alt = keys.any_pressed([KeyCode::AltLeft, KeyCode::AltRight]);
    let shift = keys.any_pressed([KeyCode::ShiftLeft, KeyCode::ShiftRight]);
    // Shift (+ Ctrl) + drag is the light gizmo's.
    if !buttons.just_pressed(MouseButton::Left) || !(ctrl || alt) || shift || egui_input.wants_any_pointer_input() {
        return;
    }
    let (Some(scene), Ok(window), Ok((camera, transform, mut orbit))) = (scene, window.single(), camera.single_mut())
    else {
        return;
    };
    let Some(ray) = window.cursor_position().and_then(|c| camera.viewport_to_world(transform, c).ok()) else { return };
    if picker.as_ref().is_none_or(|p| p.generation != scene.generation) {
        *picker = Some(Picker::new(&scene));
    }
    let picker = picker.as_ref().expect("built above");
    let Some((point, normal)) = picker.hit(ray.origin, *ray.direction) else { return };
    if ctrl {
        let lift = normal * scene.extent * 1e-4;
        let free = picker.hit(point + lift, normal).map(|(p, _)| p.distance(point));
        let (position, direction) = dropped_light(free, point, normal, scene.extent);
        params.position = position;
        params.direction = direction;
    } else {
        let eye = orbit.transform().translation;
        *orbit = OrbitCamera { scale: orbit.scale, ..OrbitCamera::looking_at(eye, point) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dropped_light_stays_under_a_low_ceiling_and_faces_the_surface() {
        // On a floor with a ceiling 1 above, in a scene 20 across: half-way up.
        let (p, d) = dropped_light(Some(1.0), Vec3::ZERO, Vec3::Y, 20.0);
        assert!((p.y - 0.5).abs() < 1e-6 && d == Vec3::NEG_Y, "{p} {d}");
        // In the open: a quarter of the scene above it.
        let (p, _) = dropped_light(None, Vec3::ZERO, Vec3::Y, 20.0);
        assert!((p.y - 5.0).abs() < 1e-6);
    }

    #[test]
    fn the_picker_finds_the_first_surface_and_turns_its_normal_to_the_viewer() {
        let mesh = shadow_fins::shapes::plane(2.0, 1);
        let object = shadow_fins::scene::SceneObject::new("floor", mesh, bevy::math::Affine3A::IDENTITY).unwrap();
        let scene = LoadedScene {
            name: "floor".into(),
            scene: Arc::new(shadow_fins::scene::Scene::new(vec![object])),
            generation: 1,
            extent: 2.0,
        };
        let picker = Picker::new(&scene);
        for (origin, up) in [(Vec3::new(0.1, 3.0, 0.2), 1.0), (Vec3::new(0.1, -3.0, 0.2), -1.0)] {
            let dir = (Vec3::new(0.1, 0.0, 0.2) - origin).normalize();
            let (point, normal) = picker.hit(origin, dir).expect("hits the floor");
            assert!(point.distance(Vec3::new(0.1, 0.0, 0.2)) < 1e-5 && normal == Vec3::Y * up, "{point} {normal}");
        }
        assert!(picker.hit(Vec3::new(5.0, 1.0, 0.0), Vec3::Y).is_none());
    }
}
