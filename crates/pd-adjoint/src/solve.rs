//! The adjoint system of one step, `H lambda = g` over the free vertices
//! (docs/design/gradients.md, "Solving the adjoint system"): conjugate
//! gradients preconditioned with the step's prefactored PD matrix `A`, and,
//! when they meet a direction of non-positive curvature (an indefinite `H`
//! under compression) or do not converge, a dense LU factorisation of `H`
//! (small systems) or preconditioned MINRES (larger ones).

use nalgebra::{DMatrix, DVector};
use pd_integrators::StepCoefficients;
use pd_mesh::Point;

use crate::operators::{ElasticHessian, Operators, dot, mask_fixed};

/// `z = A^{-1} r` over full-length vectors (zero at fixed vertices).
type Preconditioner<'a> =
    dyn FnMut(&[Point], &mut [Point]) -> Result<(), pd_solver::SolverError> + 'a;

/// How one adjoint solve went.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SolveReport {
    /// Preconditioned conjugate-gradient iterations.
    pub iterations: usize,
    /// Whether the dense fallback solved it.
    pub fallback: bool,
    /// The final relative residual `|g - H lambda| / |g|`.
    pub residual: f64,
}

/// Why a solve failed.
#[derive(Debug)]
pub(crate) enum SolveFailure {
    /// Conjugate gradients failed and the system is too large for the dense
    /// fallback.
    TooLarge { iterations: usize, residual: f64 },
    /// The preconditioner's solve failed.
    Preconditioner(pd_solver::SolverError),
    /// `H` is singular (the dense fallback found no solution).
    Singular,
}

/// Solves `H lambda = g` (full-length vectors, zero at fixed vertices) into
/// `lambda`, starting from the `lambda` given or its extrapolation from
/// `earlier` (the adjoint before it, zero at fixed vertices). `precondition` solves `A z = r` in place over the free
/// vertices' entries (one point per free vertex).
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve(
    ops: &Operators,
    c: StepCoefficients,
    k: &ElasticHessian,
    free: &[usize],
    g: &[Point],
    lambda: &mut [Point],
    earlier: Option<&[Point]>,
    (tolerance, max_iterations, dense_limit, minres_iterations): (f64, usize, usize, usize),
    precondition: &mut dyn FnMut(&mut [Point]) -> Result<(), pd_solver::SolverError>,
) -> Result<SolveReport, SolveFailure> {
    let n = g.len();
    let g_norm = dot(g, g).sqrt();
    if g_norm == 0.0 {
        lambda.iter_mut().for_each(|l| *l = Point::zeros());
        return Ok(SolveReport::default());
    }
    // The iteration starts from whichever of the `lambda` given (the
    // previous step's adjoint: successive steps' systems and right-hand
    // sides differ by little), its linear extrapolation `2 lambda - earlier`
    // from the adjoint before it, and zero has the smallest residual.
    mask_fixed(lambda, &ops.fixed);
    let mut hp = vec![Point::zeros(); n];
    let mut residual_of = |start: &[Point], r: &mut Vec<Point>| {
        ops.hessian_product(c, k, start, &mut hp);
        mask_fixed(&mut hp, &ops.fixed);
        r.clear();
        r.extend(g.iter().zip(&hp).map(|(g, h)| g - h));
        dot(r, r)
    };
    let mut r = Vec::with_capacity(n);
    let mut best = residual_of(lambda, &mut r);
    if let Some(earlier) = earlier {
        let extrapolated: Vec<Point> = lambda
            .iter()
            .zip(earlier)
            .map(|(l, e)| l * 2.0 - e)
            .collect();
        let mut r_extrapolated = Vec::with_capacity(n);
        let norm = residual_of(&extrapolated, &mut r_extrapolated);
        if norm < best {
            best = norm;
            lambda.copy_from_slice(&extrapolated);
            r = r_extrapolated;
        }
    }
    if best >= g_norm * g_norm {
        lambda.iter_mut().for_each(|l| *l = Point::zeros());
        r.copy_from_slice(g);
    }
    let mut hp = vec![Point::zeros(); n];
    let mut z = vec![Point::zeros(); n];
    let mut p = vec![Point::zeros(); n];
    let mut buffer = vec![Point::zeros(); free.len()];
    let mut apply_preconditioner = |r: &[Point], z: &mut [Point]| {
        for (b, &v) in buffer.iter_mut().zip(free) {
            *b = r[v];
        }
        precondition(&mut buffer)?;
        z.iter_mut().for_each(|z| *z = Point::zeros());
        for (b, &v) in buffer.iter().zip(free) {
            z[v] = *b;
        }
        Ok(())
    };
    apply_preconditioner(&r, &mut z).map_err(SolveFailure::Preconditioner)?;
    p.copy_from_slice(&z);
    let mut rz = dot(&r, &z);
    let mut residual = 1.0;
    let mut iterations = 0;
    let mut converged = false;
    while iterations < max_iterations {
        ops.hessian_product(c, k, &p, &mut hp);
        mask_fixed(&mut hp, &ops.fixed);
        let curvature = dot(&p, &hp);
        iterations += 1;
        if !(curvature > 0.0 && rz > 0.0) {
            break;
        }
        let alpha = rz / curvature;
        for ((l, r), (p, hp)) in lambda.iter_mut().zip(r.iter_mut()).zip(p.iter().zip(&hp)) {
            *l += p * alpha;
            *r -= hp * alpha;
        }
        residual = dot(&r, &r).sqrt() / g_norm;
        if residual <= tolerance {
            converged = true;
            break;
        }
        apply_preconditioner(&r, &mut z).map_err(SolveFailure::Preconditioner)?;
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for (p, z) in p.iter_mut().zip(&z) {
            *p = z + *p * beta;
        }
    }
    if converged {
        return Ok(SolveReport {
            iterations,
            fallback: false,
            residual,
        });
    }
    let fallback_iterations = if 3 * free.len() > dense_limit {
        // Too large to factor densely: MINRES, which needs a symmetric `H`
        // only, from zero.
        let run = minres(
            ops,
            (c, k),
            g,
            lambda,
            (tolerance, minres_iterations),
            &mut apply_preconditioner,
        )?;
        if !run.1 {
            return Err(SolveFailure::TooLarge {
                iterations: iterations + run.0,
                residual: true_residual(ops, (c, k), g, lambda) / g_norm,
            });
        }
        run.0
    } else {
        dense_solve(ops, c, k, free, g, lambda)?;
        0
    };
    Ok(SolveReport {
        iterations: iterations + fallback_iterations,
        fallback: true,
        residual: true_residual(ops, (c, k), g, lambda) / g_norm,
    })
}

