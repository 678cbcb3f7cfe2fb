//! Chebyshev semi-iterative acceleration of the local-global iteration
//! (Wang 2015, "A Chebyshev semi-iterative approach for accelerating
//! projective and position-based dynamics"), for the spectrum the
//! local-global map actually has.
//!
//! With `G` one local-global iteration, its linearisation at the solution
//! is `T = I - A^{-1} H` (`A` the prefactored matrix, `H` the objective's
//! Hessian). Where `H <= A` (PD's energies away from inverted elements),
//! `T`'s eigenvalues lie in `[0, rho]`, not in `[-rho, rho]` as Wang's
//! recurrence assumes. So each accelerated iteration first over-relaxes the
//! plain one, `y = x_k + alpha (G(x_k) - x_k)` with `alpha = 2 / (2 - rho)`,
//! which maps `[0, rho]` onto `[-rho', rho']`, `rho' = rho / (2 - rho)`, and
//! then takes Wang's recurrence with `rho'`:
//!
//! `x_{k+1} = omega_{k+1} (y - x_{k-1}) + x_{k-1}`,
//! `omega = 2 / (2 - rho'^2)` first, then `omega_{k+1} = 4 / (4 - rho'^2 omega_k)`.
//!
//! Per iteration the error then shrinks by about
//! `rho' / (1 + sqrt(1 - rho'^2))`, the rate of conjugate gradients on the
//! linearisation (0.35 for `rho = 0.77`), where Wang's form on `[-rho,
//! rho]` gets `rho / (1 + sqrt(1 - rho^2))` (0.47) and plain PD `rho`
//! (docs/solver.md, "Chebyshev on the map's own spectrum"). The first
//! `start` iterations of each step are plain.
//!
//! `rho = "auto"` is estimated once per scene, from the first step that
//! runs at least [`MIN_ESTIMATION`] iterations, whose first [`ESTIMATION`]
//! (or all, if fewer) are then plain: the largest Ritz value of `T` on the
//! Krylov space they span. With `d_k = G(x_k) - x_k`, `T d_k = d_(k+1)` for
//! the linearisation, and `A d_k = b_k - b_(k-1)` (the right-hand sides the
//! iterations solved, so no product with `A` is needed); `T` is
//! self-adjoint in the `A` inner product, so the Ritz values come from the
//! symmetric pencil `(d_i . A d_(j+1), d_i . A d_j)`. Like every Ritz
//! value it lies inside the spectrum, so it errs low, the safe side: on
//! the benchmark beam it gives 0.65 (backward Euler) and 0.58 (implicit
//! midpoint) where plain PD's asymptotic rate is 0.78 and 0.70, and the
//! ratio of successive changes, a power iteration, 0.59 and 0.51
//! (docs/solver.md, "Chebyshev on the map's own spectrum"). Fallback when
//! it oscillates: if an accelerated iteration's change grows (`|G(x_k) -
//! x_k|_M` above the previous one), that iteration is replaced by the plain
//! `G(x_k)`, the recurrence restarts (`omega = 1`) and an estimated `rho`
//! is lowered to `rho^2`.

use nalgebra::{SMatrix, SymmetricEigen};
use pd_mesh::Point;

use super::iteration::{PositionSolver, StepProblem};
use super::method::SpectralRadius;
use super::ops::{difference, mass_dot};
use crate::SolverError;

/// Plain iterations of the step that estimates `rho = "auto"` (a budget of
/// 10 or more; the benchmark beam's Ritz value: 0.60 after 6, 0.65 after
/// 10).
pub(crate) const ESTIMATION: usize = 10;

/// The size of the Ritz pencil: the pairs of [`ESTIMATION`] plain
/// iterations, `d_1 .. d_(ESTIMATION - 1)`, less the last one (only its
/// image `T d` is used).
const PENCIL: usize = ESTIMATION - 2;

/// The pencil's fixed-size matrices.
type Pencil = SMatrix<f64, PENCIL, PENCIL>;

/// The fewest iterations a step needs to estimate `rho = "auto"` (its
/// whole budget then, if below [`ESTIMATION`]).
const MIN_ESTIMATION: usize = 4;

/// The largest `rho` used: `omega` and `alpha` stay finite below 1.
const MAX_RHO: f64 = 0.999;

