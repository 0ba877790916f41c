//! The light and the frame every path of it works in (GPU, CPU, coverage):
//! the reference plane `L0`, the map window, and the widest penumbra the
//! budget plans for.

use bevy::prelude::*;
use shadow_fins::{
    light::{Light, LightFrame},
    oracle::MapRegion,
    scene::{LightSpaceScene, Scene},
};

/// A light and the frame every path of it (GPU, CPU, coverage) works in.
#[derive(Debug, Clone, Copy)]
pub(crate) struct InFrame {
    pub light: Light,
    pub frame: LightFrame,
    /// The diagonal of everything drawn, and its box.
    pub extent: f32,
    pub scene_box: (Vec3, Vec3),
    /// The part of map space the maps need cover at most (a sun's view fit,
    /// `sun_fit`); `None`: all the casters.
    pub map_window: Option<(Vec2, Vec2)>,
    /// `L0` when the frame fixes it (a sun fitted to the views: the deepest
    /// point of what the window can show, `sun_fit::window_frame`); `None`:
    /// the deepest receiver, found from the geometry.
    pub reference_depth: Option<f32>,
}

impl InFrame {
    /// The scene in this frame, its reference plane `L0` past every receiver:
    /// the scene's own and `receiver_bound` (meshes drawn but not readable),
    /// or the window's deepest point for a sun fitted to the views.
    pub fn light_space(&self, scene: &Scene, receiver_bound: impl Iterator<Item = Vec3>) -> LightSpaceScene {
        let mut ls = LightSpaceScene::in_frame(scene, self.light, self.frame, self.extent);
        match self.reference_depth {
            Some(l0) => ls.reference_depth = l0,
            None => ls.cover_receivers(receiver_bound.map(|p| self.frame.to_frame(p))),
        }
        ls
    }

    /// An estimate of the widest penumbra's half-width in texels of maps at
    /// `resolution`, for the budget's choice between resolution and layers
    /// (`budget::MIN_PENUMBRA_TEXELS`). The sun's: `tan θ` times the scene
    /// box's depth along it, over the map window's (or the box's footprint's)
    /// texel. A disk's widest penumbra comes from the casters nearest to it,
    /// which only the GPU extraction finds: unknown (`INFINITY`).
    pub fn widest_penumbra_texels(&self, resolution: u32) -> f32 {
        let shadow_fins::light::Projection::Orthographic { tan_angle } = self.frame.projection else {
            return f32::INFINITY;
        };
        let corners = crate::casters::reach::box_corners(self.scene_box).map(|c| self.frame.to_frame(c));
        let (flo, fhi) = corners.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let (mut mlo, mut mhi) = (flo.truncate(), fhi.truncate());
        if let Some((wlo, whi)) = self.map_window {
            (mlo, mhi) = (mlo.max(wlo), mhi.min(whi));
        }
        let texel = (mhi - mlo).max_element() / resolution.max(1) as f32;
        // A frame fixed at the views' window casts fins no deeper than its L0.
        let width = tan_angle * self.reference_depth.unwrap_or(fhi.z - flo.z);
        if texel > 0.0 && width.is_finite() { width / texel } else { f32::INFINITY }
    }

    /// The square of maps at `resolution` over `bounds` (map space), within
    /// the map window and a perspective map's angle limit.
    pub fn covering(&self, bounds: impl Iterator<Item = (Vec2, Vec2)>, resolution: u32) -> MapRegion {
        let limit = self.frame.map_limit(shadow_fins::oracle::RASTER_MAP_LIMIT);
        let (lo, hi) = self.map_window.unwrap_or((Vec2::NEG_INFINITY, Vec2::INFINITY));
        MapRegion::covering_within(bounds, resolution, (lo.max(Vec2::splat(-limit)), hi.min(Vec2::splat(limit))))
    }
}
