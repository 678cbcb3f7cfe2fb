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
//! # Closest matrix with orthonormal columns
//!
//! `U V^T = Q Rot`, `Rot` the 2 x 2 rotation closest to `R`: it maximises
//! `tr(Rot^T R) = cos(a) (r00 + r11) - sin(a) r01`, so
//! `(cos a, sin a) = (e, h) / sqrt(e^2 + h^2)` with `e = (r00 + r11)/2`,
//! `h = -r01/2` (the angle `atan2(h, e)` of the SVD above, without
//! trigonometry). [`closest_orthonormal`] computes it so, with a fixed
//! sequence of IEEE operations that the SIMD lanes of the triangle-strain
//! projection repeat (`docs/design/performance.md`, "Triangle strain in SIMD
//! lanes").
//!
//! # Clamped singular values
//!
//! `U2 diag(c) V^T` for `c = clamp(s, min, max)` without the angles: with
//! `R = e I + h J + d Z + g X` (`e, h` as above, `d = (r00 - r11)/2`,
//! `g = r01/2`; `J` the quarter turn, `Z = diag(1, -1)`, `X` the swap),
//! `R = rot Rot(alpha) + refl Refl(beta)`, `rot = sqrt(e^2 + h^2)`,
//! `refl = sqrt(d^2 + g^2)`, `s = (rot + refl, rot - refl)`, and
//! `U2 = Rot((alpha + beta)/2)`, `V^T = Rot((alpha - beta)/2)`. Since
//! `Rot(phi) diag(c0, c1) Rot(psi) = (c0 + c1)/2 Rot(phi + psi) +
//! (c0 - c1)/2 Rot(phi - psi) Z`, the clamped matrix is
//! `a [[e, -h], [h, e]] + b [[d, g], [g, -d]]` with
//! `a = (c0 + c1) / (2 rot)`, `b = (c0 - c1) / (2 refl)` (`b = 0` where
//! `d = g = 0`: equal singular values, `c0 = c1`, and undefined singular
//! vectors that the result does not need). With `c = s` it is `R`
//! itself. [`clamped_stretch`] computes it so, with a fixed sequence of
//! IEEE operations that the SIMD lanes repeat (`docs/design/performance.md`,
//! "Stretch-limited triangles in SIMD lanes").
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
}

/// The Gram-Schmidt factors `F = Q R` of a 3 x 2 gradient: `Q = [q0 q1]`
/// with orthonormal columns, `R = [[r00, r01], [0, r11]]`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ThinQr {
    pub q0: Vector3<f64>,
    pub q1: Vector3<f64>,
    pub r00: f64,
    pub r01: f64,
    pub r11: f64,
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

/// Below this ratio `|rest|^2 / |f1|^2` (the rest of `f1` after
/// removing its `q0` part, against `f1`: columns within about 0.6 degrees
/// of parallel) [`thin_qr`] orthogonalises the rest a second time; above
/// it one pass leaves `|q0 . q1|` below about 100 u.
pub(crate) const REORTHOGONALIZE: f64 = 1e-4;

/// Gram-Schmidt on the columns of `f` (see the module documentation).
///
/// Where both columns have a positive, finite norm, and the second's part
/// orthogonal to the first does too, the operations are (per coordinate
/// `i`, left to right, as nalgebra evaluates them): `n0 = sqrt((f0_0^2 +
/// f0_1^2) + f0_2^2)`, `q0_i = f0_i / n0`, `r01 = (q0_0 f1_0 + q0_1 f1_1) +
/// q0_2 f1_2`, `rest_i = f1_i - q0_i r01`, `q1_i = rest_i / |rest|` (the
/// same norm), `r00 = q0 . f0`, `r11 = q1 . f1` (the same dot product).
/// The triangle-strain lanes repeat exactly this sequence. Where the rest
/// is below [`REORTHOGONALIZE`] of `f1` (squared norms, both summed as
/// above), it is orthogonalised once more, `c = q0 . rest`, `rest -= q0 c`,
/// `r01 += c`, before `q1` is taken; the lanes leave those to this
/// function.
pub(crate) fn thin_qr(f: &Matrix3x2<f64>) -> ThinQr {
    let (f0, f1) = (f.column(0).into_owned(), f.column(1).into_owned());
    let q0 = match f0.try_normalize(0.0) {
        Some(q) => q,
        None => match f1.try_normalize(0.0) {
            Some(q1) => orthogonal_to(&q1),
            None => Vector3::x(),
        },
    };
    let mut r01 = q0.dot(&f1);
    let mut rest = f1 - q0 * r01;
    if rest.norm_squared() < REORTHOGONALIZE * f1.norm_squared() {
        // Most of `f1` cancelled: the rest carries the round-off of
        // `q0 r01` (relative u |f1| / |rest|) and is not orthogonal to
        // `q0`. A second pass removes that ("twice is enough").
        let c = q0.dot(&rest);
        rest -= q0 * c;
        r01 += c;
    }
    let q1 = rest
        .try_normalize(0.0)
        .unwrap_or_else(|| orthogonal_to(&q0));
    let (r00, r11) = (q0.dot(&f0), q1.dot(&f1));
    ThinQr {
        q0,
        q1,
        r00,
        r01,
        r11,
    }
}

