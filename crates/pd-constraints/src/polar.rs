//! The proper rotation closest to a 3 x 3 matrix: the tet-strain projection,
//! run once per tetrahedron per local-global iteration.
//!
//! For `det F > 0` the closest rotation is the orthogonal factor `Q` of the
//! polar decomposition `F = Q H` (`H` symmetric positive definite). Newton's
//! iteration `X <- (X + X^-T) / 2` from `X = F` converges to `Q`
//! quadratically: on the singular values it is `s <- (s + 1/s) / 2`, so a
//! deformation gradient near a rotation (the common case: strain 1e-3 takes
//! three iterations) costs three cofactor matrices and three divisions, far
//! less than any SVD. Far from a rotation, scaling each iterate
//! (`X <- z X`, `z = (|X^-1|_F / |X|_F)^1/2`, Higham 1986) keeps the
//! iteration count small.
//!
//! Inverted, flat and strongly distorted elements (`det F` small or negative
//! relative to `|F|^3`) go to the signed SVD instead
//! ([`signed_svd`](crate::signed_svd)): for `det F < 0` the
//! polar factor is a reflection, not the closest rotation, and as `det F`
//! approaches 0 the inverse in the iteration loses accuracy.

use nalgebra::Matrix3;

use crate::signed_svd::{rescaling, signed_svd};

/// Newton runs only when `det F > MIN_SHAPE |F|_F^3`. `det F / |F|_F^3` is
/// `3^-3/2 = 0.19` for a rotation and falls like the smallest singular value
/// over the largest: 1e-3 admits stretch ratios up to about 50, for which
/// the scaled iteration converges within 6 iterations (measured over 20,000
/// random stretches per ratio) and the cofactor inverse loses at most that
/// ratio's worth of digits (still near 1e-14).
pub(crate) const MIN_SHAPE: f64 = 1e-3;

/// Stop when the squared change `|X_{k+1} - X_k|_F^2` falls below this: the
/// change estimates the error of `X_k`, and the next error is about half its
/// square (quadratic convergence), so `|change| < 1.5e-8` leaves an error
/// near `1e-16`, the working precision.
pub(crate) const CONVERGED_CHANGE_SQUARED: f64 = 2.0e-16;

/// Above this squared change the iterate is still far from orthogonal and is
/// rescaled; below it the plain iteration converges quadratically anyway.
pub(crate) const SCALE_WHILE_CHANGE_SQUARED: f64 = 1e-4;

/// More than enough for the admitted stretch ratios (see `MIN_SHAPE`); a run
/// that does not converge within it falls back to the SVD.
pub(crate) const MAX_ITERATIONS: usize = 20;

/// The proper rotation closest to `f` in the Frobenius norm.
///
/// Newton's polar iteration where `f` is well shaped, the signed SVD
/// otherwise (inverted, flat or degenerate `f`). A non-finite `f` gives the
/// identity: callers detect non-finite input themselves (the solver's
/// divergence check), this function never panics.
///
/// ```
/// use nalgebra::{Matrix3, Rotation3, Vector3};
/// use pd_constraints::polar::closest_rotation;
///
/// let r = Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
/// let stretch = Matrix3::from_diagonal(&Vector3::new(1.2, 0.9, 1.05));
/// assert!((closest_rotation(&(r * stretch)) - r).norm() < 1e-14);
/// ```
pub fn closest_rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    newton_polar(f).unwrap_or_else(|| {
        let (u, _, v) = signed_svd(f);
        u * v.transpose()
    })
}

/// The orthogonal polar factor of `f` by scaled Newton iteration, or `None`
/// when `f` is not safely inside the well-shaped, positively oriented set or
/// the iteration does not converge.
fn newton_polar(f: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    // The polar factor of `c F` is that of `F` for `c > 0`: bring extreme
    // scales near 1 by an exact power of two so that `det` and `|F|^3`
    // neither underflow nor overflow.
    let mut x = f * rescaling(f.amax());
    let norm = x.norm();
    let mut cofactors = cofactor(&x);
    let mut det = determinant_from_cofactors(&x, &cofactors);
    // Also rejects NaN.
    if !(det > MIN_SHAPE * norm * norm * norm) {
        return None;
    }
    let mut scale = frobenius_scale(&x, &cofactors, det);
    for _ in 0..MAX_ITERATIONS {
        // (z X + (z X)^-T) / 2, with X^-T = cof(X) / det X.
        let next = x * (0.5 * scale) + cofactors * (0.5 / (scale * det));
        let change = (next - x).norm_squared();
        x = next;
        if change < CONVERGED_CHANGE_SQUARED {
            return Some(x);
        }
        cofactors = cofactor(&x);
        det = determinant_from_cofactors(&x, &cofactors);
        if !(det > 0.0) {
            return None;
        }
        scale = if change > SCALE_WHILE_CHANGE_SQUARED {
            frobenius_scale(&x, &cofactors, det)
        } else {
            1.0
        };
    }
    None
}

