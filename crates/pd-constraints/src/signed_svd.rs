//! Signed singular value decomposition of a 3 x 3 matrix, the kernel of the
//! tet-strain projection and of its Hessian.
//!
//! `F = U diag(s) V^T` with `U` and `V` proper rotations (`det = +1`),
//! `s_0 >= s_1 >= |s_2|`, and the sign of `det F` carried by `s_2`. Then
//! `U V^T` is the proper rotation closest to `F` in the Frobenius norm, also
//! for an inverted `F` (`det F < 0`), where a plain SVD's `U V^T` would be a
//! reflection.
//!
//! # Method
//!
//! One-sided (Hestenes) Jacobi: plane rotations applied to the columns of
//! `F` from the right, each making one pair of columns orthogonal, swept
//! cyclically until every pair is orthogonal to working precision, so that
//! `F V = B` has orthogonal columns of lengths `|s_i|`. Then the columns are
//! sorted by length, `U`'s first two columns are `B`'s normalised (the second
//! re-orthogonalised against the first) and the third is their cross product,
//! which makes `U` proper whatever the sign of `det F`; projecting `B`'s last
//! column on it gives the signed `s_2`.
//!
//! Why this and not a general SVD: nalgebra's `Matrix3::svd` goes through a
//! Householder tridiagonalisation and a symmetric QR iteration that are built
//! for any size; the local step spent 56-71 % of its time there
//! (`docs/design/performance.md`). A 3 x 3 Jacobi sweep is a few dozen flops with
//! no allocation and few branches, and near rest (`F` close to a rotation,
//! the common case) the columns are almost orthogonal already, so one or two
//! sweeps finish it. Working on `F` rather than on `F^T F` keeps the relative
//! accuracy of small singular values (the condition number is not squared).
//!
//! # Accuracy
//!
//! Each plane rotation is backward stable, so the computed factors are an
//! exact signed SVD of `F + E` with `|E|` a small multiple of `eps |F|`
//! (at most `MAX_SWEEPS * 3` rotations, each adding a few `eps`). In
//! particular `U V^T` is the exact closest rotation of a matrix within that
//! distance of `F`: `R^T F` is symmetric, and the sum of any two of its
//! eigenvalues is non-negative (the optimality conditions on SO(3)), up to
//! `|E|`. The tests check exactly these conditions over random, inverted,
//! flat, rank-deficient, repeated and badly scaled matrices.

use nalgebra::{Matrix3, Vector3};

/// A sweep treats the three column pairs once. One-sided Jacobi converges
/// quadratically: measured over 100,000 matrices per class, near-rotations
/// and random matrices finish in 3-5 sweeps (the last only confirms). Rank-
/// deficient and repeated-value inputs occasionally (6 in 100,000) never
/// meet `TOL` on their round-off-sized columns and stop here, still within
/// the backward-error budget the tests check.
const MAX_SWEEPS: usize = 12;

/// A pair of columns counts as orthogonal when `|b_p . b_q| <= TOL |b_p| |b_q|`.
const TOL: f64 = f64::EPSILON;

/// Inputs whose largest entry lies outside `[TINY, HUGE]` are rescaled by a
/// power of two first, so that products of two squared column norms (at
/// most 9e240) cannot overflow, and a squared norm underflows only for a
/// column below 1e-94 of the largest entry, far below round-off.
pub(crate) const TINY: f64 = 1e-60;
/// The upper end of the range [`rescaling`] brings a matrix's largest entry into.
pub(crate) const HUGE: f64 = 1e60;

/// The power of two (exact to apply and to undo) that brings a matrix whose
/// largest entry is `largest` into `[TINY, HUGE]`, or 1 if it is there (or
/// is 0 or not finite). Shared with `polar`, whose determinant test needs
/// the same protection.
pub(crate) fn rescaling(largest: f64) -> f64 {
    if !largest.is_finite() || largest == 0.0 || (TINY..=HUGE).contains(&largest) {
        1.0
    } else {
        2f64.powi(-largest.log2().round() as i32)
    }
}

