//! The dense kernels of the supernodal solve (`supernodal.rs`): one
//! supernode's rows below its diagonal block, with the forward step's
//! update and the backward step's dot products, run through the crate's
//! SIMD dispatch ([`crate::simd`]); diagonal blocks in `diagonal.rs`.
//!
//! Every kernel computes each value with the same operations in the same
//! order on every CPU (4 fixed lanes, no fused multiply-add), so the
//! AVX-512, the AVX2 and the plain path give the same bits.

use crate::Point;
pub(super) use crate::simd::{Avx2 as Simd, vectorized};

mod diagonal;
#[cfg(test)]
pub(super) use diagonal::TILE;

/// One supernode's columns of the factor, in either of its two layouts:
/// faer's, a dense column-major `(c + r) x c` block whose diagonal block's
/// upper triangle is padding, or packed (`SymbolicFactor::pack`), where
/// column `j` holds only rows `j..c + r`, so that every column is one
/// contiguous run and no solve loads the padding's cache lines. The kernels
/// read column `j` from its diagonal down ([`Self::column`]); both layouts
/// give them the same values in the same order, so the same bits.
#[derive(Clone, Copy)]
pub(super) struct Block<'a> {
    values: &'a [f64],
    /// Rows of the supernode, `c + r`.
    ld: usize,
    packed: bool,
}

impl<'a> Block<'a> {
    /// The supernode of `c` columns and `ld` rows stored from the start of
    /// `values` (which may run on).
    #[inline(always)]
    pub fn new(values: &'a [f64], ld: usize, c: usize, packed: bool) -> Self {
        let len = Self::stored(ld, c, packed);
        Self {
            values: &values[..len],
            ld,
            packed,
        }
    }

    /// The values a supernode of `ld` rows and `c` columns stores.
    #[inline(always)]
    pub fn stored(ld: usize, c: usize, packed: bool) -> usize {
        if packed {
            c * ld - c * (c - 1) / 2
        } else {
            c * ld
        }
    }

    /// Where column `j`'s diagonal entry is stored: `j ld + j` in faer's
    /// layout, after the `ld - k` values of each earlier column `k` when
    /// packed.
    #[inline(always)]
    pub fn start(&self, j: usize) -> usize {
        let start = j * (self.ld + 1);
        if self.packed {
            start - j * (j + 1) / 2
        } else {
            start
        }
    }

    /// Column `j` from its diagonal entry down (`ld - j` values).
    #[inline(always)]
    pub fn column(&self, j: usize) -> &'a [f64] {
        &self.values[self.start(j)..][..self.ld - j]
    }

    /// Column `j`'s `len` rows from row `row` (`>= j`), sliced once.
    #[inline(always)]
    pub fn rows(&self, j: usize, row: usize, len: usize) -> &'a [f64] {
        &self.values[self.start(j) + row - j..][..len]
    }

    /// [`prefetch`] of column `j`'s `len` values from row `row` (`>= j`).
    #[inline(always)]
    fn prefetch(&self, fetch: Option<Simd>, j: usize, row: usize, len: usize) {
        prefetch(fetch, self.values, self.start(j) + row - j, len);
    }
}

/// Supernodes narrower than this (four in five supernodes of the 80 x 14 x
/// 14 beam's METIS order, 3.5 % of its values) update the rows below them
/// row by row, straight into the solution (`Structure::forward_supernode`, [`narrow_updates`]),
/// with the sums of `Below::update`'s one-column passes, so the same bits:
/// 3-5 % off the beam's solve (docs/design/performance.md, "Narrow supernodes").
/// Wider ones (a fused loop up to 8 columns measured the same as 4) and
/// the backward step (a fused gather into the dot products' lanes was no
/// faster) keep the coordinate arrays.
pub(super) const NARROW: usize = 4;

/// The forward step's updates of the `r` rows below a supernode of
/// `top.len() < NARROW` columns, row by row: row `k`'s update summed from
/// zero column by column (the sums of [`Below::update`]'s one-column
/// passes, so the same bits), handed to `scatter(k, update)` at once
/// instead of through the coordinate arrays.
#[inline(always)]
pub(super) fn narrow_updates(
    block: &Block,
    top: &[Point],
    r: usize,
    mut scatter: impl FnMut(usize, Point),
) {
    let c = top.len();
    // Plain loops build the kernels' small arrays: `array::from_fn` and
    // `array::map` stayed out of line, outside the target features'
    // function.
    let mut columns: [&[f64]; NARROW - 1] = [&[]; NARROW - 1];
    for (j, column) in columns.iter_mut().enumerate().take(c) {
        *column = block.rows(j, c, r);
    }
    for k in 0..r {
        let mut update = Point::zeros();
        for (p, l) in top.iter().zip(&columns) {
            let l = l[k];
            update.x += p.x * l;
            update.y += p.y * l;
            update.z += p.z * l;
        }
        scatter(k, update);
    }
}

