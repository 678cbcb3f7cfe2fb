//! The largest eigenvalue of the local-global map's linearisation, from a
//! step's own iterates, whatever combines them (Chebyshev's `rho =
//! "auto"`).
//!
//! With `G` one local-global iteration and `T = I - A^{-1} H` its
//! linearisation, any iteration that builds `x_(k+1)` from affine
//! combinations of earlier iterates and their images `G(x_j)` keeps the
//! differences `u_k = x_(k+1) - x_k` in the Krylov space of `T`, and the
//! images of those differences are known without extra work:
//! `T u_k = G(x_(k+1)) - G(x_k)`, so `A T u_k = b_(k+1) - b_k` with `b_k` the
//! right-hand side iteration `k` solved (`A G(x_k) = b_k`). `A u_k` follows
//! from `A x_k`, carried along by the same combination: `A x_(k+1) = b_k`
//! after a plain iteration, and the combination of `A x_k`, `A x_(k-1)` and
//! `b_k` after an accelerated one (no product with `A` in either case).
//! `T` is self-adjoint in the `A` inner product (`A T = A - H`), so the Ritz
//! values of `T` on the span of the `u`s are the eigenvalues of the
//! symmetric pencil `(u_i . A T u_j, u_i . A u_j)`. Like every Ritz value
//! the largest lies inside the spectrum, so the estimate errs low, the safe
//! side for Chebyshev (docs/design/solver.md, "Chebyshev's `rho` from every
//! step").
//!
//! All vectors live over the free vertices (the global step's unknowns).
//! The buffers are allocated once and reused, so a step allocates nothing.

use nalgebra::{SMatrix, SymmetricEigen};
use pd_mesh::Point;

/// The most differences `u_k` kept from one step: `u_1 .. u_8`, the first
/// nine iterations after the first. The benchmark beam's per-step Ritz
/// value with 8 is within 0.01 of the value with 28 (docs/design/solver.md).
pub(crate) const PAIRS: usize = 8;

/// The largest skew part (entry by entry) of the whitened pencil that an
/// estimate may rest on; see [`RitzEstimator::estimate`].
const SKEW: f64 = 0.02;

/// The pencil's fixed-size matrices.
type Pencil = SMatrix<f64, PAIRS, PAIRS>;

/// How an iteration made `x_(k+1)` from `x_k`, for carrying `A x` along.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Next {
    /// `x_(k+1) = G(x_k)`.
    Plain,
    /// `x_(k+1) = omega (x_k + alpha (G(x_k) - x_k) - x_(k-1)) + x_(k-1)`.
    Combined { alpha: f64, omega: f64 },
}

/// A step's Krylov pairs and the pencil built from them.
#[derive(Debug, Clone, Default)]
pub(crate) struct RitzEstimator {
    /// `u_1, u_2, ...` over the free vertices, three values a vertex.
    basis: Vec<Vec<f64>>,
    /// `A T u_1, A T u_2, ...`, complete for all but a pending last one.
    images: Vec<Vec<f64>>,
    /// How many of `basis` hold this step's vectors.
    stored: usize,
    /// Whether the last stored `u` still waits for its image.
    pending: bool,
    /// `A x_k` and `A x_(k-1)` for the current iterate `x_k`, once known.
    a_current: Vec<Point>,
    a_previous: Vec<Point>,
    /// How many consecutive `A x` are known (0, 1 or 2 and more).
    known: usize,
    /// `A u_k`, and the last right-hand side `b_k`.
    a_u: Vec<f64>,
    last_rhs: Vec<Point>,
    /// `u_i . A u_j` and `u_i . A T u_j`.
    g0: Pencil,
    g1: Pencil,
}

/// Running sums of [`dot`]: independent, so the compiler runs them as
/// vector lanes (two AVX-512 or four AVX2 registers) without reordering
/// any sum, and every instruction set gives the same bits.
const SUMS: usize = 16;

/// `a . b` with [`SUMS`] running sums (one sum alone is bound by its add's
/// latency), combined in a fixed order.
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut sums = [0.0; SUMS];
    let (a_chunks, b_chunks) = (a.chunks_exact(SUMS), b.chunks_exact(SUMS));
    let mut tail = 0.0;
    for (a, b) in a_chunks.remainder().iter().zip(b_chunks.remainder()) {
        tail += a * b;
    }
    for (a, b) in a_chunks.zip(b_chunks) {
        for ((sum, a), b) in sums.iter_mut().zip(a).zip(b) {
            *sum += a * b;
        }
    }
    let mut width = SUMS;
    while width > 1 {
        width /= 2;
        for i in 0..width {
            sums[i] += sums[i + width];
        }
    }
    sums[0] + tail
}

