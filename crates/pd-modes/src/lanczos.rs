//! Shift-invert block Lanczos with full reorthogonalisation and thick
//! restarts, for the lowest modes of a large model (`docs/design/damping.md`,
//! "Modes").
//!
//! The operator `Op = (K + s M)^-1 M` is self-adjoint in the M inner
//! product, and its largest eigenvalues `theta = 1 / (lambda + s)` are the
//! wanted lowest `lambda`. The Krylov basis `V` grows by blocks of
//! [`BLOCK`] columns, one three-column solve each (`cholesky`'s supernodal
//! solve, written for three right-hand sides: the factor is read once per
//! three columns); each new block is M-orthogonalised against the rigid
//! motions and against every earlier column (classical Gram-Schmidt, twice),
//! and its coefficients fill the projected matrix `T = V^T M Op V`
//! explicitly. A Ritz pair `(theta, V y)` of `T` has the operator residual
//! `Op x - theta x = V_next B y_last` (`B` the coupling of the newest block
//! to the last expanded one), whose norm `|B y_last|` costs nothing: it
//! gates the exact check of the pencil residual `|K x - lambda M x|_{M^-1}
//! <= TOLERANCE lambda` (`lambda` the Rayleigh quotient `x^T K x`, after a
//! Rayleigh-Ritz step with `K` itself, `refine.rs`), which alone decides
//! convergence, as in subspace iteration. When the basis is
//! full, the best Ritz vectors are kept and the expansion continues from the
//! newest block (a thick restart: `T` restarts as their Ritz values on the
//! diagonal, and the next expansion computes their coupling to the newest
//! block explicitly).
//!
//! Lanczos converges in far fewer solved columns than subspace iteration
//! for well separated low modes: the error in mode `j` falls like a
//! Chebyshev polynomial of the relative gap `(theta_j - theta_{j+1}) /
//! (theta_{j+1} - theta_min)` (Kaniel-Paige-Saad), not like the ratio
//! `theta_{p+1} / theta_j` per iteration. A Ritz value with `lambda` below
//! `ZERO scale` means a zero-stiffness motion other than the deflated rigid
//! ones (a mechanism): its eigenspace may be wider than the block, which
//! Lanczos cannot count, so the caller falls back to subspace iteration.

use std::time::Instant;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use nalgebra::{DMatrix, SymmetricEigen};

use super::subspace::{TOLERANCE, random};
use super::{Phases, ShiftedFactor, Stiffness, ZERO, mass_dot, refine};

/// Columns per block: the width the supernodal solve is written for.
const BLOCK: usize = 3;

/// Blocks solved before giving up (and falling back to subspace iteration).
const MAX_BLOCKS: usize = 400;

/// What [`solve`] found.
pub(super) enum Outcome {
    /// The lowest modes, converged.
    Converged(Found),
    /// A mechanism was seen, or no convergence: use subspace iteration.
    Fallback,
}

/// The converged modes of [`solve`].
pub(super) struct Found {
    /// `(omega^2, mass-normalised phi)`, lowest first.
    pub pairs: Vec<(f64, Vec<f64>)>,
    /// Blocks expanded (one solve each).
    pub blocks: usize,
    /// Right-hand-side columns solved with the factor.
    pub columns: usize,
    /// Thick restarts made.
    pub restarts: usize,
}

/// The Krylov basis, its projected matrix and where the expansion stands.
struct Krylov {
    /// M-orthonormal columns `0..filled`, M-orthogonal to the rigid motions.
    basis: Mat<f64>,
    /// `T = V^T M Op V` over the basis (symmetric, written both ways).
    t: DMatrix<f64>,
    /// Columns `0..expanded` have had `Op` applied; `expanded..filled` is
    /// the newest block, still to be expanded.
    expanded: usize,
    filled: usize,
    /// The last expanded block's columns (coupled to the newest block).
    last: std::ops::Range<usize>,
}

