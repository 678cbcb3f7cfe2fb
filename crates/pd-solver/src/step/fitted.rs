//! The fitted predictor's recurrence (`[solver] predictor = "fitted"`,
//! docs/design/solver.md "The fitted predictor").
//!
//! A linear mode that an integrator turns by `theta` and scales by `r` each
//! step makes its share of the corrections obey the two-term recurrence
//! `c_{t+1} = 2 r cos(theta) c_t - r^2 c_{t-1}`, and a sum of `p` such modes
//! (plus a constant part, `r = 1, theta = 0`) obeys one of order `2p` (`p +
//! 1`). No fixed combination of past corrections predicts turning modes of
//! unknown `theta`; [`fit_recurrence`] finds the combination from the
//! history itself: the `k` coefficients `a` minimising
//!
//! `sum_{t < m} |c_{n-t} - sum_{j=1..k} a_j c_{n-t-j}|_M^2`
//!
//! over the last `m` steps (`m >= k` equations, from `m + k` stored
//! corrections), through their mass-weighted Gram matrix. The next
//! correction is then predicted as `sum_j a_j c_{n+1-j}`.

/// The coefficients of a fitted recurrence and how well they fit.
#[derive(Debug, Clone, PartialEq)]
pub struct RecurrenceFit {
    /// `a_1 .. a_k`: `c_{t+1} ~ sum_j a_j c_{t+1-j}`.
    pub coefficients: Vec<f64>,
    /// The fit's residual over the norm of its left-hand sides, `(sum_t
    /// |c_t - sum_j a_j c_{t-j}|_M^2 / sum_t |c_t|_M^2)^(1/2)`, in `[0, 1]`
    /// up to round-off (about `1e-7` for an exact fit: it is computed from
    /// the Gram matrix, by cancellation of terms of size one).
    pub relative_residual: f64,
}

/// Eigenvalues of the scaled normal matrix below this fraction of the
/// largest are dropped (a truncated pseudo-inverse): the Gram matrix squares
/// the history's condition number, and a direction the history barely spans
/// would otherwise get a huge coefficient that amplifies round-off. `1e-10`
/// keeps directions down to a singular value of `1e-5` of the largest, far
/// above round-off in the Gram entries (`1e-16` relative).
const EIGENVALUE_CUT: f64 = 1e-10;

/// Fits a recurrence of order `order` (`k`) to the last `equations` (`m`)
/// steps of a history, given the history's Gram matrix `gram` (`len x len`,
/// row-major, `gram[p * len + q] = <c_{n-p}, c_{n-q}>_M`, index 0 the
/// newest correction). Needs `len >= m + k` and `m >= k >= 1`.
///
/// Returns `None` when the history cannot be fitted: too short, a
/// non-finite or zero Gram matrix, or a column (a lagged correction) of
/// zero norm. The caller decides from
/// [`RecurrenceFit::relative_residual`] whether the fit is good enough.
pub fn fit_recurrence(gram: &[f64], order: usize, equations: usize) -> Option<RecurrenceFit> {
    let mut work = FitWorkspace::default();
    let relative_residual = work.fit(gram, order, equations)?;
    Some(RecurrenceFit {
        coefficients: work.coefficients().to_vec(),
        relative_residual,
    })
}

/// The buffers of one fit, kept between fits of the same order so that a
/// fit allocates only what nalgebra's eigen-decomposition takes and returns
/// (its input matrix, its internal buffers and `G a` of the residual).
#[derive(Debug, Clone, Default)]
pub(crate) struct FitWorkspace {
    /// The normal matrix `G` (`k x k`) and right-hand side `b`.
    g: nalgebra::DMatrix<f64>,
    b: nalgebra::DVector<f64>,
    /// `sqrt(G_ii)`, the Jacobi scaling.
    scale: Vec<f64>,
    /// `b_i / scale_i`.
    rhs: nalgebra::DVector<f64>,
    /// The scaled system's truncated solution.
    solution: nalgebra::DVector<f64>,
    /// The coefficients `a`.
    a: nalgebra::DVector<f64>,
}

impl FitWorkspace {
    /// Zeroes the accumulators, sized for order `k` (allocates only when
    /// `k` changes).
    fn reset(&mut self, k: usize) {
        if self.scale.len() != k {
            self.g = nalgebra::DMatrix::zeros(k, k);
            self.b = nalgebra::DVector::zeros(k);
            self.scale = vec![0.0; k];
            self.rhs = nalgebra::DVector::zeros(k);
            self.solution = nalgebra::DVector::zeros(k);
            self.a = nalgebra::DVector::zeros(k);
        }
        self.g.fill(0.0);
        self.b.fill(0.0);
        self.solution.fill(0.0);
    }

