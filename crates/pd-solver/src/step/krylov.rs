//! A measurement tool, not a method: how far the best Krylov method could
//! take a step's iterations with the prefactored PD matrix `A` as its
//! preconditioner (docs/design/solver.md, "The Krylov bound").
//!
//! Anderson, L-BFGS and Chebyshev combine preconditioned gradients
//! `A^{-1} grad g(x)`, one local-global iteration each. On a quadratic
//! objective with Hessian `H` their iterates lie in the Krylov space of
//! `A^{-1} H` from the start, where preconditioned conjugate gradients (CG)
//! has the smallest error in the `H`-norm after as many products.
//! [`KrylovProbe`] takes one step's problem from its start `x0` (the
//! predictor's, when one is set) and, given the step's converged solution
//! `x*` (from [`crate::Newton`] at a tight tolerance), measures in the mass
//! norm `|x - x*|_M`:
//!
//! - plain local-global iterations from `x0` (the real, nonlinear map);
//! - the same map on the step's quadratic model at `x*`,
//!   `e <- e - A^{-1} H e` (how well the model predicts plain PD);
//! - CG on `H d = r` from `d = 0`, preconditioned with `A` (one solve with
//!   the existing factor and one product with `H` an iteration), for four
//!   linearisations: the Hessian at `x*` (the element Hessians projected to
//!   PSD, and the true ones) with `r = H (x* - x0)`, whose solution is
//!   `x*` (the quadratic model's own bound); and the Hessian at `x0` (PSD,
//!   true) with `r = -grad g(x0)` (a first truncated Newton iteration,
//!   whose floor is the Newton step's error, measured for the PSD Hessian
//!   by a direct solve);
//! - the Ritz values of `A^{-1} H` from CG's coefficients (the Lanczos
//!   tridiagonal matrix), which bound its spectrum from inside;
//! - optionally, CG preconditioned with a PSD Hessian factorised once, at
//!   the first measured step, and the costs of the operations above.
//!
//! The step then ends at `x*`. Two other modes make the probe a method
//! whose whole runs can be measured: an oracle (CG on the model at the
//! step's own `x*` for `k` iterations, ending there) and a truncated Newton
//! bound (the true Hessian at `x0`, free, and a few outer iterations of `k`
//! CG iterations each, without a line search). The probe allocates freely;
//! it is for `benches/examples/krylov_bound.rs`, not for simulation.

use std::sync::{Arc, Mutex};

use nalgebra::{DMatrix, SymmetricEigen};
use pd_mesh::Point;

use super::iteration::{PositionSolver, StepProblem};
use super::newton::{hessian_coefficients, symmetric_product};
use crate::SolverError;
use crate::global::MatrixCoefficients;
use crate::lagged::LaggedSystem;
use crate::system::SystemCoefficients;

