//! Detection against the per-step candidate lists (`candidates.rs`):
//! building them for [`BodyContact`] and the listed counterpart of
//! [`BodyContact::first_hit`]; a file of its own to keep `bodies.rs`
//! within the size rule.

use pd_mesh::Point;

use super::super::candidates::Surface;
use super::super::grid::{cell_index, query_end};
use super::{BodyContact, Pair};

impl BodyContact {
    /// Builds the step's candidate lists around `x_n` with an inflation
    /// of twice the largest displacement of a surface vertex (this
    /// iterate's or the last build's), m; whether they cover `x_n + dx`.
    pub(super) fn build_candidates(&mut self, x_n: &[Point], dx: &[Point], thickness: f64) -> bool {
        let motion = (self.on_surface.iter())
            .map(|&i| dx[i].amax())
            .fold(0.0_f64, f64::max);
        let delta = 2.0 * motion.max(self.candidates.last_motion);
        self.candidates.last_motion = motion;
        let mut candidates = std::mem::take(&mut self.candidates);
        let surface = Surface {
            faces: &self.triangles,
            searching: &|v| self.searching(v),
            admits: &|v, f| self.admits(v, f),
        };
        let margin = thickness + self.reach;
        let covered = candidates.build(
            &surface,
            (x_n, dx, &self.on_surface),
            (delta, margin, thickness),
        );
        self.candidates = candidates;
        covered
    }

    /// [`BodyContact::first_hit`] over vertex `v`'s candidates, with the
    /// same result bit for bit: a candidate counts if the grid of this
    /// iteration's boxes (cells of size `cell`, m) would visit it, and
    /// among the earliest hits the first the grid would visit wins (cells
    /// in order, then triangles in order).
    pub(super) fn first_listed_hit(
        &self,
        v: usize,
        x_n: &[Point],
        dx: &[Point],
        (thickness, cell): (f64, f64),
    ) -> Option<Pair> {
        let (a, b) = (x_n[v], x_n[v] + dx[v]);
        let m = Point::repeat(thickness);
        let (lo, hi) = (a.inf(&b) - m, a.sup(&b) + m);
        let q_lo = cell_index(&lo, cell);
        let q_hi = query_end(&q_lo, &cell_index(&hi, cell));
        // The earliest hit; among equally early ones, the first the grid
        // would visit (cells in order, then triangles in order). Kept as a
        // running best: no allocation inside the iterations.
        let mut best: Option<(f64, ([i64; 3], usize), Pair)> = None;
        for &f in self.candidates.of(v) {
            let f = f as usize;
            let (f_lo, f_hi) = &self.boxes[f];
            if (0..3).any(|k| hi[k] < f_lo[k] || lo[k] > f_hi[k]) {
                continue;
            }
            let (c_lo, c_hi) = (cell_index(f_lo, cell), cell_index(f_hi, cell));
            let first = [0, 1, 2].map(|k| q_lo[k].max(c_lo[k]));
            if (0..3).any(|k| first[k] > q_hi[k].min(c_hi[k])) {
                continue;
            }
            let face = self.faces[f];
            let start = face.vertices.map(|i| x_n[i]);
            let end = face.vertices.map(|i| x_n[i] + dx[i]);
            if let Some((s, pair)) = self.crossing(&face, (&start, &end), (&a, &b), thickness) {
                let key = (first, f);
                if best.is_none_or(|(t, k, _)| s < t || (s == t && key < k)) {
                    best = Some((s, key, Pair { face: f, ..pair }));
                }
            }
        }
        best.map(|(_, _, p)| p)
    }
}
