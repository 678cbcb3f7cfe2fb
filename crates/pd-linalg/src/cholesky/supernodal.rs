//! The triangular solves of a supernodal factor with three right-hand sides
//! (x, y, z of every vertex at once), written for this one shape.
//!
//! faer's general solve pays a fixed price per supernode (dispatch into
//! its dense triangular-solve and product kernels, a temporary matrix,
//! three column-strided passes): measured at about 0.12 us per supernode
//! against 1.76 ns per stored value (docs/design/performance.md), which dominates on
//! the many narrow supernodes of nested-dissection orders. Here a supernode
//! costs a few loop set-ups, and the right-hand side is stored as points,
//! so each row's gather and scatter touches one cache line instead of three.
//!
//! Supernode `s` holds columns `begin[s]..end[s]` (`c` of them) and the
//! below-diagonal rows `row_idx[row_ptr[s]..row_ptr[s + 1]]` (`r` of
//! them), stored column-major at `values[value_ptr[s]..]`: in faer's
//! layout as a dense `(c + r) x c` block, the diagonal block (lower
//! triangle meaningful) on top, or packed, each column from its diagonal
//! entry down (`SymbolicFactor::pack`; `Block` reads both). The arithmetic
//! order is fixed, so results depend neither on the thread count nor on
//! the layout.
//!
//! Both cores: disjoint subtrees of the elimination tree touch disjoint
//! columns, so two bins of them (`solve_tree.rs`) are solved at once, each
//! on a compact copy of its columns, adding its updates of the rows above
//! it (the top of the tree) into an accumulator of its own, which the top
//! then subtracts in a fixed order.

use crate::Point;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;

use super::NumericFactor;
use super::solve_kernels::{Below, NARROW, narrow_updates, vectorized};
use super::solve_tree::{TOP, TreeSplit};

// A child of this module (it reads `Structure`'s fields), kept beside it.
mod packed_layout;
pub(in crate::cholesky) use packed_layout::{pack, packed_len, unpack};

/// The narrowest diagonal block whose forward solve runs on coordinate
/// arrays ([`Below::solve_diagonal`]; narrower ones stay on points, where
/// the copies would cost more than they save: 16 executed fewer
/// instructions than 8 on both the beam and the armadillo, callgrind).
/// Either way gives the same bits.
const WIDE_DIAGONAL: usize = 16;

/// The narrowest diagonal block solved by tiles in the forward and in the
/// backward step (`solve_diagonal.rs`: another summation order, so other
/// round-off, than the column-by-column solve of narrower blocks). They
/// depend only on the block's width, so every thread count gets the same
/// bits.
const BLOCKED_DIAGONAL: [usize; 2] = [16, 16];

/// The smallest factor (bytes of stored values) whose solve prefetches its
/// values (`Below::prefetch`; the same bits either way). On this machine
/// (32 MiB L3) the 80 x 14 x 14 beam's 27.8 MB factor does not stay in
/// the cache between passes and its solve was about 10 % faster with
/// prefetches, while the armadillo's 7.3 MB factor, which does, was
/// slower (the prefetch instructions cost, and the data was already
/// there; docs/design/performance.md, "pd's own supernodal solve").
const PREFETCH_BYTES: usize = 16 << 20;

/// The supernodal structure of a factor: a view of faer's symbolic
/// analysis (not a copy: its row indices alone are a tenth of the factor's
/// size), read by both halves of a split solve.
#[derive(Debug, Clone, Copy)]
struct Structure<'a> {
    /// Supernode `s` holds columns `begin[s]..end[s]`.
    begin: &'a [usize],
    end: &'a [usize],
    /// Where supernode `s`'s below-diagonal rows start in `row_idx`.
    row_ptr: &'a [usize],
    /// How many there are.
    row_len: &'a [usize],
    row_idx: &'a [usize],
    /// Where supernode `s`'s values start, in the factor's layout.
    value_ptr: &'a [usize],
    /// Whether the factor is packed (`value_ptr` is then its own).
    packed: bool,
    /// Whether the kernels prefetch the factor's values (a factor of at
    /// least [`PREFETCH_BYTES`]).
    prefetch: bool,
    /// The narrowest diagonal block solved by tiles, forward and backward
    /// ([`BLOCKED_DIAGONAL`]; tests turn them off).
    blocked: [usize; 2],
    /// Supernodes narrower than this update their rows below row by row
    /// ([`NARROW`]; tests turn it off).
    narrow: usize,
}