/// `out[i] = vectors[i] . target` for the first `out.len()` vectors,
/// compiled for the widest instruction set the CPU has. A step makes up
/// to 108 of these products over `3 x` free vertices: about 80 us of the
/// estimator's 0.16-0.19 ms a step on the 2,304-vertex beam at 9
/// iterations (4-5 % of the step; docs/design/solver.md, "Chebyshev's `rho` from
/// every step").
fn dots(vectors: &[Vec<f64>], target: &[f64], out: &mut [f64]) {
    pd_linalg::simd::vectorized(
        #[inline(always)]
        |_| {
            for (o, vector) in out.iter_mut().zip(vectors) {
                *o = dot(vector, target);
            }
        },
    );
}

impl RitzEstimator {
    /// Starts a step with `free` unknowns: `A x_0` is not known (the start
    /// did not come from a solve), so the first pair is `u_1`.
    pub(crate) fn begin_step(&mut self, free: usize) {
        if self.a_current.len() != free {
            self.basis = (0..PAIRS).map(|_| vec![0.0; 3 * free]).collect();
            self.images = (0..PAIRS).map(|_| vec![0.0; 3 * free]).collect();
            self.a_current = vec![Point::zeros(); free];
            self.a_previous = vec![Point::zeros(); free];
            self.a_u = vec![0.0; 3 * free];
            self.last_rhs = vec![Point::zeros(); free];
        }
        self.stored = 0;
        self.pending = false;
        self.known = 0;
    }

    /// Whether the window holds [`PAIRS`] complete pairs (and records
    /// nothing more until [`Self::restart_window`]).
    pub(crate) fn full(&self) -> bool {
        self.stored == PAIRS && !self.pending
    }

    /// Starts a new window of pairs at the current iterate, keeping `A x`
    /// (so the next difference is the window's first pair).
    pub(crate) fn restart_window(&mut self) {
        self.stored = 0;
        self.pending = false;
    }

    /// Whether the step still records anything.
    fn active(&self) -> bool {
        self.stored < PAIRS || self.pending
    }

    /// Iteration `k` solved for `G(x_k)` with right-hand side `rhs`
    /// (`b_k`): completes the image of `u_(k-1)`, if stored.
    pub(crate) fn solved(&mut self, rhs: &[Point]) {
        if !self.active() {
            return;
        }
        if self.pending {
            // A T u_(k-1) = b_k - b_(k-1).
            let j = self.stored - 1;
            for ((image, last), b) in self.images[j]
                .chunks_exact_mut(3)
                .zip(&self.last_rhs)
                .zip(rhs)
            {
                image.copy_from_slice((b - last).as_slice());
            }
            let mut column = [0.0; PAIRS];
            dots(&self.basis, &self.images[j], &mut column[..=j]);
            let mut row = [0.0; PAIRS];
            dots(&self.images, &self.basis[j], &mut row[..=j]);
            for i in 0..=j {
                self.g1[(i, j)] = column[i];
                self.g1[(j, i)] = row[i];
            }
            self.pending = false;
        }
        self.last_rhs.copy_from_slice(rhs);
    }

    /// The iteration made `x_(k+1)` (`next`, the whole displacement) from
    /// `x_k` (`current`) as `how` says; `free` maps the unknowns to
    /// vertices. Stores `u_k` while fewer than [`PAIRS`] are kept.
    pub(crate) fn advanced(
        &mut self,
        free: &[usize],
        next: &[Point],
        current: &[Point],
        how: Next,
    ) {
        if !self.active() {
            return;
        }
        // A x_(k+1) into a_previous (which held A x_(k-1)), then swap.
        match how {
            Next::Plain => self.a_previous.copy_from_slice(&self.last_rhs),
            Next::Combined { alpha, omega } => {
                if self.known < 2 {
                    // Cannot happen after two plain iterations; the chain
                    // restarts from here if it does.
                    self.known = 0;
                    return;
                }
                for ((p, c), b) in self
                    .a_previous
                    .iter_mut()
                    .zip(&self.a_current)
                    .zip(&self.last_rhs)
                {
                    let relaxed = *c + (b - c) * alpha;
                    *p = (relaxed - *p) * omega + *p;
                }
            }
        }
        std::mem::swap(&mut self.a_previous, &mut self.a_current);
        self.known += 1;
        // u_k needs A x_k too.
        if self.known < 2 || self.stored == PAIRS {
            return;
        }
        let j = self.stored;
        for (((u, a_u), &v), (a_next, a_here)) in self.basis[j]
            .chunks_exact_mut(3)
            .zip(self.a_u.chunks_exact_mut(3))
            .zip(free)
            .zip(self.a_current.iter().zip(&self.a_previous))
        {
            u.copy_from_slice((next[v] - current[v]).as_slice());
            a_u.copy_from_slice((a_next - a_here).as_slice());
        }
        let mut column = [0.0; PAIRS];
        dots(&self.basis, &self.a_u, &mut column[..=j]);
        for (i, &value) in column[..=j].iter().enumerate() {
            self.g0[(i, j)] = value;
            self.g0[(j, i)] = value;
        }
        self.stored += 1;
        self.pending = true;
    }

