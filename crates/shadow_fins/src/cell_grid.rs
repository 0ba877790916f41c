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
        Self::build_where(min, size, dims, bounds, |_, _, _| true)
    }

    /// [`Self::build`], keeping item `id` in a cell its bounds touch only
    /// where `keep(id, cell_min, cell_max)` says so (a finer test than the
    /// bounds: the coverage method's footprint capsule and silhouette cull).
    /// Each cell lists its items in increasing id order.
    pub fn build_where(
        min: Vec2,
        size: Vec2,
        dims: [usize; 2],
        bounds: &[Option<(Vec2, Vec2)>],
        keep: impl Fn(u32, Vec2, Vec2) -> bool,
    ) -> Self {
        let inv_cell = Vec2::new(dims[0] as f32, dims[1] as f32) / size;
        let cell_size = size / Vec2::new(dims[0] as f32, dims[1] as f32);
        // (cell, id), pushed in id order: a stable counting sort keeps it per cell.
        let mut pairs: Vec<(u32, u32)> = vec![];
        for (id, b) in bounds.iter().enumerate() {
            let Some((lo, hi)) = b else { continue };
            let (x0, x1, y0, y1) = cell_range(min, size, dims, *lo, *hi);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let cell_min = min + Vec2::new(x as f32, y as f32) * cell_size;
                    if keep(id as u32, cell_min, cell_min + cell_size) {
                        pairs.push(((y * dims[0] + x) as u32, id as u32));
                    }
                }
            }
        }
        let mut starts = vec![0u32; dims[0] * dims[1] + 1];
        for &(cell, _) in &pairs {
            starts[cell as usize + 1] += 1;
        }
        for i in 1..starts.len() {
            starts[i] += starts[i - 1];
        }
        let mut fill = starts.clone();
        let mut items = vec![0u32; pairs.len()];
        for &(cell, id) in &pairs {
            items[fill[cell as usize] as usize] = id;
            fill[cell as usize] += 1;
        }
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
