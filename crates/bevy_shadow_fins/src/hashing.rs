//! Hashing what has no `Hash`: floats by their bits, `RenderLayers` by its
//! layers — the pieces of every frame's signature (`frame/update.rs`,
//! `casters/mod.rs`).

use std::hash::{Hash, Hasher};

use bevy::camera::visibility::RenderLayers;

/// Hashes floats by their bits (`f32` has no `Hash`; `-0.0` and `0.0`, and
/// NaNs of different bits, hash apart: a signature errs towards a rebuild).
pub(crate) fn hash_floats(h: &mut impl Hasher, v: &[f32]) {
    for x in v {
        x.to_bits().hash(h);
    }
}

/// Hashes a `RenderLayers` (it has no `Hash`) by its layers.
pub(crate) fn hash_layers(layers: &RenderLayers, hasher: &mut impl Hasher) {
    layers.iter().count().hash(hasher);
    for layer in layers.iter() {
        layer.hash(hasher);
    }
}