/// The lowest `count` non-zero eigenpairs `(omega^2, mass-normalised phi)`
/// of `stiffness`, the M-orthonormal `rigid` motions deflated, with the
/// factor of `K + s M`.
pub(super) fn solve(
    stiffness: &Stiffness,
    rigid: &[Vec<f64>],
    count: usize,
    factor: &mut ShiftedFactor,
    phases: &mut Phases,
) -> Outcome {
    let nd = stiffness.pattern.n;
    let available = nd - rigid.len();
    let wanted = count.min(available);
    if wanted == 0 {
        return Outcome::Fallback;
    }
    let block = BLOCK.min(available);
    // Room for the kept Ritz vectors and several blocks beyond them.
    let keep = wanted + 2 * block;
    let capacity = available.min((keep + 8 * block).max(10 * block));
    // The wanted modes are lambda > ZERO scale, i.e. theta below this.
    let mechanism_theta = 1.0 / (factor.shift + ZERO * stiffness.scale());
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut krylov = Krylov {
        basis: Mat::zeros(nd, capacity),
        t: DMatrix::zeros(capacity, capacity),
        expanded: 0,
        filled: 0,
        last: 0..0,
    };
    let clock = Instant::now();
    let mut start: Vec<Vec<f64>> = (0..block).map(|_| random(nd, &mut seed)).collect();
    let before: Vec<f64> = start
        .iter()
        .map(|w| mass_dot(&stiffness.mass, w, w).sqrt())
        .collect();
    krylov.project_out(&stiffness.mass, rigid, &mut start);
    krylov.append(&stiffness.mass, rigid, start, &before, &mut seed);
    phases.orthonormalisation += clock.elapsed().as_secs_f64();
    let (mut columns, mut restarts) = (0, 0);
    for blocks in 1..=MAX_BLOCKS {
        columns += krylov.expand(stiffness, rigid, factor, phases, &mut seed);
        let clock = Instant::now();
        let ritz = krylov.ritz();
        if ritz.values.iter().any(|&theta| theta >= mechanism_theta) {
            phases.rayleigh_ritz += clock.elapsed().as_secs_f64();
            return Outcome::Fallback;
        }
        let estimates_small = krylov.expanded >= wanted
            && (0..wanted)
                .all(|k| krylov.residual_estimate(&ritz, k) <= TOLERANCE * ritz.values[k]);
        if estimates_small || krylov.exhausted() {
            if let Some(pairs) = krylov.checked_pairs(stiffness, &ritz, wanted) {
                phases.rayleigh_ritz += clock.elapsed().as_secs_f64();
                return Outcome::Converged(Found {
                    pairs,
                    blocks,
                    columns,
                    restarts,
                });
            }
            if krylov.exhausted() {
                phases.rayleigh_ritz += clock.elapsed().as_secs_f64();
                return Outcome::Fallback;
            }
        }
        if capacity < available && krylov.filled + block > capacity {
            krylov.restart(&ritz, keep);
            restarts += 1;
        }
        phases.rayleigh_ritz += clock.elapsed().as_secs_f64();
    }
    Outcome::Fallback
}

/// The eigenpairs of the projected matrix, largest `theta` first.
struct Ritz {
    values: Vec<f64>,
    /// Column `k`: the coefficients of Ritz vector `k` in the basis.
    vectors: DMatrix<f64>,
}

impl Krylov {
    /// Whether the basis spans the whole deflated space (no newest block).
    fn exhausted(&self) -> bool {
        self.filled == self.expanded
    }

    /// Appends `block` (already M-orthogonal to the rigid motions and the
    /// basis) as the newest block, M-orthonormalised within itself; returns
    /// the coefficients `R` of each column in the new columns (`block_j =
    /// sum_i R_ij v_i`, upper triangular). A column whose remainder is below
    /// `1e-10` of its norm `before` the projections carries no new direction
    /// and is replaced by a fresh random one (its coupling `R_jj` is 0).
    fn append(
        &mut self,
        mass: &[f64],
        rigid: &[Vec<f64>],
        mut block: Vec<Vec<f64>>,
        before: &[f64],
        seed: &mut u64,
    ) -> DMatrix<f64> {
        let q = block.len();
        let mut r = DMatrix::zeros(q, q);
        for j in 0..q {
            for (i, projection) in self.within(mass, &mut block[j], j).into_iter().enumerate() {
                r[(i, j)] = projection;
            }
            let mut norm = mass_dot(mass, &block[j], &block[j]).sqrt();
            r[(j, j)] = norm;
            let mut reference = before[j];
            for _ in 0..4 {
                if norm > 1e-10 * reference {
                    break;
                }
                r[(j, j)] = 0.0;
                let mut fresh = vec![random(mass.len(), seed)];
                reference = mass_dot(mass, &fresh[0], &fresh[0]).sqrt();
                self.project_out(mass, rigid, &mut fresh);
                block[j] = fresh.pop().expect("one column");
                self.within(mass, &mut block[j], j);
                norm = mass_dot(mass, &block[j], &block[j]).sqrt();
            }
            let column = self.basis.col_as_slice_mut(self.filled + j);
            column
                .iter_mut()
                .zip(&block[j])
                .for_each(|(v, x)| *v = x / norm);
        }
        self.filled += q;
        r
    }

