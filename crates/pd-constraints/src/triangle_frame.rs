//! What the triangle kinds (`triangle-strain`, `area`) share: the rest frame
//! of a triangle in its own plane, the thin SVD of its 3 x 2 deformation
//! gradient, and the Hessian of an isotropic energy
//! `w/2 |F - U diag(c(s)) V^T|^2` of that gradient.
//!
//! # Deformation gradient
//!
//! A rest triangle `X0, X1, X2` gets an orthonormal frame of its plane,
//! `b1 = (X1 - X0)/|X1 - X0|` and `b2` the unit part of `X2 - X0` orthogonal to
//! `b1`. In that frame its edge matrix is the upper-triangular
//! `Dm = [[|X1 - X0|, b1.(X2 - X0)], [0, b2.(X2 - X0)]]`, and the deformed
//! 3 x 2 gradient is `F = [x1 - x0, x2 - x0] Dm^-1`. As for tetrahedra,
//! `F^T = G x` with `G = B^T [-1 | I]`, `B = Dm^-1` (2 x 3): the two rows of
//! `G x` are the columns of `F`, and `G 1 = 0`.
//!
//! # Thin SVD
//!
//! `F = Q R` by Gram-Schmidt on its columns (`Q` 3 x 2 orthonormal, `R` upper
//! triangular with `R_00, R_11 >= 0`), then the closed-form SVD of the 2 x 2
//! `R = U2 diag(s) V^T` (two rotations, `s_0 >= s_1 >= 0` because
//! `det R >= 0`); `U = Q U2`. A collapsed column is replaced by a unit
//! vector orthogonal to the other (chosen deterministically), so `U` always
//! has orthonormal columns. `n = q0 x q1` completes the frame.
//!
//! # Hessian of an isotropic energy
//!
//! For `P(F) = U diag(c) V^T`, `c = c(s)`, the six matrices
//! `u_i v_i^T` (scaling), `(u_0 v_1^T +- u_1 v_0^T)/sqrt 2` (flip, twist) and
//! `n v_i^T` (out of plane) are orthonormal, and `dP/dF` acts on them as the
//! Jacobian `J = dc/ds` on the scaling pair, and with eigenvalues
//! `(c_0 - c_1)/(s_0 - s_1)`, `(c_0 + c_1)/(s_0 + s_1)` and `c_i / s_i` on the
//! others (rotating `u_i` towards `n` by `ds/s_i` moves `P` by `c_i/s_i` of
//! it). The Hessian of `w/2 |F - P(F)|^2` is `w (I - dP/dF)`; with
//! `project_psd` each eigenvalue (and the scaling block's) is clamped to
//! `>= 0`. Where `s_i -> 0` with `c_i > 0` the out-of-plane eigenvalue is
//! `-inf` (a kink: the triangle collapsed to a line), reported as
//! non-finite entries unprojected and as 0 projected, as for tetrahedra
//! (`tet_hessian.rs`).

use nalgebra::{Matrix2, Matrix3x2, Vector2, Vector3};
use pd_mesh::Point;

use crate::ConstraintError;

/// A triangle's rest operator `G = B^T [-1 | I]` (2 x 3) and rest area (m^2).
///
/// # Errors
/// [`ConstraintError::DegenerateElement`] if the rest triangle has zero
/// area (or non-finite vertices).
pub(crate) fn rest_frame(
    rest: &[Point],
    triangle: [usize; 3],
) -> Result<([[f64; 3]; 2], f64), ConstraintError> {
    let [x0, x1, x2] = triangle.map(|v| rest[v]);
    let (e1, e2) = (x1 - x0, x2 - x0);
    let area = 0.5 * e1.cross(&e2).norm();
    let degenerate = || ConstraintError::DegenerateElement {
        vertices: triangle.to_vec(),
    };
    let length = e1.norm();
    // The relative threshold rejects triangles whose area is round-off of
    // their edge lengths (their operator would be ill-conditioned noise).
    if !(area.is_finite() && area > 1e-12 * e1.norm_squared().max(e2.norm_squared())) {
        return Err(degenerate());
    }
    let b1 = e1 / length;
    let along = b1.dot(&e2);
    let across = (e2 - b1 * along).norm();
    let dm = Matrix2::new(length, along, 0.0, across);
    let b = dm.try_inverse().ok_or_else(degenerate)?;
    let mut operator = [[0.0; 3]; 2];
    for (row, g) in operator.iter_mut().enumerate() {
        // Row `row` of B^T [-1 | I]: B^T[row][j] = B[j][row].
        g[0] = -(b[(0, row)] + b[(1, row)]);
        g[1] = b[(0, row)];
        g[2] = b[(1, row)];
    }
    Ok((operator, area))
}