/// Chebyshev-accelerated local-global iteration.
#[derive(Debug, Clone)]
pub struct Chebyshev {
    rho: SpectralRadius,
    start: usize,
    /// The estimate of `rho = "auto"`, once made.
    estimated: Option<f64>,
    /// `x_{k-1}` and `x_k`.
    previous: Vec<Point>,
    current: Vec<Point>,
    /// `G(x_k) - x_k`.
    change: Vec<Point>,
    /// The estimating step's `d_k` and `A d_k` over the free vertices, and
    /// the last right-hand side (empty once `rho` is known).
    krylov: Vec<(Vec<Point>, Vec<Point>)>,
    last_rhs: Vec<Point>,
}

impl Chebyshev {
    /// A solver with spectral radius `rho` that accelerates from iteration
    /// `start` of each step.
    pub fn new(rho: SpectralRadius, start: usize) -> Self {
        Self {
            rho,
            start: start.max(2),
            estimated: None,
            previous: Vec::new(),
            current: Vec::new(),
            change: Vec::new(),
            krylov: Vec::new(),
            last_rhs: Vec::new(),
        }
    }

    /// The spectral radius in use (`None` while `auto` is still estimating).
    pub fn spectral_radius(&self) -> Option<f64> {
        match self.rho {
            SpectralRadius::Fixed(rho) => Some(rho),
            SpectralRadius::Auto => self.estimated,
        }
    }

    /// Keeps plain iteration `k`'s `d_k` (in `self.change`) and `A d_k`
    /// from the right-hand side it solved, for the estimate.
    fn record_krylov(&mut self, step: &StepProblem<'_>, k: usize) {
        let free = step.global.free();
        let rhs = &step.buffers.rhs;
        if self.last_rhs.len() != rhs.len() {
            self.last_rhs = vec![Point::zeros(); rhs.len()];
            // d_1 .. d_(ESTIMATION - 1): the first iteration's d_0 has no
            // known A d_0.
            self.krylov = (1..ESTIMATION)
                .map(|_| {
                    (
                        vec![Point::zeros(); free.len()],
                        vec![Point::zeros(); free.len()],
                    )
                })
                .collect();
        }
        // A x_k = b_(k-1) once x_k came from a plain iteration (k >= 1), so
        // A d_k = A x_(k+1) - A x_k = b_k - b_(k-1).
        if k >= 1 {
            let (d, a_d) = &mut self.krylov[k - 1];
            for (((d, a_d), &v), (b, last)) in d
                .iter_mut()
                .zip(a_d.iter_mut())
                .zip(free)
                .zip(rhs.iter().zip(&self.last_rhs))
            {
                *d = self.change[v];
                *a_d = b - last;
            }
        }
        self.last_rhs.copy_from_slice(rhs);
    }

    /// The largest Ritz value of `T` from the first `pairs` recorded
    /// `(d_k, A d_k)`, `k = 1..=pairs`, or `None` if the pencil is
    /// degenerate (the iteration converged or stalled). Fixed-size
    /// matrices: the estimate may come in any step, and steps allocate
    /// nothing.
    fn ritz_estimate(&self, pairs: usize) -> Option<f64> {
        let m = pairs.checked_sub(1).filter(|&m| m > 0)?.min(PENCIL);
        let dot = |a: &[Point], b: &[Point]| a.iter().zip(b).map(|(a, b)| a.dot(b)).sum::<f64>();
        let (mut g0, mut g1) = (Pencil::zeros(), Pencil::zeros());
        for i in 0..m {
            for j in 0..m {
                let d_i = &self.krylov[i].0;
                g0[(i, j)] = dot(d_i, &self.krylov[j].1);
                g1[(i, j)] = dot(d_i, &self.krylov[j + 1].1);
            }
        }
        // Symmetric in exact arithmetic on the linearisation; the map's
        // nonlinearity and round-off leave a small skew part.
        let mut g0 = (g0 + g0.transpose()) * 0.5;
        let g1 = (g1 + g1.transpose()) * 0.5;
        // Unused rows: identity in G0 at its largest diagonal entry (no
        // larger than its largest eigenvalue), zero in G1, so the pencil's
        // extra eigenvalues are 0 and the largest one is the estimate.
        let scale = (0..m).map(|i| g0[(i, i)]).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return None;
        }
        for i in m..PENCIL {
            g0[(i, i)] = scale;
        }
        // G0 = V D V^T; the Krylov vectors grow nearly parallel, so
        // directions below 1e-12 of the largest are dropped, and
        // W = V_kept D_kept^(-1/2) whitens the rest.
        let eigen = SymmetricEigen::new(g0);
        let largest = eigen.eigenvalues.max();
        let mut w = Pencil::zeros();
        for c in 0..PENCIL {
            let d = eigen.eigenvalues[c];
            if d > 1e-12 * largest {
                w.set_column(c, &(eigen.eigenvectors.column(c) / d.sqrt()));
            }
        }
        let theta = SymmetricEigen::new(w.transpose() * g1 * w)
            .eigenvalues
            .max();
        (theta.is_finite() && theta > 0.0).then_some(theta)
    }

    /// Sets `rho` from the `pairs` recorded so far, or from `ratio_max`,
    /// the largest ratio of successive changes (a lower estimate), if the
    /// pencil is degenerate; frees the estimation's vectors.
    fn finish_estimate(&mut self, pairs: usize, ratio_max: f64) {
        let rho = self.ritz_estimate(pairs).unwrap_or(ratio_max);
        self.estimated = Some(rho.min(MAX_RHO));
        self.krylov = Vec::new();
        self.last_rhs = Vec::new();
    }
}

