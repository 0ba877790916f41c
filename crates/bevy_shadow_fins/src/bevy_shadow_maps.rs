//! When a fin-shadowed Bevy light keeps Bevy's own shadow map as well.
//!
//! A fin-shadowed Bevy light's shadow map is off (`render/bevy_lights.rs`):
//! no double cost. But Bevy's lights are global — one shadow map serves every
//! camera — and two things still need Bevy's map:
//! - a 3D camera without [`FinShadowView`] (a minimap, a render-to-texture
//!   preview) shows Bevy's own shading, and must render exactly as it would
//!   without the plugin: the light shadowed by its Bevy shadow map;
//! - a mesh fin shadows cannot reach ([`FinReceivers`]: alpha-blended or
//!   transmissive, and forward-rendered opaque ones on a device that cannot
//!   bind the forward hook's fifth group) should get Bevy's hard shadow
//!   rather than none.
//!
//! While either holds, the map stays on (the cost is Bevy's shadow pass again,
//! and fin cameras sample Bevy's map a second time per pixel for `S`)
//! and the compositing pass replaces Bevy's shadow `S` of the light by `V` on
//! the pixels it reaches — `(V − S)` of Bevy's own contribution, `S` computed
//! by Bevy's own `fetch_*_shadow` — so a fin-shadowed camera shows the same
//! fin shadow either way. The decision is [`BevyShadowMapsKept`], recomputed
//! every frame (two counts); when it flips, every fin-shadowed Bevy light is
//! marked changed so that Bevy extracts it again with the user's
//! `shadow_maps_enabled`.

use bevy::{prelude::*, render::extract_resource::ExtractResource};

use crate::{
    frame::{FinFrames, LightShading},
    receivers::FinReceivers,
    settings::FinShadowView,
};

/// Why fin-shadowed Bevy lights keep Bevy's own shadow maps on too (see the
/// module docs): while [`kept`](Self::kept), each fin-shadowed Bevy light costs
/// its Bevy shadow pass as well as its fin passes.
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq, ExtractResource)]
pub struct BevyShadowMapsKept {
    /// Active 3D cameras without [`FinShadowView`]: they show the light with
    /// Bevy's shadow, as they would without the plugin.
    pub cameras_without_fin_view: usize,
    /// Meshes fin shadows cannot reach ([`FinReceivers`]): they get Bevy's hard
    /// shadow instead of none.
    pub unreached_receivers: usize,
}

impl BevyShadowMapsKept {
    /// Whether Bevy's own shadow maps of fin-shadowed lights stay on.
    pub fn kept(&self) -> bool {
        self.cameras_without_fin_view > 0 || self.unreached_receivers > 0
    }
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<BevyShadowMapsKept>().add_systems(
        PostUpdate,
        decide_bevy_shadow_maps
            .after(crate::receivers::count_unreached_receivers)
            .after(crate::frame::update::FinFramesUpdate),
    );
}

#[allow(clippy::type_complexity)]
fn decide_bevy_shadow_maps(
    frames: Res<FinFrames>,
    receivers: Res<FinReceivers>,
    forward: Option<Res<crate::FinForwardShading>>,
    cameras: Query<&Camera, (With<Camera3d>, Without<FinShadowView>)>,
    // A RectLight has no Bevy map.
    mut lights: Query<(Option<&mut SpotLight>, Option<&mut DirectionalLight>, Option<&mut PointLight>)>,
    mut kept: ResMut<BevyShadowMapsKept>,
) {
    let now = BevyShadowMapsKept {
        cameras_without_fin_view: cameras.iter().filter(|c| c.is_active).count(),
        unreached_receivers: receivers.unreached(forward.is_some_and(|f| f.0)),
    };
    if *kept == now {
        return;
    }
    let flipped = kept.kept() != now.kept();
    *kept = now;
    if !flipped {
        return;
    }
    if now.kept() && frames.0.iter().any(|f| matches!(f.shading, LightShading::Bevy { .. })) {
        debug!(
            "fin shadows: Bevy's own shadow maps stay on for fin-shadowed lights ({} cameras without FinShadowView, \
             {} meshes fin shadows cannot reach; see BevyShadowMapsKept)",
            now.cameras_without_fin_view, now.unreached_receivers
        );
    }
    for frame in &frames.0 {
        if !matches!(frame.shading, LightShading::Bevy { .. }) {
            continue;
        }
        // Marked changed, Bevy extracts the light again with the user's own
        // shadow setting; `render/bevy_lights.rs` then leaves it or turns it off.
        if let Ok((spot, sun, point)) = lights.get_mut(frame.light) {
            if let Some(mut spot) = spot {
                spot.set_changed();
            }
            if let Some(mut sun) = sun {
                sun.set_changed();
            }
            if let Some(mut point) = point {
                point.set_changed();
            }
        }
    }
}