    /// M-orthogonalises `column` against the first `j` columns of the block
    /// being appended (Gram-Schmidt, twice); returns the coefficients.
    fn within(&self, mass: &[f64], column: &mut [f64], j: usize) -> Vec<f64> {
        let mut total = vec![0.0; j];
        for _ in 0..2 {
            for (i, sum) in total.iter_mut().enumerate() {
                let new = self.basis.col_as_slice(self.filled + i);
                let projection = mass_dot(mass, new, column);
                column
                    .iter_mut()
                    .zip(new)
                    .for_each(|(x, y)| *x -= projection * y);
                *sum += projection;
            }
        }
        total
    }

    /// M-orthogonalises `block` against the rigid motions and the basis
    /// (classical Gram-Schmidt, twice); returns the basis coefficients
    /// `V^T M block` removed.
    fn project_out(&self, mass: &[f64], rigid: &[Vec<f64>], block: &mut [Vec<f64>]) -> Mat<f64> {
        let q = block.len();
        let filled = self.filled;
        let mut total = Mat::<f64>::zeros(filled, q);
        for _ in 0..2 {
            for column in block.iter_mut() {
                for b in rigid {
                    let projection = mass_dot(mass, b, column);
                    column
                        .iter_mut()
                        .zip(b)
                        .for_each(|(x, y)| *x -= projection * y);
                }
            }
            if filled == 0 {
                continue;
            }
            let weighted = Mat::<f64>::from_fn(mass.len(), q, |i, j| mass[i] * block[j][i]);
            let mut coefficients = Mat::<f64>::zeros(filled, q);
            let basis = self.basis.subcols(0, filled);
            matmul(
                &mut coefficients,
                Accum::Replace,
                basis.transpose(),
                &weighted,
                1.0,
                Par::Seq,
            );
            let mut update = Mat::<f64>::zeros(mass.len(), q);
            matmul(
                &mut update,
                Accum::Replace,
                basis,
                &coefficients,
                1.0,
                Par::Seq,
            );
            for (j, column) in block.iter_mut().enumerate() {
                column
                    .iter_mut()
                    .zip(update.col_as_slice(j))
                    .for_each(|(x, u)| *x -= u);
            }
            for j in 0..q {
                for i in 0..filled {
                    total[(i, j)] += coefficients[(i, j)];
                }
            }
        }
        total
    }

    /// Applies `Op` to the newest block, records its coefficients in `T`
    /// and appends the remainder as the next block; returns the columns
    /// solved.
    fn expand(
        &mut self,
        stiffness: &Stiffness,
        rigid: &[Vec<f64>],
        factor: &mut ShiftedFactor,
        phases: &mut Phases,
        seed: &mut u64,
    ) -> usize {
        let nd = stiffness.pattern.n;
        let current = self.expanded..self.filled;
        let q = current.len();
        let clock = Instant::now();
        let mut rhs = Mat::<f64>::from_fn(nd, q, |i, j| {
            stiffness.mass[i] * self.basis[(i, current.start + j)]
        });
        factor.solve(rhs.as_mut());
        phases.solves += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        let mut block: Vec<Vec<f64>> = (0..q).map(|j| rhs.col_as_slice(j).to_vec()).collect();
        let before: Vec<f64> = block
            .iter()
            .map(|w| mass_dot(&stiffness.mass, w, w).sqrt())
            .collect();
        let coefficients = self.project_out(&stiffness.mass, rigid, &mut block);
        for (j, c) in current.clone().enumerate() {
            for i in 0..self.filled {
                let value = if current.contains(&i) {
                    // The diagonal block, symmetric up to round-off.
                    0.5 * (coefficients[(i, j)] + coefficients[(c, i - current.start)])
                } else {
                    coefficients[(i, j)]
                };
                self.t[(i, c)] = value;
                self.t[(c, i)] = value;
            }
        }
        self.expanded = self.filled;
        self.last = current.clone();
        // The whole deflated space fits: the last blocks may be narrower.
        let next = q.min(stiffness.pattern.n - rigid.len() - self.filled);
        if next > 0 {
            block.truncate(next);
            let first = self.filled;
            let r = self.append(&stiffness.mass, rigid, block, &before, seed);
            for (a, row) in (first..self.filled).enumerate() {
                for (b, c) in current.clone().enumerate().take(next) {
                    let value = if a <= b { r[(a, b)] } else { 0.0 };
                    self.t[(row, c)] = value;
                    self.t[(c, row)] = value;
                }
            }
        }
        phases.orthonormalisation += clock.elapsed().as_secs_f64();
        q
    }