/// What a [`KrylovProbe`] is asked to do and what it measured, shared with
/// the caller. Errors are mass norms `|x - x*|_M` over the free vertices
/// (kg^(1/2) m).
#[derive(Debug, Clone, Default)]
pub struct KrylovRecord {
    /// Input: the converged displacement `x* - x_n` of the coming step, one
    /// point per vertex (m).
    pub reference: Vec<Point>,
    /// Input: plain local-global iterations to run from the start.
    pub plain_iterations: usize,
    /// Input: the most CG iterations of each run.
    pub cg_iterations: usize,
    /// Input: `Some(k)` makes the probe an oracle method instead: it runs
    /// only CG on the quadratic model at `x*` (true Hessian) for `k`
    /// iterations and ends the step at that iterate (no plain iterations);
    /// `None` measures everything and ends at `x*`.
    pub finish: Option<usize>,
    /// Input: when not empty, the probe is a truncated Newton method
    /// instead (and [`KrylovRecord::finish`] is ignored): the true Hessian
    /// at `x0`, assembled once, and one outer iteration per entry, each a
    /// new gradient and that many CG iterations, without a line search
    /// (the Hessian's cost left out: a bound, not a method).
    pub newton: Vec<usize>,
    /// Output: whether the step started at a predicted point.
    pub predicted: bool,
    /// Output: the start's error `|x0 - x*|_M`.
    pub start_error: f64,
    /// Output: the error after each plain local-global iteration.
    pub plain_errors: Vec<f64>,
    /// Output: the error after each iteration of the plain map on the
    /// quadratic model at `x*` (true Hessian).
    pub model_plain_errors: Vec<f64>,
    /// Output: one CG run per linearisation.
    pub runs: Vec<CgRun>,
    /// Input: also run CG on the model at `x*` (true Hessian) with the
    /// PSD Hessian at the first measured step's `x*`, factorised once, as
    /// preconditioner instead of `A` (run `true@x*, lagged psd H`).
    pub lagged_preconditioner: bool,
    /// Input: repetitions of the cost measurement (0: none).
    pub timing_repetitions: usize,
    /// Output: the fastest of `timing_repetitions` wall times (s) of each
    /// operation at the start: `iteration` (one plain local-global
    /// iteration), `projection` (its local step), `rhs` (its right-hand
    /// side), `solve` (one solve with `A`), `a product` (one product with
    /// `A`, for a gradient), `hessian product` (one product
    /// with the assembled 3n Hessian), `hessian psd` and `hessian true`
    /// (computing and assembling the element Hessians), `hessian
    /// factorisation` and `hessian solve` (of the PSD one), `cg vectors` (a
    /// CG iteration's dot products and updates).
    pub costs: Vec<(&'static str, f64)>,
}

/// One preconditioned CG run of a [`KrylovProbe`].
#[derive(Debug, Clone, Default)]
pub struct CgRun {
    /// Which Hessian and right-hand side (`psd@x*`, `true@x*`, `psd@x0`,
    /// `true@x0`, `true@x*, lagged psd H`).
    pub name: String,
    /// The error after each CG iteration.
    pub errors: Vec<f64>,
    /// `sqrt(r . A^{-1} r)` after each iteration, relative to the first.
    pub residuals: Vec<f64>,
    /// The step lengths `alpha_k`.
    pub alphas: Vec<f64>,
    /// The direction updates `beta_k`.
    pub betas: Vec<f64>,
    /// The Ritz values of `A^{-1} H` from the Lanczos matrix of all
    /// iterations, ascending.
    pub ritz: Vec<f64>,
    /// The smallest and largest Ritz values after each iteration.
    pub extreme_ritz: Vec<(f64, f64)>,
    /// The error of the exact solution of the linearised system (the
    /// Newton step), when it was solved directly.
    pub exact_error: Option<f64>,
    /// Whether CG met a direction of non-positive curvature and stopped.
    pub indefinite: bool,
}

/// The measuring [`PositionSolver`]: see the module docs. Fill
/// [`KrylovRecord::reference`] before each step.
#[derive(Debug)]
pub struct KrylovProbe {
    record: Arc<Mutex<KrylovRecord>>,
    hessian: Option<Box<LaggedSystem>>,
    /// The PSD Hessian factorised at the first measured step's `x*`
    /// ([`KrylovRecord::lagged_preconditioner`]).
    lagged: Option<Box<LaggedSystem>>,
}

impl KrylovProbe {
    /// A probe reporting into `record`.
    pub fn new(record: Arc<Mutex<KrylovRecord>>) -> Self {
        Self {
            record,
            hessian: None,
            lagged: None,
        }
    }
}

/// The Ritz values of the Lanczos tridiagonal matrix of CG's first
/// `alphas.len()` iterations (`betas` at least one shorter), ascending.
fn ritz_values(alphas: &[f64], betas: &[f64]) -> Vec<f64> {
    let k = alphas.len();
    let mut t = DMatrix::zeros(k, k);
    for j in 0..k {
        t[(j, j)] = 1.0 / alphas[j]
            + if j > 0 {
                betas[j - 1] / alphas[j - 1]
            } else {
                0.0
            };
        if j + 1 < k {
            let off = betas[j].sqrt() / alphas[j];
            t[(j, j + 1)] = off;
            t[(j + 1, j)] = off;
        }
    }
    let mut values: Vec<f64> = SymmetricEigen::new(t).eigenvalues.iter().copied().collect();
    values.sort_by(f64::total_cmp);
    values
}

fn dot(a: &[Point], b: &[Point]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a.dot(b)).sum()
}

