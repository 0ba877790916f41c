//! The drop-in: a disk light with a radius, and every mesh gets soft shadows.
//! `cargo run --example minimal --features window`
use bevy::prelude::*;
use bevy_shadow_fins::{FinLight, FinShadowView, ShadowFinsPlugin};

fn main() {
    App::new().add_plugins((DefaultPlugins, ShadowFinsPlugin)).add_systems(Startup, setup).run();
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    let material = materials.add(StandardMaterial::default());
    commands.spawn((Mesh3d(meshes.add(Plane3d::default().mesh().size(10.0, 10.0))), MeshMaterial3d(material.clone())));
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::new(1.0, 1.0, 1.0))),
        MeshMaterial3d(material),
        Transform::from_xyz(0.0, 1.5, 0.0),
    ));
    // A disk of radius 0.5 at 4.5 units up, facing down.
    commands.spawn((
        FinLight { radius: 0.5, ..default() },
        Transform::from_xyz(0.3, 4.5, 0.2).looking_at(Vec3::ZERO, Vec3::Z),
    ));
    commands.spawn((
        Camera3d::default(),
        FinShadowView::default(),
        Transform::from_xyz(3.0, 4.0, 4.5).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}