/// `|g - H lambda|` over the free vertices.
fn true_residual(
    ops: &Operators,
    (c, k): (StepCoefficients, &ElasticHessian),
    g: &[Point],
    lambda: &[Point],
) -> f64 {
    let mut check = vec![Point::zeros(); g.len()];
    ops.hessian_product(c, k, lambda, &mut check);
    mask_fixed(&mut check, &ops.fixed);
    let misfit: Vec<Point> = g.iter().zip(&check).map(|(g, h)| g - h).collect();
    dot(&misfit, &misfit).sqrt()
}

/// Preconditioned MINRES (Elman, Silvester and Wathen, "Finite Elements
/// and Fast Iterative Solvers", the preconditioned MINRES algorithm) for
/// the symmetric, possibly indefinite `H` with the symmetric positive
/// definite preconditioner `A`, from `lambda = 0`. It minimises the
/// residual in the `A^{-1}` norm over the Krylov space, so it needs no
/// definiteness of `H`. Stops when that norm has fallen by `tolerance`;
/// returns the iterations and whether it converged.
fn minres(
    ops: &Operators,
    (c, k): (StepCoefficients, &ElasticHessian),
    g: &[Point],
    lambda: &mut [Point],
    (tolerance, max_iterations): (f64, usize),
    precondition: &mut Preconditioner<'_>,
) -> Result<(usize, bool), SolveFailure> {
    let n = g.len();
    let zero = || vec![Point::zeros(); n];
    lambda.iter_mut().for_each(|l| *l = Point::zeros());
    let (mut v_prev, mut v) = (zero(), g.to_vec());
    let mut z = zero();
    precondition(&v, &mut z).map_err(SolveFailure::Preconditioner)?;
    let mut gamma = dot(&z, &v);
    if !(gamma > 0.0) {
        return Ok((0, false));
    }
    gamma = gamma.sqrt();
    let gamma_start = gamma;
    let mut gamma_prev = 1.0;
    let mut eta = gamma;
    let (mut s_prev, mut s, mut c_prev, mut c_cur) = (0.0, 0.0, 1.0, 1.0);
    let (mut w_prev, mut w, mut w_next) = (zero(), zero(), zero());
    let (mut hz, mut v_next, mut z_next) = (zero(), zero(), zero());
    for iteration in 1..=max_iterations {
        z.iter_mut().for_each(|z| *z /= gamma);
        ops.hessian_product(c, k, &z, &mut hz);
        mask_fixed(&mut hz, &ops.fixed);
        let delta = dot(&hz, &z);
        for (((next, hz), v), v_prev) in v_next.iter_mut().zip(&hz).zip(&v).zip(&v_prev) {
            *next = hz - v * (delta / gamma) - v_prev * (gamma / gamma_prev);
        }
        precondition(&v_next, &mut z_next).map_err(SolveFailure::Preconditioner)?;
        let gamma_next = dot(&z_next, &v_next).max(0.0).sqrt();
        let alpha0 = c_cur * delta - c_prev * s * gamma;
        let alpha1 = alpha0.hypot(gamma_next);
        let alpha2 = s * delta + c_prev * c_cur * gamma;
        let alpha3 = s_prev * gamma;
        if alpha1 == 0.0 {
            return Ok((iteration, false));
        }
        let (c_next, s_next) = (alpha0 / alpha1, gamma_next / alpha1);
        for (((next, z), w_prev), w) in w_next.iter_mut().zip(&z).zip(&w_prev).zip(&w) {
            *next = (z - w_prev * alpha3 - w * alpha2) / alpha1;
        }
        for (l, w) in lambda.iter_mut().zip(&w_next) {
            *l += w * (c_next * eta);
        }
        eta *= -s_next;
        if eta.abs() <= tolerance * gamma_start {
            return Ok((iteration, true));
        }
        if gamma_next == 0.0 {
            return Ok((iteration, false));
        }
        // Shift the recurrences by one.
        std::mem::swap(&mut v_prev, &mut v);
        std::mem::swap(&mut v, &mut v_next);
        std::mem::swap(&mut z, &mut z_next);
        std::mem::swap(&mut w_prev, &mut w);
        std::mem::swap(&mut w, &mut w_next);
        (gamma_prev, gamma) = (gamma, gamma_next);
        (c_prev, c_cur) = (c_cur, c_next);
        (s_prev, s) = (s, s_next);
    }
    Ok((max_iterations, false))
}

