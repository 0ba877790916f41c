//! Light-space maps at a finite resolution: what the GPU renders, texel for texel.
//!
//! Per layer `j` and texel, evaluated at the texel centre: the nearest caster
//! depth within the layer's slab, the minimum-weight inner fin and the
//! maximum-weight outer fin with their depths. Receivers look up the nearest
//! texel after a normal offset of one texel's world size (which bounds the depth
//! error of a surface across half a texel at any slope).

use glam::{Vec2, Vec3};

use super::{combine::LayerTexel, model::FinShadowModel};
use crate::receiver::Receiver;

/// Perspective map coordinates beyond this (about 83° off the light axis) are
/// not mapped.
pub const RASTER_MAP_LIMIT: f32 = 8.0;

/// The square of map space covered by the maps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapRegion {
    pub min: Vec2,
    /// Texel edge length in map units.
    pub texel: f32,
    pub resolution: u32,
}

impl MapRegion {
    /// The square of `resolution²` texels covering the union of `bounds`
    /// (map space), clamped to ±`limit` (`LightFrame::map_limit` of
    /// [`RASTER_MAP_LIMIT`]); the unit square when there is nothing to cover.
    pub fn covering(bounds: impl Iterator<Item = (Vec2, Vec2)>, resolution: u32, limit: f32) -> Self {
        Self::covering_within(bounds, resolution, (Vec2::splat(-limit), Vec2::splat(limit)))
    }

    /// [`Self::covering`] within any rectangle `window` of map space: a
    /// renderer fits a sun's maps to what its cameras see this way (casters
    /// outside still rasterise where they overlap the maps).
    pub fn covering_within(bounds: impl Iterator<Item = (Vec2, Vec2)>, resolution: u32, window: (Vec2, Vec2)) -> Self {
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for (a, b) in bounds {
            lo = lo.min(a);
            hi = hi.max(b);
        }
        lo = lo.max(window.0);
        hi = hi.min(window.1);
        if !(lo.x <= hi.x && lo.y <= hi.y) {
            (lo, hi) = (Vec2::ZERO, Vec2::ONE);
        }
        let size = (hi - lo).max_element().max(1e-9) * 1.001;
        let center = (lo + hi) * 0.5;
        Self { min: center - Vec2::splat(size * 0.5), texel: size / resolution as f32, resolution }
    }

    /// Map coordinate of a texel centre.
    #[inline]
    pub fn texel_center(&self, x: u32, y: u32) -> Vec2 {
        self.min + (Vec2::new(x as f32, y as f32) + 0.5) * self.texel
    }

    /// Nearest texel of a map point, if inside.
    #[inline]
    pub fn texel_of(&self, q: Vec2) -> Option<(u32, u32)> {
        let t = (q - self.min) / self.texel;
        let r = self.resolution as f32;
        (t.x >= 0.0 && t.y >= 0.0 && t.x < r && t.y < r).then(|| (t.x as u32, t.y as u32))
    }

    /// Inclusive texel range whose centres may lie in `[lo, hi]`.
    pub fn texel_range(&self, lo: Vec2, hi: Vec2) -> Option<(u32, u32, u32, u32)> {
        let a = ((lo - self.min) / self.texel - 0.5).ceil();
        let b = ((hi - self.min) / self.texel - 0.5).floor();
        let r = self.resolution as f32 - 1.0;
        let (x0, y0) = (a.x.max(0.0), a.y.max(0.0));
        let (x1, y1) = (b.x.min(r), b.y.min(r));
        (x0 <= x1 && y0 <= y1).then(|| (x0 as u32, x1 as u32, y0 as u32, y1 as u32))
    }
}

/// The per-layer maps of one [`FinShadowModel`].
pub struct RasterMaps<'m, 'a> {
    model: &'m FinShadowModel<'a>,
    pub region: MapRegion,
    /// `layers[j][y * resolution + x]`.
    pub layers: Vec<Vec<LayerTexel>>,
}

impl<'m, 'a> RasterMaps<'m, 'a> {
    pub fn new(model: &'m FinShadowModel<'a>, resolution: u32) -> Self {
        let resolution = resolution.clamp(1, 16384);
        let region = Self::covering_region(model, resolution);
        let n = (resolution * resolution) as usize;
        let mut layers = vec![vec![LayerTexel::EMPTY; n]; model.plan.len()];
        let res = resolution as usize;
        for (tri, &layer) in model.casters.iter().zip(&model.caster_layers) {
            let (lo, hi) = tri.bounds();
            let Some((x0, x1, y0, y1)) = region.texel_range(lo, hi) else {
                continue;
            };
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let q = region.texel_center(x, y);
                    if tri.contains(q) && tri.opaque_at(q, &model.light_space.masks) {
                        let d = tri.depth_at(q);
                        if d > model.near {
                            layers[layer as usize][y as usize * res + x as usize].add_caster(d);
                        }
                    }
                }
            }
        }
        let perspective = model.frame().is_perspective();
        for (fin, &layer) in model.fins.iter().zip(&model.fin_layers) {
            let (lo, hi) = fin.bounds();
            let Some((x0, x1, y0, y1)) = region.texel_range(lo, hi) else {
                continue;
            };
            let map = &mut layers[layer as usize];
            for y in y0..=y1 {
                for x in x0..=x1 {
                    if let Some(s) = fin.sample(region.texel_center(x, y), perspective) {
                        map[y as usize * res + x as usize].add_fin(fin.side, s);
                    }
                }
            }
        }
        Self { model, region, layers }
    }

    /// The square covering every caster and fin, a perspective one clamped
    /// to ±83° off axis.
    pub fn covering_region(model: &FinShadowModel, resolution: u32) -> MapRegion {
        let bounds = model.casters.iter().map(|c| c.bounds()).chain(model.fins.iter().map(|f| f.bounds()));
        MapRegion::covering(bounds, resolution, model.frame().map_limit(RASTER_MAP_LIMIT))
    }

    /// World size of one texel at depth `z`.
    pub fn texel_world_size(&self, z: f32) -> f32 {
        if self.model.frame().is_perspective() { self.region.texel * z } else { self.region.texel }
    }

    /// Visibility of the disk from a receiver, looked up at the nearest texel.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let m = self.model;
        let mut texels = Vec::with_capacity(self.layers.len());
        let depth_guess = receiver.position.z.max(m.near);
        let texel_world = self.texel_world_size(depth_guess);
        let eps = m.surface_epsilon(receiver);
        let p = m.lifted(receiver, eps + texel_world);
        if m.behind_light(p) {
            return 0.0;
        }
        match self.region.texel_of(m.map(p)) {
            Some((x, y)) => {
                let idx = (y * self.region.resolution + x) as usize;
                texels.extend(self.layers.iter().map(|l| l[idx]));
            }
            None => texels.resize(self.layers.len(), LayerTexel::EMPTY),
        }
        // Without a normal there is no offset: fall back to a slope-blind depth bias.
        let slack = if receiver.normal == Vec3::ZERO { 2.0 * texel_world + eps } else { 0.0 };
        m.visibility_from(&texels, p.z, p.z * (1.0 - 1e-6) - slack)
    }

    /// Memory held by the maps, in bytes.
    pub fn memory_bytes(&self) -> usize {
        self.layers.iter().map(|l| l.len() * std::mem::size_of::<LayerTexel>()).sum()
    }
}

impl<'a> FinShadowModel<'a> {
    /// Renders the per-layer light-space maps at `resolution²`, as the GPU does.
    pub fn raster(&self, resolution: u32) -> RasterMaps<'_, 'a> {
        RasterMaps::new(self, resolution)
    }
}
