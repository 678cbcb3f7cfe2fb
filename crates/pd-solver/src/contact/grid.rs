//! Broad phase of body contact: a uniform grid of axis-aligned boxes,
//! stored as a sorted list of (cell, item) keys so that building it
//! allocates nothing once its buffers have grown, and a query is a binary
//! search per cell. Deterministic: candidates come in item order per cell.

use pd_mesh::Point;

/// A uniform grid over item boxes. The cell size is the largest box extent,
/// so every box overlaps at most 2 x 2 x 2 cells.
#[derive(Debug, Default, Clone)]
pub(super) struct Grid {
    cell: f64,
    keys: Vec<([i64; 3], u32)>,
}

impl Grid {
    /// Rebuilds the grid over `boxes` (`(min, max)` per item, m).
    pub fn build(&mut self, boxes: &[(Point, Point)]) {
        self.keys.clear();
        let extent = boxes
            .iter()
            .map(|(lo, hi)| (hi - lo).max())
            .fold(0.0_f64, f64::max);
        // A positive, finite cell even for degenerate boxes.
        self.cell = if extent.is_finite() && extent > 0.0 {
            extent
        } else {
            1.0
        };
        for (item, (lo, hi)) in boxes.iter().enumerate() {
            let (a, b) = (self.index(lo), self.index(hi));
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

    fn index(&self, p: &Point) -> [i64; 3] {
        // Saturating float-to-int casts: a far or non-finite point lands in
        // an extreme cell, never out of range.
        [0, 1, 2].map(|a| (p[a] / self.cell).floor() as i64)
    }

    /// Calls `visit` with every item whose box may overlap `(lo, hi)`
    /// (an item can come more than once when the query spans cells). A
    /// query box larger than 4 cells per side is clamped to its first 4:
    /// the caller keeps query boxes of the size of a step's motion.
    pub fn query(&self, lo: &Point, hi: &Point, mut visit: impl FnMut(usize)) {
        let (a, b) = (self.index(lo), self.index(hi));
        let b = [0, 1, 2].map(|d| b[d].min(a[d].saturating_add(3)));
        for i in a[0]..=b[0] {
            for j in a[1]..=b[1] {
                for k in a[2]..=b[2] {
                    let key = [i, j, k];
                    let start = self.keys.partition_point(|(c, _)| *c < key);
                    for (_, item) in self.keys[start..].iter().take_while(|(c, _)| *c == key) {
                        visit(*item as usize);
                    }
                }
            }
        }
    }
}
