//! Newton's method on the step objective, the converged reference.
//!
//! The gradient comes from one local-global iteration: with `G(x)` its
//! result, `grad g(x) = A (x - G(x))` (docs/design/solver.md; `A` the prefactored
//! matrix), so `-grad g = A w` with `w = G(x) - x`. The Hessian is
//!
//! `H = (1/h^2 + c1 c2 gamma a1) M + c1 c2 gamma a2 L_d
//!      + c1 c2^2 (L_anchor + K(x_n + c2 dx))`,
//!
//! with `K` the constraints' energy Hessians, each projected to positive
//! semi-definite (pd-constraints' `hessian_range`; attachments are
//! quadratic, their Hessian is `L_anchor`), assembled and factorised as a
//! 3n x 3n system every iteration (the lagged damping model's machinery,
//! `crate::lagged`). `H` is positive definite, so `s = H^{-1} A w` is a
//! descent direction; a backtracking line search on the step objective
//! (Armijo, halving, at most 8 times) picks the step length, and if no
//! length lowers the objective the plain iterate `G(x)` is taken instead.
//! The iteration stops on the same residual as every method
//! (`|G(x) - x|_M <= tolerance |G(x) - x_n|_M`) and ends on `G(x)`.
//!
//! Hyperelastic materials (docs/design/materials.md): their element Hessians are
//! in `K` (the 9 x 9 stress Hessian eigen-clamped), and `step/materials.rs`
//! adds their gradient, making `w` the full `-A^{-1} grad g`.
//!
//! Refused: lagged damping models (`rayleigh-lagged`), whose step matrix
//! already is the 3n system; their damping Hessian would have to be added.

use pd_constraints::EnergyBound;
use pd_integrators::StepCoefficients;
use pd_mesh::Point;

use super::iteration::{PositionSolver, StepProblem};
use super::materials::MaterialGradient;
use super::ops::{difference, mass_dot};
use crate::SolverError;
use crate::global::{GlobalSystem, MatrixCoefficients, combine};
use crate::lagged::LaggedSystem;
use crate::system::SystemCoefficients;

/// Armijo's sufficient-decrease fraction of the line search.
const ARMIJO: f64 = 1e-4;
/// Step halvings before the line search gives up and takes the plain
/// iterate: 8 (a step of 1/128). Near the round-off floor no length passes
/// Armijo's test, and with 30 halvings L-BFGS spent about 100 objective
/// evaluations a step there (the 2,304-vertex beam at a budget of 30).
const HALVINGS: usize = 8;

/// Newton's method with PSD-projected element Hessians and a line search.
#[derive(Debug, Default)]
pub struct Newton {
    hessian: Option<Box<LaggedSystem>>,
    /// `A`'s values over the scalar lower pattern.
    values: Vec<f64>,
    iterate: Vec<Point>,
    q: Vec<Point>,
    /// `w = G(x) - x`, then per vertex; `A w` per free vertex.
    update: Vec<Point>,
    rhs: Vec<Point>,
    /// The Newton direction per vertex.
    direction: Vec<Point>,
    /// Per-chunk scratch of the objective's energy sum.
    partials: Vec<EnergyBound>,
    /// The hyperelastic materials' gradient correction (step/materials.rs).
    materials: MaterialGradient,
}

/// `out_f = (A w)_f` for every free vertex `f`, `A` given by its values over
/// the lower pattern of `system` (symmetric).
pub(crate) fn symmetric_product(
    system: &GlobalSystem,
    values: &[f64],
    w: &[Point],
    out: &mut [Point],
) {
    out.iter_mut().for_each(|o| *o = Point::zeros());
    let pattern = &system.pattern;
    for j in 0..pattern.n {
        let wj = w[system.free[j]];
        let range = pattern.col_ptr[j]..pattern.col_ptr[j + 1];
        for (&i, &value) in pattern.row_idx[range.clone()].iter().zip(&values[range]) {
            out[i] += wj * value;
            if i != j {
                out[j] += w[system.free[i]] * value;
            }
        }
    }
}

/// The coefficients of the step objective's Hessian in the lagged 3n
/// system, `mass M + c1 c2 gamma a2 L_d + L_anchor + elastic K`, from the
/// step matrix's `matrix`, and the element Hessians' factor
/// `elastic = c1 c2^2`: the system part is the elastic weight and the
/// damping part loses it (`L_anchor = L_sys - L_d`: the elastic `L_d` is
/// inside `K`).
pub(crate) fn hessian_coefficients(
    matrix: MatrixCoefficients,
    c: StepCoefficients,
) -> (MatrixCoefficients, f64) {
    let elastic = c.c1 * c.c2 * c.c2;
    let coefficients = MatrixCoefficients {
        mass: matrix.mass,
        system: elastic,
        damping: matrix.damping - elastic,
        mass_damping: matrix.mass_damping,
        series: matrix.series,
    };
    (coefficients, elastic)
}

