//! Sparse penumbra maps (`fin_types.wgsl`, `maps.wgsl`): a layer's texels
//! live in 8×8 tiles and only the tiles a caster or fin writes take memory.
//! The maps buffer is a header, a page table (one word per tile per layer)
//! and a pool of tiles. Here: the buffer's shape, how many tiles a frame
//! wants (counted on the CPU for the CPU extraction, read back from the GPU
//! for the GPU one), and the bytes the budget weighs.
//!
//! Why tiles: dense maps cost layers × resolution² × 36 B whatever the scene
//! holds (16 layers at 1024² = 576 MiB), while a deep layer holds only the
//! few casters and fins assigned to it. Tiles of 8×8 keep the page table
//! small (1 MiB at 16 layers, 1024²) and a tile's texels together.

use bevy::math::Vec2;
use shadow_fins::oracle::MapRegion;

use crate::gpu_layout::MAP_TEXEL_BYTES;

/// Texels along a tile's side (`TILE` in `fin_types.wgsl`).
pub(crate) const TILE: u32 = 8;
/// Words before the page table (`MAPS_HEADER`).
pub(crate) const HEADER_WORDS: u64 = 4;
/// Bytes of one tile in the pool.
pub(crate) const TILE_BYTES: u64 = (TILE * TILE) as u64 * MAP_TEXEL_BYTES;

/// The maps buffer's layout: resolution, layers in the page table and tiles
/// in the pool. Two frames with the same shape can share a buffer's
/// contents (a partial redraw); any other change redraws whole.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct MapShape {
    pub resolution: u32,
    pub layers: u32,
    pub tiles: u32,
}

/// Tiles along one side of a `resolution²` layer.
pub(crate) fn tiles_per_side(resolution: u32) -> u32 {
    resolution.div_ceil(TILE)
}

/// Every tile of `layers` layers: what dense maps would hold.
pub(crate) fn all_tiles(resolution: u32, layers: u32) -> u64 {
    layers.max(1) as u64 * (tiles_per_side(resolution) as u64).pow(2)
}

impl MapShape {
    /// Words of the page table.
    pub fn page_words(&self) -> u64 {
        all_tiles(self.resolution, self.layers)
    }

    /// Bytes of the whole buffer: header, page table and pool.
    pub fn bytes(&self) -> u64 {
        (HEADER_WORDS + self.page_words()) * 4 + self.tiles as u64 * TILE_BYTES
    }
}

/// How many tiles a frame's maps wanted at a resolution: the GPU's count
/// read back, or the CPU's conservative count ([`count_tiles`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct TileDemand {
    pub resolution: u32,
    pub tiles: u32,
}

impl TileDemand {
    /// The tiles to allocate at `resolution` for `layers` layers: the demand
    /// scaled by area (a tile splits into at most four at twice the
    /// resolution, less the few its outline adds), a quarter more room for
    /// content that moves, never more than every tile. Unknown demand (a
    /// GPU frame before its first read-back) asks for every tile, and the
    /// pool is what fits ([`shape_within`]).
    pub fn tiles_at(demand: Option<Self>, resolution: u32, layers: u32) -> u64 {
        let all = all_tiles(resolution, layers);
        let Some(d) = demand else { return all };
        let scale = (resolution as f64 / d.resolution.max(1) as f64).powi(2);
        let scaled = (d.tiles as f64 * scale).ceil() as u64;
        (scaled + scaled / 4 + 16).min(all)
    }
}

/// The shape for `tiles` tiles at `resolution`, `layers`, within `limit`
/// bytes: the pool holds what the limit leaves after the page table.
pub(crate) fn shape_within(resolution: u32, layers: u32, tiles: u64, limit: u64) -> MapShape {
    let pages = MapShape { resolution, layers: layers.max(1), tiles: 0 };
    let room = limit.saturating_sub(pages.bytes()) / TILE_BYTES;
    MapShape { tiles: tiles.min(room).min(u32::MAX as u64) as u32, ..pages }
}

/// Bytes the maps need at `resolution`, `layers` for `demand`: what the
/// budget compares with its limit (`budget::allocate_maps_by`). Unknown
/// demand needs only the page table and one tile: the pool takes what fits.
pub(crate) fn bytes_needed(demand: Option<TileDemand>, resolution: u32, layers: u32) -> u64 {
    let tiles = if demand.is_some() { TileDemand::tiles_at(demand, resolution, layers) } else { 1 };
    MapShape { resolution, layers: layers.max(1), tiles: tiles as u32 }.bytes()
}

