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
//! (docs/design/solver.md, "Chebyshev on the map's own spectrum"). The first
//! `start` iterations of each step are plain.
//!
//! `rho = "auto"` is estimated from every step, for the next: the largest
//! Ritz value of `T` on the Krylov space the step's own iterates span
//! ([`super::ritz`]; no extra iteration and no product with `A`). The
//! first step has no estimate: its first [`FIRST_PLAIN`] iterations are
//! plain and give one (or, if their pencil is degenerate, the largest
//! ratio of successive changes, a lower estimate), and it accelerates with
//! that for the rest. The spectrum's top moves as the body deforms (on the
//! benchmark beam, backward Euler, the per-step value rises from 0.60 to
//! 0.77 over the first 15 steps, implicit midpoint from 0.56 to 0.69),
//! which an estimate made once in the first step missed (0.65 and 0.58,
//! against plain PD's asymptotic rates 0.78 and 0.70 over a run;
//! docs/design/solver.md, "Chebyshev's `rho` from every step"). Like every Ritz
//! value the estimate lies inside the spectrum, so it errs low, the safe
//! side. Fallback when it oscillates: if an accelerated iteration's change
//! grows (`|G(x_k) - x_k|_M` above the previous one), that iteration is
//! replaced by the plain `G(x_k)`, the recurrence restarts (`omega = 1`),
//! an estimated `rho` is lowered to `rho^2` and the step's own estimate is
//! not used.

use pd_mesh::Point;

use super::estimate::Kept;
use super::iteration::{PositionSolver, StepProblem};
use super::method::SpectralRadius;
use super::ops::{difference, mass_dot};
use super::ritz::{Next, RitzEstimator};
use crate::SolverError;

/// Plain iterations of the first step of `rho = "auto"`, before the first
/// estimate (from their two complete pairs; the step then accelerates and
/// keeps collecting pairs for the next step's estimate).
const FIRST_PLAIN: usize = 4;

/// How much a window's estimate must exceed the `rho` in use to replace
/// it within a step (and restart the recurrence).
const RAISE: f64 = 0.01;

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
    /// `G(x_k) - x_k` and `G(x_{k-1}) - x_{k-1}`.
    change: Vec<Point>,
    change_before: Vec<Point>,
    /// The step's Krylov pairs, for `rho = "auto"`.
    ritz: RitzEstimator,
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
            change_before: Vec::new(),
            ritz: RitzEstimator::default(),
        }
    }

    /// The spectral radius in use (`None` while `auto` has no estimate
    /// yet).
    pub fn spectral_radius(&self) -> Option<f64> {
        match self.rho {
            SpectralRadius::Fixed(rho) => Some(rho),
            SpectralRadius::Auto => self.estimated,
        }
    }

    /// A full window of Ritz values in a long step (a tolerance or a large
    /// budget): a window of later iterates replaces a lower rho at once
    /// (the recurrence restarts, `omega = 1`), unless the step oscillated
    /// already, and a new window begins. Returns the largest window
    /// estimate of the step so far.
    fn close_window(
        &mut self,
        windows: Option<f64>,
        restarted: bool,
        omega: &mut f64,
    ) -> Option<f64> {
        let window = self.ritz.estimate();
        self.ritz.restart_window();
        let Some(window) = window else {
            return windows;
        };
        if let Some(rho) = self.estimated
            && !restarted
            && window > rho + RAISE
        {
            self.estimated = Some(window.min(MAX_RHO));
            *omega = 1.0;
        }
        windows.into_iter().chain([window]).reduce(f64::max)
    }

    /// The Chebyshev update of the step's displacement with spectral
    /// radius `rho`: `[0, rho]` mapped onto `[-rho', rho']` by
    /// over-relaxation (`alpha`), then the semi-iteration's weight `omega`
    /// (updated) on the previous iterate.
    fn relax(&mut self, step: &mut StepProblem<'_>, rho: f64, omega: &mut f64) -> Next {
        let alpha = 2.0 / (2.0 - rho);
        let mapped = rho / (2.0 - rho);
        let squared = mapped * mapped;
        *omega = if *omega == 1.0 {
            2.0 / (2.0 - squared)
        } else {
            4.0 / (4.0 - squared * *omega)
        };
        let omega = *omega;
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
        Next::Combined { alpha, omega }
    }
}