impl Newton {
    /// Builds the Hessian system on first use, sizes the buffers.
    fn prepare(&mut self, step: &StepProblem<'_>) -> Result<(), SolverError> {
        if self.hessian.is_none() {
            let system = step.global.system();
            self.hessian = Some(Box::new(LaggedSystem::new(system, step.local.blocks())?));
            let n = step.positions.len();
            self.values = vec![0.0; system.pattern.row_idx.len()];
            self.iterate = vec![Point::zeros(); n];
            self.q = vec![Point::zeros(); n];
            self.update = vec![Point::zeros(); n];
            self.direction = vec![Point::zeros(); n];
            self.rhs = vec![Point::zeros(); system.free.len()];
        }
        Ok(())
    }

    /// The Newton direction from `iterate` with `update = G(x) - x`: fills
    /// `direction` (zero at fixed vertices) and returns `grad g . s`.
    fn direction(&mut self, step: &StepProblem<'_>) -> Result<f64, SolverError> {
        let c = step.coefficients;
        let d = step.damping;
        let coefficients = SystemCoefficients::of(c, d, step.h).matrix;
        let system = step.global.system();
        combine(
            &mut self.values,
            coefficients,
            [&system.mass_part, &system.system_part, &system.damping_part],
        );
        symmetric_product(system, &self.values, &self.update, &mut self.rhs);
        for ((q, x_n), dx) in self.q.iter_mut().zip(step.positions).zip(&self.iterate) {
            *q = x_n + dx * c.c2;
        }
        let (hessian_coefficients, elastic) = hessian_coefficients(coefficients, c);
        let hessian = self.hessian.as_mut().expect("built by prepare");
        hessian.refactorise(step.local.blocks(), &self.q, hessian_coefficients, elastic)?;
        hessian.solve(&self.rhs);
        self.direction.iter_mut().for_each(|s| *s = Point::zeros());
        let mut slope = 0.0;
        for (f, &v) in system.free.iter().enumerate() {
            let s = hessian.solution(f);
            self.direction[v] = s;
            slope -= self.rhs[f].dot(&s);
        }
        Ok(slope)
    }
}

impl PositionSolver for Newton {
    fn name(&self) -> &'static str {
        "newton"
    }

    fn handles_materials(&self) -> bool {
        true
    }

    /// Its ratios are superlinear convergence, not the map's contraction.
    fn estimate_needs_contraction(&self) -> bool {
        true
    }

    /// Its Hessian is built on the n x n system's pattern.
    fn handles_lagged_damping(&self) -> bool {
        false
    }

    /// Its Hessian reuses `L_d` as the elastic part of `L_sys`, which
    /// per-body weights would scale too.
    fn handles_per_body_damping(&self) -> bool {
        false
    }

    /// Its Hessian holds the plain `L_d`, and its gradient the plain step
    /// matrix's product, not the projected ones.
    fn handles_rotation_preserving_damping(&self) -> bool {
        false
    }

    /// Its Hessian is built on the `L_sys` pattern from the three base
    /// parts, without the series' terms.
    fn handles_series_damping(&self) -> bool {
        false
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        self.prepare(step)?;
        // Its ratios are its own convergence, not the map's contraction.
        step.estimate.own_convergence();
        step.record_objective();
        if self.partials.len() != step.local_chunks() {
            self.partials = vec![EnergyBound::default(); step.local_chunks()];
        }
        // Trial points are judged from their local step's projections,
        // which then serve the next global step.
        let mut merit = step.project_with_objective(&mut self.partials);
        let materials = MaterialGradient::present(step);
        for _ in 0..step.iterations() {
            self.iterate.copy_from_slice(step.displacement());
            step.global_half();
            difference(step.displacement(), &self.iterate, &mut self.update);
            if materials {
                // w' = -A^{-1} grad g; the plain iterate is x + w'.
                self.materials
                    .correct(step, &self.iterate, &mut self.update);
                let dx = step.displacement_mut();
                for ((x, x0), w) in dx.iter_mut().zip(&self.iterate).zip(&self.update) {
                    *x = x0 + w;
                }
            }
            let masses = step.masses();
            let change = mass_dot(masses, &self.update, &self.update);
            let size = mass_dot(masses, step.displacement(), step.displacement());
            if step.record_residual(change, size) {
                step.record_objective();
                break;
            }
            let slope = self.direction(step)?;
            let mut alpha = 1.0;
            let mut accepted = false;
            if slope < 0.0 {
                for _ in 0..HALVINGS {
                    let dx = step.displacement_mut();
                    for ((x, x0), s) in dx.iter_mut().zip(&self.iterate).zip(&self.direction) {
                        *x = x0 + s * alpha;
                    }
                    let trial = step.project_with_objective(&mut self.partials);
                    if trial <= merit + ARMIJO * alpha * slope {
                        merit = trial;
                        accepted = true;
                        break;
                    }
                    alpha *= 0.5;
                }
            }
            if !accepted {
                // G(x): the local-global iterate, which lowers g.
                let dx = step.displacement_mut();
                for ((x, x0), w) in dx.iter_mut().zip(&self.iterate).zip(&self.update) {
                    *x = x0 + w;
                }
                merit = step.project_with_objective(&mut self.partials);
            }
            step.record_objective();
        }
        Ok(())
    }
}
