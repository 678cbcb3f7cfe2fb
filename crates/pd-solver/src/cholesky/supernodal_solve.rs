//! The triangular solves of a supernodal factor with three right-hand sides
//! (x, y, z of every vertex at once), written for this one shape.
//!
//! faer's general solve pays a fixed price per supernode (dispatch into
//! its dense triangular-solve and product kernels, a temporary matrix,
//! three column-strided passes): measured at about 0.12 us per supernode
//! against 1.76 ns per stored value (docs/performance.md), which dominates on
//! the many narrow supernodes of nested-dissection orders. Here a supernode
//! costs a few loop set-ups, and the right-hand side is stored as points,
//! so each row's gather and scatter touches one cache line instead of three.
//!
//! The factor's layout is faer's: supernode `s` holds columns
//! `begin[s]..begin[s + 1]` (`c` of them) and the below-diagonal rows
//! `row_idx[row_ptr[s]..row_ptr[s + 1]]` (`r` of them), stored column-major
//! as a dense `(c + r) x c` block at `values[value_ptr[s]..]`, the diagonal
//! block (lower triangle meaningful) on top. The arithmetic order is fixed,
//! so results do not depend on the thread count.

use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
use pd_mesh::Point;

/// The supernodal structure and permutation of a factor, copied once from
/// faer's symbolic analysis, and the solve's scratch.
#[derive(Debug, Clone)]
pub(crate) struct SupernodalSolve {
    begin: Vec<usize>,
    /// Where supernode `s`'s below-diagonal rows start in `row_idx`.
    row_ptr: Vec<usize>,
    /// How many there are.
    row_len: Vec<usize>,
    row_idx: Vec<usize>,
    value_ptr: Vec<usize>,
    /// `forward[new] = old`, `None` for the identity.
    forward: Option<Vec<usize>>,
    /// The permuted right-hand side and solution.
    x: Vec<Point>,
    /// One supernode's below-diagonal rows: x, y, z arrays back to back.
    below: Vec<f64>,
}

impl SupernodalSolve {
    /// The plan for `symbolic`, or `None` if faer chose a simplicial
    /// factor (small systems; faer's solve serves those).
    pub fn new(symbolic: &SymbolicCholesky<usize>) -> Option<Self> {
        let SymbolicCholeskyRaw::Supernodal(s) = symbolic.raw() else {
            return None;
        };
        let n_supernodes = s.n_supernodes();
        let begin: Vec<usize> = s
            .supernode_begin()
            .iter()
            .chain(s.supernode_end().last())
            .copied()
            .collect();
        let row_len = s.nnz_per_super().to_vec();
        let value_ptr = s.col_ptr_for_val();
        // The layout this solve assumes; anything else is left to faer.
        let dense_blocks = (0..n_supernodes).all(|k| {
            let c = begin[k + 1] - begin[k];
            value_ptr[k + 1] - value_ptr[k] == (c + row_len[k]) * c
        });
        if !dense_blocks || begin.len() != n_supernodes + 1 {
            return None;
        }
        Some(Self {
            below: vec![0.0; 3 * row_len.iter().copied().max().unwrap_or(0)],
            begin,
            row_ptr: s.col_ptr_for_row_idx().to_vec(),
            row_len,
            row_idx: s.row_idx().to_vec(),
            value_ptr: s.col_ptr_for_val().to_vec(),
            forward: symbolic.perm().map(|p| p.arrays().0.to_vec()),
            x: vec![Point::zeros(); symbolic.nrows()],
        })
    }

    /// Solves `L L^T x = b` in place, `b` given and returned as one point
    /// per row of the (unpermuted) system.
    pub fn solve(&mut self, values: &[f64], rhs: &mut [Point]) {
        match &self.forward {
            Some(forward) => {
                for (x, &old) in self.x.iter_mut().zip(forward) {
                    *x = rhs[old];
                }
            }
            None => self.x.copy_from_slice(rhs),
        }
        self.substitutions(values);
        match &self.forward {
            Some(forward) => {
                for (x, &old) in self.x.iter().zip(forward) {
                    rhs[old] = *x;
                }
            }
            None => rhs.copy_from_slice(&self.x),
        }
    }

