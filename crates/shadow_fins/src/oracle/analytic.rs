//! Exact evaluation: the centre ray of each receiver against casters and fins.

use glam::Vec2;

use super::{FinShadowModel, LayerTexel, Receiver};

/// Map coordinates beyond this (about 89° off the light axis) are clamped when
/// indexing; geometry out there is seen edge-on by the light.
const MAP_LIMIT: f32 = 64.0;

/// A uniform grid over map space listing, per cell, the casters and fins whose
/// bounds touch it. Answers visibility exactly at any map point.
pub struct AnalyticIndex<'m, 'a> {
    model: &'m FinShadowModel<'a>,
    min: Vec2,
    inv_cell: Vec2,
    dims: [usize; 2],
    /// CSR layout: items of cell `c` are `items[starts[c]..starts[c + 1]]`;
    /// ids below `casters.len()` are casters, the rest fins.
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl<'m, 'a> AnalyticIndex<'m, 'a> {
    pub fn new(model: &'m FinShadowModel<'a>) -> Self {
        let bounds: Vec<(Vec2, Vec2)> = model
            .casters
            .iter()
            .map(|c| c.bounds())
            .chain(model.fins.iter().map(|f| f.bounds()))
            .map(|(lo, hi)| (lo.max(Vec2::splat(-MAP_LIMIT)), hi.min(Vec2::splat(MAP_LIMIT))))
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
        let inv_cell = Vec2::new(dims[0] as f32, dims[1] as f32) / size;
        let cell_range = |lo: Vec2, hi: Vec2| {
            let a = ((lo - min) * inv_cell).floor();
            let b = ((hi - min) * inv_cell).floor();
            let clamp = |v: f32, d: usize| (v.max(0.0) as usize).min(d - 1);
            (clamp(a.x, dims[0]), clamp(b.x, dims[0]), clamp(a.y, dims[1]), clamp(b.y, dims[1]))
        };
        let mut counts = vec![0u32; dims[0] * dims[1] + 1];
        for &(lo, hi) in &bounds {
            if lo.x > hi.x || lo.y > hi.y {
                continue;
            }
            let (x0, x1, y0, y1) = cell_range(lo, hi);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    counts[y * dims[0] + x + 1] += 1;
                }
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut items = vec![0u32; *starts.last().unwrap() as usize];
        for (id, &(lo, hi)) in bounds.iter().enumerate() {
            if lo.x > hi.x || lo.y > hi.y {
                continue;
            }
            let (x0, x1, y0, y1) = cell_range(lo, hi);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = y * dims[0] + x;
                    items[fill[c] as usize] = id as u32;
                    fill[c] += 1;
                }
            }
        }
        Self { model, min, inv_cell, dims, starts, items }
    }

    /// Every layer's texel at map point `q`.
    pub fn layer_texels(&self, q: Vec2, out: &mut Vec<LayerTexel>) {
        out.clear();
        out.resize(self.model.plan.len(), LayerTexel::EMPTY);
        let c = (q - self.min) * self.inv_cell;
        if !(c.x >= 0.0 && c.y >= 0.0 && (c.x as usize) < self.dims[0] && (c.y as usize) < self.dims[1]) {
            return;
        }
        let cell = c.y as usize * self.dims[0] + c.x as usize;
        let m = self.model;
        let perspective = m.frame().is_perspective();
        for &id in &self.items[self.starts[cell] as usize..self.starts[cell + 1] as usize] {
            let id = id as usize;
            if let Some(tri) = m.casters.get(id) {
                if tri.contains(q) {
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