impl PositionSolver for Chebyshev {
    fn name(&self) -> &'static str {
        "chebyshev"
    }

    /// `rho = "auto"`'s estimate for the next step, once made.
    fn carried(&self) -> Vec<f64> {
        match (self.rho, self.estimated) {
            (SpectralRadius::Auto, Some(rho)) => vec![rho],
            _ => Vec::new(),
        }
    }

    fn check_carried(&self, values: &[f64]) -> Result<(), String> {
        match values {
            [] => Ok(()),
            [rho] if *rho > 0.0 && *rho <= MAX_RHO => Ok(()),
            _ => Err(format!(
                "chebyshev carries one spectral radius in (0, {MAX_RHO}], the checkpoint has {values:?}"
            )),
        }
    }

    /// With `rho = "auto"`, the saved estimate (none: the next step
    /// estimates afresh); a fixed `rho` keeps its own.
    fn restore_carried(&mut self, values: &[f64]) {
        if self.rho == SpectralRadius::Auto {
            self.estimated = values.first().copied();
        }
    }

    /// A fixed `rho` must lie in (0, 1), as a scene's `rho` must.
    fn check_settings(&self) -> Result<(), SolverError> {
        self.rho.validate()
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        let n = step.displacement().len();
        if self.previous.len() != n {
            self.previous = vec![Point::zeros(); n];
            self.current = vec![Point::zeros(); n];
            self.change = vec![Point::zeros(); n];
            self.change_before = vec![Point::zeros(); n];
        }
        step.record_objective();
        let auto = self.rho == SpectralRadius::Auto;
        if auto {
            self.ritz.begin_step(step.global.free().len());
        }
        // Without an estimate yet, the first iterations are plain and give it.
        let plain = if self.spectral_radius().is_none() {
            self.start.max(FIRST_PLAIN)
        } else {
            self.start
        };
        let mut ratio_max: f64 = 0.0;
        let mut omega = 1.0;
        let mut last_change = f64::INFINITY;
        let mut converged = false;
        let mut restarted = false;
        // The largest estimate of this step's full windows.
        let mut windows: Option<f64> = None;
        for k in 0..step.iterations() {
            self.current.copy_from_slice(step.displacement());
            if k == 0 {
                step.first_local_global_iteration();
            } else {
                step.local_global_iteration();
            }
            std::mem::swap(&mut self.change, &mut self.change_before);
            difference(step.displacement(), &self.current, &mut self.change);
            if auto {
                self.ritz.solved(&step.buffers.rhs);
            }
            let masses = step.masses();
            let change = mass_dot(masses, &self.change, &self.change);
            let size = mass_dot(masses, step.displacement(), step.displacement());
            if k > 0 {
                // The map's contraction along the step (step/estimate.rs).
                let iterates = [&self.current[..], &self.previous];
                let residuals = [&self.change[..], &self.change_before];
                (step.estimate).note_step(masses, Kept::Iterates, iterates, residuals);
            }
            if step.record_residual(change, size) {
                step.record_objective();
                converged = true;
                break;
            }
            let change = change.sqrt();
            if k < plain && k > 0 && last_change > 0.0 {
                ratio_max = ratio_max.max(change / last_change);
            }
            if auto && self.estimated.is_none() && k + 1 == plain {
                // The first estimate, from the plain iterations so far (or
                // the largest ratio of successive changes, a lower
                // estimate, if their pencil is degenerate).
                let rho = self.ritz.estimate().unwrap_or(ratio_max);
                self.estimated = Some(rho.min(MAX_RHO));
            }
            if let Some(rho) = self.spectral_radius() {
                step.estimate.note_contraction(rho);
            }
            if auto && self.ritz.full() {
                windows = self.close_window(windows, restarted, &mut omega);
            }
            let mut how = Next::Plain;
            if k >= plain
                && let Some(rho) = self.spectral_radius().filter(|&rho| rho > 0.0)
            {
                if omega > 1.0 && change > last_change {
                    // Oscillation: keep the plain iterate G(x_k), restart.
                    omega = 1.0;
                    restarted = true;
                    if auto {
                        self.estimated = Some(rho * rho);
                    }
                } else {
                    how = self.relax(step, rho, &mut omega);
                }
            }
            if auto {
                self.ritz
                    .advanced(step.global.free(), step.displacement(), &self.current, how);
            }
            last_change = change;
            std::mem::swap(&mut self.previous, &mut self.current);
            step.record_objective();
        }
        // The next step's rho: this step's largest Ritz value, unless the
        // step oscillated (then the lowered rho above stands).
        if auto && !restarted {
            let best = self.ritz.estimate().into_iter().chain(windows);
            if let Some(rho) = best.reduce(f64::max) {
                self.estimated = Some(rho.min(MAX_RHO));
            }
        }
        // With the linear predictor and implicit midpoint, 3 of 576 runs
        // of the method axis diverged without this check where plain PD
        // from `y` completes (docs/reports/stability-methods-predictor-linear-*).
        if !converged {
            step.check_predicted_end();
        }
        Ok(())
    }
}
