//! Blocked triangular solves with a wide supernode's diagonal block
//! (docs/design/performance.md, "pd's own supernodal solve"), for the
//! forward and the backward step.
//!
//! The diagonal block is cut into tiles of [`TILE`] columns, starting at
//! its first column (the last tile may be narrower), so the blocking
//! depends only on the block's width, never on the thread count. A tile's
//! own triangle is solved column by column; the rest of the block is
//! handled with dense products over [`TILE`] columns at a time:
//!
//! - forward (`x <- L^-1 x`): once a tile is solved, the rows below it in
//!   the block take away that tile's products, four columns summed at a
//!   time (one load and store of a row's sums per tile instead of one per
//!   column);
//! - backward (`x <- L^-T x`): before a tile is solved, each of its
//!   columns takes away its dot product with the finished rows below the
//!   tile, summed in four lanes ([`wide_lanes`]), so the dependent chain
//!   per column (about 3 cycles per value, the latency of an addition) is
//!   only a tile long.
//!
//! This changes the order of the additions, so the round-off, against the
//! column-by-column solve (`supernodal_solve.rs` keeps it for narrower
//! blocks); the order is still fixed, with or without AVX2. Both solves are
//! backward stable in the same way (`supernodal_solve_tests.rs` checks the
//! bound).

use crate::Point;

#[cfg(target_arch = "x86_64")]
use super::wide_lanes;
use super::{Below, Block, Lanes, quads};

/// The width of a tile: eight columns are two groups of four products per
/// row in the forward step and four pairs of dot products in the backward
/// step.
pub(crate) const TILE: usize = 8;