/// One supernode's below-diagonal rows, one array per coordinate, so that
/// the loops over rows run four rows per instruction.
pub(super) struct Below<'a> {
    pub x: &'a mut [f64],
    pub y: &'a mut [f64],
    pub z: &'a mut [f64],
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    simd: Option<Simd>,
    /// The instruction set for [`prefetch`], `None` for no prefetches.
    fetch: Option<Simd>,
}

impl<'a> Below<'a> {
    /// The scratch `storage` as three coordinate arrays; `prefetch`:
    /// whether the kernels ask for the factor's values ahead of their use
    /// ([`prefetch`]).
    #[inline(always)]
    pub fn split(storage: &'a mut [f64], simd: Option<Simd>, prefetch: bool) -> Self {
        let third = storage.len() / 3;
        let (x, rest) = storage.split_at_mut(third);
        let (y, z) = rest.split_at_mut(third);
        let fetch = simd.filter(|_| prefetch);
        Self {
            x,
            y,
            z,
            simd,
            fetch,
        }
    }

    /// [`prefetch`] of `block`'s column `j`, `len` values from row `row`,
    /// if this solve prefetches.
    #[inline(always)]
    pub fn prefetch(&self, block: &Block, j: usize, row: usize, len: usize) {
        block.prefetch(self.fetch, j, row, len);
    }

    /// Whether this solve prefetches: callers test it before working out
    /// what to prefetch, so that a solve without prefetches does not pay
    /// for the addresses (callgrind: 3 % more instructions on the
    /// armadillo without this test).
    #[inline(always)]
    pub fn prefetches(&self) -> bool {
        self.fetch.is_some()
    }

    /// `top <- L_diag^-1 top`: the forward step's triangular solve with the
    /// supernode's diagonal block, on a copy of `top` in the three arrays
    /// (this scratch is free until [`Self::update`]), so that each column's
    /// update of the rows under the diagonal runs four rows per
    /// instruction. Every row takes the same operations in the same order
    /// as on points: its value divided by the diagonal once its earlier
    /// columns have been subtracted, column by column.
    #[inline(always)]
    pub fn solve_diagonal(&mut self, block: &Block, top: &mut [Point]) {
        let c = top.len();
        let fetch = self.fetch;
        let (tx, ty, tz) = (&mut self.x[..c], &mut self.y[..c], &mut self.z[..c]);
        for (k, p) in top.iter().enumerate() {
            (tx[k], ty[k], tz[k]) = (p.x, p.y, p.z);
        }
        for j in 0..c {
            // The next column's rows under the diagonal.
            if fetch.is_some() && j + 1 < c {
                block.prefetch(fetch, j + 1, j + 1, c - j - 1);
            }
            let column = block.rows(j, j, c - j);
            let d = column[0];
            let (xj, yj, zj) = (tx[j] / d, ty[j] / d, tz[j] / d);
            (tx[j], ty[j], tz[j]) = (xj, yj, zj);
            let l = &column[1..];
            for (t, &l) in tx[j + 1..].iter_mut().zip(l) {
                *t -= xj * l;
            }
            for (t, &l) in ty[j + 1..].iter_mut().zip(l) {
                *t -= yj * l;
            }
            for (t, &l) in tz[j + 1..].iter_mut().zip(l) {
                *t -= zj * l;
            }
        }
        for (k, p) in top.iter_mut().enumerate() {
            *p = Point::new(tx[k], ty[k], tz[k]);
        }
    }

