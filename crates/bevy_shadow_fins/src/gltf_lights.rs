//! Fin shadows for the lights of a glTF as Bevy 0.19 loads them
//! (`KHR_lights_punctual` → `SpotLight`, `DirectionalLight`, `PointLight`).
//!
//! A punctual light has no size in glTF, and Bevy 0.19's loader sets a spot
//! or point light's `radius` to its `range` (`bevy_gltf` `loader/mod.rs`:
//! `radius: light.range().unwrap_or(0.0)`), which would give a 20 m light a
//! 20 m disk. [`give_gltf_lights_fin_shadows`] puts the radius right: the
//! light's `extras` `"radius"` (this project's convention, written by
//! `shadow-fins-lab make-assets`), else the caller's fallback.

use bevy::{gltf::GltfExtras, prelude::*};

use crate::{FinShadowSettings, FinShadows};

/// The physical radius a glTF light's `extras` JSON declares (`{"radius": r}`),
/// if it is a finite number ≥ 0.
pub fn gltf_light_radius(extras: &str) -> Option<f32> {
    let value: serde_json::Value = serde_json::from_str(extras).ok()?;
    let radius = value.get("radius")?.as_f64()? as f32;
    (radius.is_finite() && radius >= 0.0).then_some(radius)
}

/// What [`give_gltf_lights_fin_shadows`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GltfLightsAdopted {
    /// Spot and directional lights that now have [`FinShadows`].
    pub lights: Vec<Entity>,
    /// Point lights left with Bevy's own shadows (not modelled by fins yet).
    pub point_lights: Vec<Entity>,
}

/// Gives every `SpotLight` and `DirectionalLight` under `root` (the entity
/// a glTF scene was spawned on; itself included) [`FinShadows`] with
/// `settings`, and sets each spot or point light's radius to its `extras`
/// radius, else to `fallback_radius` (clamped ≥ 0) where Bevy's loader set it
/// to the range. A directional light keeps its `SunDisk` if it has one (else
/// fins use the Earth's sun, as Bevy draws it).
pub fn give_gltf_lights_fin_shadows(
    world: &mut World,
    root: Entity,
    settings: FinShadowSettings,
    fallback_radius: f32,
) -> GltfLightsAdopted {
    let fallback_radius = if fallback_radius.is_finite() { fallback_radius.max(0.0) } else { 0.0 };
    let under_root: Vec<Entity> = std::iter::once(root).chain(descendants(world, root)).collect();
    let mut adopted = GltfLightsAdopted::default();
    for entity in under_root {
        let extras = world.get::<GltfExtras>(entity).and_then(|e| gltf_light_radius(&e.value));
        let mut e = world.entity_mut(entity);
        let radius = |loaded: f32, range: f32| extras.unwrap_or(if loaded == range { fallback_radius } else { loaded });
        if let Some(mut spot) = e.get_mut::<SpotLight>() {
            spot.radius = radius(spot.radius, spot.range);
            e.insert((FinShadows, settings));
            adopted.lights.push(entity);
        } else if e.contains::<DirectionalLight>() {
            e.insert((FinShadows, settings));
            adopted.lights.push(entity);
        } else if let Some(mut point) = e.get_mut::<PointLight>() {
            point.radius = radius(point.radius, point.range);
            adopted.point_lights.push(entity);
        }
    }
    adopted
}

fn descendants(world: &mut World, root: Entity) -> Vec<Entity> {
    let mut children = world.query::<&Children>();
    let (mut out, mut stack) = (vec![], vec![root]);
    while let Some(e) = stack.pop() {
        if let Ok(c) = children.get(world, e) {
            out.extend(c.iter());
            stack.extend(c.iter());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lights_radius_is_read_from_its_extras_and_nonsense_is_none() {
        assert_eq!(gltf_light_radius(r#"{"radius": 0.4}"#), Some(0.4));
        assert_eq!(gltf_light_radius(r#"{"radius": 0}"#), Some(0.0));
        for bad in [r#"{"radius": -1}"#, r#"{"radius": "big"}"#, r#"{"size": 1}"#, "not json", r#"{"radius": 1e400}"#] {
            assert_eq!(gltf_light_radius(bad), None, "{bad}");
        }
    }

    #[test]
    fn lights_under_the_root_get_fin_shadows_and_a_radius_that_is_not_their_range() {
        let mut world = World::new();
        let root = world.spawn_empty().id();
        // As Bevy's loader spawns them: radius = range.
        let spot = world.spawn((SpotLight { range: 20.0, radius: 20.0, ..default() }, ChildOf(root))).id();
        let named = world
            .spawn((
                SpotLight { range: 20.0, radius: 20.0, ..default() },
                GltfExtras { value: r#"{"radius":0.4}"#.into() },
                ChildOf(root),
            ))
            .id();
        let sun = world.spawn((DirectionalLight::default(), ChildOf(spot))).id();
        let point = world.spawn((PointLight { range: 5.0, radius: 5.0, ..default() }, ChildOf(root))).id();
        let outside = world.spawn(SpotLight { range: 20.0, radius: 20.0, ..default() }).id();
        let adopted = give_gltf_lights_fin_shadows(&mut world, root, FinShadowSettings::default(), 0.25);
        assert_eq!(world.get::<SpotLight>(spot).unwrap().radius, 0.25);
        assert_eq!(world.get::<SpotLight>(named).unwrap().radius, 0.4);
        assert_eq!(world.get::<PointLight>(point).unwrap().radius, 0.25);
        for e in [spot, named, sun] {
            assert!(world.get::<FinShadows>(e).is_some() && adopted.lights.contains(&e));
        }
        assert_eq!(adopted.point_lights, vec![point]);
        assert!(world.get::<FinShadows>(outside).is_none());
        assert_eq!(world.get::<SpotLight>(outside).unwrap().radius, 20.0);
    }
}
