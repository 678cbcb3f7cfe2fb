//! Closest rotations several at a time: the scaled Newton polar iteration
//! of [`crate::polar`] on structure-of-arrays lanes, one matrix per lane,
//! run with the widest instruction set the CPU offers (detected at run time:
//! 8 lanes with AVX-512, 4 with AVX2, otherwise one matrix at a time; see
//! the private module `lane_sets`).
//!
//! Every lane performs exactly the floating-point operations of the scalar
//! iteration, in the same order (no fused multiply-add: Rust never contracts
//! `a * b + c`), so a lane's result is bit-identical to
//! [`closest_rotation`] of its matrix, at any width. The lanes run in lock
//! step: a lane that has converged keeps its iterate (a per-lane select, not
//! a branch) while the others go on. A lane that Newton declines (inverted,
//! flat or strongly stretched matrix, or no convergence) is recomputed by
//! the scalar [`closest_rotation`], whose signed SVD handles it.

use nalgebra::Matrix3;

use crate::polar::closest_rotation;

#[cfg(target_arch = "x86_64")]
pub(crate) mod lane_sets;

#[cfg(target_arch = "x86_64")]
use lane_sets::{Lanes, WithLanes, vectorize};

/// Writes into `out` the proper rotation closest to each of `f`,
/// bit-identical to [`closest_rotation`] applied to each.
///
/// # Panics
/// If `out` is shorter than `f`.
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
/// let mut batch = [Matrix3::zeros(); 4];
/// closest_rotations(&f, &mut batch);
/// for (one, f) in batch.iter().zip(&f) {
///     assert_eq!(*one, closest_rotation(f));
/// }
/// ```
pub fn closest_rotations(f: &[Matrix3<f64>], out: &mut [Matrix3<f64>]) {
    let out = &mut out[..f.len()];
    #[cfg(target_arch = "x86_64")]
    {
        struct Op<'a>(&'a [Matrix3<f64>], &'a mut [Matrix3<f64>]);
        impl WithLanes for Op<'_> {
            type Output = ();
            #[inline(always)]
            fn run<S: Lanes>(self, s: S) {
                let Op(f, out) = self;
                let mut outs = out.chunks_exact_mut(S::WIDTH);
                for (f, out) in f.chunks_exact(S::WIDTH).zip(&mut outs) {
                    let mut batch = [s.splat(0.0); 9];
                    for (i, lane) in batch.iter_mut().enumerate() {
                        let mut v = S::Values::default();
                        for (v, f) in v.as_mut().iter_mut().zip(f) {
                            *v = f[i];
                        }
                        *lane = s.pack(v);
                    }
                    let (x, converged) = newton_polar_lanes(s, &batch);
                    let x = batch_values(s, &x);
                    for (l, (out, f)) in out.iter_mut().zip(f).enumerate() {
                        *out = if converged >> l & 1 == 1 {
                            lane_matrix::<S>(&x, l)
                        } else {
                            closest_rotation(f)
                        };
                    }
                }
                let rest = f.len() / S::WIDTH * S::WIDTH;
                for (out, f) in outs.into_remainder().iter_mut().zip(&f[rest..]) {
                    *out = closest_rotation(f);
                }
            }
        }
        if vectorize(Op(f, &mut *out)).is_some() {
            return;
        }
    }
    for (out, f) in out.iter_mut().zip(f) {
        *out = closest_rotation(f);
    }
}

/// One 3 x 3 matrix per lane; entry `(r, c)` at index `3 c + r`
/// (column-major, as nalgebra stores it).
#[cfg(target_arch = "x86_64")]
pub(crate) type Batch<S> = [<S as Lanes>::F; 9];

/// The lanes of a batch as arrays, for [`lane_matrix`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn batch_values<S: Lanes>(s: S, batch: &Batch<S>) -> [S::Values; 9] {
    let mut values = [S::Values::default(); 9];
    for (v, x) in values.iter_mut().zip(batch) {
        *v = s.values(*x);
    }
    values
}

/// Lane `l` of a batch (its [`batch_values`]) as a matrix. A plain loop:
/// `Matrix3::from_fn`'s closure may be compiled out of line, outside the
/// SIMD function.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn lane_matrix<S: Lanes>(values: &[S::Values; 9], l: usize) -> Matrix3<f64> {
    let mut m = Matrix3::zeros();
    for (m, v) in m.iter_mut().zip(values) {
        *m = v.as_ref()[l];
    }
    m
}

/// The scaled Newton polar iteration of `polar::newton_polar` on every lane
/// of `f`: the final iterates and whether each lane converged (bit `l` for
/// lane `l`). A converged lane's iterate is bit-identical to
/// [`closest_rotation`] of its matrix; a lane that did not converge (Newton
/// declined it) must be recomputed by [`closest_rotation`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn newton_polar_lanes<S: Lanes>(s: S, f: &Batch<S>) -> (Batch<S>, u32) {
    lanes::newton_polar(s, f)
}

