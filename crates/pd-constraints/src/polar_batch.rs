//! Closest rotations four at a time: the scaled Newton polar iteration of
//! [`crate::polar`] on structure-of-arrays lanes, one matrix per lane, run
//! with the widest instruction set the CPU offers (`pulp` dispatches at run
//! time: AVX2 + FMA on x86-64-v3, otherwise the baseline).
//!
//! Every lane performs exactly the floating-point operations of the scalar
//! iteration, in the same order (no fused multiply-add: Rust never contracts
//! `a * b + c`), so a lane's result is bit-identical to
//! [`closest_rotation`] of its matrix. The lanes run in lock step: a lane
//! that has converged keeps its iterate (a per-lane select, not a branch)
//! while the others go on. A lane that Newton declines (inverted, flat or
//! strongly stretched matrix, or no convergence) is recomputed by the scalar
//! [`closest_rotation`], whose signed SVD handles it.

use nalgebra::Matrix3;

use crate::polar::{
    CONVERGED_CHANGE_SQUARED, MAX_ITERATIONS, MIN_SHAPE, SCALE_WHILE_CHANGE_SQUARED,
    closest_rotation,
};
use crate::signed_svd::rescaling;

/// Matrices per batch: four f64 lanes fill one 256-bit register.
pub const LANES: usize = 4;

/// One value per lane.
type Lanes = [f64; LANES];

/// One 3 x 3 matrix per lane; entry `(r, c)` at index `3 c + r`
/// (column-major, as nalgebra stores it).
type Batch = [Lanes; 9];

/// The proper rotations closest to each of `f`, bit-identical to
/// [`closest_rotation`] applied to each.
///
/// ```
/// use nalgebra::{Matrix3, Rotation3, Vector3};
/// use pd_constraints::polar::closest_rotation;
/// use pd_constraints::polar_batch::closest_rotations;
///
/// let r = Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
/// let f = [
///     r,
///     r * Matrix3::from_diagonal(&Vector3::new(1.2, 0.9, 1.05)),
///     Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)), // inverted
///     Matrix3::zeros(),
/// ];
/// let batch = closest_rotations(&f);
/// for (one, f) in batch.iter().zip(&f) {
///     assert_eq!(*one, closest_rotation(f));
/// }
/// ```
pub fn closest_rotations(f: &[Matrix3<f64>; LANES]) -> [Matrix3<f64>; LANES] {
    pulp::Arch::new().dispatch(
        #[inline(always)]
        || closest_rotations_inline(f),
    )
}

/// [`closest_rotations`] without the dispatch, for callers that dispatch
/// once around a loop of batches.
#[inline(always)]
pub(crate) fn closest_rotations_inline(f: &[Matrix3<f64>; LANES]) -> [Matrix3<f64>; LANES] {
    let (x, converged) = newton_polar_lanes(f);
    std::array::from_fn(|l| {
        if converged[l] {
            Matrix3::from_fn(|r, c| x[3 * c + r][l])
        } else {
            closest_rotation(&f[l])
        }
    })
}

#[inline(always)]
fn lanewise(op: impl Fn(usize) -> f64) -> Lanes {
    std::array::from_fn(op)
}

/// `|X|_F^2` as nalgebra sums it: per column `(a a + b b) + c c`, columns
/// added in order onto 0.
#[inline(always)]
fn norm_squared(x: &Batch) -> Lanes {
    lanewise(|l| {
        let column = |c: usize| {
            let (a, b, d) = (x[3 * c][l], x[3 * c + 1][l], x[3 * c + 2][l]);
            a * a + b * b + d * d
        };
        let mut sum = 0.0;
        sum += column(0);
        sum += column(1);
        sum += column(2);
        sum
    })
}

/// The cofactor matrix `det(X) X^-T`, each entry computed as
/// `polar::cofactor` does (products commute exactly in IEEE arithmetic).
#[inline(always)]
fn cofactor(x: &Batch) -> Batch {
    let at = |r: usize, c: usize| &x[3 * (c % 3) + r % 3];
    std::array::from_fn(|index| {
        let (r, c) = (index % 3, index / 3);
        let (a, b) = (at(r + 1, c + 1), at(r + 2, c + 2));
        let (d, e) = (at(r + 1, c + 2), at(r + 2, c + 1));
        lanewise(|l| a[l] * b[l] - d[l] * e[l])
    })
}

/// Laplace expansion along the first column.
#[inline(always)]
fn determinant(x: &Batch, cof: &Batch) -> Lanes {
    lanewise(|l| x[0][l] * cof[0][l] + x[1][l] * cof[1][l] + x[2][l] * cof[2][l])
}

/// Higham's scale `(|cof X|_F / (det X |X|_F))^(1/2)` (`polar`).
#[inline(always)]
fn frobenius_scale(x: &Batch, cof: &Batch, det: &Lanes) -> Lanes {
    let (x2, c2) = (norm_squared(x), norm_squared(cof));
    lanewise(|l| (c2[l].sqrt() / (det[l] * x2[l].sqrt())).sqrt())
}