/// `H lambda = g` by a dense LU factorisation of `H` over the free
/// vertices, columns built by products with unit vectors.
fn dense_solve(
    ops: &Operators,
    c: StepCoefficients,
    k: &ElasticHessian,
    free: &[usize],
    g: &[Point],
    lambda: &mut [Point],
) -> Result<(), SolveFailure> {
    let n = g.len();
    let size = 3 * free.len();
    let mut matrix = DMatrix::<f64>::zeros(size, size);
    let mut unit = vec![Point::zeros(); n];
    let mut column = vec![Point::zeros(); n];
    for (j, &vj) in free.iter().enumerate() {
        for b in 0..3 {
            unit[vj][b] = 1.0;
            ops.hessian_product(c, k, &unit, &mut column);
            unit[vj][b] = 0.0;
            for (i, &vi) in free.iter().enumerate() {
                for a in 0..3 {
                    matrix[(3 * i + a, 3 * j + b)] = column[vi][a];
                }
            }
        }
    }
    let rhs = DVector::from_iterator(size, free.iter().flat_map(|&v| g[v].iter().copied()));
    let solution = matrix.lu().solve(&rhs).ok_or(SolveFailure::Singular)?;
    for (i, &v) in free.iter().enumerate() {
        lambda[v] = Point::new(solution[3 * i], solution[3 * i + 1], solution[3 * i + 2]);
    }
    Ok(())
}
