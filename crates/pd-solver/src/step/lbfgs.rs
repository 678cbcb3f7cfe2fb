//! L-BFGS on the step objective with the prefactored matrix as initial
//! Hessian (Liu, Bouaziz and Kavan 2017, "Quasi-Newton methods for
//! real-time simulation of hyperelastic materials"), for PD energies and
//! hyperelastic materials (whose gradient `step/materials.rs` adds to `w`,
//! making it `w' = -A^{-1} grad g`; with materials the last iteration runs
//! its line search too).
//!
//! One local-global iteration from `x_k` gives `w_k = G(x_k) - x_k =
//! -A^{-1} grad g(x_k)` (docs/design/solver.md), so the gradient is
//! `grad_k = -A w_k` (one sparse product) and the initial-Hessian solve of
//! the two-loop recursion needs no extra factor solve: with
//! `s_i = x_{i+1} - x_i`, `y_i = grad_{i+1} - grad_i`, the recursion's
//! `A^{-1} q` for `q = grad_k - sum_i alpha_i y_i` is
//! `-w_k + sum_i alpha_i (w_{i+1} - w_i)`. The direction is then checked to
//! be a descent direction (else the history restarts and the direction is
//! `w_k`, plain PD's), and a backtracking line search on the step objective
//! (Armijo, halving, at most 8 times; else the plain iterate `G(x_k)`)
//! picks the step. Pairs with `s . y <= 0` are not stored. The last
//! iteration of the budget ends on the plain iterate `G(x_k)`.
//!
//! With implicit midpoint, a step that took an L-BFGS step ends with the
//! end-of-step check of `step/ray.rs`, as Anderson's does.
//!
//! Cost per iteration: one local-global iteration and one product with
//! `A`. Line-search trials are judged from their local step's projections
//! (summing the energy from them), and the accepted trial's projections
//! serve the next global step, so only backtracking and fallbacks cost
//! extra projection passes.
//!
//! Refused: lagged damping models (`rayleigh-lagged`), whose step matrix is
//! not the scalar `A` the gradient is computed with.

use pd_constraints::EnergyBound;
use pd_mesh::Point;

use super::estimate::Kept;
use super::iteration::{PositionSolver, StepProblem};
use super::materials::MaterialGradient;
use super::ops::{difference, mass_dot};
use super::ray::RayCheck;
use crate::SolverError;
use crate::system::SystemCoefficients;

/// Armijo's sufficient-decrease fraction of the line search.
const ARMIJO: f64 = 1e-4;
/// Step halvings before the line search gives up and takes the plain
/// iterate: 8 (a step of 1/128). Near the round-off floor no length passes
/// Armijo's test, and with 30 halvings L-BFGS spent about 100 objective
/// evaluations a step there (the 2,304-vertex beam at a budget of 30).
const HALVINGS: usize = 8;

/// L-BFGS with history `window` and the PD matrix as initial Hessian.
#[derive(Debug, Clone)]
pub struct Lbfgs {
    window: usize,
    /// Ring of `s_i`, `y_i` and `w_{i+1} - w_i` (per vertex).
    s: Vec<Vec<Point>>,
    y: Vec<Vec<Point>>,
    dw: Vec<Vec<Point>>,
    /// `1 / (s_i . y_i)` and the first loop's `alpha_i`.
    rho: Vec<f64>,
    alpha: Vec<f64>,
    /// `A`'s values over the scalar lower pattern.
    values: Vec<f64>,
    /// `x_k`, `w_k`, `grad_k` and their previous values.
    iterate: [Vec<Point>; 2],
    update: [Vec<Point>; 2],
    gradient: [Vec<Point>; 2],
    /// The search direction, per vertex.
    direction: Vec<Point>,
    /// The two-loop recursion's `q`, per vertex.
    q: Vec<Point>,
    /// `A w` per free vertex.
    product: Vec<Point>,
    /// Per-chunk scratch of the objective's energy sum.
    partials: Vec<EnergyBound>,
    /// The hyperelastic materials' gradient correction (step/materials.rs).
    materials: MaterialGradient,
    /// The end-of-step check of implicit midpoint (step/ray.rs).
    ray: RayCheck,
}

