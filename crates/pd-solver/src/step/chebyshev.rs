//! Chebyshev semi-iterative acceleration of the local-global iteration
//! (Wang 2015, "A Chebyshev semi-iterative approach for accelerating
//! projective and position-based dynamics").
//!
//! With `G` one local-global iteration and `rho` the spectral radius of its
//! linearisation, the first `start` iterations of a step are plain
//! (`x_{k+1} = G(x_k)`), then
//!
//! `x_{k+1} = omega_{k+1} (G(x_k) - x_{k-1}) + x_{k-1}`,
//! `omega_{start+1} = 2 / (2 - rho^2)`, `omega_{k+1} = 4 / (4 - rho^2 omega_k)`.
//!
//! `rho = "auto"` is estimated once per scene, in its first step, as the
//! largest ratio `|G(x_k) - x_k|_M / |G(x_{k-1}) - x_{k-1}|_M` over the plain
//! iterations after the first (the ratio tends to `rho` for a linear
//! iteration). Fallback when it oscillates: if an accelerated iteration's
//! change grows (`|G(x_k) - x_k|_M` above the previous one), that iteration
//! is replaced by the plain `G(x_k)`, the recurrence restarts
//! (`omega = 1`, `start` plain iterations again are not needed: it resumes
//! at the next iteration), and an estimated `rho` is lowered to `rho^2`
//! (one Chebyshev degree less aggressive).

use pd_mesh::Point;

use super::iteration::{PositionSolver, StepProblem};
use super::method::SpectralRadius;
use super::ops::{difference, mass_dot};
use crate::SolverError;

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
        }
    }

    /// The spectral radius in use (`None` while `auto` is still estimating).
    pub fn spectral_radius(&self) -> Option<f64> {
        match self.rho {
            SpectralRadius::Fixed(rho) => Some(rho),
            SpectralRadius::Auto => self.estimated,
        }
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
        let estimating = self.rho == SpectralRadius::Auto && self.estimated.is_none();
        let mut ratio_max: f64 = 0.0;
        let mut omega = 1.0;
        let mut last_change = f64::INFINITY;
        for k in 0..step.iterations() {
            self.current.copy_from_slice(step.displacement());
            step.local_global_iteration();
            difference(step.displacement(), &self.current, &mut self.change);
            let masses = step.masses();
            let change = mass_dot(masses, &self.change, &self.change);
            let size = mass_dot(masses, step.displacement(), step.displacement());
            if step.record_residual(change, size) {
                step.record_objective();
                break;
            }
            let change = change.sqrt();
            if k < self.start {
                if estimating && k > 0 && last_change > 0.0 {
                    ratio_max = ratio_max.max(change / last_change);
                }
                if estimating && k + 1 == self.start && ratio_max > 0.0 {
                    // A ratio at or above 1 would make omega singular.
                    self.estimated = Some(ratio_max.min(0.999));
                }
            } else if let Some(rho) = self.spectral_radius() {
                if omega > 1.0 && change > last_change {
                    // Oscillation: keep the plain iterate G(x_k), restart.
                    omega = 1.0;
                    if self.rho == SpectralRadius::Auto {
                        self.estimated = Some(rho * rho);
                    }
                } else {
                    omega = if omega == 1.0 {
                        2.0 / (2.0 - rho * rho)
                    } else {
                        4.0 / (4.0 - rho * rho * omega)
                    };
                    let previous = &self.previous;
                    for (x, p) in step.displacement_mut().iter_mut().zip(previous) {
                        *x = (*x - p) * omega + p;
                    }
                }
            }
            last_change = change;
            std::mem::swap(&mut self.previous, &mut self.current);
            step.record_objective();
        }
        Ok(())
    }
}