/// The thin SVD `F = U diag(s) V^T` of a 3 x 2 gradient and the unit normal
/// `n` completing `U`'s columns to a right-handed frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ThinSvd {
    /// 3 x 2, orthonormal columns.
    pub u: Matrix3x2<f64>,
    /// `s_0 >= s_1 >= 0`.
    pub s: Vector2<f64>,
    /// 2 x 2 rotation.
    pub v: Matrix2<f64>,
    /// `u_0 x u_1`.
    pub n: Vector3<f64>,
    /// The closest matrix with orthonormal columns, `U V^T`.
    pub closest: Matrix3x2<f64>,
}

/// A unit vector orthogonal to the unit vector `a`: the cross product with
/// the coordinate axis least aligned with it.
fn orthogonal_to(a: &Vector3<f64>) -> Vector3<f64> {
    let axis = if a.x.abs() <= a.y.abs() && a.x.abs() <= a.z.abs() {
        Vector3::x()
    } else if a.y.abs() <= a.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    a.cross(&axis).normalize()
}

fn rotation(angle: f64) -> Matrix2<f64> {
    let (sin, cos) = angle.sin_cos();
    Matrix2::new(cos, -sin, sin, cos)
}

/// Thin SVD of `f` (see the module documentation). Non-finite input gives
/// non-finite singular values.
pub(crate) fn thin_svd(f: &Matrix3x2<f64>) -> ThinSvd {
    let (f0, f1) = (f.column(0).into_owned(), f.column(1).into_owned());
    let q0 = match f0.try_normalize(0.0) {
        Some(q) => q,
        None => match f1.try_normalize(0.0) {
            Some(q1) => orthogonal_to(&q1),
            None => Vector3::x(),
        },
    };
    let r01 = q0.dot(&f1);
    let rest = f1 - q0 * r01;
    let q1 = rest
        .try_normalize(0.0)
        .unwrap_or_else(|| orthogonal_to(&q0));
    let (r00, r11) = (q0.dot(&f0), q1.dot(&f1));
    // R = E I + H J + F sz + G sx: rotation part sqrt(E^2 + H^2) R(alpha),
    // reflection part sqrt(F^2 + G^2) Refl(beta); then
    // R = R(phi) diag(s) R(psi), phi = (alpha + beta)/2, psi = (alpha - beta)/2.
    let (e, d, g, h) = (0.5 * (r00 + r11), 0.5 * (r00 - r11), 0.5 * r01, -0.5 * r01);
    let (rot, refl) = (e.hypot(h), d.hypot(g));
    let (alpha, beta) = (h.atan2(e), g.atan2(d));
    let u2 = rotation(0.5 * (alpha + beta));
    let v = rotation(0.5 * (alpha - beta)).transpose();
    let q = Matrix3x2::from_columns(&[q0, q1]);
    // `det R >= 0` makes `rot >= refl`; `max` removes round-off.
    let s = Vector2::new(rot + refl, (rot - refl).max(0.0));
    ThinSvd {
        u: q * u2,
        s,
        v,
        n: q0.cross(&q1),
        closest: q * rotation(alpha),
    }
}

/// The parts of `dP/dF` for `P = U diag(c) V^T`: the singular values `s`,
/// the targets `c`, the Jacobian `dc/ds` and, for `s_0 = s_1`, the flip
/// eigenvalue to use.
pub(crate) struct IsotropicProjection {
    /// `c(s)`.
    pub c: Vector2<f64>,
    /// `dc/ds`, symmetric.
    pub jacobian: Matrix2<f64>,
    /// Flip eigenvalue of `dP/dF` where `s_0 = s_1`.
    pub flip_at_equal: f64,
}