/// The step's quantities the CG runs need, over the free vertices.
struct Free<'a> {
    free: &'a [usize],
    masses: &'a [f64],
    start: &'a [Point],
    reference: &'a [Point],
}

impl Free<'_> {
    /// `x* - x0` per free vertex.
    fn to_reference(&self) -> Vec<Point> {
        (self.free.iter())
            .map(|&v| self.reference[v] - self.start[v])
            .collect()
    }

    /// `|x0 + d - x*|_M`, `d` per free vertex.
    fn error(&self, d: &[Point]) -> f64 {
        let mut sum = 0.0;
        for (f, &v) in self.free.iter().enumerate() {
            sum += self.masses[v] * (self.start[v] + d[f] - self.reference[v]).norm_squared();
        }
        sum.sqrt()
    }
}

/// `A^{-1} r` per free vertex.
fn precondition(step: &mut StepProblem<'_>, r: &[Point], z: &mut [Point]) {
    step.global.solve(r);
    for (f, z) in z.iter_mut().enumerate() {
        *z = step.global.solution(f);
    }
}

/// Preconditioned CG on `H d = r0` from `d = 0`.
/// `P^{-1} r` per free vertex: `P = A` without `lagged`, else the
/// factorised Hessian `lagged`.
fn precondition_with(
    step: &mut StepProblem<'_>,
    lagged: Option<&mut LaggedSystem>,
    r: &[Point],
    z: &mut [Point],
) {
    match lagged {
        None => precondition(step, r, z),
        Some(lagged) => {
            lagged.solve(r);
            for (f, z) in z.iter_mut().enumerate() {
                *z = lagged.solution(f);
            }
        }
    }
}

