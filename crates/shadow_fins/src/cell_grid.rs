//! A uniform grid over light-map space whose cells list the items (casters,
//! fins, edges) whose map bounds touch them, in CSR form: the exact oracle's
//! index of casters and fins, and the coverage method's tiled edge list.

use glam::Vec2;

/// Per cell, the ids of the items whose bounds touch it.
#[derive(Debug, Clone)]
pub struct CellGrid {
    min: Vec2,
    inv_cell: Vec2,
    dims: [usize; 2],
    /// Items of cell `c` are `items[starts[c]..starts[c + 1]]`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

/// The cells `(x0, x1, y0, y1)` (inclusive, clamped into the grid) that the
/// bounds `lo..hi` touch, in a grid of `dims` cells over `min..min + size`.
pub fn cell_range(min: Vec2, size: Vec2, dims: [usize; 2], lo: Vec2, hi: Vec2) -> (usize, usize, usize, usize) {
    let inv_cell = Vec2::new(dims[0] as f32, dims[1] as f32) / size;
    let (a, b) = (((lo - min) * inv_cell).floor(), ((hi - min) * inv_cell).floor());
    let c = |v: f32, d: usize| (v.max(0.0) as usize).min(d - 1);
    (c(a.x, dims[0]), c(b.x, dims[0]), c(a.y, dims[1]), c(b.y, dims[1]))
}

impl CellGrid {
    /// Bins item `id` of `bounds` (`None`: not binned) into `dims` cells over
    /// `min..min + size`.
    pub fn build(min: Vec2, size: Vec2, dims: [usize; 2], bounds: &[Option<(Vec2, Vec2)>]) -> Self {
        let range = |lo: Vec2, hi: Vec2| cell_range(min, size, dims, lo, hi);
        let mut counts = vec![0u32; dims[0] * dims[1] + 1];
        for (lo, hi) in bounds.iter().flatten() {
            let (x0, x1, y0, y1) = range(*lo, *hi);
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
        let mut items = vec![0u32; *starts.last().unwrap_or(&0) as usize];
        for (id, b) in bounds.iter().enumerate() {
            let Some((lo, hi)) = b else { continue };
            let (x0, x1, y0, y1) = range(*lo, *hi);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = y * dims[0] + x;
                    items[fill[c] as usize] = id as u32;
                    fill[c] += 1;
                }
            }
        }
        let inv_cell = Vec2::new(dims[0] as f32, dims[1] as f32) / size;
        Self { min, inv_cell, dims, starts, items }
    }

    /// The items binned in the cell of map point `q` (none outside the grid).
    pub fn cell(&self, q: Vec2) -> &[u32] {
        let c = (q - self.min) * self.inv_cell;
        if !(c.x >= 0.0 && c.y >= 0.0 && (c.x as usize) < self.dims[0] && (c.y as usize) < self.dims[1]) {
            return &[];
        }
        let cell = c.y as usize * self.dims[0] + c.x as usize;
        &self.items[self.starts[cell] as usize..self.starts[cell + 1] as usize]
    }

    /// The grid's origin, cells per map unit and size in cells (for a GPU copy).
    pub fn grid(&self) -> (Vec2, Vec2, [usize; 2]) {
        (self.min, self.inv_cell, self.dims)
    }

    /// The CSR arrays: where each cell's items start in `items`, and the ids.
    pub fn lists(&self) -> (&[u32], &[u32]) {
        (&self.starts, &self.items)
    }
}
