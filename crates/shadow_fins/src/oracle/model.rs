//! [`FinShadowModel`]: one scene under one light prepared for one method —
//! silhouettes, fins, the layer plan and the casters in map space — which
//! both evaluations (`analytic.rs`, `raster.rs`) read.

use glam::{Vec2, Vec3};

use super::{
    combine::{CombineParams, LayerTexel, combine_layers},
    extractor::{FinExtractor, near_depth},
    map_geometry::MapTriangle,
    settings::{FinSettings, Method},
};
use crate::{
    fins::{Fin, FinSide},
    layers::LayerPlan,
    light::LightFrame,
    receiver::Receiver,
    scene::{LightSpaceScene, Scene},
    silhouette::{NO_PATCH, SilhouetteEdge},
};

/// One scene under one light, prepared for one method.
pub struct FinShadowModel<'a> {
    pub light_space: &'a LightSpaceScene,
    pub method: Method,
    pub settings: FinSettings,
    pub silhouettes: Vec<SilhouetteEdge>,
    pub fins: Vec<Fin>,
    pub fin_layers: Vec<u32>,
    pub plan: LayerPlan,
    pub casters: Vec<MapTriangle>,
    /// Layer of each map caster.
    pub caster_layers: Vec<u32>,
    pub near: f32,
}

impl<'a> FinShadowModel<'a> {
    /// Extracts silhouettes and fins and plans layers as `method` asks.
    pub fn new(scene: &Scene, light_space: &'a LightSpaceScene, method: Method, settings: FinSettings) -> Self {
        let mut ex = FinExtractor::default();
        let layers = if method == Method::MultiLayer { settings.layers } else { 1 };
        ex.extract(scene, light_space, layers, settings.sub_layers);
        let keep = |f: &Fin| match method {
            Method::Hard => false,
            Method::OuterFins => f.side == FinSide::Outer,
            Method::SingleLayer | Method::MultiLayer => true,
        };
        let (fins, fin_layers): (Vec<Fin>, Vec<u32>) =
            ex.fins.iter().zip(&ex.fin_layers).filter(|(f, _)| keep(f)).map(|(f, l)| (*f, *l)).unzip();
        let near = near_depth(light_space);
        let perspective = light_space.frame.is_perspective();
        let (mut casters, mut caster_layers) = (Vec::new(), Vec::new());
        for (k, (tri, &patch)) in light_space.casters.iter().zip(&ex.face_patches).enumerate() {
            if patch != NO_PATCH {
                let cutout = light_space.cutout(k);
                for t in MapTriangle::clipped_with_cutout(tri, cutout, &light_space.frame, near, perspective) {
                    casters.push(t);
                    caster_layers.push(ex.patch_layers[patch as usize]);
                }
            }
        }
        Self {
            light_space,
            method,
            settings,
            silhouettes: ex.silhouettes,
            fins,
            fin_layers,
            plan: ex.plan,
            casters,
            caster_layers,
            near,
        }
    }

    pub fn frame(&self) -> &LightFrame {
        &self.light_space.frame
    }

    pub(super) fn combine_params(&self) -> CombineParams<'_> {
        CombineParams {
            frame: &self.light_space.frame,
            reference_depth: self.light_space.reference_depth,
            refinement: self.settings.refinement,
            overlap: self.settings.overlap,
        }
    }

    /// Receiver moved off its surface by `offset` along its normal.
    pub(super) fn lifted(&self, r: Receiver, offset: f32) -> Vec3 {
        r.position + r.normal * offset
    }

    /// Epsilon for self-shadowing at a receiver ([`crate::scene::surface_epsilon`]).
    pub fn surface_epsilon(&self, receiver: Receiver) -> f32 {
        crate::scene::surface_epsilon(receiver.position, self.light_space.extent)
    }

    /// Visibility from the layer texels at a receiver: `falloff(I)`.
    pub(super) fn visibility_from(&self, texels: &[LayerTexel], depth: f32, blocking_limit: f32) -> f32 {
        let i = combine_layers(texels, depth, blocking_limit, self.combine_params());
        self.settings.falloff.apply(i)
    }

    /// Shared tail of both evaluations: a receiver at or behind the light plane
    /// sees nothing of a one-sided disk.
    pub(super) fn behind_light(&self, p: Vec3) -> bool {
        !(p.z > self.near) || !p.is_finite()
    }

    /// Map coordinate of a frame point.
    #[inline]
    pub(super) fn map(&self, p: Vec3) -> Vec2 {
        self.light_space.frame.map(p)
    }
}