    /// The Ritz pairs of the expanded part of the basis.
    fn ritz(&self) -> Ritz {
        let e = self.expanded;
        let eigen = SymmetricEigen::new(self.t.view((0, 0), (e, e)).into_owned());
        let mut order: Vec<usize> = (0..e).collect();
        order.sort_by(|&i, &j| eigen.eigenvalues[j].total_cmp(&eigen.eigenvalues[i]));
        Ritz {
            values: order.iter().map(|&k| eigen.eigenvalues[k]).collect(),
            vectors: DMatrix::from_fn(e, e, |i, k| eigen.eigenvectors[(i, order[k])]),
        }
    }

    /// `|Op x - theta x|_M` of Ritz pair `k`: `|B y_last|`.
    fn residual_estimate(&self, ritz: &Ritz, k: usize) -> f64 {
        (self.expanded..self.filled)
            .map(|row| {
                self.last
                    .clone()
                    .map(|c| self.t[(row, c)] * ritz.vectors[(c, k)])
                    .sum::<f64>()
                    .powi(2)
            })
            .sum::<f64>()
            .sqrt()
    }

    /// The `wanted` lowest modes, refined from the leading Ritz vectors
    /// (`refine.rs`), if they meet the convergence criterion.
    fn checked_pairs(
        &self,
        stiffness: &Stiffness,
        ritz: &Ritz,
        wanted: usize,
    ) -> Option<Vec<(f64, Vec<f64>)>> {
        let vectors = self.combine(ritz, wanted);
        let basis = (0..wanted)
            .map(|k| vectors.col_as_slice(k).to_vec())
            .collect();
        refine::refine(stiffness, basis, wanted)
    }

    /// The first `k` Ritz vectors `V y` as columns.
    fn combine(&self, ritz: &Ritz, k: usize) -> Mat<f64> {
        let e = self.expanded;
        let coefficients = Mat::<f64>::from_fn(e, k, |i, j| ritz.vectors[(i, j)]);
        let mut out = Mat::<f64>::zeros(self.basis.nrows(), k);
        matmul(
            &mut out,
            Accum::Replace,
            self.basis.subcols(0, e),
            &coefficients,
            1.0,
            Par::Seq,
        );
        out
    }

    /// Keeps the `keep` leading Ritz vectors and the newest block.
    fn restart(&mut self, ritz: &Ritz, keep: usize) {
        let keep = keep.min(self.expanded);
        let kept = self.combine(ritz, keep);
        let newest = self.expanded..self.filled;
        let q = newest.len();
        for (j, c) in newest.enumerate() {
            let (target, source) = (keep + j, c);
            for i in 0..self.basis.nrows() {
                self.basis[(i, target)] = self.basis[(i, source)];
            }
        }
        for j in 0..keep {
            self.basis
                .col_as_slice_mut(j)
                .copy_from_slice(kept.col_as_slice(j));
        }
        self.t.fill(0.0);
        for j in 0..keep {
            self.t[(j, j)] = ritz.values[j];
        }
        self.expanded = keep;
        self.filled = keep + q;
        self.last = 0..0;
    }
}
