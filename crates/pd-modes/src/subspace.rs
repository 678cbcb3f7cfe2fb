//! Shift-invert subspace iteration with Rayleigh-Ritz for the lowest modes of
//! a large model: `Y <- (K + s M)^-1 M X`, the rigid motions projected out,
//! `Y` made M-orthonormal, then the small problem `Y^T K Y` solved densely
//! and `X` set to its Ritz vectors. Each iteration multiplies the error in
//! mode `j` by `(lambda_j + s) / (lambda_{p+1} + s)`, `p` the block size.
//! One factorisation serves every iteration. The default large-model solver
//! is block Lanczos (`lanczos.rs`), which needs far fewer solves; this one
//! serves models with mechanisms (zero-stiffness motions other than the
//! rigid ones), whose eigenspace a Lanczos block cannot count.

use std::time::Instant;

use faer::Mat;
use nalgebra::{DMatrix, SymmetricEigen};

use pd_solver::SolverError;

use super::{Phases, ShiftedFactor, Stiffness, ZERO, mass_dot};

/// A Ritz pair counts as converged when `|K x - lambda M x|_{M^-1} <=
/// TOLERANCE lambda` for mass-normalised `x`: then an exact eigenvalue lies
/// within that distance of `lambda` (the residual bound of the symmetric
/// definite pencil), a relative frequency error below `TOLERANCE / 2`.
pub(super) const TOLERANCE: f64 = 1e-9;

/// Iterations before giving up on convergence.
const MAX_ITERATIONS: usize = 400;

/// What [`solve`] found.
pub(super) struct Subspace {
    pub pairs: Vec<(f64, Vec<f64>)>,
    pub mechanisms: usize,
    pub iterations: usize,
    /// Right-hand-side columns solved with the factor.
    pub columns: usize,
}

/// The lowest `count` non-zero eigenpairs `(omega^2, mass-normalised phi)`
/// of `stiffness`, the M-orthonormal `rigid` motions deflated, with the
/// factor of `K + s M`.
pub(super) fn solve(
    stiffness: &Stiffness,
    rigid: &[Vec<f64>],
    count: usize,
    factor: &ShiftedFactor,
    phases: &mut Phases,
) -> Result<Subspace, SolverError> {
    let nd = stiffness.pattern.n;
    let scale = stiffness.scale();
    let mut columns = 0;
    let available = nd - rigid.len();
    let mut width = (2 * count + 8).min(available);
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut block: Vec<Vec<f64>> = (0..width).map(|_| random(nd, &mut seed)).collect();
    let mut product = vec![0.0; nd];
    for iteration in 1..=MAX_ITERATIONS {
        // Y = (K + s M)^-1 M X, every column in one solve (the factor is
        // read once per block, not once per column).
        let clock = Instant::now();
        let mut rhs = Mat::<f64>::from_fn(nd, block.len(), |i, j| stiffness.mass[i] * block[j][i]);
        factor.solve_wide(rhs.as_mut());
        columns += block.len();
        for (j, x) in block.iter_mut().enumerate() {
            x.iter_mut()
                .enumerate()
                .for_each(|(i, xi)| *xi = rhs[(i, j)]);
        }
        phases.solves += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        orthonormalise(&stiffness.mass, rigid, &mut block, &mut seed);
        phases.orthonormalisation += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        // Rayleigh-Ritz on span(Y).
        let products: Vec<Vec<f64>> = block
            .iter()
            .map(|y| {
                stiffness.mul(y, &mut product);
                product.clone()
            })
            .collect();
        // Y^T K Y, symmetric: the upper triangle mirrored.
        let mut small = DMatrix::<f64>::zeros(width, width);
        for i in 0..width {
            for j in i..width {
                let v: f64 = block[i].iter().zip(&products[j]).map(|(a, b)| a * b).sum();
                small[(i, j)] = v;
                small[(j, i)] = v;
            }
        }
        let eigen = SymmetricEigen::new(small);
        let mut order: Vec<usize> = (0..width).collect();
        order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
        let combine = |vectors: &[Vec<f64>], k: usize| {
            let mut out = vec![0.0; nd];
            for (v, c) in vectors.iter().zip(eigen.eigenvectors.column(k).iter()) {
                out.iter_mut().zip(v).for_each(|(o, x)| *o += c * x);
            }
            out
        };
        let ritz: Vec<(f64, Vec<f64>, Vec<f64>)> = order
            .iter()
            .map(|&k| {
                (
                    eigen.eigenvalues[k],
                    combine(&block, k),
                    combine(&products, k),
                )
            })
            .collect();
        let threshold = ZERO * scale;
        let mechanisms = ritz.iter().filter(|r| r.0 <= threshold).count();
        let wanted: Vec<&(f64, Vec<f64>, Vec<f64>)> = ritz
            .iter()
            .filter(|r| r.0 > threshold)
            .take(count)
            .collect();
        let converged = wanted.iter().all(|(lambda, x, kx)| {
            let residual: f64 = kx
                .iter()
                .zip(x)
                .zip(&stiffness.mass)
                .map(|((k, x), m)| (k - lambda * m * x).powi(2) / m)
                .sum();
            residual.sqrt() <= TOLERANCE * lambda
        });
        let found = wanted.len();
        let enough = found == count || width == available;
        phases.rayleigh_ritz += clock.elapsed().as_secs_f64();
        if converged && enough {
            return Ok(Subspace {
                pairs: wanted
                    .into_iter()
                    .map(|(l, x, _)| (*l, x.clone()))
                    .collect(),
                mechanisms,
                iterations: iteration,
                columns,
            });
        }
        drop(wanted);
        block = ritz.into_iter().map(|(_, x, _)| x).collect();
        if !enough {
            // Mechanisms fill the block: widen it by as many vectors.
            let grow = (count - found + 4).min(available - width);
            block.extend((0..grow).map(|_| random(nd, &mut seed)));
            width += grow;
        }
    }
    Err(SolverError::Factorisation {
        reason: format!(
            "modal analysis: the lowest {count} modes did not converge in {MAX_ITERATIONS} \
             subspace iterations"
        ),
    })
}

/// Makes `block` M-orthonormal and M-orthogonal to `rigid` (Gram-Schmidt
/// applied twice); a column that vanishes is replaced by a fresh random one.
fn orthonormalise(mass: &[f64], rigid: &[Vec<f64>], block: &mut [Vec<f64>], seed: &mut u64) {
    for j in 0..block.len() {
        let mut tries = 0;
        loop {
            let before = mass_dot(mass, &block[j], &block[j]).sqrt();
            let (done, rest) = block.split_at_mut(j);
            let column = &mut rest[0];
            for _ in 0..2 {
                for b in rigid.iter().chain(done.iter()) {
                    let projection = mass_dot(mass, b, column);
                    column
                        .iter_mut()
                        .zip(b)
                        .for_each(|(x, y)| *x -= projection * y);
                }
            }
            let norm = mass_dot(mass, &block[j], &block[j]).sqrt();
            if norm > 1e-10 * before || tries == 3 {
                block[j].iter_mut().for_each(|x| *x /= norm);
                break;
            }
            tries += 1;
            block[j] = random(mass.len(), seed);
        }
    }
}

/// A deterministic pseudo-random vector with entries in `[-1, 1)`.
pub(super) fn random(n: usize, seed: &mut u64) -> Vec<f64> {
    (0..n)
        .map(|_| {
            *seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}