/// `(cos a, sin a)` of the 2 x 2 rotation closest to the upper-triangular
/// `[[r00, r01], [0, r11]]`: `(e, h) / sqrt(e^2 + h^2)` with
/// `e = 0.5 (r00 + r11)`, `h = -0.5 r01`, evaluated in that order, where
/// `e^2 + h^2` is a normal, finite number (for a gradient with columns of
/// norm between about 1e-150 and 1e150). Elsewhere (`e = h = 0`, a
/// subnormal or overflowing `e^2 + h^2`, NaN) from the angle
/// `atan2(h, e)` as the thin SVD computes it, bit for bit the result from
/// before this form existed: an over- or underflowing square would make
/// the quotient wrong, not merely rounded.
#[inline]
pub(crate) fn closest_rotation_2x2(r00: f64, r01: f64, r11: f64) -> (f64, f64) {
    let (e, h) = (0.5 * (r00 + r11), -0.5 * r01);
    let r2 = e * e + h * h;
    if (f64::MIN_POSITIVE..=f64::MAX).contains(&r2) {
        let r = r2.sqrt();
        (e / r, h / r)
    } else {
        let (sin, cos) = h.atan2(e).sin_cos();
        (cos, sin)
    }
}

/// The matrix with orthonormal columns closest to `f` in the Frobenius
/// norm, `U V^T` of the thin SVD, computed as `Q Rot` (see the module
/// documentation): [`thin_qr`], [`closest_rotation_2x2`], then the columns
/// `q0 cos + q1 sin` and `q1 cos - q0 sin` (per coordinate, left to right).
/// It differs from `Q` times the rotation by `atan2(h, e)` (the thin SVD's
/// angle) by round-off only: at most a few units of 2^-52 per entry
/// (`docs/design/performance.md`, "Triangle strain in SIMD lanes"). Degenerate
/// columns are handled as in [`thin_svd`].
pub(crate) fn closest_orthonormal(f: &Matrix3x2<f64>) -> Matrix3x2<f64> {
    let ThinQr {
        q0,
        q1,
        r00,
        r01,
        r11,
    } = thin_qr(f);
    let (cos, sin) = closest_rotation_2x2(r00, r01, r11);
    Matrix3x2::from_columns(&[q0 * cos + q1 * sin, q1 * cos - q0 * sin])
}

/// `U clamp(s, min, max) V^T` of the thin SVD of `f` as [`thin_svd`]
/// gives it (two `atan2`, three `sin_cos`): the stretch-limited projection
/// from before [`clamped_stretch`], and that function's result where its
/// closed form does not apply.
pub(crate) fn clamped_stretch_by_angles(f: &Matrix3x2<f64>, min: f64, max: f64) -> Matrix3x2<f64> {
    let svd = thin_svd(f);
    let c = svd.s.map(|s| s.clamp(min, max));
    svd.u * Matrix2::from_diagonal(&c) * svd.v.transpose()
}