/// The tiles the CPU extraction's casters and fins can write, by their
/// map-space bounds `(layer, (min, max))` (a superset of what `maps.wgsl`
/// marks): every tile holding a texel of the bounds' `texel_range`.
pub(crate) fn count_tiles(
    region: &MapRegion,
    layers: u32,
    footprints: impl Iterator<Item = (u32, (Vec2, Vec2))>,
) -> u32 {
    let side = tiles_per_side(region.resolution) as usize;
    let mut marked = vec![false; all_tiles(region.resolution, layers) as usize];
    for (layer, (lo, hi)) in footprints.filter(|(layer, _)| *layer < layers.max(1)) {
        let Some((x0, x1, y0, y1)) = region.texel_range(lo, hi) else { continue };
        let (x0, x1) = ((x0 / TILE) as usize, (x1 / TILE) as usize);
        let base = layer as usize * side * side;
        for y in (y0 / TILE) as usize..=(y1 / TILE) as usize {
            marked[base + y * side + x0..=base + y * side + x1].fill(true);
        }
    }
    marked.iter().filter(|m| **m).count() as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds(lo: [f32; 2], hi: [f32; 2]) -> (Vec2, Vec2) {
        (Vec2::from(lo), Vec2::from(hi))
    }

    #[test]
    fn a_shape_costs_its_page_table_and_its_pool() {
        let shape = MapShape { resolution: 1024, layers: 16, tiles: 1000 };
        assert_eq!(shape.page_words(), 16 * 128 * 128);
        assert_eq!(shape.bytes(), (4 + 16 * 128 * 128) * 4 + 1000 * 64 * 36);
        // 16 layers at 1024² fit 128 MiB when a fifth of their tiles are used.
        let fitted = shape_within(1024, 16, u64::MAX, 128 << 20);
        assert!(fitted.bytes() <= 128 << 20 && fitted.tiles > 16 * 128 * 128 / 5, "{fitted:?}");
    }

    #[test]
    fn demand_scales_by_area_with_room_and_never_past_every_tile() {
        let d = TileDemand { resolution: 512, tiles: 400 };
        assert_eq!(TileDemand::tiles_at(Some(d), 1024, 4), 1600 + 400 + 16);
        assert_eq!(TileDemand::tiles_at(Some(d), 256, 4), 100 + 25 + 16);
        // A 16² layer has four tiles: never more.
        assert_eq!(TileDemand::tiles_at(Some(d), 16, 1), 4);
        assert_eq!(TileDemand::tiles_at(None, 64, 2), 128);
    }

    #[test]
    fn tiles_are_counted_once_per_layer_under_each_primitives_bounds() {
        // A 64² map of unit texels from the origin: 8×8 tiles.
        let region = |resolution| MapRegion { min: Vec2::ZERO, texel: 1.0, resolution };
        let a = (0, bounds([0.0, 0.0], [20.0, 4.0]));
        // The same tiles again on layer 0, and one tile on layer 1.
        let b = (0, bounds([1.0, 1.0], [2.0, 2.0]));
        let c = (1, bounds([60.0, 60.0], [61.0, 61.0]));
        // Texel centres 0.5 … 19.5 span tiles 0..=2 in x, one row in y.
        assert_eq!(count_tiles(&region(64), 2, [a, b, c].into_iter()), 3 + 1);
        // Outside the map, or past the layers allocated: nothing.
        let out = (0, bounds([-9.0, -9.0], [-8.0, -8.0]));
        assert_eq!(count_tiles(&region(64), 1, [out, c].into_iter()), 0);
        // A sector fin of radius 9 around (32, 32): texels 23..=40 → tiles 2..=5.
        let sector = (0, bounds([23.0, 23.0], [41.0, 41.0]));
        assert_eq!(count_tiles(&region(64), 1, [sector].into_iter()), 16);
        // Bounds not finite reach every tile.
        let unbounded = (0, bounds([f32::NEG_INFINITY; 2], [f32::INFINITY; 2]));
        assert_eq!(count_tiles(&region(64), 1, [unbounded].into_iter()), 64);
    }

    #[test]
    fn unknown_demand_needs_only_the_page_table() {
        assert_eq!(bytes_needed(None, 1024, 16), (4 + 16 * 128 * 128) * 4 + TILE_BYTES);
        let d = TileDemand { resolution: 1024, tiles: 10_000 };
        assert_eq!(bytes_needed(Some(d), 1024, 16), (4 + 16 * 128 * 128) * 4 + 12_516 * TILE_BYTES);
    }
}