/// Writes `w (I - dP/dF)` (6 x 6, index `3 r + a` for `F[(a, r)]`) for the
/// thin SVD `svd`; see the module documentation.
pub(crate) fn isotropic_hessian(
    w: f64,
    svd: &ThinSvd,
    p: &IsotropicProjection,
    project_psd: bool,
    out: &mut [f64],
) {
    let s = svd.s;
    let out = &mut out[..36];
    if !s.iter().all(|x| x.is_finite()) {
        out.fill(f64::NAN);
        return;
    }
    out.fill(0.0);
    let u = |i: usize| svd.u.column(i).into_owned();
    let v = |i: usize| svd.v.column(i).into_owned();
    let vec6 = |m: Matrix3x2<f64>| -> [f64; 6] {
        // Column-major: entry `3 r + a` is `m[(a, r)]`.
        let mut x = [0.0; 6];
        x.copy_from_slice(m.as_slice());
        x
    };
    let mut add = |eigen: f64, a: &[f64; 6], b: &[f64; 6]| {
        if eigen == 0.0 {
            return;
        }
        for (i, &ai) in a.iter().enumerate() {
            for (j, &bj) in b.iter().enumerate() {
                out[6 * i + j] += w * eigen * ai * bj;
            }
        }
    };
    let clamp = |eigen: f64| if project_psd { eigen.max(0.0) } else { eigen };
    // A mode's `dP/dF` eigenvalue `c_i / s_i`-like ratio: 1 where `c = s`
    // (the projection follows `F`), `inf` on a kink.
    let ratio = |num: f64, den: f64| {
        if num == den {
            1.0
        } else if den > 0.0 {
            num / den
        } else {
            f64::INFINITY
        }
    };

    // Scaling block: `I - J`, clamped through its eigen-decomposition.
    let scaling = [vec6(u(0) * v(0).transpose()), vec6(u(1) * v(1).transpose())];
    let block = Matrix2::identity() - p.jacobian;
    let block = if project_psd {
        let eig = nalgebra::SymmetricEigen::new(block);
        let clamped = eig.eigenvalues.map(|x| x.max(0.0));
        eig.eigenvectors * Matrix2::from_diagonal(&clamped) * eig.eigenvectors.transpose()
    } else {
        block
    };
    for a in 0..2 {
        for b in 0..2 {
            add(block[(a, b)], &scaling[a], &scaling[b]);
        }
    }
    let flip_mu = if s[0] == s[1] {
        p.flip_at_equal
    } else {
        (p.c[0] - p.c[1]) / (s[0] - s[1])
    };
    let cross = u(0) * v(1).transpose();
    let cross_t = u(1) * v(0).transpose();
    let flip = vec6((cross + cross_t) / std::f64::consts::SQRT_2);
    add(clamp(1.0 - flip_mu), &flip, &flip);
    let twist = vec6((cross - cross_t) / std::f64::consts::SQRT_2);
    add(
        clamp(1.0 - ratio(p.c[0] + p.c[1], s[0] + s[1])),
        &twist,
        &twist,
    );
    for i in 0..2 {
        let normal = vec6(svd.n * v(i).transpose());
        add(clamp(1.0 - ratio(p.c[i], s[i])), &normal, &normal);
    }
    for row in 1..6 {
        for col in 0..row {
            let mean = 0.5 * (out[6 * row + col] + out[6 * col + row]);
            out[6 * row + col] = mean;
            out[6 * col + row] = mean;
        }
    }
}

/// The 3 x 2 gradient from the two rows of `G x`.
pub(crate) fn gradient_of(gx: &[Point]) -> Matrix3x2<f64> {
    Matrix3x2::from_columns(&[gx[0], gx[1]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thin_svd_reconstructs() {
        let cases = [
            Matrix3x2::new(1.0, 0.0, 0.0, 1.0, 0.0, 0.0),
            Matrix3x2::new(0.3, -1.2, 2.0, 0.1, -0.4, 0.9),
            Matrix3x2::new(1.0, 2.0, 2.0, 4.0, 3.0, 6.0),
            Matrix3x2::new(0.0, 1.0, 0.0, 0.5, 0.0, -0.2),
            Matrix3x2::zeros(),
            Matrix3x2::new(-1.0, 0.0, 0.0, -1.0, 0.0, 0.0),
            Matrix3x2::new(0.0, 1.0, 1.0, 0.0, 0.0, 0.0),
        ];
        for f in cases {
            let svd = thin_svd(&f);
            let back = svd.u * Matrix2::from_diagonal(&svd.s) * svd.v.transpose();
            // Round-off of a few operations on O(1) entries.
            assert!((back - f).norm() < 1e-13, "{f} -> {back}");
            assert!((svd.u.transpose() * svd.u - Matrix2::identity()).norm() < 1e-13);
            assert!((svd.v.transpose() * svd.v - Matrix2::identity()).norm() < 1e-13);
            assert!(svd.s[0] >= svd.s[1] && svd.s[1] >= 0.0);
            assert!((svd.closest - svd.u * svd.v.transpose()).norm() < 1e-13);
            assert!((svd.n.norm() - 1.0).abs() < 1e-13);
        }
    }

    #[test]
    fn degenerate_rest_triangles_are_rejected() {
        let rest = [Point::zeros(), Point::x(), Point::x() * 2.0, Point::y()];
        assert!(rest_frame(&rest, [0, 1, 2]).is_err());
        assert!(rest_frame(&rest, [0, 0, 3]).is_err());
        let (g, area) = rest_frame(&rest, [0, 1, 3]).unwrap();
        assert!((area - 0.5).abs() < 1e-15);
        // G 1 = 0.
        assert!(g.iter().all(|row| row.iter().sum::<f64>().abs() < 1e-15));
    }
}
