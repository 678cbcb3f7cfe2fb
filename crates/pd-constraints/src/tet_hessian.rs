//! Hessian of the tetrahedral strain energy `Psi(F) = w/2 |F - P(F)|^2` with
//! respect to the deformation gradient `F`, from its analytic eigensystem
//! (Smith, De Goes and Kim 2019, "Analytic eigensystems for isotropic
//! distortion energies").
//!
//! # The energy is isotropic
//!
//! With the signed SVD `F = U diag(s) V^T` ([`signed_svd`]) the projection is
//! `P(F) = U diag(c) V^T`, `c_i = clamp(s_i, min, max)`. Corotational strain
//! without limits is the case `min = max = 1` (`c_i = 1`, `P(F) = U V^T`), so
//! one formula covers both. Then `Psi = w/2 sum_i (s_i - c_i)^2` depends on the
//! singular values only, and its gradient is `w (F - P(F))`: the Hessian is
//! `w (I_9 - dP/dF)`.
//!
//! # Eigensystem of `dP/dF`
//!
//! Differentiating `P = U diag(c) V^T` along `dU = U Omega_U`,
//! `dV = V Omega_V` (skew) and solving `U^T dF V = Omega_U S + dS - S Omega_V`
//! for the rotations gives nine orthonormal eigenvectors of `dP/dF` (`u_i`,
//! `v_i` the columns of `U`, `V`):
//!
//! | mode | matrix | eigenvalue `mu` of `dP/dF` |
//! |---|---|---|
//! | scaling `i` | `u_i v_i^T` | `c'(s_i)`: 1 strictly inside the limits, 0 outside |
//! | flip `ij` | `(u_i v_j^T + u_j v_i^T) / sqrt 2` | `(c_i - c_j) / (s_i - s_j)`, or `c'(s_i)` if `s_i = s_j` |
//! | twist `ij` | `(u_i v_j^T - u_j v_i^T) / sqrt 2` | `(c_i + c_j) / (s_i + s_j)` |
//!
//! so `H = w (I_9 - sum_modes mu m m^T)` and the Hessian eigenvalues are
//! `w (1 - mu)`. Without limits the scaling and flip eigenvalues are `w` and
//! the twist eigenvalues `w (1 - 2 / (s_i + s_j))`, Smith et al.'s ARAP
//! result: a twist (an infinitesimal rotation at rest) costs nothing at
//! `s = 1` and the energy is concave in it when `s_i + s_j < 2`.
//!
//! Because the clamp is monotone and 1-Lipschitz, the scaling and flip `mu`
//! lie in `[0, 1]`: those Hessian eigenvalues are never negative. The twist
//! `mu` is in `[0, +inf)` (the signed SVD keeps `s_i + s_j >= 0` and
//! `c >= min >= 0`), so only twist eigenvalues can be negative, unboundedly
//! so as `s_i + s_j -> 0`: on that set (an element collapsed to a line or a
//! point, or inverted with `s_j = -s_i`) the projection jumps and the energy
//! has a concave kink.
//!
//! # What is returned
//!
//! - Unprojected: the true Hessian where it exists. On the kink
//!   `s_i + s_j = 0` the twist eigenvalue is `-inf`, so the matrix has
//!   non-finite entries, as a collapsed spring's does; with limits, on the
//!   boundaries `s_i = min` or `s_i = max` (where the second derivative jumps)
//!   the larger one-sided value (scaling and flip eigenvalue `w`) is used.
//! - With `project_psd`: each twist eigenvalue clamped to `max(0, .)`, and 0
//!   on the kink: the tangent there has no finite limit, and 0 keeps the
//!   matrix positive semi-definite and bounded by `w` in norm (every
//!   eigenvalue lies in `[0, w]`) even for inverted and degenerate elements.
//! - A non-finite `F`: all entries NaN, so that the caller's divergence check
//!   reports it rather than a plausible-looking matrix.