impl Lbfgs {
    /// A solver keeping the last `window` pairs, taken into
    /// `1..=`[`SolverSpec::MAX_WINDOW`](super::method::SolverSpec::MAX_WINDOW)
    /// (a scene's `window` outside that range is an error).
    pub fn new(window: usize) -> Self {
        let window = window.clamp(1, super::method::SolverSpec::MAX_WINDOW);
        Self {
            window,
            s: vec![Vec::new(); window],
            y: vec![Vec::new(); window],
            dw: vec![Vec::new(); window],
            rho: vec![0.0; window],
            alpha: vec![0.0; window],
            values: Vec::new(),
            iterate: [Vec::new(), Vec::new()],
            update: [Vec::new(), Vec::new()],
            gradient: [Vec::new(), Vec::new()],
            direction: Vec::new(),
            q: Vec::new(),
            product: Vec::new(),
            partials: Vec::new(),
            materials: MaterialGradient::default(),
            ray: RayCheck::default(),
        }
    }

    fn prepare(&mut self, step: &StepProblem<'_>) -> Result<(), SolverError> {
        let n = step.positions.len();
        let system = step.global.system();
        if self.direction.len() != n {
            let zero = vec![Point::zeros(); n];
            for v in self
                .s
                .iter_mut()
                .chain(&mut self.y)
                .chain(&mut self.dw)
                .chain(&mut self.iterate)
                .chain(&mut self.update)
                .chain(&mut self.gradient)
            {
                v.clone_from(&zero);
            }
            self.q.clone_from(&zero);
            self.direction = zero;
            self.values = vec![0.0; system.pattern.row_idx.len()];
            self.product = vec![Point::zeros(); system.free.len()];
        }
        let coefficients = SystemCoefficients::of(step.coefficients, step.damping, step.h).matrix;
        system.values_into(coefficients, &mut self.values);
        Ok(())
    }

    /// `gradient[0] = -A update[0]` per vertex (zero at fixed vertices).
    fn gradient(&mut self, step: &StepProblem<'_>) {
        let system = step.global.system();
        super::newton::symmetric_product(system, &self.values, &self.update[0], &mut self.product);
        step.global
            .correct_product(&self.update[0], &mut self.product);
        let gradient = &mut self.gradient[0];
        gradient.iter_mut().for_each(|g| *g = Point::zeros());
        for (f, &v) in system.free.iter().enumerate() {
            gradient[v] = -self.product[f];
        }
    }

    /// The two-loop direction over the `stored` pairs (newest at ring slot
    /// `newest`), into `direction`; returns `grad . direction`.
    fn two_loop(&mut self, stored: usize, newest: usize) -> f64 {
        let dot =
            |a: &[Point], b: &[Point]| -> f64 { a.iter().zip(b).map(|(a, b)| a.dot(b)).sum() };
        let window = self.window;
        let slot = |j: usize| (newest + window - j) % window;
        // q = grad - sum alpha_i y_i, newest first.
        self.q.copy_from_slice(&self.gradient[0]);
        for j in 0..stored {
            let i = slot(j);
            let a = self.rho[i] * dot(&self.s[i], &self.q);
            self.alpha[i] = a;
            for (q, y) in self.q.iter_mut().zip(&self.y[i]) {
                *q -= y * a;
            }
        }
        // r = A^{-1} q = -w_k + sum alpha_i (w_{i+1} - w_i).
        for (r, w) in self.direction.iter_mut().zip(&self.update[0]) {
            *r = -w;
        }
        for j in 0..stored {
            let i = slot(j);
            let a = self.alpha[i];
            for (r, d) in self.direction.iter_mut().zip(&self.dw[i]) {
                *r += d * a;
            }
        }
        // Oldest first: r += s_i (alpha_i - rho_i y_i . r).
        for j in (0..stored).rev() {
            let i = slot(j);
            let c = self.alpha[i] - self.rho[i] * dot(&self.y[i], &self.direction);
            for (r, s) in self.direction.iter_mut().zip(&self.s[i]) {
                *r += s * c;
            }
        }
        // The direction is -r.
        self.direction.iter_mut().for_each(|r| *r = -*r);
        dot(&self.gradient[0], &self.direction)
    }
}