/// Higham's Frobenius-norm scaling `z = (|X^-1|_F / |X|_F)^(1/2)`, with
/// `|X^-1|_F = |cof X|_F / |det X|`: it makes `z X` and its inverse
/// transpose equally large, which is what the averaging step needs far from
/// convergence. (Determinant scaling, `|det X|^(-1/3)`, costs a software
/// cube root: 7 % of a whole step in a profile.)
#[inline]
fn frobenius_scale(x: &Matrix3<f64>, cofactors: &Matrix3<f64>, det: f64) -> f64 {
    (cofactors.norm() / (det * x.norm())).sqrt()
}

/// The cofactor matrix, `det(X) X^-T`.
#[inline]
fn cofactor(x: &Matrix3<f64>) -> Matrix3<f64> {
    let m = |r: usize, c: usize| x[(r, c)];
    Matrix3::new(
        m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1),
        m(1, 2) * m(2, 0) - m(1, 0) * m(2, 2),
        m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0),
        m(0, 2) * m(2, 1) - m(0, 1) * m(2, 2),
        m(0, 0) * m(2, 2) - m(0, 2) * m(2, 0),
        m(0, 1) * m(2, 0) - m(0, 0) * m(2, 1),
        m(0, 1) * m(1, 2) - m(0, 2) * m(1, 1),
        m(0, 2) * m(1, 0) - m(0, 0) * m(1, 2),
        m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0),
    )
}

/// Laplace expansion along the first column, reusing the cofactors.
#[inline]
fn determinant_from_cofactors(x: &Matrix3<f64>, cofactors: &Matrix3<f64>) -> f64 {
    x[(0, 0)] * cofactors[(0, 0)] + x[(1, 0)] * cofactors[(1, 0)] + x[(2, 0)] * cofactors[(2, 0)]
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use proptest::prelude::*;

    use super::*;
    use crate::signed_svd::test_support::{
        BUDGET, assert_closest_rotation, rotation, structured_matrix,
    };

    #[test]
    fn cofactors_are_the_inverse_transpose_times_det() {
        let x = Matrix3::new(0.3, -1.2, 0.5, 2.0, 0.1, -0.7, -0.4, 0.9, 0.2);
        let c = cofactor(&x);
        let det = determinant_from_cofactors(&x, &c);
        assert!((det - x.determinant()).abs() < 1e-14);
        let expected = x.try_inverse().unwrap().transpose() * det;
        assert!((c - expected).norm() < 1e-14, "{c} vs {expected}");
    }

    #[test]
    fn newton_handles_well_shaped_and_declines_the_rest() {
        let r = rotation([0.3, -1.0, 0.7], 2.1);
        let diag = |a: f64, b: f64, c: f64| Matrix3::from_diagonal(&Vector3::new(a, b, c));
        for f in [
            r,
            r * 1e-200,
            r * 1e200,
            r * diag(1.5, 0.8, 1.1),
            r * diag(10.0, 1.0, 0.5),
        ] {
            let q = newton_polar(&f).expect("well shaped: Newton answers");
            assert_closest_rotation(&f, &q);
        }
        for f in [
            r * diag(1.0, 1.0, -1.0),
            r * diag(1.0, 1.0, 1e-6),
            Matrix3::zeros(),
            Matrix3::from_element(f64::NAN),
        ] {
            assert!(newton_polar(&f).is_none(), "should decline {f}");
        }
    }

    #[test]
    fn agrees_with_the_signed_svd() {
        // Both are exact for matrices within BUDGET |F| of F (backward
        // stable), and the closest rotation is Lipschitz in F with constant
        // 2/(s_1 + s_2) (the twist modes, docs/design/constraints.md), so they differ
        // by at most that constant times twice the backward error.
        let r = rotation([1.0, 2.0, -0.5], 0.8);
        let s = rotation([-0.2, 0.4, 1.0], -2.5);
        for stretch in [
            [1.0, 1.0, 1.0],
            [1.001, 0.999, 1.0],
            [1.3, 0.7, 1.1],
            [5.0, 0.5, 0.3],
        ] {
            let f = r * Matrix3::from_diagonal(&Vector3::from(stretch)) * s.transpose();
            let (u, sv, v) = signed_svd(&f);
            let bound = 2.0 * BUDGET * f.norm() * 2.0 / (sv[1] + sv[2]);
            assert!((closest_rotation(&f) - u * v.transpose()).norm() <= bound);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, max_shrink_iters: 2000, ..ProptestConfig::default() })]

        #[test]
        fn closest_for_structured_matrices(f in structured_matrix()) {
            assert_closest_rotation(&f, &closest_rotation(&f));
        }

        #[test]
        fn closest_for_random_entries(entries in prop::array::uniform9(-10.0..10.0f64)) {
            let f = Matrix3::from_iterator(entries);
            assert_closest_rotation(&f, &closest_rotation(&f));
        }

        #[test]
        fn closest_near_rotations(axis in prop::array::uniform3(-1.0..1.0f64), angle in -3.2..3.2f64,
                                  strain in prop::array::uniform9(-0.3..0.3f64)) {
            let f = rotation(axis, angle) * (Matrix3::identity() + Matrix3::from_iterator(strain));
            assert_closest_rotation(&f, &closest_rotation(&f));
        }
    }
}
