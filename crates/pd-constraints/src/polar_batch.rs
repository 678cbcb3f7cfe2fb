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

use crate::polar::closest_rotation;

/// Matrices per batch: four f64 lanes fill one 256-bit register.
pub const LANES: usize = 4;

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
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = Simd::try_new() {
        struct Op<'a>(Simd, &'a [Matrix3<f64>; LANES]);
        impl pulp::WithSimd for Op<'_> {
            type Output = [Matrix3<f64>; LANES];
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, _: S) -> Self::Output {
                closest_rotations_inline(self.0, self.1)
            }
        }
        return pulp::Simd::vectorize(simd, Op(simd, f));
    }
    f.map(|f| closest_rotation(&f))
}

/// The 4-lane f64 instruction set the batched path needs (AVX2 on x86-64;
/// `None` elsewhere or on older CPUs, where callers project one at a time).
#[cfg(target_arch = "x86_64")]
pub(crate) type Simd = pulp::x86::V3;

/// One 3 x 3 matrix per lane; entry `(r, c)` at index `3 c + r`
/// (column-major, as nalgebra stores it).
#[cfg(target_arch = "x86_64")]
pub(crate) type Batch = [pulp::f64x4; 9];

/// The values of the four lanes of `v`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn lanes_of(v: pulp::f64x4) -> [f64; LANES] {
    [v.0, v.1, v.2, v.3]
}

/// Lane `l` of `batch` as a matrix.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn lane_matrix(batch: &Batch, l: usize) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| lanes_of(batch[3 * c + r])[l])
}

/// [`closest_rotations`] without the dispatch, for callers that dispatch
/// once around a loop of batches (`simd.vectorize`). Everything here is
/// `inline(always)` so that it is compiled inside the dispatcher's
/// `#[target_feature]` function.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn closest_rotations_inline(
    simd: Simd,
    f: &[Matrix3<f64>; LANES],
) -> [Matrix3<f64>; LANES] {
    let batch: Batch = std::array::from_fn(|i| pulp::f64x4(f[0][i], f[1][i], f[2][i], f[3][i]));
    let (x, converged) = newton_polar_lanes(simd, &batch);
    std::array::from_fn(|l| {
        if converged[l] {
            lane_matrix(&x, l)
        } else {
            closest_rotation(&f[l])
        }
    })
}

/// The scaled Newton polar iteration of `polar::newton_polar` on every lane
/// of `f`: the final iterates and whether each lane converged. A converged
/// lane's iterate is bit-identical to [`closest_rotation`] of its matrix; a
/// lane that did not converge (Newton declined it) must be recomputed by
/// [`closest_rotation`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn newton_polar_lanes(simd: Simd, f: &Batch) -> (Batch, [bool; LANES]) {
    lanes::newton_polar(simd, f)
}

#[cfg(target_arch = "x86_64")]
mod lanes {
    use pulp::{f64x4, m64, m64x4};

    use super::{Batch, LANES, Simd, lanes_of};
    use crate::polar::{
        CONVERGED_CHANGE_SQUARED, MAX_ITERATIONS, MIN_SHAPE, SCALE_WHILE_CHANGE_SQUARED,
    };
    use crate::signed_svd::{HUGE, TINY, rescaling};

    /// `|X|_F^2` as nalgebra sums it: per column `(a a + b b) + c c`,
    /// columns added in order onto 0.
    #[inline(always)]
    fn norm_squared(s: Simd, x: &Batch) -> f64x4 {
        let mut sum = s.splat_f64x4(0.0);
        for c in 0..3 {
            let (a, b, d) = (x[3 * c], x[3 * c + 1], x[3 * c + 2]);
            let column = s.add_f64x4(
                s.add_f64x4(s.mul_f64x4(a, a), s.mul_f64x4(b, b)),
                s.mul_f64x4(d, d),
            );
            sum = s.add_f64x4(sum, column);
        }
        sum
    }