/// Signed SVD `F = U diag(s) V^T`: `U`, `V` proper rotations, singular values
/// sorted as `s_0 >= s_1 >= |s_2|` (up to round-off where two are equal), the
/// sign of `det F` on `s_2`.
///
/// A non-finite `F` gives identity factors and NaN singular values, so that
/// the caller's divergence check, not a panic, reports it. Cost: a few hundred
/// flops, no allocation.
///
/// ```
/// use nalgebra::Matrix3;
/// use pd_constraints::signed_svd::signed_svd;
///
/// // Inverted: det F < 0. The sign goes to the smallest singular value.
/// let f = Matrix3::new(2.0, 0.0, 0.0, 0.0, -0.5, 0.0, 0.0, 0.0, 1.0);
/// let (u, s, v) = signed_svd(&f);
/// assert!((s - nalgebra::Vector3::new(2.0, 1.0, -0.5)).norm() < 1e-15);
/// assert!((u.determinant() - 1.0).abs() < 1e-15 && (v.determinant() - 1.0).abs() < 1e-15);
/// assert!((u * Matrix3::from_diagonal(&s) * v.transpose() - f).norm() < 1e-15);
/// ```
pub fn signed_svd(f: &Matrix3<f64>) -> (Matrix3<f64>, Vector3<f64>, Matrix3<f64>) {
    if !f.iter().all(|x| x.is_finite()) {
        return (
            Matrix3::identity(),
            Vector3::from_element(f64::NAN),
            Matrix3::identity(),
        );
    }
    let largest = f.amax();
    if largest == 0.0 {
        return (Matrix3::identity(), Vector3::zeros(), Matrix3::identity());
    }
    let scale = rescaling(largest);
    let mut columns = [0, 1, 2].map(|c| [0, 1, 2].map(|r| f[(r, c)] * scale));
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    orthogonalise_columns(&mut columns, &mut v);

    // Sort by column length, longest first. Each swap flips det V; one
    // negated column (of both V and B, so that F V = B still holds) restores
    // det V = +1.
    let mut lengths = columns.map(|c| dot(&c, &c));
    let mut swaps = 0;
    for (p, q) in [(0, 1), (0, 2), (1, 2)] {
        if lengths[q] > lengths[p] {
            columns.swap(p, q);
            v.swap(p, q);
            lengths.swap(p, q);
            swaps += 1;
        }
    }
    if swaps % 2 == 1 {
        columns[2] = columns[2].map(|x| -x);
        v[2] = v[2].map(|x| -x);
    }

    let s0 = lengths[0].sqrt();
    let u0 = columns[0].map(|x| x / s0);
    let along = dot(&u0, &columns[1]);
    let rest = [0, 1, 2].map(|k| columns[1][k] - along * u0[k]);
    let rest_length = dot(&rest, &rest).sqrt();
    let u1 = if rest_length > 0.0 {
        rest.map(|x| x / rest_length)
    } else {
        any_unit_orthogonal(&u0)
    };
    let u2 = cross(&u0, &u1);
    let s1 = dot(&u1, &columns[1]);
    let s2 = dot(&u2, &columns[2]);

    let u = Matrix3::from_columns(&[u0.into(), u1.into(), u2.into()]);
    let v = Matrix3::from_columns(&[v[0].into(), v[1].into(), v[2].into()]);
    (u, Vector3::new(s0, s1, s2) / scale, v)
}

