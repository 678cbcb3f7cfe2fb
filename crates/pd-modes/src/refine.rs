//! The last step of block Lanczos: Rayleigh-Ritz with `K` itself, then
//! Davidson corrections if the residuals are not yet small enough.
//!
//! The Lanczos projection `T` is that of the operator as computed: each
//! solve with the factor of `K + s M` errs by about the unit round-off
//! times the condition number of `K + s M` (`u lambda_max / lambda_1`,
//! 8e-10 on the 19 440-dof beam, docs/design/damping.md), and the error reaches
//! every direction of the Krylov basis, the high-frequency ones included,
//! where `K` magnifies it: the pencil residual of the Ritz vectors stalls
//! near that level (1.2e-9 lambda on that beam), whatever the number of
//! blocks. The directions that remove it are the Jacobi-preconditioned
//! residuals `D^-1 (K x - lambda M x)` (`D` the diagonal of `K`), which
//! approximate the error where `K` is large: Rayleigh-Ritz on the Ritz
//! vectors and these corrections (one Davidson step) lowers the residual
//! without another solve.

use nalgebra::{DMatrix, SymmetricEigen};

use super::subspace::TOLERANCE;
use super::{Stiffness, mass_dot};

/// Davidson steps tried after the first Rayleigh-Ritz.
const ROUNDS: usize = 3;

/// Davidson steps are tried only if every residual is within this factor
/// of the tolerance: they remove the solves' round-off, not what more
/// Lanczos blocks would (on the beam one step takes the lowest mode from
/// 1.2e-9 to 5e-10 lambda, and a mode 300 times off the tolerance by 6
/// only).
const NEAR: f64 = 10.0;

/// The `wanted` lowest eigenpairs `(omega^2, mass-normalised phi)` of
/// `stiffness` on the span of the M-orthonormal `basis` (refined by up to
/// [`ROUNDS`] Davidson steps), if every one meets `|K x - lambda M x|_{M^-1}
/// <= TOLERANCE lambda`; lowest first.
pub(super) fn refine(
    stiffness: &Stiffness,
    mut basis: Vec<Vec<f64>>,
    wanted: usize,
) -> Option<Vec<(f64, Vec<f64>)>> {
    let nd = stiffness.pattern.n;
    let apply = |x: &[f64]| {
        let mut y = vec![0.0; nd];
        stiffness.mul(x, &mut y);
        y
    };
    let mut products: Vec<Vec<f64>> = basis.iter().map(|x| apply(x)).collect();
    for round in 0..=ROUNDS {
        let pairs = rayleigh_ritz(&stiffness.mass, &basis, &products, wanted);
        let residuals: Vec<Vec<f64>> = pairs
            .iter()
            .map(|(lambda, x, kx)| {
                kx.iter()
                    .zip(x)
                    .zip(&stiffness.mass)
                    .map(|((k, x), m)| k - lambda * m * x)
                    .collect()
            })
            .collect();
        // |K x - lambda M x|_{M^-1} / (TOLERANCE lambda) of each pair.
        let ratio: Vec<f64> = residuals
            .iter()
            .zip(&pairs)
            .map(|(r, (lambda, _, _))| {
                let norm: f64 = r.iter().zip(&stiffness.mass).map(|(r, m)| r * r / m).sum();
                norm.sqrt() / (TOLERANCE * lambda)
            })
            .collect();
        let failing: Vec<usize> = (0..pairs.len()).filter(|&k| !(ratio[k] <= 1.0)).collect();
        if failing.is_empty() {
            return Some(pairs.into_iter().map(|(l, x, _)| (l, x)).collect());
        }
        if round == ROUNDS || !failing.iter().all(|&k| ratio[k] <= NEAR) {
            break;
        }
        let mut corrections: Vec<Vec<f64>> = failing
            .iter()
            .map(|&k| {
                residuals[k]
                    .iter()
                    .enumerate()
                    .map(|(i, r)| r / stiffness.values[stiffness.pattern.col_ptr[i]])
                    .collect()
            })
            .collect();
        (basis, products) = pairs.into_iter().map(|(_, x, kx)| (x, kx)).unzip();
        for mut t in corrections.drain(..) {
            for _ in 0..2 {
                for b in &basis {
                    let projection = mass_dot(&stiffness.mass, b, &t);
                    t.iter_mut().zip(b).for_each(|(x, y)| *x -= projection * y);
                }
            }
            let norm = mass_dot(&stiffness.mass, &t, &t).sqrt();
            if norm > 0.0 {
                t.iter_mut().for_each(|x| *x /= norm);
                products.push(apply(&t));
                basis.push(t);
            }
        }
    }
    None
}

/// Rayleigh-Ritz on the span of the M-orthonormal `basis` with `products =
/// K basis`: the `wanted` lowest `(lambda, x, K x)`, `x` mass-normalised
/// and `lambda` its Rayleigh quotient, lowest first.
fn rayleigh_ritz(
    mass: &[f64],
    basis: &[Vec<f64>],
    products: &[Vec<f64>],
    wanted: usize,
) -> Vec<(f64, Vec<f64>, Vec<f64>)> {
    let width = basis.len();
    let mut small = DMatrix::<f64>::zeros(width, width);
    for i in 0..width {
        for j in i..width {
            let v: f64 = basis[i].iter().zip(&products[j]).map(|(a, b)| a * b).sum();
            small[(i, j)] = v;
            small[(j, i)] = v;
        }
    }
    let eigen = SymmetricEigen::new(small);
    let mut order: Vec<usize> = (0..width).collect();
    order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
    order
        .into_iter()
        .take(wanted)
        .map(|k| {
            let combine = |vectors: &[Vec<f64>]| {
                let mut out = vec![0.0; vectors[0].len()];
                for (v, g) in vectors.iter().zip(eigen.eigenvectors.column(k).iter()) {
                    out.iter_mut().zip(v).for_each(|(o, x)| *o += g * x);
                }
                out
            };
            let (mut x, mut kx) = (combine(basis), combine(products));
            // The basis is M-orthonormal only to round-off.
            let norm = mass_dot(mass, &x, &x).sqrt();
            x.iter_mut().for_each(|v| *v /= norm);
            kx.iter_mut().for_each(|v| *v /= norm);
            let lambda: f64 = x.iter().zip(&kx).map(|(a, b)| a * b).sum();
            (lambda, x, kx)
        })
        .collect()
}
