//! The drop-in: Bevy's own lights with `FinShadows` — two spot lights with a
//! radius and a dim sun with a `SunDisk` — and every mesh gets physically
//! sized soft shadows from each.
//! `cargo run --example minimal --features window`
use bevy::prelude::*;
use bevy_shadow_fins::{FinShadowView, FinShadows, ShadowFinsPlugin};

fn main() {
    App::new()
        // No renderer setting: Bevy's forward materials (its default) and
        // deferred ones alike get fin shadows.
        .add_plugins((DefaultPlugins, ShadowFinsPlugin))
        .add_systems(Startup, setup)
        .run();
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    let material = materials.add(StandardMaterial::default());
    commands.spawn((Mesh3d(meshes.add(Plane3d::default().mesh().size(10.0, 10.0))), MeshMaterial3d(material.clone())));
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::new(1.0, 1.0, 1.0))),
        MeshMaterial3d(material),
        Transform::from_xyz(0.0, 1.5, 0.0),
    ));
    // Two spot lights: a warm one of radius 0.5 at 4.5 units up and a smaller
    // cool one to the side; each casts its own soft shadow.
    for (at, radius, color) in [
        (Vec3::new(0.3, 4.5, 0.2), 0.5, Color::srgb(1.0, 0.9, 0.8)),
        (Vec3::new(-3.0, 4.0, 1.0), 0.2, Color::srgb(0.7, 0.8, 1.0)),
    ] {
        commands.spawn((
            SpotLight { radius, color, intensity: 1_000_000.0, range: 20.0, outer_angle: 1.0, ..default() },
            FinShadows,
            Transform::from_translation(at).looking_at(Vec3::ZERO, Vec3::Z),
        ));
    }
    // The sun, 3° wide (six times the real one, for a visible penumbra).
    commands.spawn((
        DirectionalLight { illuminance: 2000.0, ..default() },
        bevy::light::SunDisk { angular_size: 3f32.to_radians(), intensity: 1.0 },
        FinShadows,
        Transform::default().looking_to(Vec3::new(0.4, -1.0, -0.3), Vec3::Y),
    ));
    commands.spawn((
        Camera3d::default(),
        FinShadowView::default(),
        Transform::from_xyz(3.0, 4.0, 4.5).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}