/// The scaled Newton polar iteration on every lane: the final iterates and
/// whether each lane converged (`polar::newton_polar` answered `Some`).
#[inline(always)]
fn newton_polar_lanes(f: &[Matrix3<f64>; LANES]) -> (Batch, [bool; LANES]) {
    let scaled: [Matrix3<f64>; LANES] = std::array::from_fn(|l| f[l] * rescaling(f[l].amax()));
    let mut x: Batch = std::array::from_fn(|i| lanewise(|l| scaled[l][i]));
    let norm = lanewise(|l| norm_squared(&x)[l].sqrt());
    let mut cof = cofactor(&x);
    let mut det = determinant(&x, &cof);
    // Also rejects NaN.
    let mut running: [bool; LANES] =
        std::array::from_fn(|l| det[l] > MIN_SHAPE * norm[l] * norm[l] * norm[l]);
    let mut converged = [false; LANES];
    let mut scale = frobenius_scale(&x, &cof, &det);
    for _ in 0..MAX_ITERATIONS {
        if !running.contains(&true) {
            break;
        }
        let (a, b) = (
            lanewise(|l| 0.5 * scale[l]),
            lanewise(|l| 0.5 / (scale[l] * det[l])),
        );
        let next: Batch = std::array::from_fn(|i| lanewise(|l| x[i][l] * a[l] + cof[i][l] * b[l]));
        let step: Batch = std::array::from_fn(|i| lanewise(|l| next[i][l] - x[i][l]));
        let change = norm_squared(&step);
        for i in 0..9 {
            x[i] = lanewise(|l| if running[l] { next[i][l] } else { x[i][l] });
        }
        for l in 0..LANES {
            let done = running[l] && change[l] < CONVERGED_CHANGE_SQUARED;
            converged[l] |= done;
            running[l] &= !done;
        }
        cof = cofactor(&x);
        det = determinant(&x, &cof);
        let rescaled = frobenius_scale(&x, &cof, &det);
        for l in 0..LANES {
            running[l] &= det[l] > 0.0;
            scale[l] = if change[l] > SCALE_WHILE_CHANGE_SQUARED {
                rescaled[l]
            } else {
                1.0
            };
        }
    }
    (x, converged)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use proptest::prelude::*;

    use super::*;
    use crate::signed_svd::test_support::{assert_closest_rotation, rotation, structured_matrix};

    /// Bit-identical to the scalar projection, and (through it) optimal.
    fn assert_matches_scalar(f: [Matrix3<f64>; LANES]) {
        let batch = closest_rotations(&f);
        for (r, f) in batch.iter().zip(&f) {
            let scalar = closest_rotation(f);
            assert!(
                r.iter()
                    .zip(scalar.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "F = {f}: batch {r} vs scalar {scalar}"
            );
            if f.iter().all(|v| v.is_finite()) {
                assert_closest_rotation(f, r);
            }
        }
    }

    #[test]
    fn mixed_batches_match_the_scalar_projection() {
        let r = rotation([0.3, -1.0, 0.7], 2.1);
        let diag = |a: f64, b: f64, c: f64| Matrix3::from_diagonal(&Vector3::new(a, b, c));
        let cases = [
            r,
            r * diag(1.001, 0.999, 1.0),
            r * diag(1.5, 0.8, 1.1),
            r * diag(10.0, 1.0, 0.5),
            r * diag(1.0, 1.0, -1.0),
            r * diag(2.0, 0.5, -0.1),
            r * diag(1.0, 1.0, 1e-6),
            r * diag(1.0, 0.0, 0.0),
            Matrix3::zeros(),
            -Matrix3::identity(),
            r * 1e-200,
            r * 1e200,
            r * diag(60.0, 1.0, 1.0),
            Matrix3::from_element(f64::NAN),
            Matrix3::from_element(f64::INFINITY),
            Matrix3::new(0.3, -1.2, 0.5, 2.0, 0.1, -0.7, -0.4, 0.9, 0.2),
        ];
        // Every case in every lane position, next to every kind of neighbour.
        for shift in 0..cases.len() {
            for start in (0..cases.len()).step_by(LANES) {
                assert_matches_scalar(std::array::from_fn(|l| {
                    cases[(start + l + shift) % cases.len()]
                }));
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 500, max_shrink_iters: 500, ..ProptestConfig::default() })]

        #[test]
        fn structured_batches_match(f in prop::array::uniform4(structured_matrix())) {
            assert_matches_scalar(f);
        }

        #[test]
        fn random_batches_match(entries in prop::array::uniform4(prop::array::uniform9(-10.0..10.0f64))) {
            assert_matches_scalar(entries.map(Matrix3::from_iterator));
        }

        #[test]
        fn near_rotation_batches_match(axis in prop::array::uniform3(-1.0..1.0f64),
                                       angles in prop::array::uniform4(-3.2..3.2f64),
                                       strain in prop::array::uniform9(-0.01..0.01f64),
                                       log_scale in -300.0..300.0f64) {
            let f = angles.map(|angle| {
                rotation(axis, angle) * (Matrix3::identity() + Matrix3::from_iterator(strain))
                    * 10f64.powf(log_scale)
            });
            assert_matches_scalar(f);
        }
    }
}