impl PositionSolver for Lbfgs {
    fn name(&self) -> &'static str {
        "lbfgs"
    }

    fn handles_materials(&self) -> bool {
        true
    }

    /// Its ratios are superlinear convergence, not the map's contraction.
    fn estimate_needs_contraction(&self) -> bool {
        true
    }

    /// Its initial Hessian is the prefactored n x n matrix.
    fn handles_lagged_damping(&self) -> bool {
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
        // which then serve the next global step (the start's are kept from
        // the predictor's safeguard when it ran).
        let mut merit = match step.take_start_projections() {
            Some(value) => value,
            None => step.project_with_objective(&mut self.partials),
        };
        let (mut stored, mut newest) = (0usize, self.window - 1);
        let iterations = step.iterations();
        // With materials, `update` is the corrected `w'` and the plain
        // iterate `x + w'` is not safeguarded: the last iteration runs its
        // line search too.
        let materials = MaterialGradient::present(step);
        // Whether a step other than the plain iterate was taken (else the
        // step is plain PD's and needs no end-of-step check).
        let check = RayCheck::applies(step);
        let mut accelerated = step.predicted;
        for k in 0..iterations {
            self.iterate.swap(0, 1);
            self.update.swap(0, 1);
            self.gradient.swap(0, 1);
            self.iterate[0].copy_from_slice(step.displacement());
            step.global_half();
            difference(step.displacement(), &self.iterate[0], &mut self.update[0]);
            if materials {
                self.materials
                    .correct(step, &self.iterate[0], &mut self.update[0]);
                let dx = step.displacement_mut();
                for ((x, x0), w) in dx.iter_mut().zip(&self.iterate[0]).zip(&self.update[0]) {
                    *x = x0 + w;
                }
            }
            let masses = step.masses();
            let change = mass_dot(masses, &self.update[0], &self.update[0]);
            let size = mass_dot(masses, step.displacement(), step.displacement());
            if k > 0 {
                // The map's contraction along the step (step/estimate.rs).
                let iterates = [&self.iterate[0][..], &self.iterate[1]];
                let residuals = [&self.update[0][..], &self.update[1]];
                (step.estimate).note_step(masses, Kept::Iterates, iterates, residuals);
            }
            let converged = step.record_residual(change, size);
            if converged || (k + 1 == iterations && !materials) {
                if check && accelerated && !converged {
                    self.ray.finish(step, &mut self.partials);
                }
                step.record_objective();
                break;
            }
            self.gradient(step);
            if k > 0 {
                let next = (newest + 1) % self.window;
                difference(&self.iterate[0], &self.iterate[1], &mut self.s[next]);
                difference(&self.gradient[0], &self.gradient[1], &mut self.y[next]);
                let sy: f64 = self.s[next]
                    .iter()
                    .zip(&self.y[next])
                    .map(|(a, b)| a.dot(b))
                    .sum();
                if sy > 0.0 && sy.is_finite() {
                    difference(&self.update[0], &self.update[1], &mut self.dw[next]);
                    self.rho[next] = 1.0 / sy;
                    newest = next;
                    stored = (stored + 1).min(self.window);
                }
            }
            let mut slope = self.two_loop(stored, newest);
            if !(slope < 0.0) && stored > 0 {
                // Not a descent direction: restart from plain PD's.
                stored = 0;
                slope = self.two_loop(0, newest);
            }
            let mut accepted = false;
            if slope < 0.0 {
                let mut alpha = 1.0;
                for _ in 0..HALVINGS {
                    let dx = step.displacement_mut();
                    for ((x, x0), d) in dx.iter_mut().zip(&self.iterate[0]).zip(&self.direction) {
                        *x = x0 + d * alpha;
                    }
                    let trial = step.project_with_objective(&mut self.partials);
                    if trial <= merit + ARMIJO * alpha * slope {
                        merit = trial;
                        accepted = true;
                        accelerated |= stored > 0 || alpha != 1.0;
                        break;
                    }
                    alpha *= 0.5;
                }
            }
            if !accepted {
                let dx = step.displacement_mut();
                for ((x, x0), w) in dx.iter_mut().zip(&self.iterate[0]).zip(&self.update[0]) {
                    *x = x0 + w;
                }
                merit = step.project_with_objective(&mut self.partials);
                stored = 0;
            }
            step.record_objective();
        }
        Ok(())
    }
}