impl<'a> Structure<'a> {
    /// The view of `symbolic`'s supernodes, `None` for a simplicial factor.
    fn of(symbolic: &'a SymbolicCholesky<usize>) -> Option<Self> {
        let SymbolicCholeskyRaw::Supernodal(s) = symbolic.raw() else {
            return None;
        };
        Some(Self {
            begin: s.supernode_begin(),
            end: s.supernode_end(),
            row_ptr: s.col_ptr_for_row_idx(),
            row_len: s.nnz_per_super(),
            row_idx: s.row_idx(),
            value_ptr: s.col_ptr_for_val(),
            packed: false,
            prefetch: s.col_ptr_for_val().last().copied().unwrap_or(0) * 8 >= PREFETCH_BYTES,
            blocked: BLOCKED_DIAGONAL,
            narrow: NARROW,
        })
    }
}

/// One bin's scratch: its columns' compact copy, a supernode's
/// below-diagonal rows, and the sums of its updates to the top's rows (in
/// the order of [`TreeSplit::top_columns`]).
#[derive(Debug, Clone)]
struct Lane {
    x: Vec<Point>,
    below: Vec<f64>,
    top_updates: Vec<Point>,
}

/// The two-thread split of a factor's elimination tree and the solve's
/// scratch; the structure and permutation are read from faer's symbolic
/// factor at each solve.
#[derive(Debug, Clone)]
pub(crate) struct SupernodalSolve {
    split: TreeSplit,
    /// The permuted right-hand side and solution.
    x: Vec<Point>,
    /// The top's scratch, and each bin's.
    below: Vec<f64>,
    lanes: [Lane; 2],
    /// Whether the kernels prefetch the factor (at least
    /// [`PREFETCH_BYTES`] stored).
    prefetch: bool,
    /// The narrowest diagonal block solved by tiles, forward and backward
    /// ([`BLOCKED_DIAGONAL`]).
    blocked: [usize; 2],
    /// Supernodes narrower than this update row by row ([`NARROW`]).
    narrow: usize,
}

impl SupernodalSolve {
    /// The plan for `symbolic`, or `None` if faer chose a simplicial
    /// factor (small systems; faer's solve serves those).
    pub fn new(symbolic: &SymbolicCholesky<usize>) -> Option<Self> {
        let structure = Structure::of(symbolic)?;
        let n_supernodes = structure.begin.len();
        let Structure {
            begin,
            end,
            row_len,
            value_ptr,
            ..
        } = structure;
        // The layout this solve assumes; anything else is left to faer.
        let dense_blocks = (0..n_supernodes).all(|k| {
            let c = end[k] - begin[k];
            value_ptr[k + 1] - value_ptr[k] == (c + row_len[k]) * c
        });
        let contiguous = (1..n_supernodes).all(|k| begin[k] == end[k - 1]);
        if !dense_blocks || !contiguous || end.len() != n_supernodes {
            return None;
        }
        let split = structure.tree_split();
        let n = symbolic.nrows();
        // A supernode's rows below its diagonal block, or its columns (the
        // forward step's diagonal solve uses the same scratch first).
        let widest = (0..n_supernodes).map(|s| end[s] - begin[s]).max();
        let width = 3 * structure
            .row_len
            .iter()
            .copied()
            .chain(widest)
            .max()
            .unwrap_or(0);
        let lane = |columns: &[usize]| Lane {
            x: vec![Point::zeros(); columns.len()],
            below: vec![0.0; width],
            top_updates: vec![
                Point::zeros();
                if split.is_split() {
                    split.top_columns.len()
                } else {
                    0
                }
            ],
        };
        Some(Self {
            below: vec![0.0; width],
            lanes: [lane(&split.bin_columns[0]), lane(&split.bin_columns[1])],
            split,
            x: vec![Point::zeros(); n],
            prefetch: structure.prefetch,
            blocked: BLOCKED_DIAGONAL,
            narrow: NARROW,
        })
    }

    /// Sets the narrowest diagonal block solved by tiles, forward and
    /// backward (tests: `usize::MAX` gives the column-by-column solve).
    #[cfg(test)]
    pub fn set_blocked(&mut self, narrowest: [usize; 2]) {
        self.blocked = narrowest;
    }