use nalgebra::Matrix3;
use pd_mesh::Point;

use crate::{Constraint, TetStrain, signed_svd::signed_svd};

/// Writes the 9 x 9 Hessian of `w/2 |F - P(F)|^2` with respect to the rows of
/// `G x` (the columns of `F`), index `3 r + a` for `F[(a, r)]` (row-major,
/// weight included). With `project_psd` the negative (twist) eigenvalues are
/// clamped to zero. Cost: one 3 x 3 SVD and at most nine rank-one updates.
pub(crate) fn strain_hessian(c: &TetStrain, gx: &[Point], project_psd: bool, out: &mut [f64]) {
    let f = Matrix3::from_columns(&[gx[0], gx[1], gx[2]]);
    let (u, s, v) = signed_svd(&f);
    if !s.iter().all(|sigma| sigma.is_finite()) {
        out[..81].fill(f64::NAN);
        return;
    }
    // Without limits the projection is `U V^T`: the clamp to `[1, 1]`.
    let (min, max) = c.limits().unwrap_or((1.0, 1.0));
    let clamped = s.map(|sigma| sigma.clamp(min, max));
    // Strict inequalities: on a limit the larger one-sided second derivative
    // is used, and without limits (`min = max`) the slope is 0 everywhere.
    let clamp_slope = |sigma: f64| if min < sigma && sigma < max { 1.0 } else { 0.0 };

    let w = c.weight();
    for (i, h) in out[..81].iter_mut().enumerate() {
        *h = if i % 10 == 0 { w } else { 0.0 };
    }
    // Subtracts `w mu m m^T` for the mode `m = (u_i v_j^T + sign u_j v_i^T) / norm`.
    let mut subtract_mode = |mu: f64, i: usize, j: usize, sign: f64, norm: f64| {
        if mu == 0.0 {
            return;
        }
        let m = (u.column(i) * v.column(j).transpose()
            + u.column(j) * v.column(i).transpose() * sign)
            / norm;
        // `m.as_slice()` is column-major: entry `3 r + a` is `m[(a, r)]`, the
        // index convention of `out`. Only the upper triangle is updated and
        // then mirrored, so the result is exactly symmetric.
        let m = m.as_slice();
        for (row, &m_row) in m.iter().enumerate() {
            let scaled = w * mu * m_row;
            for (h, &m_col) in out[9 * row + row..9 * row + 9].iter_mut().zip(&m[row..]) {
                *h -= scaled * m_col;
            }
        }
    };

    for i in 0..3 {
        // Scaling: `u_i v_i^T = (u_i v_i^T + u_i v_i^T) / 2`.
        subtract_mode(clamp_slope(s[i]), i, i, 1.0, 2.0);
    }
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let flip = if s[i] == s[j] {
            clamp_slope(s[i])
        } else {
            // In [0, 1] in exact arithmetic; the clamp removes round-off when
            // `s_i` and `s_j` straddle a limit and nearly coincide.
            ((clamped[i] - clamped[j]) / (s[i] - s[j])).clamp(0.0, 1.0)
        };
        subtract_mode(flip, i, j, 1.0, std::f64::consts::SQRT_2);

        let sum = s[i] + s[j];
        let twist = if sum > 0.0 {
            (clamped[i] + clamped[j]) / sum
        } else {
            f64::INFINITY
        };
        let twist = if project_psd { twist.min(1.0) } else { twist };
        subtract_mode(twist, i, j, -1.0, std::f64::consts::SQRT_2);
    }
    for row in 1..9 {
        for col in 0..row {
            out[9 * row + col] = out[9 * col + row];
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Rotation3, SMatrix, SVector, Vector3};

    use super::*;

    fn hessian(c: &TetStrain, f: &Matrix3<f64>, project_psd: bool) -> SMatrix<f64, 9, 9> {
        let gx = [f.column(0).into(), f.column(1).into(), f.column(2).into()];
        let mut out = [0.0; 81];
        strain_hessian(c, &gx, project_psd, &mut out);
        SMatrix::from_row_slice(&out)
    }

    fn unit_tet(stiffness: f64, limits: Option<(f64, f64)>) -> TetStrain {
        let rest = [Point::zeros(), Point::x(), Point::y(), Point::z()];
        TetStrain::new(&rest, [0, 1, 2, 3], stiffness, limits).unwrap()
    }

    /// `vec(u e_i e_j^T v^T + sign u e_j e_i^T v^T) / norm`, column-major.
    fn mode(u: &Matrix3<f64>, v: &Matrix3<f64>, i: usize, j: usize, sign: f64) -> SVector<f64, 9> {
        let m =
            u.column(i) * v.column(j).transpose() + u.column(j) * v.column(i).transpose() * sign;
        SVector::from_column_slice(m.normalize().as_slice())
    }

    #[test]
    fn arap_modes_have_the_analytic_eigenvalues() {
        // F = U diag(2, 1, 0.5) V^T: twist eigenvalues w (1 - 2 / (s_i + s_j))
        // = w (1/3, 1/5, -1/3) for the pairs (0, 1), (0, 2), (1, 2), every
        // other mode w.
        let c = unit_tet(6.0, None);
        let w = c.weight();
        let u = Rotation3::from_euler_angles(0.3, -0.7, 1.2).into_inner();
        let v = Rotation3::from_euler_angles(-1.0, 0.4, 0.1).into_inner();
        let s = Vector3::new(2.0, 1.0, 0.5);
        let h = hessian(&c, &(u * Matrix3::from_diagonal(&s) * v.transpose()), false);
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            let twist = mode(&u, &v, i, j, -1.0);
            let expected = w * (1.0 - 2.0 / (s[i] + s[j]));
            assert!(
                (h * twist - twist * expected).norm() < 1e-12 * w,
                "twist {i}{j}"
            );
            let flip = mode(&u, &v, i, j, 1.0);
            assert!((h * flip - flip * w).norm() < 1e-12 * w, "flip {i}{j}");
        }
        for i in 0..3 {
            let scaling = mode(&u, &v, i, i, 1.0);
            assert!(
                (h * scaling - scaling * w).norm() < 1e-12 * w,
                "scaling {i}"
            );
        }
        // Projection clamps exactly the negative twist eigenvalue to 0.
        let projected = hessian(&c, &(u * Matrix3::from_diagonal(&s) * v.transpose()), true);
        let twist_12 = mode(&u, &v, 1, 2, -1.0);
        assert!((projected * twist_12).norm() < 1e-12 * w);
        let clamped_part = (projected - h).norm();
        assert!((clamped_part - w / 3.0).abs() < 1e-12 * w, "{clamped_part}");
    }

    #[test]
    fn strain_limited_hessian_vanishes_inside_the_limits() {
        let c = unit_tet(3.0, Some((0.8, 1.2)));
        let f = Rotation3::from_euler_angles(0.5, 0.2, -0.3).into_inner()
            * Matrix3::from_diagonal(&Vector3::new(1.1, 0.9, 1.0));
        for project_psd in [false, true] {
            assert!(hessian(&c, &f, project_psd).amax() < 1e-14 * c.weight());
        }
    }

    #[test]
    fn kink_gives_non_finite_true_hessian_and_finite_projection() {
        // An element collapsed to a line: s = (1, 0, 0), s_2 + s_3 = 0.
        let c = unit_tet(1.0, None);
        let f = Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0));
        assert!(hessian(&c, &f, false).iter().any(|h| !h.is_finite()));
        assert!(hessian(&c, &f, true).iter().all(|h| h.is_finite()));
        let nan = Matrix3::from_element(f64::NAN);
        assert!(hessian(&c, &nan, true).iter().all(|h| h.is_nan()));
    }
}