    /// The cofactor matrix `det(X) X^-T`, each entry computed as
    /// `polar::cofactor` does (products commute exactly in IEEE arithmetic).
    /// Written out entry by entry: `array::from_fn` with a closure was
    /// compiled out of line, outside the AVX2 function.
    #[inline(always)]
    fn cofactor(s: Simd, x: &Batch) -> Batch {
        let at = |r: usize, c: usize| x[3 * (c % 3) + r % 3];
        let entry = |r: usize, c: usize| {
            s.sub_f64x4(
                s.mul_f64x4(at(r + 1, c + 1), at(r + 2, c + 2)),
                s.mul_f64x4(at(r + 1, c + 2), at(r + 2, c + 1)),
            )
        };
        [
            entry(0, 0),
            entry(1, 0),
            entry(2, 0),
            entry(0, 1),
            entry(1, 1),
            entry(2, 1),
            entry(0, 2),
            entry(1, 2),
            entry(2, 2),
        ]
    }

    /// The first column of [`cofactor`] (entries `(0, 0)`, `(1, 0)`,
    /// `(2, 0)`, the same products), all that [`determinant`] reads.
    #[inline(always)]
    fn first_cofactor_column(s: Simd, x: &Batch) -> [f64x4; 3] {
        let at = |r: usize, c: usize| x[3 * (c % 3) + r % 3];
        let entry = |r: usize| {
            s.sub_f64x4(
                s.mul_f64x4(at(r + 1, 1), at(r + 2, 2)),
                s.mul_f64x4(at(r + 1, 2), at(r + 2, 1)),
            )
        };
        [entry(0), entry(1), entry(2)]
    }

    /// Laplace expansion along the first column (`cof` holds at least the
    /// cofactors' first column).
    #[inline(always)]
    fn determinant(s: Simd, x: &Batch, cof: &[f64x4]) -> f64x4 {
        s.add_f64x4(
            s.add_f64x4(s.mul_f64x4(x[0], cof[0]), s.mul_f64x4(x[1], cof[1])),
            s.mul_f64x4(x[2], cof[2]),
        )
    }

    /// Higham's scale `(|cof X|_F / (det X |X|_F))^(1/2)` (`polar`).
    #[inline(always)]
    fn frobenius_scale(s: Simd, x: &Batch, cof: &Batch, det: f64x4) -> f64x4 {
        let x_norm = s.sqrt_f64x4(norm_squared(s, x));
        let cof_norm = s.sqrt_f64x4(norm_squared(s, cof));
        s.sqrt_f64x4(s.div_f64x4(cof_norm, s.mul_f64x4(det, x_norm)))
    }

    #[inline(always)]
    fn mask_bits(mask: m64x4) -> [bool; LANES] {
        [
            mask.0.is_set(),
            mask.1.is_set(),
            mask.2.is_set(),
            mask.3.is_set(),
        ]
    }

