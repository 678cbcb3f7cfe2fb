//! The accelerated methods' end of a step with implicit midpoint, and plain
//! PD's when the step started at a predicted point (step/predictor.rs): the
//! end iterate must not lie past the minimum of the step objective along the
//! step's ray from `x_n` (docs/design/solver.md, "The end-of-step check with
//! implicit midpoint" and "A better start: predictors").
//!
//! Why: implicit midpoint evaluates the forces at `x_n + dx/2` and sets
//! `v_{n+1} = 2 dx/h - v_n`, so an unconverged end point `x` changes the
//! total energy (kinetic + elastic + gravitational) by
//! `2 grad g(x) . (x - x_n)` more than the converged one (exact for linear
//! forces and gravity; measured to three digits on the clamped beam of
//! `tests/method_divergence.rs`). Plain PD's iterates approach the
//! minimiser monotonically in every mode of the quadratic model;
//! extrapolating methods can overshoot slow modes (which still lowers `g`,
//! so the safeguard accepts it), and the gain then recurs step after step
//! (the stability map's three method-axis divergences: Anderson and L-BFGS
//! with 10 iterations a step).
//!
//! The check: with `phi(beta) = g(x_n + beta dx)`, `phi(1)` and
//! `phi'(1) = grad g(x) . dx` come from one local step at `x`
//! (`grad g = A dx - rhs(p)`, one product with the prefactored matrix `A`).
//! If `phi'(1) > 0`, `phi(0)` (one more local step) and the quadratic
//! through the three give the line minimum `beta* < 1`, where `phi' = 0`;
//! the end iterate moves there if the objective is lower there (one more
//! local step), else stays. Backward Euler and BDF-2 (`c2 = 1`) are not
//! checked: an overshoot there shrinks (`|1 - a| < 1` of it remains) instead
//! of being doubled.

use pd_constraints::EnergyBound;
use pd_mesh::Point;

use super::iteration::StepProblem;
use crate::global::MatrixCoefficients;
use crate::system::SystemCoefficients;

/// `A`'s values, a product buffer and the end iterate under check.
#[derive(Debug, Clone, Default)]
pub(crate) struct RayCheck {
    /// `A`'s values over the scalar lower pattern.
    values: Vec<f64>,
    /// The coefficients `values` were combined for.
    coefficients: Option<MatrixCoefficients>,
    /// `A dx` per free vertex.
    product: Vec<Point>,
    /// The end iterate before the check.
    end: Vec<Point>,
}

impl RayCheck {
    /// Whether the check applies to `step`: implicit midpoint (`c2 < 1`),
    /// a scalar step matrix (no lagged damping, whose matrix is the 3n
    /// system) and PD energies only (the gradient of hyperelastic
    /// materials is not in the right-hand side).
    pub fn applies(step: &StepProblem<'_>) -> bool {
        step.coefficients.c2 < 1.0
            && step.damping.lagged_stiffness == 0.0
            && !super::materials::MaterialGradient::present(step)
    }

    /// Checks the current displacement, the step's end iterate, and moves
    /// it back along the ray from `x_n` when it lies past the line minimum
    /// and the objective is lower there. Costs one local step and one
    /// product with `A` (and two more local steps when it lies past).
    /// Returns whether it moved.
    pub fn finish(&mut self, step: &mut StepProblem<'_>, partials: &mut [EnergyBound]) -> bool {
        let end_merit = step.project_with_objective(partials);
        let slope = self.slope(step);
        if !(slope > 0.0 && end_merit.is_finite()) {
            return false;
        }
        self.end.clone_from(&step.buffers.displacement);
        step.buffers.displacement.fill(Point::zeros());
        let rise = end_merit - step.project_with_objective(partials);
        // phi(beta) = phi(0) + b beta + c beta^2 through phi(0), phi(1) and
        // phi'(1): c = phi'(1) - (phi(1) - phi(0)), b = phi'(1) - 2 c.
        let curvature = slope - rise;
        if !(curvature > 0.0) {
            // No minimum before beta = 1 in the model: keep the end iterate.
            step.buffers.displacement.copy_from_slice(&self.end);
            return false;
        }
        let beta = ((2.0 * curvature - slope) / (2.0 * curvature)).clamp(0.0, 1.0);
        for (x, e) in step.buffers.displacement.iter_mut().zip(&self.end) {
            *x = e * beta;
        }
        let moved = step.project_with_objective(partials);
        // Not `<=`: a NaN objective keeps the end iterate.
        if moved < end_merit {
            true
        } else {
            step.buffers.displacement.copy_from_slice(&self.end);
            false
        }
    }

    /// `phi'(1) = grad g(x) . dx` in J at the current displacement,
    /// whose projections are the step's current ones:
    /// `grad g = A dx - rhs(p)` on the free rows.
    fn slope(&mut self, step: &mut StepProblem<'_>) -> f64 {
        let system = step.global.system();
        if self.product.len() != system.free.len() {
            self.product = vec![Point::zeros(); system.free.len()];
        }
        // `A` is constant while its coefficients are: combine its values
        // only when they (or the pattern) change.
        let coefficients = SystemCoefficients::of(step.coefficients, step.damping, step.h).matrix;
        if self.values.len() != system.pattern.row_idx.len()
            || self.coefficients != Some(coefficients)
        {
            self.values.resize(system.pattern.row_idx.len(), 0.0);
            system.values_into(coefficients, &mut self.values);
            self.coefficients = Some(coefficients);
        }
        let dx = &step.buffers.displacement;
        super::newton::symmetric_product(system, &self.values, dx, &mut self.product);
        step.global.correct_product(dx, &mut self.product);
        step.rhs_from_projections();
        let b = &*step.buffers;
        let system = step.global.system();
        let mut slope = 0.0;
        for (f, &v) in system.free.iter().enumerate() {
            let gradient = self.product[f] - b.rhs[f];
            slope += gradient.dot(&b.displacement[v]);
        }
        slope
    }
}