    /// Forward then backward substitution, compiled for AVX2 where the CPU
    /// has it (`pulp` dispatches at run time). Rust does not contract
    /// `a * b + c` into a fused multiply-add, so both paths compute the same
    /// bits.
    fn substitutions(&mut self, values: &[f64]) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            struct Op<'a>(&'a mut SupernodalSolve, &'a [f64]);
            impl pulp::WithSimd for Op<'_> {
                type Output = ();
                #[inline(always)]
                fn with_simd<S: pulp::Simd>(self, _: S) {
                    self.0.forward_substitution(self.1);
                    self.0.backward_substitution(self.1);
                }
            }
            return pulp::Simd::vectorize(simd, Op(self, values));
        }
        self.forward_substitution(values);
        self.backward_substitution(values);
    }

    /// `x <- L^-1 x`, supernodes in order.
    #[inline(always)]
    fn forward_substitution(&mut self, values: &[f64]) {
        let Self {
            begin,
            row_ptr,
            row_len,
            row_idx,
            value_ptr,
            x,
            below,
            ..
        } = self;
        let mut below = Below::split(below);
        for s in 0..begin.len() - 1 {
            let (start, c) = (begin[s], begin[s + 1] - begin[s]);
            let rows = &row_idx[row_ptr[s]..row_ptr[s] + row_len[s]];
            let ld = c + rows.len();
            let block = &values[value_ptr[s]..value_ptr[s] + ld * c];
            for j in 0..c {
                let column = &block[j * ld..(j + 1) * ld];
                let xj = x[start + j] / column[j];
                x[start + j] = xj;
                for (i, &l) in column[j + 1..c].iter().enumerate() {
                    x[start + j + 1 + i] -= xj * l;
                }
            }
            below.update(block, ld, c, &x[start..start + c], rows.len());
            for (k, &row) in rows.iter().enumerate() {
                x[row] -= Point::new(below.x[k], below.y[k], below.z[k]);
            }
        }
    }

    /// `x <- L^-T x`, supernodes in reverse order.
    #[inline(always)]
    fn backward_substitution(&mut self, values: &[f64]) {
        let Self {
            begin,
            row_ptr,
            row_len,
            row_idx,
            value_ptr,
            x,
            below,
            ..
        } = self;
        let below = Below::split(below);
        for s in (0..begin.len() - 1).rev() {
            let (start, c) = (begin[s], begin[s + 1] - begin[s]);
            let rows = &row_idx[row_ptr[s]..row_ptr[s] + row_len[s]];
            let ld = c + rows.len();
            let block = &values[value_ptr[s]..value_ptr[s] + ld * c];
            for (k, &row) in rows.iter().enumerate() {
                (below.x[k], below.y[k], below.z[k]) = (x[row].x, x[row].y, x[row].z);
            }
            below.subtract_products(block, ld, c, &mut x[start..start + c], rows.len());
            for j in (0..c).rev() {
                let column = &block[j * ld..(j + 1) * ld];
                let mut sum = x[start + j];
                for (i, &l) in column[j + 1..c].iter().enumerate() {
                    sum -= x[start + j + 1 + i] * l;
                }
                x[start + j] = sum / column[j];
            }
        }
    }
}

/// One supernode's below-diagonal rows, one array per coordinate, so that
/// the loops over rows run four rows per instruction.
struct Below<'a> {
    x: &'a mut [f64],
    y: &'a mut [f64],
    z: &'a mut [f64],
}

impl<'a> Below<'a> {
    #[inline(always)]
    fn split(storage: &'a mut [f64]) -> Self {
        let third = storage.len() / 3;
        let (x, rest) = storage.split_at_mut(third);
        let (y, z) = rest.split_at_mut(third);
        Self { x, y, z }
    }

    /// `below[..r] = L_below x_top`: the forward step's update of the rows
    /// below the supernode, four columns at a time.
    #[inline(always)]
    fn update(&mut self, block: &[f64], ld: usize, c: usize, top: &[Point], r: usize) {
        let (bx, by, bz) = (&mut self.x[..r], &mut self.y[..r], &mut self.z[..r]);
        bx.fill(0.0);
        by.fill(0.0);
        bz.fill(0.0);
        let column = |j: usize| &block[j * ld + c..(j + 1) * ld];
        let mut j = 0;
        while j + 4 <= c {
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
    /// four fixed lanes per coordinate (deterministic order).
    #[inline(always)]
    fn subtract_products(&self, block: &[f64], ld: usize, c: usize, top: &mut [Point], r: usize) {
        let (bx, by, bz) = (&self.x[..r], &self.y[..r], &self.z[..r]);
        let split = r - r % 4;
        for (j, p) in top.iter_mut().enumerate() {
            let l = &block[j * ld + c..(j + 1) * ld];
            let (mut sx, mut sy, mut sz) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4]);
            for k in (0..split).step_by(4) {
                for lane in 0..4 {
                    sx[lane] += l[k + lane] * bx[k + lane];
                    sy[lane] += l[k + lane] * by[k + lane];
                    sz[lane] += l[k + lane] * bz[k + lane];
                }
            }
            let sum = |s: [f64; 4]| (s[0] + s[1]) + (s[2] + s[3]);
            let (mut tx, mut ty, mut tz) = (sum(sx), sum(sy), sum(sz));
            for k in split..r {
                tx += l[k] * bx[k];
                ty += l[k] * by[k];
                tz += l[k] * bz[k];
            }
            *p -= Point::new(tx, ty, tz);
        }
    }
}
