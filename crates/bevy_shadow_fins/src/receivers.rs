//! Receivers of Bevy's forward passes, counted, and those fin shadows do not
//! reach said once.
//!
//! Fin shadows reach deferred opaque materials through the G-buffer (the
//! compositing pass) and forward opaque or alpha-masked `StandardMaterial`s
//! through the forward hook (`render/forward.rs`, on devices that bind five
//! groups). An alpha-blended or transmissive `StandardMaterial` is drawn
//! over pixels the visibility pass shaded for the surface behind it: there a
//! fin-shadowed Bevy light keeps Bevy's own hard shadow
//! (`bevy_shadow_maps.rs` keeps its map on while such meshes exist), and a
//! `FinLight` does not shine on any forward material. [`FinReceivers`] counts
//! such meshes (custom materials are not inspected), recounted only when a
//! material or a mesh's material changed.

use bevy::{
    light::NotShadowReceiver, material::OpaqueRendererMethod, pbr::DefaultOpaqueRendererMethod, prelude::*,
    reflect::tuple_struct::TupleStruct,
};

use crate::{frame::FinFrames, settings::NotFinShadowReceiver};

/// Meshes of Bevy's forward passes (see the module docs): the alpha-blended
/// and transmissive ones fin shadows do not reach — a documented limitation,
/// warned once when any exist while a light has fin shadows.
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FinReceivers {
    /// Opaque (or alpha-masked) meshes rendered forward: fin-shadowed by the
    /// forward hook where the device has it.
    pub forward: usize,
    /// Alpha-blended or transmissive meshes.
    pub blended: usize,
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<FinReceivers>().add_systems(PostUpdate, count_unreached_receivers);
}

impl FinReceivers {
    /// The meshes fin shadows do not reach: the blended ones, and the
    /// forward ones unless the forward hook is on (`FinForwardShading`).
    pub fn unreached(&self, forward_hook: bool) -> usize {
        self.blended + if forward_hook { 0 } else { self.forward }
    }

    /// Counts one mesh of `material` if the compositing pass cannot reach it
    /// (an unlit material receives no light, hence no shadow, either way).
    fn count(&mut self, material: &StandardMaterial, default_forward: bool) {
        if material.unlit {
            return;
        }
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
    changed: Query<
        (),
        Or<(
            Changed<MeshMaterial3d<StandardMaterial>>,
            Added<NotFinShadowReceiver>,
            Added<NotShadowReceiver>,
            Changed<InheritedVisibility>,
        )>,
    >,
    removed: (
        RemovedComponents<MeshMaterial3d<StandardMaterial>>,
        RemovedComponents<NotFinShadowReceiver>,
        RemovedComponents<NotShadowReceiver>,
    ),
    // Meshes that receive no shadow (opted out, hidden) do not count: they
    // would keep Bevy's maps on for nothing (`bevy_shadow_maps.rs`).
    meshes: Query<
        (&MeshMaterial3d<StandardMaterial>, Option<&InheritedVisibility>),
        (Without<NotFinShadowReceiver>, Without<NotShadowReceiver>),
    >,
    mut counted: ResMut<FinReceivers>,
    forward: Option<Res<crate::FinForwardShading>>,
    pending: Option<Res<crate::forward_hook::PbrFragment>>,
) {
    let material_changed = events.read().count() > 0;
    let (mut gone_material, mut gone_fin_marker, mut gone_marker) = removed;
    let removed = gone_material.read().count() + gone_fin_marker.read().count() + gone_marker.read().count() > 0;
    if !(material_changed || !changed.is_empty() || removed || default.is_changed()) {
        return;
    }
    // `DefaultOpaqueRendererMethod` keeps its method private; Reflect reads it.
    let default_forward = default
        .field(0)
        .and_then(|f| f.try_downcast_ref::<OpaqueRendererMethod>())
        .is_some_and(|m| *m == OpaqueRendererMethod::Forward);
    let mut now = FinReceivers::default();
    let drawn = meshes.iter().filter(|(_, v)| v.is_none_or(|v| v.get()));
    for material in drawn.filter_map(|(m, _)| materials.get(&m.0)) {
        now.count(material, default_forward);
    }
    if *counted != now {
        *counted = now;
    }
    // A hook still going in (its first frames) is counted as in: no warning.
    let hook = forward.is_some_and(|f| f.0) || pending.is_some();
    if !frames.0.is_empty() && now.unreached(hook) > 0 {
        warn_once!(
            "fin shadows: {} meshes get Bevy's hard shadow, not fin shadows: {} alpha-blended/transmissive{} \
             (see FinReceivers)",
            now.unreached(hook),
            now.blended,
            if hook {
                String::new()
            } else {
                format!(", {} forward opaque (this device has no forward hook)", now.forward)
            }
        );
    }
}
