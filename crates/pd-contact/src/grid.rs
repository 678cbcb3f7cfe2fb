//! Broad phase of body contact: a uniform grid of axis-aligned boxes.
//! Deterministic: a query visits the cells in a fixed order and the items
//! of a cell in increasing order. Building it allocates nothing once its
//! buffers have grown.
//!
//! Two layouts with the same visiting order. When the occupied cells' index
//! range is small (at most [`DENSE_FACTOR`] cells per (cell, item) key), a
//! dense table: the items of each cell, counted and placed in item order
//! (a counting sort), found by the cell's linear index. Otherwise (bodies
//! far apart) the sorted list of (cell, item) keys, a query being a binary
//! search per cell. The dense table costs O(keys + cells) per build instead
//! of a sort, and O(1) per cell looked up.

use pd_mesh::Point;

/// Largest number of cells in the dense table's range per key.
const DENSE_FACTOR: usize = 8;

/// A uniform grid over item boxes. The cell size is the largest box extent,
/// so every box overlaps at most 2 x 2 x 2 cells.
#[derive(Debug, Default, Clone)]
pub(super) struct Grid {
    cell: f64,
    /// Sparse layout: sorted (cell, item) keys.
    keys: Vec<([i64; 3], u32)>,
    /// Dense layout, when `dense`: the lowest cell index and the number of
    /// cells per axis of the range, and per linear cell index `l` its items
    /// `items[start[l]..start[l + 1]]`.
    dense: bool,
    origin: [i64; 3],
    dims: [i64; 3],
    start: Vec<u32>,
    items: Vec<u32>,
    /// Per item, the cells `(first, last)` its box spans, taken once per
    /// build (`index` of its corners): the dense build reads them three
    /// times, and recomputing them (six divisions and floors per box) was
    /// most of a build's cost (docs/design/contact.md, "Detection and the broad phase").
    spans: Vec<([i64; 3], [i64; 3])>,
}

impl Grid {
    /// Rebuilds the grid over `boxes` (`(min, max)` per item, m).
    pub fn build(&mut self, boxes: &[(Point, Point)]) {
        self.build_with_cell(boxes, cell_size(boxes));
    }

    /// [`Grid::build`] with a given cell size (m, positive and finite; at
    /// least every box's extent for the overlap bound of the type's docs),
    /// e.g. one shared by several grids.
    pub fn build_with_cell(&mut self, boxes: &[(Point, Point)], cell: f64) {
        self.keys.clear();
        self.cell = cell;
        self.spans.clear();
        self.spans.extend(
            boxes
                .iter()
                .map(|(lo, hi)| (cell_index(lo, cell), cell_index(hi, cell))),
        );
        self.dense = self.build_dense(boxes.len());
        if self.dense {
            return;
        }
        for (item, &(a, b)) in self.spans.iter().enumerate() {
            for i in a[0]..=b[0] {
                for j in a[1]..=b[1] {
                    for k in a[2]..=b[2] {
                        self.keys.push(([i, j, k], item as u32));
                    }
                }
            }
        }
        self.keys.sort_unstable();
    }

    /// The dense table, if its range is small enough; `false` otherwise.
    /// `items` boxes, spanning the cells of `spans`.
    fn build_dense(&mut self, items: usize) -> bool {
        let (mut low, mut high) = ([i64::MAX; 3], [i64::MIN; 3]);
        let mut keys = 0usize;
        for &(a, b) in &self.spans {
            let mut count = 1usize;
            for d in 0..3 {
                low[d] = low[d].min(a[d]);
                high[d] = high[d].max(b[d]);
                let Some(n) = b[d].checked_sub(a[d]).and_then(|n| usize::try_from(n).ok()) else {
                    return false;
                };
                count = count.saturating_mul(n.saturating_add(1));
            }
            keys = keys.saturating_add(count);
        }
        if items == 0 {
            return false;
        }
        let mut cells = 1usize;
        for d in 0..3 {
            let Some(n) = high[d].checked_sub(low[d]).and_then(|n| n.checked_add(1)) else {
                return false;
            };
            self.dims[d] = n;
            cells = cells.saturating_mul(usize::try_from(n).unwrap_or(usize::MAX));
        }
        let limit = DENSE_FACTOR.saturating_mul(keys.max(items));
        if cells > limit || keys > u32::MAX as usize {
            return false;
        }
        self.origin = low;
        self.start.clear();
        self.start.resize(cells + 1, 0);
        self.items.clear();
        self.items.resize(keys, 0);
        // Count per cell (shifted by one), prefix-sum, then place the items
        // in increasing order, using `start[l + 1]` as cell `l`'s cursor.
        self.for_each_key(|start, _, l| start[l + 1] += 1);
        for l in 0..cells {
            self.start[l + 1] += self.start[l];
        }
        for l in (0..cells).rev() {
            self.start[l + 1] = self.start[l];
        }
        let mut items = std::mem::take(&mut self.items);
        self.for_each_key(|start, item, l| {
            items[start[l + 1] as usize] = item;
            start[l + 1] += 1;
        });
        self.items = items;
        true
    }