/// `U2 clamp(s, min, max) V^T` of the upper-triangular
/// `R = [[r00, r01], [0, r11]] = U2 diag(s) V^T`, as the entries
/// `[p00, p10, p01, p11]` (column-major), without trigonometry (see the
/// module documentation): with `e, d, g, h` as in [`thin_svd`],
/// `rot = sqrt(e^2 + h^2)`, `refl = sqrt(d^2 + g^2)`, `s0 = rot + refl`,
/// `s1 = max(rot - refl, 0)`, `c_i = clamp(s_i, min, max)`,
/// `a = 0.5 (c0 + c1) / rot`, `b = 0.5 (c0 - c1) / refl` (0 where
/// `d = g = 0`: equal singular values, so `c0 = c1`), the matrix
/// `a [[e, -h], [h, e]] + b [[d, g], [g, -d]]`, each entry one sum of two
/// products in the order written. `None` (the caller takes the angles)
/// where `e^2 + h^2` is not a normal, finite number, or `d^2 + g^2` is
/// neither one nor exactly 0 from `d = g = 0`: an over- or underflowing
/// square would make a quotient wrong, not merely rounded. The
/// triangle-strain lanes repeat exactly these operations.
#[inline]
pub(crate) fn clamped_stretch_2x2(
    r00: f64,
    r01: f64,
    r11: f64,
    min: f64,
    max: f64,
) -> Option<[f64; 4]> {
    let (e, d, g, h) = (0.5 * (r00 + r11), 0.5 * (r00 - r11), 0.5 * r01, -0.5 * r01);
    let rot2 = e * e + h * h;
    let refl2 = d * d + g * g;
    let normal = |x: f64| (f64::MIN_POSITIVE..=f64::MAX).contains(&x);
    let isotropic = d == 0.0 && g == 0.0;
    if !(normal(rot2) && (isotropic || normal(refl2))) {
        return None;
    }
    let (rot, refl) = (rot2.sqrt(), refl2.sqrt());
    // `det R >= 0` makes `rot >= refl`; `max` removes round-off, as in
    // `thin_svd`.
    let (s0, s1) = (rot + refl, (rot - refl).max(0.0));
    let (c0, c1) = (s0.clamp(min, max), s1.clamp(min, max));
    let a = 0.5 * (c0 + c1) / rot;
    let b = if isotropic {
        0.0
    } else {
        0.5 * (c0 - c1) / refl
    };
    Some([a * e + b * d, a * h + b * g, b * g - a * h, a * e - b * d])
}

/// `U clamp(S, min, max) V^T` for the thin SVD `f = U S V^T`: [`thin_qr`],
/// [`clamped_stretch_2x2`] of `R`, then `Q` times that 2 x 2 matrix, the
/// columns `q0 p00 + q1 p10` and `q0 p01 + q1 p11` (per coordinate, left
/// to right). It differs from [`clamped_stretch_by_angles`] by round-off
/// only (`docs/design/performance.md`, "Stretch-limited triangles in SIMD
/// lanes"), and is that function's result to the bit where the closed
/// form does not apply (`F = 0`, columns of norm below about 1e-150 or
/// above 1e150, NaN). Degenerate columns are handled as in [`thin_svd`].
pub(crate) fn clamped_stretch(f: &Matrix3x2<f64>, min: f64, max: f64) -> Matrix3x2<f64> {
    let ThinQr {
        q0,
        q1,
        r00,
        r01,
        r11,
    } = thin_qr(f);
    match clamped_stretch_2x2(r00, r01, r11, min, max) {
        Some([p00, p10, p01, p11]) => {
            Matrix3x2::from_columns(&[q0 * p00 + q1 * p10, q0 * p01 + q1 * p11])
        }
        None => clamped_stretch_by_angles(f, min, max),
    }
}