    /// `below[..r] = L_below x_top`: the forward step's update of the rows
    /// below the supernode, eight columns per pass over the rows, then four,
    /// then one. Each row's sums are those of four columns at a time: a row
    /// starts at zero and adds each group of four columns' products, summed
    /// left to right, in column order; a pass of eight adds its two groups
    /// one after the other (loading and storing the row's sums once instead
    /// of twice, with the same bits).
    #[inline(always)]
    pub fn update(&mut self, block: &Block, c: usize, top: &[Point], r: usize) {
        let (bx, by, bz) = (&mut self.x[..r], &mut self.y[..r], &mut self.z[..r]);
        bx.fill(0.0);
        by.fill(0.0);
        bz.fill(0.0);
        let column = |j: usize| block.rows(j, c, r);
        let mut j = 0;
        while j + 8 <= c {
            let mut l: [&[f64]; 8] = [&[]; 8];
            for (i, l) in l.iter_mut().enumerate() {
                *l = column(j + i);
            }
            let mut p = [Point::zeros(); 8];
            p.copy_from_slice(&top[j..j + 8]);
            for k in 0..r {
                let group = |q: &[Point], l: &[&[f64]], coordinate: fn(&Point) -> f64| {
                    coordinate(&q[0]) * l[0][k]
                        + coordinate(&q[1]) * l[1][k]
                        + coordinate(&q[2]) * l[2][k]
                        + coordinate(&q[3]) * l[3][k]
                };
                let (q0, q1) = p.split_at(4);
                let (l0, l1) = l.split_at(4);
                bx[k] = (bx[k] + group(q0, l0, |p| p.x)) + group(q1, l1, |p| p.x);
                by[k] = (by[k] + group(q0, l0, |p| p.y)) + group(q1, l1, |p| p.y);
                bz[k] = (bz[k] + group(q0, l0, |p| p.z)) + group(q1, l1, |p| p.z);
            }
            j += 8;
        }
        if j + 4 <= c {
            let (l0, l1, l2, l3) = (column(j), column(j + 1), column(j + 2), column(j + 3));
            let (p0, p1, p2, p3) = (top[j], top[j + 1], top[j + 2], top[j + 3]);
            for k in 0..r {
                bx[k] += p0.x * l0[k] + p1.x * l1[k] + p2.x * l2[k] + p3.x * l3[k];
                by[k] += p0.y * l0[k] + p1.y * l1[k] + p2.y * l2[k] + p3.y * l3[k];
                bz[k] += p0.z * l0[k] + p1.z * l1[k] + p2.z * l2[k] + p3.z * l3[k];
            }
            j += 4;
        }
        for (j, p) in top.iter().enumerate().skip(j) {
            let l = column(j);
            for k in 0..r {
                bx[k] += p.x * l[k];
                by[k] += p.y * l[k];
                bz[k] += p.z * l[k];
            }
        }
    }

    /// `top -= L_below^T below[..r]`: the backward step's dot products, in
    /// four fixed lanes per coordinate (deterministic order), two columns
    /// per pass so that they share the loads of `below` and keep six
    /// independent sums in flight (each column's sums are the same
    /// operations in the same order as one column at a time); with AVX2,
    /// [`wide_lanes`] does the same additions on explicit 4-wide vectors.
    #[inline(always)]
    pub fn subtract_products(&self, block: &Block, c: usize, top: &mut [Point], r: usize) {
        let (bx, by, bz) = (&self.x[..r], &self.y[..r], &self.z[..r]);
        #[cfg(target_arch = "x86_64")]
        if let Some(s) = self.simd {
            let column = |j: usize| block.rows(j, c, r);
            let mut pairs = top.chunks_exact_mut(2);
            for (j, pair) in (0..).step_by(2).zip(&mut pairs) {
                // The next pair's columns.
                if self.prefetches() {
                    for i in j + 2..c.min(j + 4) {
                        self.prefetch(block, i, c, r);
                    }
                }
                let (la, lb) = (column(j), column(j + 1));
                let [a, b] = wide_lanes(s, [la, lb], bx, by, bz);
                pair[0] -= a.finish(la, bx, by, bz);
                pair[1] -= b.finish(lb, bx, by, bz);
            }
            if let [p] = pairs.into_remainder() {
                let l = column(c - 1);
                let [a] = wide_lanes(s, [l], bx, by, bz);
                *p -= a.finish(l, bx, by, bz);
            }
            return;
        }
        let x4 = quads(bx);
        let y4 = quads(by);
        let z4 = quads(bz);
        let column = |j: usize| block.rows(j, c, r);
        let mut pairs = top.chunks_exact_mut(2);
        let mut j = 0;
        for pair in &mut pairs {
            let (la, lb) = (column(j), column(j + 1));
            let a4 = quads(la);
            let b4 = quads(lb);
            let (mut a, mut b) = (Lanes::default(), Lanes::default());
            for ((((la, lb), x), y), z) in
                a4.zip(b4).zip(x4.clone()).zip(y4.clone()).zip(z4.clone())
            {
                a.add(la, x, y, z);
                b.add(lb, x, y, z);
            }
            pair[0] -= a.finish(la, bx, by, bz);
            pair[1] -= b.finish(lb, bx, by, bz);
            j += 2;
        }
        if let [p] = pairs.into_remainder() {
            let l = column(j);
            let l4 = quads(l);
            let mut a = Lanes::default();
            for (((l, x), y), z) in l4.zip(x4).zip(y4).zip(z4) {
                a.add(l, x, y, z);
            }
            *p -= a.finish(l, bx, by, bz);
        }
    }
}

