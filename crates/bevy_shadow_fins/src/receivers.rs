//! Receivers fin shadows do not reach, counted and said once.
//!
//! Fin shadows are applied to the G-buffer (see the crate docs for why), so
//! they reach deferred opaque materials only. A `StandardMaterial` rendered
//! forward (`OpaqueRendererMethod::Forward`, or `Auto` while the app's
//! default is forward), alpha-blended or transmissive is drawn by Bevy's
//! forward passes: there a fin-shadowed Bevy light keeps Bevy's own hard
//! shadow (`bevy_shadow_maps.rs` keeps its map on while such meshes exist)
//! and a `FinLight` does not shine at all. [`FinReceivers`] counts such meshes
//! (custom materials are not inspected), recounted only when a material or
//! a mesh's material changed.

use bevy::{
    material::OpaqueRendererMethod, pbr::DefaultOpaqueRendererMethod, prelude::*, reflect::tuple_struct::TupleStruct,
};

use crate::{extract::FinFrames, light::NotFinShadowReceiver};

/// Meshes whose `StandardMaterial` fin shadows cannot reach (see the module
/// docs): a documented limitation, warned once when any exist while a light
/// has fin shadows.
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FinReceivers {
    /// Opaque meshes rendered forward.
    pub forward: usize,
    /// Alpha-blended or transmissive meshes.
    pub blended: usize,
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<FinReceivers>().add_systems(PostUpdate, count_unreached_receivers);
}

impl FinReceivers {
    /// Counts one mesh of `material` if the compositing pass cannot reach it.
    fn count(&mut self, material: &StandardMaterial, default_forward: bool) {
        let blended = !matches!(material.alpha_mode, AlphaMode::Opaque | AlphaMode::Mask(_))
            || material.specular_transmission > 0.0
            || material.diffuse_transmission > 0.0;
        let forward = match material.opaque_render_method {
            OpaqueRendererMethod::Forward => true,
            OpaqueRendererMethod::Deferred => false,
            OpaqueRendererMethod::Auto => default_forward,
        };
        if blended {
            self.blended += 1;
        } else if forward {
            self.forward += 1;
        }
    }
}

#[allow(clippy::type_complexity)]
pub(crate) fn count_unreached_receivers(
    frames: Res<FinFrames>,
    default: Res<DefaultOpaqueRendererMethod>,
    materials: Res<Assets<StandardMaterial>>,
    mut events: MessageReader<AssetEvent<StandardMaterial>>,
    changed: Query<(), Or<(Changed<MeshMaterial3d<StandardMaterial>>, Added<NotFinShadowReceiver>)>>,
    removed: RemovedComponents<MeshMaterial3d<StandardMaterial>>,
    meshes: Query<&MeshMaterial3d<StandardMaterial>, Without<NotFinShadowReceiver>>,
    mut counted: ResMut<FinReceivers>,
) {
    let material_changed = events.read().count() > 0;
    if !(material_changed || !changed.is_empty() || !removed.is_empty() || default.is_changed()) {
        return;
    }
    // `DefaultOpaqueRendererMethod` keeps its method private; Reflect reads it.
    let default_forward = default
        .field(0)
        .and_then(|f| f.try_downcast_ref::<OpaqueRendererMethod>())
        .is_some_and(|m| *m == OpaqueRendererMethod::Forward);
    let mut now = FinReceivers::default();
    for material in meshes.iter().filter_map(|m| materials.get(&m.0)) {
        now.count(material, default_forward);
    }
    if *counted != now {
        *counted = now;
    }
    if !frames.0.is_empty() && (now.forward > 0 || now.blended > 0) {
        warn_once!(
            "fin shadows: {} forward-rendered and {} alpha-blended/transmissive meshes get Bevy's hard shadow, \
             not fin shadows (fin shadows reach deferred opaque materials: insert \
             DefaultOpaqueRendererMethod::deferred() for every opaque material; see FinReceivers)",
            now.forward,
            now.blended
        );
    }
}