impl Below<'_> {
    /// `top <- L_diag^-1 top` by tiles (module documentation), on a copy
    /// of `top` in the three arrays (free until [`Self::update`]).
    #[inline(always)]
    pub fn solve_diagonal_blocked(&mut self, block: &Block, top: &mut [Point]) {
        let c = top.len();
        let fetch = self.fetch;
        let (tx, ty, tz) = (&mut self.x[..c], &mut self.y[..c], &mut self.z[..c]);
        for (k, p) in top.iter().enumerate() {
            (tx[k], ty[k], tz[k]) = (p.x, p.y, p.z);
        }
        let mut j0 = 0;
        while j0 < c {
            let j1 = (j0 + TILE).min(c);
            if fetch.is_some() {
                // The next tile's columns, from its diagonal down.
                for j in j1..(j1 + TILE).min(c) {
                    block.prefetch(fetch, j, j, c - j);
                }
            }
            for j in j0..j1 {
                // Column j from its diagonal: row i is column[i - j].
                let column = block.rows(j, j, j1 - j);
                let d = column[0];
                let (xj, yj, zj) = (tx[j] / d, ty[j] / d, tz[j] / d);
                (tx[j], ty[j], tz[j]) = (xj, yj, zj);
                for i in j + 1..j1 {
                    tx[i] -= xj * column[i - j];
                    ty[i] -= yj * column[i - j];
                    tz[i] -= zj * column[i - j];
                }
            }
            if j1 < c {
                // A tile with rows below it is a whole one.
                // Plain loops, as in `narrow_updates`.
                let mut l: [&[f64]; TILE] = [&[]; TILE];
                for (i, l) in l.iter_mut().enumerate() {
                    *l = block.rows(j0 + i, j1, c - j1);
                }
                let p = |t: &[f64]| -> [f64; TILE] {
                    let mut p = [0.0; TILE];
                    p.copy_from_slice(&t[j0..j0 + TILE]);
                    p
                };
                let (px, py, pz) = (p(tx), p(ty), p(tz));
                subtract_tile(&l, &px, &mut tx[j1..]);
                subtract_tile(&l, &py, &mut ty[j1..]);
                subtract_tile(&l, &pz, &mut tz[j1..]);
            }
            j0 = j1;
        }
        for (k, p) in top.iter_mut().enumerate() {
            *p = Point::new(tx[k], ty[k], tz[k]);
        }
    }

    /// `top <- L_diag^-T top` by tiles (module documentation), last tile
    /// first, on a copy of `top` in the three arrays (free once
    /// [`Self::subtract_products`] is done).
    #[inline(always)]
    pub fn solve_diagonal_transposed_blocked(&mut self, block: &Block, top: &mut [Point]) {
        let c = top.len();
        let fetch = self.fetch;
        #[cfg(target_arch = "x86_64")]
        let simd = self.simd;
        let (tx, ty, tz) = (&mut self.x[..c], &mut self.y[..c], &mut self.z[..c]);
        for (k, p) in top.iter().enumerate() {
            (tx[k], ty[k], tz[k]) = (p.x, p.y, p.z);
        }
        let mut j0 = (c - 1) / TILE * TILE;
        loop {
            let j1 = (j0 + TILE).min(c);
            if fetch.is_some() && j0 > 0 {
                // The previous tile's columns, from the diagonal down.
                for j in j0 - TILE..j0 {
                    block.prefetch(fetch, j, j, c - j);
                }
            }
            if j1 < c {
                let (hx, rx) = tx.split_at_mut(j1);
                let (hy, ry) = ty.split_at_mut(j1);
                let (hz, rz) = tz.split_at_mut(j1);
                let (rx, ry, rz) = (&*rx, &*ry, &*rz);
                let column = |j: usize| block.rows(j, j1, c - j1);
                for j in (j0..j1).step_by(2) {
                    let (la, lb) = (column(j), column(j + 1));
                    #[cfg(target_arch = "x86_64")]
                    let [a, b] = match simd {
                        Some(s) => wide_lanes(s, [la, lb], rx, ry, rz),
                        None => plain_lanes([la, lb], rx, ry, rz),
                    };
                    #[cfg(not(target_arch = "x86_64"))]
                    let [a, b] = plain_lanes([la, lb], rx, ry, rz);
                    let (a, b) = (a.finish(la, rx, ry, rz), b.finish(lb, rx, ry, rz));
                    (hx[j], hy[j], hz[j]) = (hx[j] - a.x, hy[j] - a.y, hz[j] - a.z);
                    let k = j + 1;
                    (hx[k], hy[k], hz[k]) = (hx[k] - b.x, hy[k] - b.y, hz[k] - b.z);
                }
            }
            for j in (j0..j1).rev() {
                // Column j from its diagonal: row i is column[i - j].
                let column = block.rows(j, j, j1 - j);
                let (mut sx, mut sy, mut sz) = (tx[j], ty[j], tz[j]);
                for i in j + 1..j1 {
                    sx -= tx[i] * column[i - j];
                    sy -= ty[i] * column[i - j];
                    sz -= tz[i] * column[i - j];
                }
                let d = column[0];
                (tx[j], ty[j], tz[j]) = (sx / d, sy / d, sz / d);
            }
            if j0 == 0 {
                break;
            }
            j0 -= TILE;
        }
        for (k, p) in top.iter_mut().enumerate() {
            *p = Point::new(tx[k], ty[k], tz[k]);
        }
    }
}

/// `t[k] -= (p[0] l[0][k] + ... + p[3] l[3][k]) + (p[4] l[4][k] + ... +
/// p[7] l[7][k])` for every row `k` of `t`: each group of four products
/// summed left to right, then the two groups.
#[inline(always)]
fn subtract_tile(l: &[&[f64]; TILE], p: &[f64; TILE], t: &mut [f64]) {
    let r = t.len();
    // Sliced in a plain loop, as in `narrow_updates`.
    let mut l: [&[f64]; TILE] = *l;
    for l in &mut l {
        *l = &l[..r];
    }
    for k in 0..r {
        let g0 = p[0] * l[0][k] + p[1] * l[1][k] + p[2] * l[2][k] + p[3] * l[3][k];
        let g1 = p[4] * l[4][k] + p[5] * l[5][k] + p[6] * l[6][k] + p[7] * l[7][k];
        t[k] -= g0 + g1;
    }
}

/// [`wide_lanes`] without explicit SIMD: the same additions lane by lane.
#[inline(always)]
fn plain_lanes<const N: usize>(l: [&[f64]; N], x: &[f64], y: &[f64], z: &[f64]) -> [Lanes; N] {
    let mut sums: [Lanes; N] = std::array::from_fn(|_| Lanes::default());
    for (q, ((x, y), z)) in quads(x).zip(quads(y)).zip(quads(z)).enumerate() {
        for (sum, l) in sums.iter_mut().zip(&l) {
            sum.add(&l[4 * q..4 * q + 4], x, y, z);
        }
    }
    sums
}