fn cg(
    step: &mut StepProblem<'_>,
    hessian: &LaggedSystem,
    r0: &[Point],
    free: &Free<'_>,
    (iterations, mut lagged): (usize, Option<&mut LaggedSystem>),
    name: &str,
) -> (CgRun, Vec<Point>) {
    let nf = r0.len();
    let mut run = CgRun {
        name: name.to_string(),
        ..CgRun::default()
    };
    let mut d = vec![Point::zeros(); nf];
    let mut r = r0.to_vec();
    let mut z = vec![Point::zeros(); nf];
    precondition_with(step, lagged.as_deref_mut(), &r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let rz0 = rz;
    let mut hp = vec![Point::zeros(); nf];
    for _ in 0..iterations {
        hessian.product(&p, &mut hp);
        let curvature = dot(&p, &hp);
        if !(curvature > 0.0) {
            run.indefinite = true;
            break;
        }
        let alpha = rz / curvature;
        for f in 0..nf {
            d[f] += p[f] * alpha;
            r[f] -= hp[f] * alpha;
        }
        run.alphas.push(alpha);
        run.errors.push(free.error(&d));
        precondition_with(step, lagged.as_deref_mut(), &r, &mut z);
        let rz_new = dot(&r, &z);
        run.residuals.push((rz_new / rz0).sqrt());
        let ritz = ritz_values(&run.alphas, &run.betas);
        run.extreme_ritz.push((ritz[0], ritz[ritz.len() - 1]));
        if !(rz_new > 1e-28 * rz0) {
            break;
        }
        let beta = rz_new / rz;
        run.betas.push(beta);
        for f in 0..nf {
            p[f] = z[f] + p[f] * beta;
        }
        rz = rz_new;
    }
    if !run.alphas.is_empty() {
        run.ritz = ritz_values(&run.alphas, &run.betas);
    }
    (run, d)
}

/// `-grad g = rhs(p(dx)) - A dx` on the free rows at the current
/// displacement (one local step), `a_values` holding `A`.
fn minus_gradient(step: &mut StepProblem<'_>, a_values: &[f64]) -> Vec<Point> {
    let mut gradient = vec![Point::zeros(); step.buffers.rhs.len()];
    symmetric_product(
        step.global.system(),
        a_values,
        &step.buffers.displacement,
        &mut gradient,
    );
    step.project_here();
    step.rhs_from_projections();
    for (g, r) in gradient.iter_mut().zip(&step.buffers.rhs) {
        *g = r - *g;
    }
    gradient
}

/// The fastest of `repetitions` wall times of `f`, s.
pub(crate) fn fastest(repetitions: usize, mut f: impl FnMut()) -> f64 {
    (0..repetitions)
        .map(|_| {
            let t = std::time::Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// [`KrylovRecord::costs`] at the displacement `start` (restored after).
/// Never inlined, so that `valgrind --toggle-collect` can find it.
#[inline(never)]
fn costs(
    step: &mut StepProblem<'_>,
    hessian: &mut LaggedSystem,
    start: &[Point],
    repetitions: usize,
) -> Vec<(&'static str, f64)> {
    let mut costs = Vec::new();
    let iteration = fastest(repetitions, || {
        step.buffers.displacement.copy_from_slice(start);
        step.local_global_iteration();
    });
    step.buffers.displacement.copy_from_slice(start);
    costs.push(("iteration", iteration));
    costs.push(("projection", fastest(repetitions, || step.project_here())));
    costs.push(("rhs", fastest(repetitions, || step.rhs_from_projections())));
    let nf = step.buffers.rhs.len();
    let r = step.buffers.rhs.clone();
    let mut z = vec![Point::zeros(); nf];
    costs.push((
        "solve",
        fastest(repetitions, || precondition(step, &r, &mut z)),
    ));
    let c = step.coefficients;
    let matrix = SystemCoefficients::of(c, step.damping, step.h).matrix;
    let system = step.global.system();
    let mut a_values = vec![0.0; system.pattern.row_idx.len()];
    system.values_into(matrix, &mut a_values);
    let mut product = vec![Point::zeros(); nf];
    costs.push((
        "a product",
        fastest(repetitions, || {
            symmetric_product(system, &a_values, start, &mut product);
        }),
    ));
    let (coefficients, elastic) = hessian_coefficients(matrix, c);
    let q = step.buffers.q.clone();
    let local = step.local;
    for (name, psd) in [("hessian psd", true), ("hessian true", false)] {
        costs.push((
            name,
            fastest(repetitions, || {
                hessian.assemble(local.blocks(), &q, coefficients, elastic, psd);
            }),
        ));
    }
    let mut out = vec![Point::zeros(); nf];
    costs.push((
        "hessian product",
        fastest(repetitions, || hessian.product(&z, &mut out)),
    ));
    hessian.assemble(local.blocks(), &q, coefficients, elastic, true);
    if hessian.factorise_assembled().is_ok() {
        let factorise = fastest(repetitions.min(5), || {
            // The same matrix, factorised just above: it succeeds again.
            hessian.factorise_assembled().ok();
        });
        costs.push(("hessian factorisation", factorise));
        costs.push(("hessian solve", fastest(repetitions, || hessian.solve(&r))));
    }
    let (mut d, mut p) = (z.clone(), z.clone());
    let vectors = fastest(repetitions, || {
        let curvature = dot(&p, &out);
        let alpha = 1e-3 / curvature.max(1.0);
        for f in 0..nf {
            d[f] += p[f] * alpha;
            z[f] -= out[f] * alpha;
        }
        let rz = dot(&r, &z);
        let beta = 1e-3 / rz.max(1.0);
        for f in 0..nf {
            p[f] = z[f] + p[f] * beta;
        }
    });
    costs.push(("cg vectors", vectors));
    costs
}

/// The coefficients of the step's matrix `A` and its values on the global
/// system's pattern.
fn step_matrix(step: &StepProblem<'_>) -> (MatrixCoefficients, Vec<f64>) {
    let matrix = SystemCoefficients::of(step.coefficients, step.damping, step.h).matrix;
    let system = step.global.system();
    let mut a_values = vec![0.0; system.pattern.row_idx.len()];
    system.values_into(matrix, &mut a_values);
    (matrix, a_values)
}

/// The probe measures steps without lagged or per-body damping, against a
/// reference displacement of the model's length.
fn check_probe(step: &StepProblem<'_>, record: &KrylovRecord) -> Result<(), SolverError> {
    if step.damping.lagged_stiffness != 0.0 || step.global.damping_weights().is_some() {
        return Err(SolverError::Unsupported {
            what: "krylov probe: lagged or per-body damping".into(),
        });
    }
    if record.reference.len() != step.positions.len() {
        return Err(SolverError::Unsupported {
            what: "krylov probe: no reference displacement of the right length".into(),
        });
    }
    Ok(())
}

/// `plain` local-global iterations from the step's start (the real,
/// nonlinear map) and the error after each; the start is restored after.
fn plain_errors(step: &mut StepProblem<'_>, free: &Free<'_>, plain: usize) -> Vec<f64> {
    let mut errors = Vec::with_capacity(plain);
    for _ in 0..plain {
        step.local_global_iteration();
        let d: Vec<Point> = free
            .free
            .iter()
            .map(|&v| step.buffers.displacement[v] - free.start[v])
            .collect();
        errors.push(free.error(&d));
    }
    step.buffers.displacement.copy_from_slice(free.start);
    errors
}

/// The truncated Newton bound: with `hessian` assembled at the start, one
/// outer iteration per entry of `newton` (a new gradient, `first` for the
/// first, then that many CG iterations), each added to the step's
/// displacement, no line search.
fn truncated_newton(
    step: &mut StepProblem<'_>,
    hessian: &LaggedSystem,
    free: &Free<'_>,
    newton: &[usize],
    a_values: &[f64],
    first: Vec<Point>,
) {
    let mut r0 = first;
    for (o, &inner) in newton.iter().enumerate() {
        if o > 0 {
            r0 = minus_gradient(step, a_values);
        }
        let (_, d) = cg(step, hessian, &r0, free, (inner, None), "true@x0");
        for (f, &v) in free.free.iter().enumerate() {
            step.buffers.displacement[v] += d[f];
        }
    }
}

/// The plain map on the quadratic model at `x*`, `d <- d + A^{-1} H (e0 -
/// d)` from `d = 0`, and its error after each of `iterations`.
fn model_plain_errors(
    step: &mut StepProblem<'_>,
    hessian: &LaggedSystem,
    free: &Free<'_>,
    error_to_reference: &[Point],
    iterations: usize,
) -> Vec<f64> {
    let nf = error_to_reference.len();
    let mut errors = Vec::with_capacity(iterations);
    let mut d = vec![Point::zeros(); nf];
    let (mut rest, mut hr, mut z) = (d.clone(), d.clone(), d.clone());
    for _ in 0..iterations {
        for f in 0..nf {
            rest[f] = error_to_reference[f] - d[f];
        }
        hessian.product(&rest, &mut hr);
        precondition(step, &hr, &mut z);
        for f in 0..nf {
            d[f] += z[f];
        }
        errors.push(free.error(&d));
    }
    errors
}

impl KrylovProbe {
    /// The Hessian system, built at the first step and kept.
    fn take_hessian(&mut self, step: &StepProblem<'_>) -> Result<Box<LaggedSystem>, SolverError> {
        match self.hessian.take() {
            Some(hessian) => Ok(hessian),
            None => Ok(Box::new(LaggedSystem::new(
                step.global.system(),
                step.local.blocks(),
            )?)),
        }
    }
}

impl PositionSolver for KrylovProbe {
    fn name(&self) -> &'static str {
        "krylov-probe"
    }

    /// Its products use the plain step matrix and Hessian.
    fn handles_rotation_preserving_damping(&self) -> bool {
        false
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        let record = Arc::clone(&self.record);
        let mut record = record.lock().map_err(|_| SolverError::Unsupported {
            what: "krylov probe: a poisoned record".into(),
        })?;
        check_probe(step, &record)?;
        record.predicted = step.predicted;
        let mut hessian = self.take_hessian(step)?;
        let start = step.displacement().to_vec();
        let reference = record.reference.clone();
        let free_vertices = step.global.system().free.clone();
        let free = Free {
            free: &free_vertices,
            masses: step.masses,
            start: &start,
            reference: &reference,
        };
        let nf = free_vertices.len();
        record.start_error = free.error(&vec![Point::zeros(); nf]);
        if record.timing_repetitions > 0 {
            record.costs = costs(step, &mut hessian, &start, record.timing_repetitions);
        }

        // Plain local-global iterations, the nonlinear map (not for the
        // oracle and the truncated Newton bound).
        let method = record.finish.is_some() || !record.newton.is_empty();
        let plain = if method { 0 } else { record.plain_iterations };
        record.plain_errors = plain_errors(step, &free, plain);

        let c = step.coefficients;
        let (matrix, a_values) = step_matrix(step);
        let minus_gradient = minus_gradient(step, &a_values);

        let (hessian_coefficients, elastic) = hessian_coefficients(matrix, c);
        let q_of = |dx: &[Point]| -> Vec<Point> {
            (step.positions.iter().zip(dx))
                .map(|(x, d)| x + d * c.c2)
                .collect()
        };
        let (q_reference, q_start) = (q_of(&reference), q_of(&start));
        let error_to_reference = free.to_reference();
        let local = step.local;
        let blocks = local.blocks();
        if !record.newton.is_empty() {
            hessian.assemble(blocks, &q_start, hessian_coefficients, elastic, false);
            truncated_newton(
                step,
                &hessian,
                &free,
                &record.newton,
                &a_values,
                minus_gradient,
            );
            self.hessian = Some(hessian);
            return Ok(());
        }
        let iterations = record.finish.unwrap_or(record.cg_iterations);
        let mut runs = Vec::new();
        let mut model_plain = Vec::new();
        let linearisations = [
            ("true@x*", &q_reference, false),
            ("psd@x*", &q_reference, true),
            ("psd@x0", &q_start, true),
            ("true@x0", &q_start, false),
        ];
        let count = if record.finish.is_some() { 1 } else { 4 };
        for (name, q, psd) in linearisations.into_iter().take(count) {
            hessian.assemble(blocks, q, hessian_coefficients, elastic, psd);
            let at_reference = std::ptr::eq(q, &q_reference);
            let r0 = if at_reference {
                let mut r0 = vec![Point::zeros(); nf];
                hessian.product(&error_to_reference, &mut r0);
                r0
            } else {
                minus_gradient.clone()
            };
            if name == "true@x*" && record.finish.is_none() {
                model_plain = model_plain_errors(
                    step,
                    &hessian,
                    &free,
                    &error_to_reference,
                    record.plain_iterations,
                );
            }
            let (mut run, d) = cg(step, &hessian, &r0, &free, (iterations, None), name);
            if record.finish.is_some() {
                for (f, &v) in free_vertices.iter().enumerate() {
                    step.buffers.displacement[v] = start[v] + d[f];
                }
            }
            if name == "true@x*" && record.lagged_preconditioner && record.finish.is_none() {
                if self.lagged.is_none() {
                    let mut lagged = LaggedSystem::new(step.global.system(), blocks)?;
                    lagged.refactorise(blocks, &q_reference, hessian_coefficients, elastic)?;
                    self.lagged = Some(Box::new(lagged));
                }
                let lagged = (iterations, self.lagged.as_deref_mut());
                runs.push(cg(step, &hessian, &r0, &free, lagged, "true@x*, lagged psd H").0);
            }
            if name == "psd@x0" && hessian.factorise_assembled().is_ok() {
                hessian.solve(&r0);
                let d: Vec<Point> = (0..nf).map(|f| hessian.solution(f)).collect();
                run.exact_error = Some(free.error(&d));
            }
            runs.push(run);
        }
        record.runs = runs;
        record.model_plain_errors = model_plain;
        self.hessian = Some(hessian);
        if record.finish.is_none() {
            step.buffers.displacement.copy_from_slice(&reference);
        }
        Ok(())
    }
}
