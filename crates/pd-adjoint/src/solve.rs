//! The adjoint system of one step, `H lambda = g` over the free vertices
//! (docs/design/gradients.md, "Solving the adjoint system"): conjugate
//! gradients preconditioned with the step's prefactored PD matrix `A`, and a
//! dense LU factorisation of `H` when they meet a direction of non-positive
//! curvature (an indefinite `H` under compression) or do not converge.

use nalgebra::{DMatrix, DVector};
use pd_integrators::StepCoefficients;
use pd_mesh::Point;

use crate::operators::{ElementHessians, Operators, dot, mask_fixed};

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
/// `lambda`, starting from the `lambda` given. `precondition` solves `A z = r` in place over the free
/// vertices' entries (one point per free vertex).
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve(
    ops: &Operators,
    c: StepCoefficients,
    k: &ElementHessians,
    free: &[usize],
    g: &[Point],
    lambda: &mut [Point],
    (tolerance, max_iterations, dense_limit): (f64, usize, usize),
    precondition: &mut dyn FnMut(&mut [Point]) -> Result<(), pd_solver::SolverError>,
) -> Result<SolveReport, SolveFailure> {
    let n = g.len();
    let g_norm = dot(g, g).sqrt();
    if g_norm == 0.0 {
        lambda.iter_mut().for_each(|l| *l = Point::zeros());
        return Ok(SolveReport::default());
    }
    // The iteration starts from the `lambda` given (the previous step's
    // adjoint: successive steps' systems and right-hand sides differ by
    // little), or from zero when that is the better start.
    mask_fixed(lambda, &ops.fixed);
    let mut hp = vec![Point::zeros(); n];
    ops.hessian_product(c, k, lambda, &mut hp);
    mask_fixed(&mut hp, &ops.fixed);
    let mut r: Vec<Point> = g.iter().zip(&hp).map(|(g, h)| g - h).collect();
    if dot(&r, &r) >= g_norm * g_norm {
        lambda.iter_mut().for_each(|l| *l = Point::zeros());
        r.copy_from_slice(g);
    }
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
    if 3 * free.len() > dense_limit {
        return Err(SolveFailure::TooLarge {
            iterations,
            residual,
        });
    }
    dense_solve(ops, c, k, free, g, lambda)?;
    let mut check = vec![Point::zeros(); n];
    ops.hessian_product(c, k, lambda, &mut check);
    mask_fixed(&mut check, &ops.fixed);
    let misfit: Vec<Point> = g.iter().zip(&check).map(|(g, h)| g - h).collect();
    Ok(SolveReport {
        iterations,
        fallback: true,
        residual: dot(&misfit, &misfit).sqrt() / g_norm,
    })
}

/// `H lambda = g` by a dense LU factorisation of `H` over the free
/// vertices, columns built by products with unit vectors.
fn dense_solve(
    ops: &Operators,
    c: StepCoefficients,
    k: &ElementHessians,
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