    /// The scaled Newton polar iteration of `polar::newton_polar` on every
    /// lane: the final iterates and whether each lane converged (the scalar
    /// iteration answered `Some`, with bit-identical values).
    #[inline(always)]
    pub(super) fn newton_polar(s: Simd, f: &Batch) -> (Batch, [bool; LANES]) {
        let mut x = *f;
        // `rescaling(f.amax())` per lane. The largest |entry| is the same in
        // any order; NaN entries may give another value than nalgebra's
        // fold, but such a lane's determinant is NaN, Newton declines it and
        // the scalar path recomputes it. Scaling by 1 is exact, so the
        // common case (every lane within range) skips the product.
        let mut largest = s.splat_f64x4(0.0);
        for v in f {
            largest = pulp::Simd::max_f64s(s, largest, s.abs_f64x4(*v));
        }
        let in_range = s.and_m64x4(
            s.cmp_ge_f64x4(largest, s.splat_f64x4(TINY)),
            s.cmp_le_f64x4(largest, s.splat_f64x4(HUGE)),
        );
        if mask_bits(in_range).contains(&false) {
            let [a, b, c, d] = lanes_of(largest);
            let scale = f64x4(rescaling(a), rescaling(b), rescaling(c), rescaling(d));
            for v in &mut x {
                *v = s.mul_f64x4(*v, scale);
            }
        }
        let norm = s.sqrt_f64x4(norm_squared(s, &x));
        let mut cof = cofactor(s, &x);
        let mut det = determinant(s, &x, &cof);
        // `det > MIN_SHAPE |X|^3`, evaluated left to right; also rejects NaN
        // (an ordered comparison).
        let shape = s.mul_f64x4(
            s.mul_f64x4(s.mul_f64x4(s.splat_f64x4(MIN_SHAPE), norm), norm),
            norm,
        );
        let mut running = s.cmp_gt_f64x4(det, shape);
        let mut converged = s.splat_m64x4(m64::new(false));
        let mut scale = frobenius_scale(s, &x, &cof, det);
        let (half, one) = (s.splat_f64x4(0.5), s.splat_f64x4(1.0));
        // Only `x`, `det` and `scale` are carried from one iteration to the
        // next: the cofactors are recomputed from `x` where they are used
        // (the same products, so the same bits). Carrying all nine as well
        // left too few of the sixteen registers, and the spills cost more
        // than the three cofactor entries computed twice.
        for iteration in 0..MAX_ITERATIONS {
            if !mask_bits(running).contains(&true) {
                break;
            }
            if iteration > 0 {
                cof = cofactor(s, &x);
            }
            let a = s.mul_f64x4(half, scale);
            let b = s.div_f64x4(half, s.mul_f64x4(scale, det));
            // `|next - x|^2` column by column as `norm_squared` sums it.
            let mut change = s.splat_f64x4(0.0);
            for c in 0..3 {
                let mut column = s.splat_f64x4(0.0);
                for i in 3 * c..3 * c + 3 {
                    let next = s.add_f64x4(s.mul_f64x4(x[i], a), s.mul_f64x4(cof[i], b));
                    let step = s.sub_f64x4(next, x[i]);
                    let square = s.mul_f64x4(step, step);
                    // `(a a + b b) + c c`: the first term is not added to 0.
                    column = if i == 3 * c {
                        square
                    } else {
                        s.add_f64x4(column, square)
                    };
                    // A converged or declined lane keeps its iterate.
                    x[i] = s.select_f64x4(running, next, x[i]);
                }
                change = s.add_f64x4(change, column);
            }
            let done = s.and_m64x4(
                running,
                s.cmp_lt_f64x4(change, s.splat_f64x4(CONVERGED_CHANGE_SQUARED)),
            );
            converged = s.or_m64x4(converged, done);
            running = s.and_m64x4(running, s.not_m64x4(done));
            det = determinant(s, &x, &first_cofactor_column(s, &x));
            running = s.and_m64x4(running, s.cmp_gt_f64x4(det, s.splat_f64x4(0.0)));
            let far = s.cmp_gt_f64x4(change, s.splat_f64x4(SCALE_WHILE_CHANGE_SQUARED));
            // Near convergence (the last two or three iterations of a
            // well-shaped element) no lane rescales: skip the three square
            // roots and the division rather than select them away.
            scale = if mask_bits(far).contains(&true) {
                let cof = cofactor(s, &x);
                s.select_f64x4(far, frobenius_scale(s, &x, &cof, det), one)
            } else {
                one
            };
        }
        (x, mask_bits(converged))
    }
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

    /// Matrices whose largest entry sits at either end of the rescaling
    /// range `[TINY, HUGE]`, one lane at a time next to ordinary ones: the
    /// lanes decide "no rescaling" from `|F|^2` first, which must never let
    /// through a lane that the scalar path rescales (a largest entry just
    /// outside the range with `|F|^2` up to 9 times its square) nor change
    /// any other lane.
    #[test]
    fn lanes_at_the_rescaling_thresholds_match() {
        use crate::signed_svd::{HUGE, TINY};
        let r = rotation([0.3, -1.0, 0.7], 2.1);
        let diag = |a: f64, b: f64, c: f64| Matrix3::from_diagonal(&Vector3::new(a, b, c));
        let shapes = [
            Matrix3::identity(),
            r,
            r * diag(1.0, 0.9, 0.8),
            Matrix3::from_element(1.0),
            diag(1.0, 1e-3, 1e-3),
        ];
        let factors = [0.3, 1.0 / 3.0, 0.5, 0.999, 1.0, 1.001, 2.0, 3.0, 3.001, 5.0];
        for end in [TINY, HUGE] {
            for shape in shapes {
                for factor in factors {
                    let amax = shape.amax();
                    let f = shape * (end * factor / amax);
                    for lane in 0..LANES {
                        let mut batch = [r, r * diag(1.2, 0.9, 1.0), -r, r * 1e-3];
                        batch[lane] = f;
                        assert_matches_scalar(batch);
                    }
                }
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