#[cfg(target_arch = "x86_64")]
mod lanes {
    use super::Batch;
    use super::lane_sets::Lanes;
    use crate::polar::{
        CONVERGED_CHANGE_SQUARED, MAX_ITERATIONS, MIN_SHAPE, SCALE_WHILE_CHANGE_SQUARED,
    };
    use crate::signed_svd::{HUGE, TINY, rescaling};

    /// `|X|_F^2` as nalgebra sums it: per column `(a a + b b) + c c`,
    /// columns added in order onto 0.
    #[inline(always)]
    fn norm_squared<S: Lanes>(s: S, x: &Batch<S>) -> S::F {
        let mut sum = s.splat(0.0);
        for c in 0..3 {
            let (a, b, d) = (x[3 * c], x[3 * c + 1], x[3 * c + 2]);
            let column = s.add(s.add(s.mul(a, a), s.mul(b, b)), s.mul(d, d));
            sum = s.add(sum, column);
        }
        sum
    }

    /// The cofactor matrix `det(X) X^-T`, each entry computed as
    /// `polar::cofactor` does (products commute exactly in IEEE arithmetic).
    /// Written out entry by entry: `array::from_fn` with a closure was
    /// compiled out of line, outside the SIMD function.
    #[inline(always)]
    fn cofactor<S: Lanes>(s: S, x: &Batch<S>) -> Batch<S> {
        let at = |r: usize, c: usize| x[3 * (c % 3) + r % 3];
        let entry = |r: usize, c: usize| {
            s.sub(
                s.mul(at(r + 1, c + 1), at(r + 2, c + 2)),
                s.mul(at(r + 1, c + 2), at(r + 2, c + 1)),
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
    fn first_cofactor_column<S: Lanes>(s: S, x: &Batch<S>) -> [S::F; 3] {
        let at = |r: usize, c: usize| x[3 * (c % 3) + r % 3];
        let entry = |r: usize| {
            s.sub(
                s.mul(at(r + 1, 1), at(r + 2, 2)),
                s.mul(at(r + 1, 2), at(r + 2, 1)),
            )
        };
        [entry(0), entry(1), entry(2)]
    }

    /// Laplace expansion along the first column (`cof` holds at least the
    /// cofactors' first column).
    #[inline(always)]
    fn determinant<S: Lanes>(s: S, x: &Batch<S>, cof: &[S::F]) -> S::F {
        s.add(
            s.add(s.mul(x[0], cof[0]), s.mul(x[1], cof[1])),
            s.mul(x[2], cof[2]),
        )
    }

    /// Higham's scale `(|cof X|_F / (det X |X|_F))^(1/2)` (`polar`).
    #[inline(always)]
    fn frobenius_scale<S: Lanes>(s: S, x: &Batch<S>, cof: &Batch<S>, det: S::F) -> S::F {
        let x_norm = s.sqrt(norm_squared(s, x));
        let cof_norm = s.sqrt(norm_squared(s, cof));
        s.sqrt(s.div(cof_norm, s.mul(det, x_norm)))
    }

    /// The scaled Newton polar iteration of `polar::newton_polar` on every
    /// lane: the final iterates and which lanes converged (the scalar
    /// iteration answered `Some`, with bit-identical values).
    #[inline(always)]
    pub(super) fn newton_polar<S: Lanes>(s: S, f: &Batch<S>) -> (Batch<S>, u32) {
        let all = (1u32 << S::WIDTH) - 1;
        let mut x = *f;
        // `rescaling(f.amax())` per lane. The largest |entry| is the same in
        // any order; NaN entries may give another value than nalgebra's
        // fold, but such a lane's determinant is NaN, Newton declines it and
        // the scalar path recomputes it. Scaling by 1 is exact, so the
        // common case (every lane within range) skips the product.
        let mut largest = s.splat(0.0);
        for v in f {
            largest = s.max(largest, s.abs(*v));
        }
        let in_range = s.and(s.ge(largest, s.splat(TINY)), s.le(largest, s.splat(HUGE)));
        if s.bits(in_range) != all {
            let mut scale = s.values(largest);
            for v in scale.as_mut() {
                *v = rescaling(*v);
            }
            let scale = s.pack(scale);
            for v in &mut x {
                *v = s.mul(*v, scale);
            }
        }
        let norm = s.sqrt(norm_squared(s, &x));
        let mut cof = cofactor(s, &x);
        let mut det = determinant(s, &x, &cof);
        // `det > MIN_SHAPE |X|^3`, evaluated left to right; also rejects NaN
        // (an ordered comparison).
        let shape = s.mul(s.mul(s.mul(s.splat(MIN_SHAPE), norm), norm), norm);
        let mut running = s.gt(det, shape);
        let mut converged = s.none();
        let mut scale = frobenius_scale(s, &x, &cof, det);
        let (half, one) = (s.splat(0.5), s.splat(1.0));
        // Only `x`, `det` and `scale` are carried from one iteration to the
        // next: the cofactors are recomputed from `x` where they are used
        // (the same products, so the same bits). Carrying all nine as well
        // left too few of AVX2's sixteen registers, and the spills cost more
        // than the three cofactor entries computed twice; with AVX-512's 32
        // registers carrying them measured the same as not (see
        // docs/design/performance.md), so both widths share this code.
        for iteration in 0..MAX_ITERATIONS {
            if s.bits(running) == 0 {
                break;
            }
            if iteration > 0 {
                cof = cofactor(s, &x);
            }
            let a = s.mul(half, scale);
            let b = s.div(half, s.mul(scale, det));
            // `|next - x|^2` column by column as `norm_squared` sums it.
            let mut change = s.splat(0.0);
            for c in 0..3 {
                let mut column = s.splat(0.0);
                for i in 3 * c..3 * c + 3 {
                    let next = s.add(s.mul(x[i], a), s.mul(cof[i], b));
                    let step = s.sub(next, x[i]);
                    let square = s.mul(step, step);
                    // `(a a + b b) + c c`: the first term is not added to 0.
                    column = if i == 3 * c {
                        square
                    } else {
                        s.add(column, square)
                    };
                    // A converged or declined lane keeps its iterate.
                    x[i] = s.select(running, next, x[i]);
                }
                change = s.add(change, column);
            }
            let done = s.and(running, s.lt(change, s.splat(CONVERGED_CHANGE_SQUARED)));
            converged = s.or(converged, done);
            running = s.and_not(running, done);
            det = determinant(s, &x, &first_cofactor_column(s, &x));
            running = s.and(running, s.gt(det, s.splat(0.0)));
            let far = s.gt(change, s.splat(SCALE_WHILE_CHANGE_SQUARED));
            // Near convergence (the last two or three iterations of a
            // well-shaped element) no lane rescales: skip the three square
            // roots and the division rather than select them away.
            scale = if s.bits(far) != 0 {
                let cof = cofactor(s, &x);
                s.select(far, frobenius_scale(s, &x, &cof, det), one)
            } else {
                one
            };
        }
        (x, s.bits(converged))
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use proptest::prelude::*;

    use super::*;
    use crate::signed_svd::test_support::{assert_closest_rotation, rotation, structured_matrix};

    /// Bit-identical to the scalar projection, and (through it) optimal,
    /// with the lanes of every SIMD width this CPU has.
    fn assert_matches_scalar(f: &[Matrix3<f64>]) {
        #[cfg(target_arch = "x86_64")]
        pd_linalg::simd::for_each_simd_width(|_| assert_matches_scalar_once(f));
        assert_matches_scalar_once(f);
    }

    fn assert_matches_scalar_once(f: &[Matrix3<f64>]) {
        let mut batch = vec![Matrix3::zeros(); f.len()];
        closest_rotations(f, &mut batch);
        for (r, f) in batch.iter().zip(f) {
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
        // Every case in every lane position of 4 and 8 lanes, next to every
        // kind of neighbour.
        for shift in 0..cases.len() {
            let batch: Vec<_> = (0..cases.len())
                .map(|l| cases[(l + shift) % cases.len()])
                .collect();
            assert_matches_scalar(&batch);
            // And a remainder that the scalar path projects.
            assert_matches_scalar(&batch[..cases.len() - 3]);
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
                    let ordinary = [r, r * diag(1.2, 0.9, 1.0), -r, r * 1e-3];
                    for lane in 0..8 {
                        let mut batch = [ordinary, ordinary].concat();
                        batch[lane] = f;
                        assert_matches_scalar(&batch);
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 500, max_shrink_iters: 500, ..ProptestConfig::default() })]

        #[test]
        fn structured_batches_match(f in prop::array::uniform8(structured_matrix())) {
            assert_matches_scalar(&f);
        }

        #[test]
        fn random_batches_match(entries in prop::array::uniform8(prop::array::uniform9(-10.0..10.0f64))) {
            assert_matches_scalar(&entries.map(Matrix3::from_iterator));
        }

        #[test]
        fn near_rotation_batches_match(axis in prop::array::uniform3(-1.0..1.0f64),
                                       angles in prop::array::uniform8(-3.2..3.2f64),
                                       strain in prop::array::uniform9(-0.01..0.01f64),
                                       log_scale in -300.0..300.0f64) {
            let f = angles.map(|angle| {
                rotation(axis, angle) * (Matrix3::identity() + Matrix3::from_iterator(strain))
                    * 10f64.powf(log_scale)
            });
            assert_matches_scalar(&f);
        }
    }
}