    /// Calls `f(start, item, linear cell)` for every (cell, item) key, in
    /// item order.
    ///
    /// Every span lies in the table's range (its bounds were taken from the
    /// spans), so the linear index of cell `a + (di, dj, dk)` is that of
    /// `a` plus `(di n_1 + dj) n_2 + dk`, integers without overflow (the
    /// range's cell count fits a `usize`): the values of
    /// [`Grid::linear`] per cell, without its checks.
    fn for_each_key(&mut self, mut f: impl FnMut(&mut [u32], u32, usize)) {
        let (n1, n2) = (self.dims[1] as usize, self.dims[2] as usize);
        for item in 0..self.spans.len() {
            let (a, b) = self.spans[item];
            let base = self.linear(a).unwrap_or(0);
            let span = |d: usize| (b[d] - a[d]) as usize;
            for di in 0..=span(0) {
                for dj in 0..=span(1) {
                    let row = base + (di * n1 + dj) * n2;
                    for dk in 0..=span(2) {
                        f(&mut self.start, item as u32, row + dk);
                    }
                }
            }
        }
    }

    /// The dense table's linear index of a cell, `None` outside its range.
    fn linear(&self, cell: [i64; 3]) -> Option<usize> {
        let mut l = 0i64;
        for ((c, o), n) in cell.iter().zip(&self.origin).zip(&self.dims) {
            let offset = c.checked_sub(*o)?;
            if !(0..*n).contains(&offset) {
                return None;
            }
            l = l * n + offset;
        }
        usize::try_from(l).ok()
    }

    fn index(&self, p: &Point) -> [i64; 3] {
        cell_index(p, self.cell)
    }

    /// Calls `visit` with every item whose box may overlap `(lo, hi)`
    /// (an item can come more than once when the query spans cells). A
    /// query box larger than 4 cells per side is clamped to its first 4:
    /// the caller keeps query boxes of the size of a step's motion.
    pub fn query(&self, lo: &Point, hi: &Point, mut visit: impl FnMut(usize)) {
        let (a, b) = (self.index(lo), self.index(hi));
        let b = query_end(&a, &b);
        for i in a[0]..=b[0] {
            for j in a[1]..=b[1] {
                for k in a[2]..=b[2] {
                    let key = [i, j, k];
                    if self.dense {
                        if let Some(l) = self.linear(key) {
                            let (from, to) = (self.start[l] as usize, self.start[l + 1] as usize);
                            self.items[from..to]
                                .iter()
                                .for_each(|&item| visit(item as usize));
                        }
                        continue;
                    }
                    let start = self.keys.partition_point(|(c, _)| *c < key);
                    for (_, item) in self.keys[start..].iter().take_while(|(c, _)| *c == key) {
                        visit(*item as usize);
                    }
                }
            }
        }
    }
}

/// The cell size [`Grid::build`] takes for `boxes`, m: the largest box
/// extent (1 for degenerate or non-finite boxes).
pub(super) fn cell_size(boxes: &[(Point, Point)]) -> f64 {
    let extent = boxes
        .iter()
        .map(|(lo, hi)| (hi - lo).max())
        .fold(0.0_f64, f64::max);
    // A positive, finite cell even for degenerate boxes.
    if extent.is_finite() && extent > 0.0 {
        extent
    } else {
        1.0
    }
}