    /// The coefficients `a_1 .. a_k` of the last successful
    /// [`FitWorkspace::fit`].
    pub fn coefficients(&self) -> &[f64] {
        self.a.as_slice()
    }

    /// [`fit_recurrence`] into this workspace: returns the relative
    /// residual, the coefficients in [`FitWorkspace::coefficients`].
    pub fn fit(&mut self, gram: &[f64], order: usize, equations: usize) -> Option<f64> {
        let len = (gram.len() as f64).sqrt() as usize;
        let (k, m) = (order, equations);
        if len * len != gram.len() || k == 0 || m < k || len < m + k {
            return None;
        }
        if !gram.iter().all(|g| g.is_finite()) {
            return None;
        }
        self.reset(k);
        let h = |p: usize, q: usize| gram[p * len + q];
        // Normal equations G a = b over the m equations t = 0..m: the
        // unknown a_j multiplies c_{n-t-j}.
        let (g, b) = (&mut self.g, &mut self.b);
        let mut norm = 0.0;
        for t in 0..m {
            norm += h(t, t);
            for i in 0..k {
                b[i] += h(t + 1 + i, t);
                for j in 0..k {
                    g[(i, j)] += h(t + 1 + i, t + 1 + j);
                }
            }
        }
        for (i, s) in self.scale.iter_mut().enumerate() {
            *s = g[(i, i)].sqrt();
        }
        let scale = &self.scale;
        if norm <= 0.0 || scale.iter().any(|&s| s <= 0.0 || !s.is_finite()) {
            return None;
        }
        // Jacobi scaling, then a truncated eigen-decomposition.
        let scaled = nalgebra::DMatrix::from_fn(k, k, |i, j| g[(i, j)] / (scale[i] * scale[j]));
        for (i, r) in self.rhs.iter_mut().enumerate() {
            *r = b[i] / scale[i];
        }
        let eigen = nalgebra::SymmetricEigen::new(scaled);
        let largest = eigen.eigenvalues.iter().fold(0.0_f64, |a, &l| a.max(l));
        if largest <= 0.0 || !largest.is_finite() {
            return None;
        }
        for (l, v) in eigen
            .eigenvalues
            .iter()
            .zip(eigen.eigenvectors.column_iter())
        {
            if *l > EIGENVALUE_CUT * largest {
                // `solution += v * s`, element by element: the same
                // products and sums, without the temporary vector.
                let s = v.dot(&self.rhs) / l;
                for (x, v) in self.solution.iter_mut().zip(v.iter()) {
                    *x += v * s;
                }
            }
        }
        for (i, a) in self.a.iter_mut().enumerate() {
            *a = self.solution[i] / scale[i];
        }
        let a = &self.a;
        let residual = norm - 2.0 * a.dot(b) + (&*g * a).dot(a);
        let relative_residual = (residual.max(0.0) / norm).sqrt();
        if !relative_residual.is_finite() || a.iter().any(|a| !a.is_finite()) {
            return None;
        }
        Some(relative_residual)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic history of `len` vectors in R^dim made of turning,
    /// decaying modes `r^t (cos(theta t) u + sin(theta t) w)` plus a
    /// constant part; index 0 is the newest (`t = len - 1`). Also returns
    /// the next vector (`t = len`).
    fn history(modes: &[(f64, f64)], len: usize, dim: usize) -> (Vec<Vec<f64>>, Vec<f64>) {
        // Deterministic, well spread directions.
        let dir = |seed: usize, i: usize| ((seed * 7919 + i * 104_729) as f64 * 0.618).sin();
        let at = |t: usize| -> Vec<f64> {
            (0..dim)
                .map(|i| {
                    let mut x = 0.3 * dir(1, i);
                    for (mode, &(r, theta)) in modes.iter().enumerate() {
                        let (u, w) = (dir(2 * mode + 2, i), dir(2 * mode + 3, i));
                        let s = r.powi(t as i32);
                        x += s * ((theta * t as f64).cos() * u + (theta * t as f64).sin() * w);
                    }
                    x
                })
                .collect()
        };
        let past = (0..len).rev().map(at).collect();
        (past, at(len))
    }

    fn gram(history: &[Vec<f64>], mass: &[f64]) -> Vec<f64> {
        let len = history.len();
        let mut g = vec![0.0; len * len];
        for p in 0..len {
            for q in 0..len {
                g[p * len + q] = (history[p].iter().zip(&history[q]).zip(mass))
                    .map(|((a, b), m)| a * b * m)
                    .sum();
            }
        }
        g
    }

    fn predict(history: &[Vec<f64>], a: &[f64]) -> Vec<f64> {
        let mut p = vec![0.0; history[0].len()];
        for (j, a) in a.iter().enumerate() {
            for (p, c) in p.iter_mut().zip(&history[j]) {
                *p += a * c;
            }
        }
        p
    }

    fn relative_error(a: &[f64], b: &[f64]) -> f64 {
        let diff: f64 = a.iter().zip(b).map(|(a, b)| (a - b).powi(2)).sum();
        let norm: f64 = b.iter().map(|b| b * b).sum();
        (diff / norm).sqrt()
    }

    /// One, two and three turning modes plus a constant part obey a
    /// recurrence of order 3, 5 and 7; fitting that order (and one more)
    /// over twice as many steps predicts the next vector to round-off.
    /// Bound 1e-9: the fit solves normal equations whose condition number is
    /// the square of the history's (below 1e6 for these modes, whose angles
    /// are 0.4 to 2.9 rad and whose decay rates differ by up to 10%), times
    /// the double precision of the Gram entries (1e-16), with margin;
    /// measured 8e-16 to 1.1e-14.
    #[test]
    fn fitted_recurrence_predicts_turning_modes_exactly() {
        let cases: [&[(f64, f64)]; 3] = [
            &[(0.98, 1.3)],
            &[(1.0, 0.4), (0.95, 2.5)],
            &[(0.99, 0.7), (1.0, 1.6), (0.9, 2.9)],
        ];
        let mass: Vec<f64> = (0..60).map(|i| 1.0 + (i % 5) as f64 * 0.25).collect();
        for modes in cases {
            let order = 2 * modes.len() + 1;
            for k in [order, order + 1] {
                let m = 2 * k;
                let (past, next) = history(modes, m + k, mass.len());
                let fit = fit_recurrence(&gram(&past, &mass), k, m).expect("a fit");
                let error = relative_error(&predict(&past, &fit.coefficients), &next);
                eprintln!("modes {}, k {k}: error {error:.1e}", modes.len());
                assert!(error < 1e-9, "{modes:?}, k = {k}: error {error}");
                assert!(fit.relative_residual < 1e-3, "{fit:?}");
            }
        }
    }

    /// Too low an order cannot reproduce three modes: the residual says so
    /// (the caller's gate falls back to the linear predictor).
    #[test]
    fn too_low_an_order_leaves_a_large_residual() {
        let modes = [(0.99, 0.7), (1.0, 1.6), (0.9, 2.9)];
        let (past, _) = history(&modes, 8, 60);
        let fit = fit_recurrence(&gram(&past, &[1.0; 60]), 2, 6).expect("a fit");
        assert!(fit.relative_residual > 0.1, "{fit:?}");
    }

    /// A degenerate history (all zero, a zero column, non-finite, too
    /// short) gives no fit.
    #[test]
    fn degenerate_history_gives_no_fit() {
        let zero = vec![vec![0.0; 10]; 8];
        assert_eq!(fit_recurrence(&gram(&zero, &[1.0; 10]), 3, 4), None);
        let mut one = zero.clone();
        one[0][3] = 1.0;
        assert_eq!(fit_recurrence(&gram(&one, &[1.0; 10]), 3, 4), None);
        let (past, _) = history(&[(1.0, 1.0)], 8, 10);
        let mut g = gram(&past, &[1.0; 10]);
        assert_eq!(fit_recurrence(&g, 3, 6), None, "too short");
        assert!(fit_recurrence(&g, 3, 5).is_some());
        g[5] = f64::NAN;
        assert_eq!(fit_recurrence(&g, 3, 5), None);
    }

    /// A constant history spans one direction: the truncated solve still
    /// predicts the constant (coefficients summing to one), not a blow-up.
    #[test]
    fn rank_deficient_history_predicts_its_span() {
        let past = vec![vec![1.0, -2.0, 0.5]; 8];
        let fit = fit_recurrence(&gram(&past, &[1.0; 3]), 4, 4).expect("a fit");
        let sum: f64 = fit.coefficients.iter().sum();
        // The eigenvalue cut leaves 1e-10 of the Gram scale: round-off.
        assert!((sum - 1.0).abs() < 1e-12, "{fit:?}");
        assert!(fit.relative_residual < 1e-6, "{fit:?}");
    }
}
