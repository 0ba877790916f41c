//! # bevy_shadow_fins
//!
//! Soft shadows from a light with a size, by multi-layered shadow fins (Cai et
//! al. 2006) with this project's measured improvements (see `CHANGELOG.md`).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_shadow_fins::{FinLight, FinShadowView, ShadowFinsPlugin};
//!
//! fn main() {
//!     App::new().add_plugins((DefaultPlugins, ShadowFinsPlugin)).add_systems(Startup, setup).run();
//! }
//!
//! fn setup(mut commands: Commands) {
//!     commands.spawn((FinLight { radius: 0.5, ..default() }, Transform::from_xyz(0.0, 5.0, 0.0).looking_at(Vec3::ZERO, Vec3::Z)));
//!     commands.spawn((Camera3d::default(), Msaa::Off, FinShadowView::default()));
//! }
//! ```
//!
//! Every mesh with a `Mesh3d` casts and receives (opt out of casting with
//! [`NotFinShadowCaster`]); materials are unchanged.
//!
//! Stages, per frame and only when something moved or a setting changed:
//! 1. **fin extraction and layer assignment** on the CPU with the core crate
//!    (silhouettes, patches, fins, the 1024-bin histogram cut into layers), as
//!    the paper does;
//! 2. **penumbra maps** on the GPU: compute passes rasterise every layer's slab
//!    depth and its inner and outer fin extremes into one storage buffer, texel
//!    for texel the core's raster oracle;
//! 3. **visibility** per camera: a compute pass reads the depth and normal
//!    prepass and combines the layers (refinement, overlap rule, falloff) into
//!    the illuminance buffer, which [`FinShadowView::visibility_target`] can copy
//!    into an image (tests, the editor).

mod extract;
mod light;
mod render;

pub use extract::{FinFrame, FinFrameStats, FinSceneError};
pub use light::{FinLight, FinMethod, FinShadowSettings, FinShadowView, NotFinShadowCaster};
pub use shadow_fins;

use bevy::prelude::*;

/// Adds fin shadows. See the crate docs.
#[derive(Default)]
pub struct ShadowFinsPlugin;

impl Plugin for ShadowFinsPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<FinLight>()
            .register_type::<FinShadowSettings>()
            .register_type::<FinShadowView>()
            .register_type::<NotFinShadowCaster>();
        extract::build(app);
        render::build(app);
    }

    fn finish(&self, app: &mut App) {
        render::finish(app);
    }
}