/// Cyclic one-sided Jacobi: rotates pairs of `columns` (and the same pairs
/// of `v`) until every pair is orthogonal to `TOL`.
fn orthogonalise_columns(columns: &mut [[f64; 3]; 3], v: &mut [[f64; 3]; 3]) {
    for _ in 0..MAX_SWEEPS {
        let mut rotated = false;
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            let alpha = dot(&columns[p], &columns[p]);
            let beta = dot(&columns[q], &columns[q]);
            let gamma = dot(&columns[p], &columns[q]);
            // |gamma| <= TOL sqrt(alpha beta), squared; also skips a zero
            // column (gamma = 0).
            if gamma * gamma <= TOL * TOL * alpha * beta {
                continue;
            }
            rotated = true;
            // The rotation that diagonalises [[alpha, gamma], [gamma, beta]]
            // (Golub and Van Loan, symmetric Schur decomposition of a 2 x 2
            // block): t = tan(theta) is the smaller root of
            // t^2 + 2 zeta t - 1 = 0.
            let zeta = (beta - alpha) / (2.0 * gamma);
            let t = if zeta.abs() > 1e100 {
                0.5 / zeta
            } else {
                zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt())
            };
            let c = 1.0 / (1.0 + t * t).sqrt();
            let s = c * t;
            rotate(columns, p, q, c, s);
            rotate(v, p, q, c, s);
        }
        if !rotated {
            return;
        }
    }
}

/// `(col_p, col_q) <- (c col_p - s col_q, s col_p + c col_q)`.
#[inline]
fn rotate(m: &mut [[f64; 3]; 3], p: usize, q: usize, c: f64, s: f64) {
    let (a, b) = (m[p], m[q]);
    m[p] = [0, 1, 2].map(|k| c * a[k] - s * b[k]);
    m[q] = [0, 1, 2].map(|k| s * a[k] + c * b[k]);
}

#[inline]
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// A unit vector orthogonal to the unit vector `u`: the axis along which `u`
/// is smallest, with its `u` component removed.
fn any_unit_orthogonal(u: &[f64; 3]) -> [f64; 3] {
    let axis = (0..3)
        .min_by(|&i, &j| u[i].abs().total_cmp(&u[j].abs()))
        .unwrap_or(0);
    let mut w = [0.0; 3];
    w[axis] = 1.0;
    let along = u[axis];
    let w = [0, 1, 2].map(|k| w[k] - along * u[k]);
    let length = dot(&w, &w).sqrt();
    w.map(|x| x / length)
}

/// Checks shared by the tests of this module and of `polar`.
#[cfg(test)]
pub(crate) mod test_support {
    use nalgebra::{Matrix3, Rotation3, SymmetricEigen, Unit, Vector3};
    use proptest::prelude::*;

    /// Backward-error budget: at most `3 * MAX_SWEEPS` rotations, each
    /// perturbing the columns by about `4 eps` relative, plus the
    /// normalisation and the products below; 400 eps (9e-14) is a generous
    /// bound for that, and still 1e12 times smaller than any wrong answer
    /// (a wrong rotation is off by O(1)).
    pub const BUDGET: f64 = 400.0 * f64::EPSILON;

    /// A fixed pseudo-random sequence (xorshift64 from `seed`), uniform in
    /// `[-1, 1)`: the many-case tests' inputs, the same on every run.
    pub fn uniform_sequence(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
    }

