//! The subspace predictor's Galerkin start (`[solver] predictor =
//! "subspace"`, docs/solver.md "Implicit midpoint's 3x: a subspace start").
//!
//! From the linear predictor's start `x_lin`, one local step gives the
//! projections there and with them the gradient of the step objective,
//! `grad g(x_lin) = A x_lin - b(x_lin)` (`A` the prefactored matrix, `b`
//! the right-hand side from those projections). The start then moves to the
//! minimiser of the local-global surrogate (the quadratic with those
//! projections, which touches `g` at `x_lin` and lies above it) over
//! `x_lin + span C`, `C` the last `m` stored corrections:
//!
//! `a = -(C^T A C)^+ C^T grad g(x_lin)`, `x0 = x_lin + C a`,
//!
//! the pseudo-inverse truncated as the fitted predictor's (Jacobi scaling,
//! eigenvalues below `1e-10` of the largest dropped). The surrogate lies
//! above `g`, so `g(x0) <= g(x_lin)`. A linear body's corrections in `p`
//! modes lie in a `p`-dimensional span, which `m >= p` corrections
//! reproduce exactly, whatever each mode's turn per step.

use pd_mesh::Point;

use super::iteration::StepProblem;
use super::ops::ScalarMatrix;
use super::predictor::PredictorState;

/// Eigenvalues of the scaled Galerkin matrix below this fraction of the
/// largest are dropped, as in the fitted predictor (step/fitted.rs).
const EIGENVALUE_CUT: f64 = 1e-10;

/// The Galerkin start's buffers, kept between steps.
#[derive(Debug, Default)]
pub(crate) struct SubspaceScratch {
    matrix: ScalarMatrix,
    /// `grad g(x_lin)` per free vertex.
    gradient: Vec<Point>,
    /// `A c_j` per free vertex, one per column.
    products: Vec<Vec<Point>>,
}

impl SubspaceScratch {
    /// Moves `step`'s displacement (the linear start) to the Galerkin
    /// start over the span of the newest `window` corrections of `state`
    /// (per vertex, zero at fixed vertices). Costs one local step (counted as an objective
    /// evaluation), one product with `A` per column and one for the start.
    /// Leaves the start unchanged when the system is degenerate or the
    /// matrix is not scalar.
    pub fn galerkin_start(
        &mut self,
        step: &mut StepProblem<'_>,
        state: &PredictorState,
        window: usize,
    ) {
        let columns = state.correction_history().take(window);
        if !super::ray::RayCheck::scalar_pd(step) {
            return;
        }
        let free = step.global.system().free.len();
        let m = state.correction_history().take(window).count();
        if m == 0 {
            return;
        }
        self.gradient.resize(free, Point::zeros());
        self.products.resize_with(m, Vec::new);
        step.project_here();
        step.rhs_from_projections();
        self.matrix
            .product(step, &step.buffers.displacement, &mut self.gradient);
        for (g, r) in self.gradient.iter_mut().zip(&step.buffers.rhs) {
            *g -= r;
        }
        for (product, c) in self
            .products
            .iter_mut()
            .zip(state.correction_history().take(window))
        {
            product.resize(free, Point::zeros());
            self.matrix.product(step, c, product);
        }
        let system = step.global.system();
        let dot = |c: &[Point], free_values: &[Point]| -> f64 {
            system
                .free
                .iter()
                .zip(free_values)
                .map(|(&v, w)| c[v].dot(w))
                .sum()
        };
        let mut h = nalgebra::DMatrix::zeros(m, m);
        let mut r = nalgebra::DVector::zeros(m);
        for (i, ci) in state.correction_history().take(window).enumerate() {
            r[i] = -dot(ci, &self.gradient);
            for j in i..m {
                let value = dot(ci, &self.products[j]);
                h[(i, j)] = value;
                h[(j, i)] = value;
            }
        }
        let Some(a) = truncated_solve(h, r) else {
            return;
        };
        let dx = &mut step.buffers.displacement;
        for (a, c) in a.iter().zip(columns) {
            for (x, c) in dx.iter_mut().zip(c) {
                *x += c * *a;
            }
        }
    }
}

/// `H^+ r` for a symmetric positive semi-definite `H`: Jacobi-scaled, then
/// a truncated eigen-decomposition. `None` if anything is not finite.
fn truncated_solve(
    mut h: nalgebra::DMatrix<f64>,
    mut r: nalgebra::DVector<f64>,
) -> Option<nalgebra::DVector<f64>> {
    let m = r.len();
    let scale: Vec<f64> = (0..m)
        .map(|i| {
            let d = h[(i, i)];
            if d > 0.0 { d.sqrt() } else { f64::INFINITY }
        })
        .collect();
    for i in 0..m {
        r[i] /= scale[i];
        for j in 0..m {
            h[(i, j)] /= scale[i] * scale[j];
        }
    }
    if !h.iter().chain(r.iter()).all(|x| x.is_finite()) {
        return None;
    }
    let eigen = nalgebra::SymmetricEigen::new(h);
    let largest = eigen.eigenvalues.iter().fold(0.0_f64, |a, &l| a.max(l));
    if largest <= 0.0 || !largest.is_finite() {
        return None;
    }
    let mut solution = nalgebra::DVector::zeros(m);
    for (l, v) in eigen
        .eigenvalues
        .iter()
        .zip(eigen.eigenvectors.column_iter())
    {
        if *l > EIGENVALUE_CUT * largest {
            solution += v * (v.dot(&r) / l);
        }
    }
    for i in 0..m {
        solution[i] /= scale[i];
    }
    solution.iter().all(|x| x.is_finite()).then_some(solution)
}