/// Thin SVD of `f` (see the module documentation). Non-finite input gives
/// non-finite singular values.
pub(crate) fn thin_svd(f: &Matrix3x2<f64>) -> ThinSvd {
    let ThinQr {
        q0,
        q1,
        r00,
        r01,
        r11,
    } = thin_qr(f);
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
    let flip_mu = crate::unit_product::flip_slope([p.c[0], p.c[1]], [s[0], s[1]], p.flip_at_equal);
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

/// Gradients and checks shared by the triangle-strain tests.
#[cfg(test)]
pub(crate) mod test_support {
    use nalgebra::{Matrix2, Matrix3x2, SymmetricEigen, Vector3};
    use proptest::prelude::*;

    use super::{ThinQr, rotation, thin_qr};
    use crate::signed_svd::test_support::rotation as rotation3;

    /// The projection as it was computed before the quotient form: `Q`
    /// times the rotation by `atan2(h, e)` (the thin SVD's angle), with
    /// the same `Q` and `R`.
    pub fn atan2_closest(f: &Matrix3x2<f64>) -> Matrix3x2<f64> {
        let ThinQr {
            q0,
            q1,
            r00,
            r01,
            r11,
        } = thin_qr(f);
        let (e, h) = (0.5 * (r00 + r11), -0.5 * r01);
        Matrix3x2::from_columns(&[q0, q1]) * rotation(h.atan2(e))
    }

    /// `U diag(s0, s1) V^T` with `U` two orthonormal columns of a random
    /// 3D rotation and `V` a random 2D rotation; `s1 < 0` is an in-plane
    /// reflection (`det(Q^T F) < 0`).
    pub fn from_singular_values(
        axis: [f64; 3],
        angle: f64,
        in_plane: f64,
        s: [f64; 2],
    ) -> Matrix3x2<f64> {
        let u = rotation3(axis, angle).fixed_columns::<2>(0).into_owned();
        u * Matrix2::from_diagonal(&s.into()) * rotation(in_plane).transpose()
    }

    /// Random 3 x 2 gradients of every class the projection meets: random
    /// entries; near-rotations; in-plane reflections; flat (one singular
    /// value 0 or tiny); extremely stretched or compressed (ratios up to
    /// 1e6); at scales 1e-8 and 1e8 and in between.
    pub fn gradient() -> impl Strategy<Value = Matrix3x2<f64>> {
        let stretch = prop_oneof![
            Just(1.0),
            (1.0 - 1e-3)..(1.0 + 1e-3),
            0.5..2.0f64,
            1e-6..1e-3f64,
            1e3..1e6f64,
            Just(0.0),
            Just(1e-12),
        ];
        let structured = (
            prop::array::uniform3(-1.0..1.0f64),
            -3.2..3.2f64,
            -3.2..3.2f64,
            prop::array::uniform2(stretch),
            prop::bool::ANY,
            prop_oneof![Just(1.0), Just(1e-8), Just(1e8), 1e-3..1e3f64],
        )
            .prop_map(|(axis, angle, in_plane, s, reflect, scale)| {
                let s1 = if reflect { -s[1] } else { s[1] };
                from_singular_values(axis, angle, in_plane, [s[0], s1]) * scale
            });
        let random = prop::array::uniform6(-10.0..10.0f64).prop_map(Matrix3x2::from_iterator);
        prop_oneof![3 => structured, 1 => random]
    }

    /// Hand-picked gradients, the degenerate branches of [`thin_qr`] and
    /// both ends of the quotient form's range included.
    pub fn special_gradients() -> Vec<Matrix3x2<f64>> {
        let m = |f0: [f64; 3], f1: [f64; 3]| {
            Matrix3x2::from_columns(&[Vector3::from(f0), Vector3::from(f1)])
        };
        let a = [0.1, 0.2, 0.3];
        let tilted = from_singular_values([0.3, -1.0, 0.7], 2.1, 0.4, [1.2, 0.9]);
        vec![
            m([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            m([-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]),
            m([1.0, 0.0, 0.0], [0.0, -1.0, 0.0]),
            m([0.0, 1.0, 0.0], [1.0, 0.0, 0.0]),
            tilted,
            tilted * 1e-8,
            tilted * 1e8,
            tilted * 1e-160,
            tilted * 1e-200,
            tilted * 1e200,
            // Zero columns: exactly, with negative zeros, both.
            Matrix3x2::zeros(),
            m([-0.0, -0.0, -0.0], [-0.0, -0.0, -0.0]),
            m([0.0, 0.0, 0.0], [0.3, -1.2, 2.0]),
            m([-0.0, 0.0, -0.0], [0.3, -1.2, 2.0]),
            m([0.3, -1.2, 2.0], [0.0, 0.0, 0.0]),
            // Parallel columns: a rest exactly 0, and one of round-off.
            m([1.0, 0.0, 0.0], [2.0, 0.0, 0.0]),
            m([1.0, 0.0, 0.0], [-0.5, 0.0, 0.0]),
            m(a, a.map(|x| 3.0 * x)),
            m(a, a.map(|x| -0.7 * x)),
            m(a, [0.1, 0.2, 0.3 + 1e-12]),
            // Flat, stretched, compressed.
            from_singular_values([1.0, 2.0, 3.0], 0.7, -1.1, [1.0, 0.0]),
            from_singular_values([1.0, 2.0, 3.0], 0.7, -1.1, [1e6, 1.0]),
            from_singular_values([1.0, 2.0, 3.0], 0.7, -1.1, [1.0, -1e-6]),
            from_singular_values([-1.0, 0.5, 0.0], -2.0, 3.0, [1e-6, 1e-6]),
            // Non-finite.
            m([f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]),
            m([1.0, 0.0, 0.0], [0.0, f64::INFINITY, 0.0]),
            m([f64::NEG_INFINITY, 0.0, 0.0], [0.0, 1.0, 0.0]),
            m([1.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0]),
        ]
    }

    /// Optimality of `p` for `f`, independent of how it was computed: `p`
    /// has orthonormal columns, `f`'s columns lie in their span
    /// (`f = p p^T f`), and `p^T f` is symmetric with non-negative
    /// eigenvalues; then `f = p (p^T f)` is a polar decomposition, and `p`
    /// maximises `tr(p^T f)`: the closest matrix with orthonormal columns.
    /// The tolerance is the polar tests' budget (400 eps) times the
    /// condition number `s0 / s1` of `f` (Gram-Schmidt loses orthogonality
    /// in proportion to it); the caller keeps it moderate.
    pub fn assert_closest_orthonormal(f: &Matrix3x2<f64>, p: &Matrix3x2<f64>) {
        let s = f.singular_values();
        // A rank-deficient `f` (a zero column, or parallel columns whose
        // rest Gram-Schmidt finds exactly 0) is held to the plain budget.
        let condition = if s.min() > 0.0 {
            (s.max() / s.min()).max(1.0)
        } else {
            1.0
        };
        let budget = crate::signed_svd::test_support::BUDGET * condition;
        let scale = f.norm().max(f64::MIN_POSITIVE);
        assert!(
            (p.transpose() * p - Matrix2::identity()).norm() <= budget,
            "columns not orthonormal: P = {p:?}, F = {f:?}"
        );
        let h = p.transpose() * f;
        assert!(
            (f - p * h).norm() <= budget * scale,
            "F not in the span of P: P = {p:?}, F = {f:?}"
        );
        let skew = (h - h.transpose()).norm() * 0.5;
        assert!(
            skew <= budget * scale,
            "P^T F not symmetric ({:e}): P = {p:?}, F = {f:?}",
            skew / scale
        );
        let lambda = SymmetricEigen::new((h + h.transpose()) * 0.5).eigenvalues;
        assert!(
            lambda.min() >= -budget * scale,
            "not the closest: eigenvalues {lambda:?} of P^T F, F = {f:?}"
        );
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::test_support::{
        assert_closest_orthonormal, atan2_closest, gradient, special_gradients,
    };
    use super::*;
    use crate::signed_svd::test_support::uniform_sequence;

    /// The bound of `docs/design/performance.md` ("Triangle strain in SIMD
    /// lanes") on `|P_new - P_old|` per entry, in units of 2^-52.
    const ROUND_OFF_BOUND: f64 = 8.0 * f64::EPSILON;

    /// The largest entry of `|a - b|`, 0 where both are the same NaN.
    fn largest_difference(a: &Matrix3x2<f64>, b: &Matrix3x2<f64>) -> f64 {
        a.iter()
            .zip(b.iter())
            .map(|(x, y)| {
                if x.to_bits() == y.to_bits() {
                    0.0
                } else {
                    (x - y).abs()
                }
            })
            .fold(0.0, f64::max)
    }

    /// Whether `f` takes the quotient form (`closest_rotation_2x2`'s first
    /// branch); elsewhere the result must be the old one to the bit.
    fn quotient_form(f: &Matrix3x2<f64>) -> bool {
        let ThinQr { r00, r01, r11, .. } = thin_qr(f);
        let (e, h) = (0.5 * (r00 + r11), -0.5 * r01);
        (f64::MIN_POSITIVE..=f64::MAX).contains(&(e * e + h * h))
    }

    fn assert_round_off_change(f: &Matrix3x2<f64>) {
        let (new, old) = (closest_orthonormal(f), atan2_closest(f));
        if quotient_form(f) {
            let d = largest_difference(&new, &old);
            assert!(
                d <= ROUND_OFF_BOUND,
                "F = {f:?}: new {new:?} vs old {old:?}, {} eps",
                d / f64::EPSILON
            );
        } else {
            let bits = |m: &Matrix3x2<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&new), bits(&old), "F = {f:?}");
        }
    }

    #[test]
    fn special_gradients_change_by_round_off_only() {
        for f in special_gradients() {
            assert_round_off_change(&f);
        }
    }

    /// Half a million gradients from a fixed sequence (xorshift), so that
    /// the largest difference is measured over far more cases than the
    /// proptest below runs; it is printed with `--nocapture`.
    #[test]
    fn largest_round_off_change_over_many_gradients() {
        let mut uniform = uniform_sequence(0x9E37_79B9_7F4A_7C15);
        let mut largest = 0.0f64;
        for i in 0..500_000 {
            let f = if i % 2 == 0 {
                Matrix3x2::from_fn(|_, _| uniform())
            } else {
                // Near-rotations, where `cos` and `sin` of the angle are
                // both O(1) or one is small.
                let s = [1.0 + 1e-2 * uniform(), 1.0 + 1e-2 * uniform()];
                let axis = [uniform(), uniform(), uniform()];
                let f =
                    test_support::from_singular_values(axis, 3.2 * uniform(), 3.2 * uniform(), s);
                f * 10f64.powf(8.0 * uniform())
            };
            let d = largest_difference(&closest_orthonormal(&f), &atan2_closest(&f));
            largest = largest.max(d);
        }
        eprintln!(
            "largest |P_new - P_old| entry: {} eps",
            largest / f64::EPSILON
        );
        assert!(largest <= ROUND_OFF_BOUND, "{} eps", largest / f64::EPSILON);
    }

    /// The projection is optimal on moderately conditioned gradients and on
    /// the special ones whose rest is exactly 0 or well above round-off.
    #[test]
    fn closest_orthonormal_is_optimal_on_special_gradients() {
        let mut checked = 0;
        for f in special_gradients() {
            if !(f.iter().all(|x| x.is_finite()) && f.norm() > 1e-150 && f.norm() < 1e150) {
                continue;
            }
            // Columns parallel up to round-off (or to the 1e-12 tilt) are
            // now orthogonalised twice (`REORTHOGONALIZE`) and checked too;
            // only the rank-deficient and badly conditioned are left out.
            let s = f.singular_values();
            let ThinQr { q0, q1, .. } = thin_qr(&f);
            if q0.dot(&q1).abs() < 1e-12 && (s.min() == 0.0 || s.max() / s.min() <= 1e6) {
                assert_closest_orthonormal(&f, &closest_orthonormal(&f));
                checked += 1;
            }
        }
        assert_eq!(checked, 17);
    }

    /// Columns parallel up to a tilt of 1e-12 to 1e-3 (a triangle nearly
    /// collapsed to a line): one Gram-Schmidt pass left `|q0 . q1|` of
    /// order `u |f1| / |rest|` (up to 1e-4 here), so `Q` was not
    /// orthonormal. With the second pass the rotation's columns are
    /// orthonormal, and the clamped matrix's singular values are the
    /// clamped ones of `f`, to 8 eps (each column is normalised once, an
    /// error of a few u, and the second pass leaves `q0 . q1` at a few u).
    #[test]
    fn nearly_parallel_columns_project_to_orthonormal_columns() {
        let a = Vector3::new(0.1, 0.2, 0.3);
        let mut worst: f64 = 0.0;
        for tilt in [1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 1e-3] {
            for direction in [Vector3::z(), Vector3::new(1.0, -1.0, 0.5)] {
                let f = Matrix3x2::from_columns(&[a, a * 1.7 + direction * tilt]);
                let p = closest_orthonormal(&f);
                let error = (p.transpose() * p - Matrix2::identity()).norm();
                worst = worst.max(error);
                assert!(
                    error <= 8.0 * f64::EPSILON,
                    "tilt {tilt}: P = {p:?}, |P^T P - I| = {error:e}"
                );
                for (min, max) in [(0.95, 1.05), (0.0, 1.0)] {
                    let mut expected: Vec<f64> = f
                        .singular_values()
                        .iter()
                        .map(|s| s.clamp(min, max))
                        .collect();
                    let mut got: Vec<f64> = clamped_stretch(&f, min, max)
                        .singular_values()
                        .iter()
                        .copied()
                        .collect();
                    expected.sort_by(f64::total_cmp);
                    got.sort_by(f64::total_cmp);
                    for (g, e) in got.iter().zip(&expected) {
                        let error = (g - e).abs() / max;
                        worst = worst.max(error);
                        assert!(
                            error <= 8.0 * f64::EPSILON,
                            "tilt {tilt}, limits {min}, {max}: singular values {got:?}, expected {expected:?}"
                        );
                    }
                }
            }
        }
        eprintln!("largest error: {} eps", worst / f64::EPSILON);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, max_shrink_iters: 500, ..ProptestConfig::default() })]

        #[test]
        fn closest_orthonormal_changes_by_round_off_only(f in gradient()) {
            assert_round_off_change(&f);
        }

        #[test]
        fn clamped_stretch_changes_by_round_off_only(f in gradient()) {
            assert_clamped_round_off_change(&f);
        }

        #[test]
        fn closest_orthonormal_is_optimal(f in gradient()) {
            let s = f.singular_values();
            // Gram-Schmidt's loss of orthogonality grows with the condition
            // number (the old projection's too): beyond 1e6 the budget
            // would be meaningless, so flat gradients are skipped.
            if s.max() / s.min() <= 1e6 {
                assert_closest_orthonormal(&f, &closest_orthonormal(&f));
            }
        }
    }

    /// The bound of `docs/design/performance.md` ("Stretch-limited triangles in
    /// SIMD lanes") on `|P_new - P_old|` per entry, in units of
    /// `2^-52 max(s0, min) sqrt(1 + |q0 . q1|)`.
    const CLAMPED_ROUND_OFF_BOUND: f64 = 19.0 * f64::EPSILON;

    /// Stretch limits of every kind the constraints accept: the cloth
    /// scenes', a wide and a degenerate pair, `min = 0`, `max = 1`.
    const LIMITS: [(f64, f64); 6] = [
        (0.95, 1.05),
        (0.9, 1.1),
        (0.5, 2.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (0.0, 1e6),
    ];

    /// Whether `f` takes [`clamped_stretch_2x2`]'s closed form.
    fn clamped_closed_form(f: &Matrix3x2<f64>, min: f64, max: f64) -> bool {
        let ThinQr { r00, r01, r11, .. } = thin_qr(f);
        clamped_stretch_2x2(r00, r01, r11, min, max).is_some()
    }

    /// `|P_new - P_old|`'s largest entry over the bound's unit
    /// `2^-52 max(s0, min) sqrt(1 + |q0 . q1|)` (0 where the bits agree),
    /// and checks that outside the closed form the bits agree.
    fn clamped_change(f: &Matrix3x2<f64>, min: f64, max: f64) -> f64 {
        let (new, old) = (
            clamped_stretch(f, min, max),
            clamped_stretch_by_angles(f, min, max),
        );
        if !clamped_closed_form(f, min, max) {
            let bits = |m: &Matrix3x2<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&new), bits(&old), "F = {f:?}, limits {min}, {max}");
            return 0.0;
        }
        let ThinQr { q0, q1, .. } = thin_qr(f);
        let scale = thin_svd(f).s[0].max(min) * (1.0 + q0.dot(&q1).abs()).sqrt();
        largest_difference(&new, &old) / scale
    }

    fn assert_clamped_round_off_change(f: &Matrix3x2<f64>) {
        for (min, max) in LIMITS {
            let d = clamped_change(f, min, max);
            assert!(
                d <= CLAMPED_ROUND_OFF_BOUND,
                "F = {f:?}, limits {min}, {max}: {} eps: new {:?} vs old {:?}",
                d / f64::EPSILON,
                clamped_stretch(f, min, max),
                clamped_stretch_by_angles(f, min, max)
            );
        }
    }

    /// Gradients with equal singular values exactly (`R = c I` or a
    /// rotation of it: `d = g = 0`), or up to round-off; the last two
    /// with an anisotropy so small that `d^2` is subnormal or 0.
    fn isotropic_gradients() -> Vec<Matrix3x2<f64>> {
        let m = |f0: [f64; 3], f1: [f64; 3]| {
            Matrix3x2::from_columns(&[Vector3::from(f0), Vector3::from(f1)])
        };
        let mut cases = Vec::new();
        for c in [1.0, 1.2, 0.7, 1.05, 0.95, 1e-3, 1e3, 1e-140, 1e140] {
            cases.push(m([c, 0.0, 0.0], [0.0, c, 0.0]));
            cases.push(m([0.0, 0.0, c], [c, 0.0, 0.0]));
            cases.push(m([0.6 * c, 0.8 * c, 0.0], [-0.8 * c, 0.6 * c, 0.0]));
            cases.push(test_support::from_singular_values(
                [0.2, 0.5, -1.0],
                1.3,
                0.4,
                [c, c],
            ));
        }
        // Anisotropy whose `d^2` is subnormal, and one whose `d^2`
        // underflows to 0 with `d != 0`: outside the closed form.
        cases.push(m([1e-150 + 2e-157, 0.0, 0.0], [0.0, 1e-150, 0.0]));
        cases.push(m([1e-150 + 2e-163, 0.0, 0.0], [0.0, 1e-150, 0.0]));
        cases
    }

    #[test]
    fn clamped_special_gradients_change_by_round_off_only() {
        let tilted = test_support::from_singular_values([0.3, -1.0, 0.7], 2.1, 0.4, [1.2, 0.9]);
        let extreme = [1e-150, 1e150, 1e-154, 1e154, 1e-300, 1e300].map(|x| tilted * x);
        let isotropic = isotropic_gradients();
        for f in &isotropic[isotropic.len() - 2..] {
            assert!(!clamped_closed_form(f, 0.0, 1.0), "{f:?}");
        }
        for f in special_gradients()
            .into_iter()
            .chain(isotropic)
            .chain(extreme)
        {
            assert_clamped_round_off_change(&f);
        }
    }

    /// Exactly isotropic gradients take the closed form (its `d = g = 0`
    /// case, no division by `refl = 0`) and are scaled to the clamped
    /// singular value: `clamp(c) / c` times `F`, up to round-off.
    #[test]
    fn isotropic_gradients_are_scaled() {
        for f in isotropic_gradients().into_iter().step_by(4).take(7) {
            let c = f[(0, 0)];
            for (min, max) in LIMITS {
                assert!(clamped_closed_form(&f, min, max));
                let expected = f * (c.clamp(min, max) / c);
                let p = clamped_stretch(&f, min, max);
                assert!(
                    largest_difference(&p, &expected) <= 4.0 * f64::EPSILON * c.max(min),
                    "{f:?}, {min}, {max}: {p:?}"
                );
            }
        }
    }

    /// Where both singular values lie within the limits the constraint is
    /// satisfied and the projection is `F` itself, up to round-off (a
    /// sanity check of the closed form with a loose tolerance, not a
    /// derived bound: the bound above is against the old form).
    #[test]
    fn gradients_within_the_limits_are_kept() {
        let mut uniform = uniform_sequence(0x2545_F491_4F6C_DD1D);
        for _ in 0..10_000 {
            let s = [1.0 + 0.05 * uniform(), 1.0 + 0.05 * uniform()];
            let axis = [uniform(), uniform(), uniform()];
            let f = test_support::from_singular_values(axis, 3.2 * uniform(), 3.2 * uniform(), s);
            let p = clamped_stretch(&f, 0.9, 1.1);
            assert!(
                largest_difference(&p, &f) <= 32.0 * f64::EPSILON,
                "{f:?}: {p:?}"
            );
        }
    }

    /// Half a million gradients with limits from a fixed sequence: random
    /// entries, near-isometries, stretched and compressed ones, at scales
    /// 1e-8 to 1e8; the largest change is printed with `--nocapture`.
    #[test]
    fn largest_clamped_round_off_change_over_many_gradients() {
        let mut uniform = uniform_sequence(0x9E37_79B9_7F4A_7C15);
        let mut largest = 0.0f64;
        let n = if cfg!(debug_assertions) {
            60_000
        } else {
            500_000
        };
        for i in 0..n {
            let f = match i % 4 {
                0 => Matrix3x2::from_fn(|_, _| uniform()),
                1 => {
                    let s = [1.0 + 0.1 * uniform(), 1.0 + 0.1 * uniform()];
                    let axis = [uniform(), uniform(), uniform()];
                    test_support::from_singular_values(axis, 3.2 * uniform(), 3.2 * uniform(), s)
                }
                _ => {
                    let s = [10f64.powf(2.0 * uniform()), 10f64.powf(2.0 * uniform())];
                    let axis = [uniform(), uniform(), uniform()];
                    let f = test_support::from_singular_values(
                        axis,
                        3.2 * uniform(),
                        3.2 * uniform(),
                        s,
                    );
                    f * 10f64.powf(8.0 * uniform())
                }
            };
            let (min, max) = LIMITS[i % LIMITS.len()];
            largest = largest.max(clamped_change(&f, min, max));
        }
        eprintln!(
            "largest |P_new - P_old| entry: {} eps max(s0, min) sqrt(1 + |q0.q1|)",
            largest / f64::EPSILON
        );
        assert!(
            largest <= CLAMPED_ROUND_OFF_BOUND,
            "{} eps",
            largest / f64::EPSILON
        );
    }

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
            let closest = closest_orthonormal(&f);
            assert!((closest - svd.u * svd.v.transpose()).norm() < 1e-13);
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
