//! [`TetStrain`]'s lanes for the batched loop of [`crate::lane_rows`]: as
//! many elements at a time as the CPU has f64 lanes (8 with AVX-512, 4 with
//! AVX2), from the positions straight into the SIMD lanes and back.
//!
//! Per batch: gather the deformation gradients into structure-of-arrays
//! lanes (`F = G q` with lane-wide products and sums, in the order of
//! `apply_operator`, so each lane's `F` is bit-identical to the scalar one),
//! run the lane polar iteration of [`crate::polar_batch`], and write each
//! converged lane's rotation into its three output rows; a lane that Newton
//! declined is projected by the scalar [`closest_rotation`]. Everything is
//! `inline(always)` below the loop's `WithLanes::run`, so it is compiled inside the
//! dispatcher's `#[target_feature]` function: no closure the compiler could
//! keep out of line (std's `array::from_fn` did) sits on the hot path.

use pd_mesh::Point;

use super::TetStrain;
use crate::lane_rows::LaneKind;
use crate::polar::closest_rotation;
use crate::polar_batch::lane_sets::Lanes;
use crate::polar_batch::{Batch, batch_values, lane_matrix, newton_polar_lanes};

impl LaneKind<9> for TetStrain {
    #[inline(always)]
    fn one_at_a_time(&self) -> bool {
        self.has_limits()
    }

    #[inline(always)]
    fn gradients<S: Lanes>(s: S, batch: &[Self], q: &[Point]) -> Batch<S> {
        gradients(s, batch, q)
    }

    #[inline(always)]
    fn project_lanes<S: Lanes>(s: S, _: &[Self], f: &Batch<S>) -> (Batch<S>, u32) {
        newton_polar_lanes(s, f)
    }

    #[inline(always)]
    fn scatter<S: Lanes>(
        s: S,
        _: &[Self],
        x: &Batch<S>,
        converged: u32,
        f: &Batch<S>,
        rows: &mut [Point],
    ) {
        scatter(s, x, converged, f, rows);
    }
}

/// The deformation gradients of a batch of elements, one per lane: entry
/// `(r, c)` of lane `l` is `sum_k q[v_k][r] G[c][k]` of element `l`, summed
/// from 0 in the order `k = 0..4` exactly as `apply_operator` does (no fused
/// multiply-add), so every lane is bit-identical to the scalar `F`.
#[inline(always)]
fn gradients<S: Lanes>(s: S, elements: &[TetStrain], q: &[Point]) -> Batch<S> {
    let zero = s.splat(0.0);
    let operator = operator_lanes(s, elements);
    // Vertex by vertex: each entry still sums its terms in the order
    // `k = 0..4`, and only one vertex's three position lanes are live.
    let mut f = [zero; 9];
    for k in 0..4 {
        let positions: [S::F; 3] = s.transpose(elements, |e| q[e.vertices[k] as usize].as_slice());
        for (r, p) in positions.into_iter().enumerate() {
            for (column, g) in operator.iter().enumerate() {
                let acc = &mut f[3 * column + r];
                *acc = s.add(*acc, s.mul(p, g[k]));
            }
        }
    }
    f
}

/// The operator `G` of a batch of elements in lanes: entry `[c][k]` holds
/// `G[c][k]` of each element. The stored `B^T` entries (`G[c][1..4]`) are
/// moved in lane by lane (building them from 128-bit pairs and shuffles
/// instead ran more instructions: LLVM turned the shuffles into broadcasts
/// and blends); the first column is recomputed
/// per lane exactly as [`first_entry`](super::first_entry) sums it (the
/// fold of `Iterator::sum` from its start value, then the sign flipped), so
/// every lane holds the scalar `operator(c, k)` to the bit.
#[inline(always)]
fn operator_lanes<S: Lanes>(s: S, elements: &[TetStrain]) -> [[S::F; 4]; 3] {
    let lanes: [S::F; 9] = s.transpose(elements, |e| e.inverse_t.as_flattened());
    // `Iterator::sum`'s start value (the fold's first operand).
    let start = s.splat(std::iter::empty::<f64>().sum());
    let mut g = [[s.splat(0.0); 4]; 3];
    for (row, g) in g.iter_mut().enumerate() {
        let [b0, b1, b2] = [lanes[3 * row], lanes[3 * row + 1], lanes[3 * row + 2]];
        let sum = s.add(s.add(s.add(start, b0), b1), b2);
        *g = [s.neg(sum), b0, b1, b2];
    }
    g
}

