//! Exact evaluation: the centre ray of each receiver against casters and fins.

use glam::Vec2;

use super::{combine::LayerTexel, model::FinShadowModel};
use crate::cell_grid::CellGrid;
use crate::receiver::Receiver;

/// Perspective map coordinates beyond this (about 89° off the light axis) are
/// clamped when indexing; geometry out there is seen edge-on by the light.
const MAP_LIMIT: f32 = 64.0;

/// A uniform grid over map space listing, per cell, the casters and fins whose
/// bounds touch it. Answers visibility exactly at any map point.
pub struct AnalyticIndex<'m, 'a> {
    model: &'m FinShadowModel<'a>,
    /// Ids below `casters.len()` are casters, the rest fins.
    grid: CellGrid,
}

impl<'m, 'a> AnalyticIndex<'m, 'a> {
    pub fn new(model: &'m FinShadowModel<'a>) -> Self {
        let limit = model.frame().map_limit(MAP_LIMIT);
        let bounds: Vec<(Vec2, Vec2)> = model
            .casters
            .iter()
            .map(|c| c.bounds())
            .chain(model.fins.iter().map(|f| f.bounds()))
            .map(|(lo, hi)| (lo.max(Vec2::splat(-limit)), hi.min(Vec2::splat(limit))))
            .collect();
        let (mut min, mut max) =
            bounds.iter().fold((Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)), |(a, b), (lo, hi)| {
                (a.min(*lo), b.max(*hi))
            });
        if !(min.x <= max.x && min.y <= max.y) {
            (min, max) = (Vec2::ZERO, Vec2::ONE);
        }
        let size = (max - min).max(Vec2::splat(1e-12));
        let n = (bounds.len() as f32).sqrt().clamp(1.0, 1024.0);
        let aspect = (size.x / size.y).clamp(1e-3, 1e3).sqrt();
        let dims = [((n * aspect).ceil() as usize).clamp(1, 2048), ((n / aspect).ceil() as usize).clamp(1, 2048)];
        // Bounds clamped empty (wholly past the limit) are not binned.
        let binned: Vec<Option<(Vec2, Vec2)>> =
            bounds.iter().map(|&(lo, hi)| (!(lo.x > hi.x || lo.y > hi.y)).then_some((lo, hi))).collect();
        Self { model, grid: CellGrid::build(min, size, dims, &binned) }
    }

    /// Every layer's texel at map point `q`.
    pub fn layer_texels(&self, q: Vec2, out: &mut Vec<LayerTexel>) {
        out.clear();
        out.resize(self.model.plan.len(), LayerTexel::EMPTY);
        let m = self.model;
        let perspective = m.frame().is_perspective();
        for &id in self.grid.cell(q) {
            let id = id as usize;
            if let Some(tri) = m.casters.get(id) {
                if tri.contains(q) && tri.opaque_at(q, &m.light_space.masks) {
                    let d = tri.depth_at(q);
                    if d > m.near {
                        out[m.caster_layers[id] as usize].add_caster(d);
                    }
                }
            } else {
                let f = id - m.casters.len();
                if let Some(s) = m.fins[f].sample(q, perspective) {
                    out[m.fin_layers[f] as usize].add_fin(m.fins[f].side, s);
                }
            }
        }
    }

    /// Visibility of the disk from a receiver, `V ∈ [0, 1]`.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let mut texels = Vec::new();
        self.visibility_with(receiver, &mut texels)
    }

    /// [`Self::visibility`] reusing a buffer.
    pub fn visibility_with(&self, receiver: Receiver, texels: &mut Vec<LayerTexel>) -> f32 {
        let m = self.model;
        let eps = m.surface_epsilon(receiver);
        let p = m.lifted(receiver, eps);
        if m.behind_light(p) {
            return 0.0;
        }
        self.layer_texels(m.map(p), texels);
        let slack = if receiver.normal == glam::Vec3::ZERO { eps } else { 0.0 };
        m.visibility_from(texels, p.z, p.z * (1.0 - 1e-6) - slack)
    }
}

impl<'a> FinShadowModel<'a> {
    /// Builds the map-space index for exact evaluation.
    pub fn analytic(&self) -> AnalyticIndex<'_, 'a> {
        AnalyticIndex::new(self)
    }
}