impl PositionSolver for Chebyshev {
    fn name(&self) -> &'static str {
        "chebyshev"
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        let n = step.displacement().len();
        if self.previous.len() != n {
            self.previous = vec![Point::zeros(); n];
            self.current = vec![Point::zeros(); n];
            self.change = vec![Point::zeros(); n];
        }
        step.record_objective();
        let estimating = self.spectral_radius().is_none() && step.iterations() >= MIN_ESTIMATION;
        let plain = if estimating {
            step.iterations().min(ESTIMATION)
        } else {
            self.start
        };
        let mut ratio_max: f64 = 0.0;
        let mut omega = 1.0;
        let mut last_change = f64::INFINITY;
        let mut converged = false;
        for k in 0..step.iterations() {
            self.current.copy_from_slice(step.displacement());
            step.local_global_iteration();
            difference(step.displacement(), &self.current, &mut self.change);
            if estimating && k < plain {
                self.record_krylov(step, k);
            }
            let masses = step.masses();
            let change = mass_dot(masses, &self.change, &self.change);
            let size = mass_dot(masses, step.displacement(), step.displacement());
            if step.record_residual(change, size) {
                if estimating && k + 1 >= MIN_ESTIMATION && k < plain {
                    // Converged before the estimate: its iterations so far.
                    self.finish_estimate(k, ratio_max);
                }
                step.record_objective();
                converged = true;
                break;
            }
            let change = change.sqrt();
            if k < plain {
                if estimating && k > 0 && last_change > 0.0 {
                    ratio_max = ratio_max.max(change / last_change);
                }
                if estimating && k + 1 == plain {
                    self.finish_estimate(plain - 1, ratio_max);
                }
            } else if let Some(rho) = self.spectral_radius().filter(|&rho| rho > 0.0) {
                if omega > 1.0 && change > last_change {
                    // Oscillation: keep the plain iterate G(x_k), restart.
                    omega = 1.0;
                    if self.rho == SpectralRadius::Auto {
                        self.estimated = Some(rho * rho);
                    }
                } else {
                    // [0, rho] mapped onto [-rho', rho'] by over-relaxation.
                    let alpha = 2.0 / (2.0 - rho);
                    let mapped = rho / (2.0 - rho);
                    let squared = mapped * mapped;
                    omega = if omega == 1.0 {
                        2.0 / (2.0 - squared)
                    } else {
                        4.0 / (4.0 - squared * omega)
                    };
                    let (previous, current) = (&self.previous, &self.current);
                    for ((x, p), c) in step
                        .displacement_mut()
                        .iter_mut()
                        .zip(previous)
                        .zip(current)
                    {
                        let relaxed = *c + (*x - c) * alpha;
                        *x = (relaxed - p) * omega + p;
                    }
                }
            }
            last_change = change;
            std::mem::swap(&mut self.previous, &mut self.current);
            step.record_objective();
        }
        // With the linear predictor and implicit midpoint, 3 of 576 runs
        // of the method axis diverged without this check where plain PD
        // from `y` completes (docs/stability-methods-predictor-linear-*).
        if !converged {
            step.check_predicted_end();
        }
        Ok(())
    }
}