    /// Sets the width below which supernodes update row by row (tests: 0
    /// gives the coordinate arrays' passes everywhere).
    #[cfg(test)]
    pub fn set_narrow(&mut self, narrow: usize) {
        self.narrow = narrow;
    }

    /// Turns the kernels' prefetches on or off, whatever the factor's size
    /// (tests: they must not change a bit).
    #[cfg(test)]
    pub fn set_prefetch(&mut self, on: bool) {
        self.prefetch = on;
    }

    /// Whether the solve runs in two halves (independent of the thread
    /// count: with one thread they run one after the other).
    #[cfg(test)]
    pub fn is_split(&self) -> bool {
        self.split.is_split()
    }

    /// Solves `L L^T x = b` in place, `b` given and returned as one point
    /// per row of the (unpermuted) system, with `factor` in either layout.
    /// `symbolic` is the factor's symbolic analysis this plan was made for.
    pub fn solve(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
        factor: &NumericFactor,
        rhs: &mut [Point],
    ) {
        let values = &factor.values[..];
        let structure = self.structure(symbolic, factor);
        let forward = symbolic.perm().map(|p| p.arrays().0);
        self.permute_in(forward, rhs);
        self.forward_substitution(&structure, values);
        self.backward_substitution(&structure, values);
        self.permute_out(forward, rhs);
    }

    /// The view of `symbolic`'s supernodes in `factor`'s layout, with this
    /// plan's kernel settings (prefetches, tiled diagonal blocks, narrow
    /// supernodes).
    fn structure<'a>(
        &self,
        symbolic: &'a SymbolicCholesky<usize>,
        factor: &'a NumericFactor,
    ) -> Structure<'a> {
        Structure {
            prefetch: self.prefetch,
            blocked: self.blocked,
            narrow: self.narrow,
            ..Structure::of(symbolic)
                .expect("the plan of a supernodal factor")
                .in_layout_of(factor)
        }
    }

    /// `x = P rhs`: the right-hand side in the factor's order.
    fn permute_in(&mut self, forward: Option<&[usize]>, rhs: &[Point]) {
        match forward {
            Some(forward) => {
                for (x, &old) in self.x.iter_mut().zip(forward) {
                    *x = rhs[old];
                }
            }
            None => self.x.copy_from_slice(rhs),
        }
    }

    /// `rhs = P^T x`: the solution back in the caller's order.
    fn permute_out(&self, forward: Option<&[usize]>, rhs: &mut [Point]) {
        match forward {
            Some(forward) => {
                for (x, &old) in self.x.iter().zip(forward) {
                    rhs[old] = *x;
                }
            }
            None => rhs.copy_from_slice(&self.x),
        }
    }

    /// `x <- L^-1 x`: the bins' subtrees (at once when there are two
    /// threads), their updates of the top's rows subtracted bin 0 first,
    /// then the top's supernodes in order.
    fn forward_substitution(&mut self, structure: &Structure<'_>, values: &[f64]) {
        let Self {
            split,
            x,
            below,
            lanes,
            ..
        } = self;
        if split.is_split() {
            let [lane0, lane1] = lanes;
            let shared: &[Point] = x;
            rayon::join(
                || structure.forward_bin(values, split, 0, shared, lane0),
                || structure.forward_bin(values, split, 1, shared, lane1),
            );
            for (lane, columns) in lanes.iter().zip(&split.bin_columns) {
                for (&column, p) in columns.iter().zip(&lane.x) {
                    x[column] = *p;
                }
                for (&row, update) in split.top_columns.iter().zip(&lane.top_updates) {
                    x[row] -= *update;
                }
            }
        }
        vectorized(
            #[inline(always)]
            |simd| {
                let mut below = Below::split(below, simd, structure.prefetch);
                for &s in &split.top {
                    let first = structure.begin[s];
                    structure.forward_supernode(values, s, x, first, Some, &mut below, |_, _| {});
                }
            },
        );
    }

    /// `x <- L^-T x`: the top's supernodes in reverse order, then the bins'
    /// subtrees (at once when there are two threads), which read the top's
    /// rows from `x`.
    fn backward_substitution(&mut self, structure: &Structure<'_>, values: &[f64]) {
        let Self {
            split,
            x,
            below,
            lanes,
            ..
        } = self;
        vectorized(
            #[inline(always)]
            |simd| {
                let mut below = Below::split(below, simd, structure.prefetch);
                for (i, &s) in split.top.iter().enumerate().rev() {
                    if i > 0 && below.prefetches() {
                        structure.prefetch_backward_start(values, split.top[i - 1], &below);
                    }
                    let first = structure.begin[s];
                    structure.backward_supernode(values, s, x, first, Some, &mut below, |_| {
                        Point::zeros()
                    });
                }
            },
        );
        if split.is_split() {
            let [lane0, lane1] = lanes;
            let shared: &[Point] = x;
            rayon::join(
                || structure.backward_bin(values, split, 0, shared, lane0),
                || structure.backward_bin(values, split, 1, shared, lane1),
            );
            for (lane, columns) in lanes.iter().zip(&split.bin_columns) {
                for (&column, p) in columns.iter().zip(&lane.x) {
                    x[column] = *p;
                }
            }
        }
    }
}

