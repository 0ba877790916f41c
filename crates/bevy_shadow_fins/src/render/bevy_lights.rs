//! Bevy's own lights with fin shadows: their Bevy shadow map (and contact
//! shadows) are off while fin shadows are on — no double GPU cost —, without
//! touching the user's light, unless a camera without fin shadows or a
//! receiver fin shadows cannot reach still needs them (`bevy_shadow_maps.rs`). (Bevy's CPU-side shadow culling for the light still runs;
//! volumetric light needs Bevy's shadow map, so a `VolumetricLight` loses its
//! shafts while fin-shadowed.)
//!
//! Bevy's `extract_lights` copies a light into the render world only when it
//! changed; this system then clears `shadow_maps_enabled` on the extracted
//! copy of every fin-shadowed Bevy light, before Bevy's `prepare_lights`
//! allocates shadow maps. The main world marks a light changed when it stops
//! being fin-shadowed (`frame/update.rs`) and when Bevy's maps start or stop being
//! kept (`bevy_shadow_maps.rs`), so Bevy extracts it again with the user's
//! own setting.

use bevy::{
    pbr::{ExtractedDirectionalLight, ExtractedPointLight},
    prelude::*,
    render::{Render, RenderApp, RenderSystems},
};

use crate::{
    BevyShadowMapsKept,
    frame::{FinFrames, LightShading},
};

pub(super) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app.add_systems(
        Render,
        bevy_shadow_maps_off.after(RenderSystems::ExtractCommands).before(RenderSystems::CreateViews),
    );
}

/// Spot and point lights are `ExtractedPointLight`s, suns `ExtractedDirectionalLight`s.
fn bevy_shadow_maps_off(
    frames: Res<FinFrames>,
    kept: Option<Res<BevyShadowMapsKept>>,
    mut lights: Query<&mut ExtractedPointLight>,
    mut suns: Query<&mut ExtractedDirectionalLight>,
) {
    // Kept for cameras without fin shadows or receivers fin shadows cannot reach
    // (`bevy_shadow_maps.rs`): the compositing pass replaces Bevy's shadow by V.
    if kept.is_some_and(|k| k.kept()) {
        return;
    }
    for frame in &frames.0 {
        let LightShading::Bevy { render_entity } = frame.shading else { continue };
        if let Ok(mut light) = lights.get_mut(render_entity)
            && (light.shadow_maps_enabled || light.contact_shadows_enabled)
        {
            light.shadow_maps_enabled = false;
            light.contact_shadows_enabled = false;
        }
        if let Ok(mut sun) = suns.get_mut(render_entity)
            && (sun.shadow_maps_enabled || sun.contact_shadows_enabled)
        {
            sun.shadow_maps_enabled = false;
            sun.contact_shadows_enabled = false;
        }
    }
}