/// Writes lane `l`'s projection into rows `3 l..3 l + 3` of `rows`: the
/// columns of the converged iterate `x`, or of the scalar
/// [`closest_rotation`] of the lane's `F` where Newton declined it.
/// (Recomputing a declined element's `F` from `q` instead, so that the
/// lanes of `F` need not outlive the Newton loop, ran more instructions.)
#[inline(always)]
fn scatter<S: Lanes>(s: S, x: &Batch<S>, converged: u32, f: &Batch<S>, rows: &mut [Point]) {
    let values = batch_values(s, x);
    for (l, rows) in rows.chunks_exact_mut(3).enumerate().take(S::WIDTH) {
        if converged >> l & 1 == 1 {
            for (c, row) in rows.iter_mut().enumerate() {
                *row = Point::new(
                    values[3 * c].as_ref()[l],
                    values[3 * c + 1].as_ref()[l],
                    values[3 * c + 2].as_ref()[l],
                );
            }
        } else {
            let target = closest_rotation(&lane_matrix::<S>(&batch_values(s, f), l));
            for (c, row) in rows.iter_mut().enumerate() {
                *row = target.column(c).into_owned();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix3;
    use proptest::prelude::*;

    use super::*;
    use crate::lane_rows::test_support::assert_all_bit_identical;

    /// Elements over a random cloud of 8 points: each takes 4 distinct
    /// points, the rest shape (the cloud's rest positions) decides which
    /// combinations are valid; positions are the rest ones mapped by a
    /// per-vertex perturbation of `a`, so elements range from near-rotations
    /// to inverted and flat ones, at any scale.
    fn elements_and_positions(
        rest: &[[f64; 3]; 8],
        a: [f64; 9],
        noise: &[[f64; 3]; 8],
        log_scale: f64,
        limited: usize,
    ) -> (Vec<TetStrain>, Vec<Point>) {
        let rest: Vec<Point> = rest.iter().map(|p| Point::from(*p)).collect();
        let mut constraints = Vec::new();
        for (i, tet) in [
            [0, 1, 2, 3],
            [4, 5, 6, 7],
            [0, 2, 4, 6],
            [1, 3, 5, 7],
            [0, 1, 4, 5],
            [2, 3, 6, 7],
            [0, 3, 5, 6],
            [1, 2, 4, 7],
            [0, 1, 6, 7],
            [2, 3, 4, 5],
            [0, 4, 1, 5],
        ]
        .into_iter()
        .enumerate()
        {
            // Either orientation of the rest shape is valid.
            let [a0, a1, a2, a3] = tet;
            let limits = (i == limited).then_some((0.9, 1.1));
            let c = TetStrain::new(&rest, tet, 1e5, limits)
                .or_else(|_| TetStrain::new(&rest, [a0, a2, a1, a3], 1e5, limits));
            if let Ok(c) = c {
                constraints.push(c);
            }
        }
        let map = Matrix3::from_iterator(a);
        let scale = 10f64.powf(log_scale);
        let q = rest
            .iter()
            .zip(noise)
            .map(|(x, n)| (map * x + Point::from(*n)) * scale)
            .collect();
        (constraints, q)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, max_shrink_iters: 300, ..ProptestConfig::default() })]

        /// Random elements, from near-rotations (small `a - I`, small noise)
        /// to inverted and flat ones, at scales 1e-250 to 1e250, with one
        /// strain-limited element at a random place (or none, so that
        /// whole batches of 8 take the lanes) and a remainder.
        #[test]
        fn gathered_batches_are_bit_identical(
            rest in prop::array::uniform8(prop::array::uniform3(-1.0..1.0f64)),
            strain in prop::array::uniform9(-1.0..1.0f64),
            strain_size in prop::sample::select(vec![0.0, 1e-3, 0.1, 1.0, 3.0]),
            noise in prop::array::uniform8(prop::array::uniform3(-0.05..0.05f64)),
            noise_size in prop::sample::select(vec![0.0, 1e-4, 1.0, 10.0]),
            log_scale in prop::sample::select(vec![-250.0, -3.0, 0.0, 2.5, 250.0]),
            limited in 0usize..22,
        ) {
            let a = std::array::from_fn(|i| {
                f64::from(u8::from(i % 4 == 0)) + strain[i] * strain_size
            });
            let noise = noise.map(|n| n.map(|v| v * noise_size));
            let (constraints, q) = elements_and_positions(&rest, a, &noise, log_scale, limited);
            assert_all_bit_identical(&constraints, &q);
        }
    }

    #[test]
    fn non_finite_positions_match_too() {
        let rest = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 0.0],
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 1.0],
        ];
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (constraints, mut q) =
                elements_and_positions(&rest, identity, &[[0.0; 3]; 8], 0.0, 99);
            assert!(constraints.len() >= 8, "{} elements", constraints.len());
            q[5].y = bad;
            assert_all_bit_identical(&constraints, &q);
        }
    }
}
