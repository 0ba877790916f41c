//! Whether the forward hook is in Bevy's forward shader yet: main-world
//! resources that `render/forward.rs` sets and the main world's bookkeeping
//! reads (`bevy_shadow_maps.rs`, `receivers.rs`), kept below both.

use bevy::prelude::*;

/// Whether fin shadows reach forward materials: the device binds at least
/// five groups and the hook is in Bevy's `pbr_fragment` shader. Read by
/// `bevy_shadow_maps.rs`: until then forward opaque meshes keep Bevy's maps on.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Eq)]
pub struct FinForwardShading(pub bool);

/// Bevy's `pbr_fragment` shader, kept so it can be given the hook's import;
/// present while the hook is not in it yet (nor given up on).
#[derive(Resource)]
pub(crate) struct PbrFragment(pub(crate) Handle<Shader>);