/// Asks the caches for `values[start..start + len]` ahead of its use:
/// one prefetch per 64-byte line (8 values), no effect on any value.
/// Nothing without AVX2. The solve reads its factor once per pass in
/// short column pieces, too short for the hardware's stream detection
/// to run ahead of them (`perf annotate` showed the backward dot
/// products waiting on the loads of the factor).
#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
fn prefetch(simd: Option<Simd>, values: &[f64], start: usize, len: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(s) = simd {
        let base = values.as_ptr();
        let end = start + len;
        let mut k = start;
        while k < end {
            // A prefetch never faults, and `wrapping_add` makes no
            // promise that the address is inside `values`.
            s.sse
                ._mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(base.wrapping_add(k).cast());
            k += 8;
        }
        if len > 0 {
            s.sse._mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(
                base.wrapping_add(end - 1).cast(),
            );
        }
    }
}

/// [`Lanes`] of each of the columns `l` (as many rows as `x`, `y`, `z`)
/// with explicit 4-wide multiplies and adds whose sums stay in registers
/// across the rows: each lane takes the same additions in the same order as
/// [`Lanes::add`] (LLVM rebuilt [`Lanes`]' arrays from scalars at every
/// group of four rows).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn wide_lanes<const N: usize>(
    s: Simd,
    l: [&[f64]; N],
    x: &[f64],
    y: &[f64],
    z: &[f64],
) -> [Lanes; N] {
    let load = |a: &[f64]| -> pulp::f64x4 {
        let a: [f64; 4] = a.try_into().expect("a group of four");
        pulp::cast(a)
    };
    let zero = s.splat_f64x4(0.0);
    let mut sums = [[zero; 3]; N];
    for (q, ((x, y), z)) in quads(x).zip(quads(y)).zip(quads(z)).enumerate() {
        let (x, y, z) = (load(x), load(y), load(z));
        for (sum, l) in sums.iter_mut().zip(&l) {
            let l = load(&l[4 * q..4 * q + 4]);
            sum[0] = s.add_f64x4(sum[0], s.mul_f64x4(l, x));
            sum[1] = s.add_f64x4(sum[1], s.mul_f64x4(l, y));
            sum[2] = s.add_f64x4(sum[2], s.mul_f64x4(l, z));
        }
    }
    // A plain loop, as in `narrow_updates`.
    let mut lanes = [Lanes::default(); N];
    for (lanes, [x, y, z]) in lanes.iter_mut().zip(sums) {
        *lanes = Lanes {
            x: pulp::cast(x),
            y: pulp::cast(y),
            z: pulp::cast(z),
        };
    }
    lanes
}

/// `v`'s whole groups of four (the rows past the last multiple of four are
/// left out).
#[inline(always)]
fn quads(v: &[f64]) -> std::slice::ChunksExact<'_, f64> {
    v.chunks_exact(4)
}

/// One column's partial dot products with the three coordinate arrays of
/// [`Below`]: four lanes per coordinate.
#[derive(Default, Clone, Copy)]
struct Lanes {
    x: [f64; 4],
    y: [f64; 4],
    z: [f64; 4],
}

impl Lanes {
    /// Adds four rows' products (groups of four from [`quads`]), the plain
    /// path of [`wide_lanes`].
    #[inline(always)]
    fn add(&mut self, l: &[f64], x: &[f64], y: &[f64], z: &[f64]) {
        for lane in 0..4 {
            self.x[lane] += l[lane] * x[lane];
            self.y[lane] += l[lane] * y[lane];
            self.z[lane] += l[lane] * z[lane];
        }
    }

    /// The lanes summed pairwise, then the rows past the last multiple of
    /// four of `l` added one by one.
    #[inline(always)]
    fn finish(&self, l: &[f64], x: &[f64], y: &[f64], z: &[f64]) -> Point {
        let sum = |s: [f64; 4]| (s[0] + s[1]) + (s[2] + s[3]);
        let (mut tx, mut ty, mut tz) = (sum(self.x), sum(self.y), sum(self.z));
        for k in l.len() - l.len() % 4..l.len() {
            tx += l[k] * x[k];
            ty += l[k] * y[k];
            tz += l[k] * z[k];
        }
        Point::new(tx, ty, tz)
    }
}