    /// The number of pairs with both entries known.
    fn pairs(&self) -> usize {
        self.stored - usize::from(self.pending)
    }

    /// The largest Ritz value of `T` from this step's complete pairs, or
    /// `None` with fewer than two or a degenerate pencil (the iteration
    /// converged or stalled). Fixed-size matrices: steps allocate nothing.
    pub(crate) fn estimate(&self) -> Option<f64> {
        let m = self.pairs();
        if m < 2 {
            return None;
        }
        let mut g0 = self.g0;
        let mut g1 = self.g1;
        // Unused rows: identity in G0 at its largest diagonal entry (no
        // larger than its largest eigenvalue), zero in G1, so the pencil's
        // extra eigenvalues are 0 and the largest one is the estimate.
        let scale = (0..m).map(|i| g0[(i, i)]).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return None;
        }
        for i in 0..PAIRS {
            for j in 0..PAIRS {
                if i >= m || j >= m {
                    g0[(i, j)] = if i == j { scale } else { 0.0 };
                    g1[(i, j)] = 0.0;
                }
            }
        }
        // G0 = V D V^T. The Krylov vectors grow nearly parallel, and their
        // images carry the map's nonlinearity (each pair is linearised at a
        // different iterate), which the whitening amplifies in the weakest
        // directions. On the linearisation the whitened pencil
        // S = W^T G1 W (W = V_kept D_kept^(-1/2)) is symmetric, so its skew
        // part measures that error: directions are dropped from the weakest
        // up until the skew part is below SKEW, and the estimate is the
        // largest eigenvalue of S's symmetric part, which a symmetric error
        // of that size moves by no more (Weyl).
        let eigen = SymmetricEigen::new(g0);
        let largest = eigen.eigenvalues.max();
        let mut order: [usize; PAIRS] = std::array::from_fn(|c| c);
        order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
        let mut accepted = None;
        for kept in 1..=PAIRS {
            let d = eigen.eigenvalues[order[kept - 1]];
            if !(d > 1e-14 * largest) {
                break;
            }
            let mut w = Pencil::zeros();
            for &c in &order[..kept] {
                w.set_column(
                    c,
                    &(eigen.eigenvectors.column(c) / eigen.eigenvalues[c].sqrt()),
                );
            }
            let whitened = w.transpose() * g1 * w;
            let skew = (whitened - whitened.transpose()).abs().max() * 0.5;
            if skew > SKEW {
                break;
            }
            accepted = Some(whitened);
        }
        let whitened = accepted?;
        let theta = SymmetricEigen::new((whitened + whitened.transpose()) * 0.5)
            .eigenvalues
            .max();
        (theta.is_finite() && theta > 0.0).then_some(theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear map with a known spectrum: per unknown `G(x) = x - (h x -
    /// f) / a`, so `T = I - A^{-1} H` is diagonal with `t = 1 - h / a`, and
    /// `A G(x) = a x - h x + f` is the right-hand side it "solved".
    struct Linear {
        a: Vec<Point>,
        h: Vec<Point>,
        f: Vec<Point>,
    }

    impl Linear {
        /// `n` vertices: one eigenvalue `top`, the other `3 n - 1` spread
        /// over `[0, rest]`.
        fn new(n: usize, top: f64, rest: f64) -> Self {
            let count = 3 * n - 1;
            let mut a = Vec::new();
            let mut h = Vec::new();
            let mut f = Vec::new();
            for v in 0..n {
                let mut a_v = Point::zeros();
                let mut h_v = Point::zeros();
                for c in 0..3 {
                    let i = 3 * v + c;
                    let t = if i == 0 {
                        top
                    } else {
                        rest * (i - 1) as f64 / (count - 1) as f64
                    };
                    // A's scale varies too, as the mass and stiffness do.
                    a_v[c] = 1.0 + (i % 7) as f64;
                    h_v[c] = a_v[c] * (1.0 - t);
                }
                a.push(a_v);
                h.push(h_v);
                f.push(Point::new(1.0, -0.5, 0.25) * (v as f64 + 1.0).sqrt());
            }
            Self { a, h, f }
        }

        /// `G(x)` and its right-hand side `A G(x)`.
        fn apply(&self, x: &[Point]) -> (Vec<Point>, Vec<Point>) {
            let rhs: Vec<Point> = (0..x.len())
                .map(|v| {
                    self.a[v].component_mul(&x[v]) - self.h[v].component_mul(&x[v]) + self.f[v]
                })
                .collect();
            let g = (0..x.len())
                .map(|v| rhs[v].component_div(&self.a[v]))
                .collect();
            (g, rhs)
        }
    }

    /// Runs `iterations` iterations of plain PD (`rho = None`) or of the
    /// over-relaxed Chebyshev recurrence from iteration 2, as
    /// `chebyshev.rs` does, feeding the estimator; returns its estimate.
    fn drive(map: &Linear, rho: Option<f64>, iterations: usize) -> Option<f64> {
        let n = map.a.len();
        let free: Vec<usize> = (0..n).collect();
        let mut estimator = RitzEstimator::default();
        estimator.begin_step(n);
        let mut x: Vec<Point> = (0..n)
            .map(|v| Point::new((v as f64).sin(), (2.0 * v as f64).cos(), 0.3))
            .collect();
        let mut previous = x.clone();
        let mut omega: f64 = 1.0;
        for k in 0..iterations {
            let (g, rhs) = map.apply(&x);
            estimator.solved(&rhs);
            let (next, how) = match rho {
                Some(rho) if k >= 2 => {
                    let alpha = 2.0 / (2.0 - rho);
                    let squared = (rho / (2.0 - rho)).powi(2);
                    omega = if omega == 1.0 {
                        2.0 / (2.0 - squared)
                    } else {
                        4.0 / (4.0 - squared * omega)
                    };
                    let next = (0..n)
                        .map(|v| {
                            let relaxed = x[v] + (g[v] - x[v]) * alpha;
                            (relaxed - previous[v]) * omega + previous[v]
                        })
                        .collect();
                    (next, Next::Combined { alpha, omega })
                }
                _ => (g, Next::Plain),
            };
            estimator.advanced(&free, &next, &x, how);
            previous = std::mem::replace(&mut x, next);
        }
        estimator.estimate()
    }

    /// On a linear map whose largest eigenvalue (0.8) stands apart from
    /// the rest ([0, 0.5]), eight pairs find it whether the iterates are
    /// plain or Chebyshev's (with a `rho` below it, 0.6, or above, 0.9):
    /// Kaniel-Paige's bound for 7 Lanczos steps and that gap, `0.8 tan^2
    /// / T_7(2.2)^2`, is about 1e-8 of the start's angle, so 1e-6 leaves
    /// room only for round-off and no Ritz value may exceed the spectrum.
    #[test]
    fn finds_an_isolated_top_from_plain_and_accelerated_iterates() {
        let map = Linear::new(40, 0.8, 0.5);
        for rho in [None, Some(0.6), Some(0.9)] {
            let estimate = drive(&map, rho, 10).expect("an estimate");
            assert!(
                (estimate - 0.8).abs() < 1e-6,
                "rho {rho:?}: estimate {estimate}"
            );
        }
    }

    /// With a band at the top instead (eigenvalues spread evenly over [0,
    /// 0.8]), the estimate lies inside the spectrum (the safe side) and,
    /// from 8 pairs, within 0.1 of its top (measured 0.787 from plain and
    /// accelerated iterates alike).
    #[test]
    fn a_band_is_underestimated_not_overestimated() {
        let map = Linear::new(40, 0.8, 0.8);
        for rho in [None, Some(0.6)] {
            let estimate = drive(&map, rho, 10).expect("an estimate");
            assert!(estimate <= 0.8 + 1e-12, "rho {rho:?}: {estimate}");
            assert!(estimate > 0.7, "rho {rho:?}: {estimate}");
        }
    }

    /// Too few pairs, or a map that does not move, give no estimate.
    #[test]
    fn no_estimate_without_two_pairs_or_motion() {
        let map = Linear::new(10, 0.8, 0.5);
        assert_eq!(drive(&map, None, 3), None);
        let still = Linear {
            a: vec![Point::repeat(1.0); 4],
            h: vec![Point::repeat(1.0); 4],
            f: vec![Point::zeros(); 4],
        };
        // x is the fixed point 0 from the start: no motion, G0 = 0.
        let free: Vec<usize> = (0..4).collect();
        let mut estimator = RitzEstimator::default();
        estimator.begin_step(4);
        let x = vec![Point::zeros(); 4];
        for _ in 0..6 {
            let (g, rhs) = still.apply(&x);
            estimator.solved(&rhs);
            estimator.advanced(&free, &g, &x, Next::Plain);
        }
        assert_eq!(estimator.estimate(), None);
    }
}