impl Structure<'_> {
    /// The two-thread split of this factor's elimination tree.
    fn tree_split(&self) -> TreeSplit {
        let n = self.row_len.len();
        let mut supernode_of = vec![0; self.end.last().copied().unwrap_or(0)];
        for s in 0..n {
            supernode_of[self.begin[s]..self.end[s]].fill(s);
        }
        let parent: Vec<Option<usize>> = (0..n)
            .map(|s| {
                let rows = &self.row_idx[self.row_ptr[s]..self.row_ptr[s] + self.row_len[s]];
                rows.iter().min().map(|&r| supernode_of[r])
            })
            .collect();
        let cost: Vec<usize> = (0..n)
            .map(|s| self.value_ptr[s + 1] - self.value_ptr[s])
            .collect();
        let begin: Vec<usize> = self.begin.iter().chain(self.end.last()).copied().collect();
        TreeSplit::new(&begin, &parent, &cost)
    }

    /// Forward substitution over bin `bin`'s supernodes, on a compact copy
    /// of its columns taken from `x`; its updates of the top's rows are
    /// summed in `lane.top_updates`.
    fn forward_bin(
        &self,
        values: &[f64],
        split: &TreeSplit,
        bin: usize,
        x: &[Point],
        lane: &mut Lane,
    ) {
        let Lane {
            x: local,
            below,
            top_updates,
        } = lane;
        top_updates.fill(Point::zeros());
        for (p, &column) in local.iter_mut().zip(&split.bin_columns[bin]) {
            *p = x[column];
        }
        let locate = |row: usize| Some(split.slot[row] as usize).filter(|_| split.slot[row] != TOP);
        vectorized(
            #[inline(always)]
            |simd| {
                let mut below = Below::split(below, simd, self.prefetch);
                for &s in &split.bins[bin] {
                    let first = split.slot[self.begin[s]] as usize;
                    self.forward_supernode(
                        values,
                        s,
                        local,
                        first,
                        locate,
                        &mut below,
                        #[inline(always)]
                        |row, u| {
                            top_updates[split.top_position[row] as usize] += u;
                        },
                    );
                }
            },
        );
    }

    /// Backward substitution over bin `bin`'s supernodes, on a compact copy
    /// of its columns taken from `x`, reading the top's rows from `x`.
    fn backward_bin(
        &self,
        values: &[f64],
        split: &TreeSplit,
        bin: usize,
        x: &[Point],
        lane: &mut Lane,
    ) {
        let Lane {
            x: local, below, ..
        } = lane;
        for (p, &column) in local.iter_mut().zip(&split.bin_columns[bin]) {
            *p = x[column];
        }
        let locate = |row: usize| Some(split.slot[row] as usize).filter(|_| split.slot[row] != TOP);
        vectorized(
            #[inline(always)]
            |simd| {
                let mut below = Below::split(below, simd, self.prefetch);
                for (i, &s) in split.bins[bin].iter().enumerate().rev() {
                    if i > 0 && below.prefetches() {
                        self.prefetch_backward_start(values, split.bins[bin][i - 1], &below);
                    }
                    let first = split.slot[self.begin[s]] as usize;
                    self.backward_supernode(values, s, local, first, locate, &mut below, |row| {
                        x[row]
                    });
                }
            },
        );
    }

    /// Prefetches what supernode `s`'s backward step reads first: its row
    /// indices and its first two columns' rows below the diagonal block.
    #[inline(always)]
    fn prefetch_backward_start(&self, values: &[f64], s: usize, below: &Below) {
        let c = self.end[s] - self.begin[s];
        let block = self.block(values, s);
        for j in 0..c.min(2) {
            below.prefetch(&block, j, c, self.row_len[s]);
        }
    }

    /// Supernode `s`'s forward step on `x`, where its columns start at
    /// `first` and `locate` finds a row (`None`: not in `x`): its columns
    /// solved with the diagonal block, and each row below updated in `x` or
    /// handed to `outside`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn forward_supernode(
        &self,
        values: &[f64],
        s: usize,
        x: &mut [Point],
        first: usize,
        locate: impl Fn(usize) -> Option<usize>,
        below: &mut Below,
        mut outside: impl FnMut(usize, Point),
    ) {
        let c = self.end[s] - self.begin[s];
        let rows = &self.row_idx[self.row_ptr[s]..self.row_ptr[s] + self.row_len[s]];
        let block = self.block(values, s);
        let top = &mut x[first..first + c];
        if c >= self.blocked[0] {
            below.solve_diagonal_blocked(&block, top);
        } else if c >= WIDE_DIAGONAL {
            below.solve_diagonal(&block, top);
        } else {
            for j in 0..c {
                // Column j from its diagonal: row j + 1 + i is column[1 + i].
                let column = block.column(j);
                let xj = top[j] / column[0];
                top[j] = xj;
                for (i, &l) in column[1..c - j].iter().enumerate() {
                    top[j + 1 + i] -= xj * l;
                }
            }
        }
        let r = rows.len();
        if c < self.narrow {
            let mut p = [Point::zeros(); NARROW - 1];
            p[..c].copy_from_slice(top);
            narrow_updates(
                &block,
                &p[..c],
                r,
                #[inline(always)]
                |k, update| match locate(rows[k]) {
                    Some(i) => x[i] -= update,
                    None => outside(rows[k], update),
                },
            );
            return;
        }
        below.update(&block, c, top, r);
        let updates = below.x[..r].iter().zip(&below.y[..r]).zip(&below.z[..r]);
        for (&row, ((&ux, &uy), &uz)) in rows.iter().zip(updates) {
            let update = Point::new(ux, uy, uz);
            match locate(row) {
                Some(i) => x[i] -= update,
                None => outside(row, update),
            }
        }
    }

    /// Supernode `s`'s backward step on `x`, where its columns start at
    /// `first` and `locate` finds a row; rows not in `x` are read from
    /// `outside`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn backward_supernode(
        &self,
        values: &[f64],
        s: usize,
        x: &mut [Point],
        first: usize,
        locate: impl Fn(usize) -> Option<usize>,
        below: &mut Below,
        outside: impl Fn(usize) -> Point,
    ) {
        let c = self.end[s] - self.begin[s];
        let rows = &self.row_idx[self.row_ptr[s]..self.row_ptr[s] + self.row_len[s]];
        let block = self.block(values, s);
        let r = rows.len();
        let gathered = below.x[..r]
            .iter_mut()
            .zip(&mut below.y[..r])
            .zip(&mut below.z[..r]);
        for (&row, ((bx, by), bz)) in rows.iter().zip(gathered) {
            let p = match locate(row) {
                Some(i) => x[i],
                None => outside(row),
            };
            (*bx, *by, *bz) = (p.x, p.y, p.z);
        }
        let top = &mut x[first..first + c];
        below.subtract_products(&block, c, top, r);
        if c >= self.blocked[1] {
            below.solve_diagonal_transposed_blocked(&block, top);
            return;
        }
        for j in (0..c).rev() {
            // The next column's rows under the diagonal.
            if below.prefetches() && j > 0 && c >= WIDE_DIAGONAL {
                below.prefetch(&block, j - 1, j, c - j);
            }
            // Column j from its diagonal: row j + 1 + i is column[1 + i].
            let column = block.column(j);
            let mut sum = top[j];
            for (i, &l) in column[1..c - j].iter().enumerate() {
                sum -= top[j + 1 + i] * l;
            }
            top[j] = sum / column[0];
        }
    }
}

#[cfg(test)]
mod tests;