    /// Optimality of `R` on SO(3), independent of how it was computed:
    /// `R^T F = S` symmetric, and `lambda_i + lambda_j >= 0` for every pair of
    /// `S`'s eigenvalues (the second-order condition: a rotation by `theta`
    /// about `S`'s eigenvector `k` changes `tr(R^T F)` by
    /// `-(lambda_i + lambda_j) theta^2 / 2`). Together they make `R` a global
    /// maximiser of `tr(R^T F)`, i.e. the closest rotation.
    pub fn assert_closest_rotation(f: &Matrix3<f64>, r: &Matrix3<f64>) {
        // A rotation first: an unconverged polar iterate `Q p(H)` would pass
        // the symmetry condition below, since `p(H) H` is symmetric.
        assert!(
            (r.transpose() * r - Matrix3::identity()).norm() <= BUDGET
                && (r.determinant() - 1.0).abs() <= BUDGET,
            "not a rotation: R = {r:?}, F = {f:?}"
        );
        let scale = f.norm().max(f64::MIN_POSITIVE);
        let s = r.transpose() * f;
        let skew = (s - s.transpose()) * 0.5;
        assert!(
            skew.norm() <= BUDGET * scale,
            "R^T F not symmetric ({:e}): F = {f:?}",
            skew.norm() / scale
        );
        let lambda = SymmetricEigen::new((s + s.transpose()) * 0.5).eigenvalues;
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            assert!(
                lambda[i] + lambda[j] >= -BUDGET * scale,
                "not the closest rotation: eigenvalues {lambda:?} of R^T F, F = {f:?}"
            );
        }
    }

    pub fn rotation(axis: [f64; 3], angle: f64) -> Matrix3<f64> {
        let axis = Vector3::from(axis);
        let axis = if axis.norm() > 1e-9 {
            Unit::new_normalize(axis)
        } else {
            Vector3::x_axis()
        };
        Rotation3::from_axis_angle(&axis, angle).into_inner()
    }

    /// Matrices of chosen singular values and random rotations, covering the
    /// classes that break naive methods: repeated and nearly repeated values,
    /// nearly flat and collapsed elements, inversion, extreme scales.
    pub fn structured_matrix() -> impl Strategy<Value = Matrix3<f64>> {
        let axis = prop::array::uniform3(-1.0..1.0f64);
        let angle = -3.2..3.2f64;
        let magnitude = prop_oneof![
            Just(1.0),
            Just(0.0),
            1e-12..1e-6f64,
            0.5..2.0f64,
            1e-3..1e3f64,
        ];
        (
            (axis.clone(), angle.clone()),
            (axis, angle),
            prop::array::uniform3(magnitude),
            prop::array::uniform3(prop::bool::ANY),
            prop_oneof![Just(1.0), Just(1e-150), Just(1e150), 1e-3..1e3f64],
        )
            .prop_map(|((a1, t1), (a2, t2), s, flips, scale)| {
                let signs = flips.map(|flip| if flip { -1.0 } else { 1.0 });
                let diag = Vector3::new(s[0] * signs[0], s[1] * signs[1], s[2] * signs[2]);
                rotation(a1, t1)
                    * Matrix3::from_diagonal(&diag)
                    * rotation(a2, t2).transpose()
                    * scale
            })
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::test_support::{BUDGET, assert_closest_rotation, rotation, structured_matrix};
    use super::*;

    fn assert_signed_svd(f: &Matrix3<f64>) {
        let (u, s, v) = signed_svd(f);
        let size = f.norm();
        let scale = size.max(f64::MIN_POSITIVE);
        let tag = format!("F = {f:?}, s = {s:?}");
        for (name, m) in [("U", &u), ("V", &v)] {
            assert!(
                (m.transpose() * m - Matrix3::identity()).norm() <= BUDGET,
                "{name} not orthogonal: {tag}"
            );
            assert!(
                (m.determinant() - 1.0).abs() <= BUDGET,
                "{name} not proper: {tag}"
            );
        }
        let rebuilt = u * Matrix3::from_diagonal(&s) * v.transpose();
        assert!(
            (rebuilt - f).norm() <= BUDGET * scale,
            "reconstruction off by {:e}: {tag}",
            (rebuilt - f).norm() / scale
        );
        // Equal singular values may come out in either order by an ulp.
        assert!(
            s[0] >= s[1] - BUDGET * scale && s[1] >= s[2].abs() - BUDGET * scale,
            "not sorted: {tag}"
        );
        let det = f.determinant();
        // The sign of det F is determined only when it exceeds the
        // determinant's own round-off (about eps |F|^3).
        if det.abs() > BUDGET * size.powi(3) {
            assert_eq!(s[2] < 0.0, det < 0.0, "sign of det F not on s_2: {tag}");
        }
        assert_closest_rotation(f, &(u * v.transpose()));
    }

    #[test]
    fn special_matrices() {
        let r = rotation([0.3, -1.0, 0.7], 2.1);
        let cases = [
            Matrix3::identity(),
            -Matrix3::identity(),
            Matrix3::zeros(),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            Matrix3::from_diagonal(&Vector3::new(2.0, 0.5, -0.1)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0)),
            Matrix3::from_diagonal(&Vector3::new(0.0, 0.0, 3.0)),
            Matrix3::from_diagonal(&Vector3::new(-1.0, -2.0, -3.0)),
            r,
            r * 1e-200,
            r * 1e200,
            r * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 1e-17)),
            Matrix3::new(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0),
            Matrix3::new(0.3, -1.2, 0.5, 2.0, 0.1, -0.7, -0.4, 0.9, 0.2),
            Matrix3::new(1.0, 1e-300, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, f64::MIN_POSITIVE),
        ];
        for f in cases {
            assert_signed_svd(&f);
        }
    }

    #[test]
    fn known_decompositions() {
        // F = diag(3, 2, -1): singular values 3, 2, -1; closest rotation I
        // (flip the axis of the smallest |s| only).
        let f = Matrix3::from_diagonal(&Vector3::new(3.0, 2.0, -1.0));
        let (u, s, v) = signed_svd(&f);
        assert_eq!(s, Vector3::new(3.0, 2.0, -1.0));
        assert!((u * v.transpose() - Matrix3::identity()).norm() < 1e-15);
        // A rotation times a stretch: the rotation comes back.
        let r = rotation([1.0, 2.0, -0.5], 0.8);
        let (u, s, v) = signed_svd(&(r * Matrix3::from_diagonal(&Vector3::new(1.5, 1.2, 0.7))));
        assert!((s - Vector3::new(1.5, 1.2, 0.7)).norm() < 1e-14);
        assert!((u * v.transpose() - r).norm() < 1e-14);
    }

    #[test]
    fn non_finite_input_gives_nan_singular_values() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut f = Matrix3::identity();
            f[(1, 2)] = bad;
            let (u, s, v) = signed_svd(&f);
            assert!(s.iter().all(|x| x.is_nan()));
            assert_eq!((u, v), (Matrix3::identity(), Matrix3::identity()));
        }
    }

    #[test]
    fn agrees_with_nalgebra_where_the_rotation_is_well_conditioned() {
        // The closest rotation is Lipschitz with constant 2/(s_1 + s_2) in
        // F (the twist modes of docs/design/constraints.md); both computations are
        // backward stable, so they differ by at most that times twice the
        // backward error.
        let mut next = test_support::uniform_sequence(0x9e37_79b9_7f4a_7c15);
        for _ in 0..2000 {
            let f = Matrix3::from_fn(|_, _| next() * 2.0);
            let ours = {
                let (u, _, v) = signed_svd(&f);
                u * v.transpose()
            };
            let svd = f.svd(true, true);
            let (mut u, s, v) = (
                svd.u.unwrap(),
                svd.singular_values,
                svd.v_t.unwrap().transpose(),
            );
            let smallest = s.imin();
            if (u * v.transpose()).determinant() < 0.0 {
                u.column_mut(smallest).neg_mut();
            }
            let theirs = u * v.transpose();
            let mut sorted = s.as_slice().to_vec();
            sorted.sort_by(f64::total_cmp);
            let twist = if f.determinant() < 0.0 {
                sorted[1] - sorted[0]
            } else {
                sorted[1] + sorted[0]
            };
            let bound = 2.0 * BUDGET * f.norm() * 2.0 / twist.max(1e-300);
            assert!(
                (ours - theirs).norm() <= bound,
                "F = {f:?}: differ by {:e}, bound {bound:e}",
                (ours - theirs).norm()
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, max_shrink_iters: 2000, ..ProptestConfig::default() })]

        #[test]
        fn random_entries(entries in prop::array::uniform9(-10.0..10.0f64)) {
            assert_signed_svd(&Matrix3::from_iterator(entries));
        }

        #[test]
        fn structured(f in structured_matrix()) {
            assert_signed_svd(&f);
        }

        #[test]
        fn near_rotations(axis in prop::array::uniform3(-1.0..1.0f64), angle in -3.2..3.2f64,
                          strain in prop::array::uniform9(-1e-3..1e-3f64)) {
            // The local step's common case: F = R (I + small strain).
            let f = rotation(axis, angle) * (Matrix3::identity() + Matrix3::from_iterator(strain));
            assert_signed_svd(&f);
        }
    }
}