/// The grid cell of `p` for cells of size `cell` (m).
pub(super) fn cell_index(p: &Point, cell: f64) -> [i64; 3] {
    [
        floor_to_i64(p[0] / cell),
        floor_to_i64(p[1] / cell),
        floor_to_i64(p[2] / cell),
    ]
}

/// `x.floor() as i64`, without the call to the software `floor` (the
/// build does not assume SSE4.1's rounding instruction, and that `floor`
/// branches on the exponent: the most mispredicted branch of contact
/// detection). The cast truncates towards zero and saturates, and one is
/// taken off when the truncation rounded up (negative non-integers): the
/// same integer for every `x`, finite or not (NaN gives 0, infinities and
/// far values the extreme cells, as the saturating cast of the floor).
fn floor_to_i64(x: f64) -> i64 {
    let t = x as i64;
    t.saturating_sub(i64::from((t as f64) > x))
}

/// The cells [`Grid::query`] visits for a query box from cell `a` to cell
/// `b`: the last is clamped to 4 cells per side.
pub(super) fn query_end(a: &[i64; 3], b: &[i64; 3]) -> [i64; 3] {
    [0, 1, 2].map(|d| b[d].min(a[d].saturating_add(3)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `floor_to_i64` is the saturating cast of the floor, on integers,
    /// halves, values next to them, signed zeros, far values beyond the
    /// range of `i64`, infinities and NaN.
    #[test]
    fn floor_to_i64_is_the_cast_floor() {
        let mut values = vec![0.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
        for x in [0.5_f64, 1.0, 2.0, 3.5, 1e15, 4.5e15, 9.2e18, 9.3e18, 1e300] {
            for y in [x, -x] {
                // Both float neighbours of `y` (its bits plus and minus 1).
                let bits = y.to_bits();
                values.extend([y, f64::from_bits(bits + 1), f64::from_bits(bits - 1)]);
            }
        }
        values.extend([
            i64::MIN as f64,
            i64::MAX as f64,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
        ]);
        for x in values {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "{x:e}");
        }
    }

    /// Every query visits the same items in the same order in both
    /// layouts.
    #[test]
    fn dense_and_sparse_layouts_visit_the_same_items_in_order() {
        let boxes: Vec<(Point, Point)> = (0..40)
            .map(|i| {
                let x = f64::from(i);
                let lo = Point::new((x * 0.37).sin(), (x * 0.11).cos(), 0.05 * x);
                (lo, lo + Point::new(0.3, 0.2 + 0.01 * x, 0.25))
            })
            .collect();
        let mut dense = Grid::default();
        dense.build(&boxes);
        assert!(dense.dense);
        let mut sparse = dense.clone();
        sparse.dense = false;
        sparse.keys.clear();
        for (item, (lo, hi)) in boxes.iter().enumerate() {
            let (a, b) = (sparse.index(lo), sparse.index(hi));
            for i in a[0]..=b[0] {
                for j in a[1]..=b[1] {
                    for k in a[2]..=b[2] {
                        sparse.keys.push(([i, j, k], item as u32));
                    }
                }
            }
        }
        sparse.keys.sort_unstable();
        for q in 0..60 {
            let x = f64::from(q) * 0.1 - 1.5;
            let (lo, hi) = (
                Point::new(x, 0.3 * x, 0.7),
                Point::new(x + 0.4, 0.3 * x + 0.9, 1.9),
            );
            let (mut a, mut b) = (Vec::new(), Vec::new());
            dense.query(&lo, &hi, |i| a.push(i));
            sparse.query(&lo, &hi, |i| b.push(i));
            assert_eq!(a, b, "query {q}");
        }
        // Boxes far apart fall back to the sparse layout.
        let far = [
            (Point::zeros(), Point::repeat(0.1)),
            (Point::repeat(1e3), Point::repeat(1e3 + 0.1)),
        ];
        let mut grid = Grid::default();
        grid.build(&far);
        assert!(!grid.dense);
        let mut seen = Vec::new();
        grid.query(&Point::repeat(1e3), &Point::repeat(1e3), |i| seen.push(i));
        assert_eq!(seen, vec![1]);
    }
}
