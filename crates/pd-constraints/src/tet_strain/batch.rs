//! [`TetStrain`]'s [`project_many`](crate::Constraint::project_many) as a
//! batched loop: as many elements at a time as the CPU has f64 lanes (8
//! with AVX-512, 4 with AVX2), from the positions straight into the SIMD
//! lanes and back.
//!
//! Per batch: gather the deformation gradients into structure-of-arrays
//! lanes (`F = G q` with lane-wide products and sums, in the order of
//! `apply_operator`, so each lane's `F` is bit-identical to the scalar one),
//! run the lane polar iteration of [`crate::polar_batch`], and write each
//! converged lane's rotation into its three output rows; a lane that Newton
//! declined is projected by the scalar [`closest_rotation`]. Everything is
//! `inline(always)` below a [`WithLanes::run`], so it is compiled inside the
//! dispatcher's `#[target_feature]` function: no closure the compiler could
//! keep out of line (std's `array::from_fn` did) sits on the hot path.

use pd_mesh::Point;

use super::{TetStrain, energies_one_by_one, project_one_by_one};
use crate::lane_rows::{batch_bytes, distances, gather_rows};
use crate::polar::closest_rotation;
use crate::polar_batch::lane_sets::{Lanes, WithLanes};
use crate::polar_batch::{Batch, batch_values, lane_matrix, newton_polar_lanes};

/// Batches ahead of the one projected whose elements are prefetched, and
/// whose output rows are prefetched for writing (docs/performance.md,
/// "Prefetching the next batches (issue 18, sixth round)": the elements
/// arrive from memory at 527,280 tets, and the hardware prefetcher alone
/// left the loop waiting).
const ELEMENTS_AHEAD: usize = 2;
const ROWS_AHEAD: usize = 1;

/// [`TetStrain`]'s [`project_many`](crate::Constraint::project_many) loop
/// as a lane operation.
/// With `ENERGIES`, each element's energy `w/2 |G q - p|^2` goes into
/// `energies` too (`project_many_with_energies`); without, `energies` is
/// empty and the loop is the plain projection's (compiled without it).
pub(super) struct ProjectBatched<'a, const ENERGIES: bool> {
    pub constraints: &'a [TetStrain],
    pub q: &'a [Point],
    pub out: &'a mut [Point],
    pub energies: &'a mut [f64],
}

impl<const ENERGIES: bool> WithLanes for ProjectBatched<'_, ENERGIES> {
    type Output = ();

    #[inline(always)]
    fn run<S: Lanes>(self, s: S) {
        let Self {
            constraints,
            q,
            out,
            energies,
        } = self;
        let batches = constraints.chunks_exact(S::WIDTH);
        let rest = batches.remainder();
        let (elements, rows_out) = (constraints.as_ptr(), out.as_ptr());
        let (n_elements, n_rows) = (constraints.len(), out.len());
        let mut out_batches = out.chunks_exact_mut(S::WIDTH * 3);
        let mut energy_batches = energies.chunks_exact_mut(S::WIDTH);
        for (b, (batch, rows)) in batches.zip(&mut out_batches).enumerate() {
            let ahead = b + ELEMENTS_AHEAD;
            s.prefetch::<false>(batch_bytes(elements, n_elements, ahead, S::WIDTH));
            let ahead = b + ROWS_AHEAD;
            s.prefetch::<true>(batch_bytes(rows_out, n_rows, ahead, 3 * S::WIDTH));
            if batch.iter().any(TetStrain::has_limits) {
                project_one_by_one(batch, q, rows);
                if ENERGIES && let Some(energy) = energy_batches.next() {
                    energies_one_by_one(batch, q, rows, energy);
                }
                continue;
            }
            let f = gradients(s, batch, q);
            let (x, converged) = newton_polar_lanes(s, &f);
            scatter(s, &x, converged, &f, rows);
            if ENERGIES && let Some(energy) = energy_batches.next() {
                lane_energies(s, batch, &f, &x, converged, rows, energy);
            }
        }
        let rows = out_batches.into_remainder();
        project_one_by_one(rest, q, rows);
        if ENERGIES {
            energies_one_by_one(rest, q, rows, energy_batches.into_remainder());
        }
    }
}

/// The energies `w/2 |F - P|^2` of a batch from its lanes of `F = G q` and
/// of the projection: the converged iterate `x`, or (when a lane was
/// projected by the scalar fallback) the rows just written. Summed as
/// [`distances`] does, bit-identical to the one-at-a-time energies.
#[inline(always)]
fn lane_energies<S: Lanes>(
    s: S,
    batch: &[TetStrain],
    f: &Batch<S>,
    x: &Batch<S>,
    converged: u32,
    rows: &[Point],
    out: &mut [f64],
) {
    let distance2 = if converged == (1 << S::WIDTH) - 1 {
        distances(s, f, x)
    } else {
        distances(s, f, &gather_rows(s, rows))
    };
    for ((e, c), d) in out.iter_mut().zip(batch).zip(distance2.as_ref()) {
        *e = 0.5 * c.weight * d;
    }
}

/// [`TetStrain`]'s [`energies_many`](crate::Constraint::energies_many)
/// loop as a lane operation: `w/2 |G q - p|^2` per element, with `G q`
/// from [`gradients`] and the squared distances summed in the scalar
/// order (per row `((0 + dx^2) + dy^2) + dz^2`, then the rows in order),
/// so every energy is bit-identical to the one-at-a-time one.
pub(super) struct EnergiesBatched<'a> {
    pub constraints: &'a [TetStrain],
    pub q: &'a [Point],
    pub projections: &'a [Point],
    pub out: &'a mut [f64],
}

impl WithLanes for EnergiesBatched<'_> {
    type Output = ();

    #[inline(always)]
    fn run<S: Lanes>(self, s: S) {
        let Self {
            constraints,
            q,
            projections,
            out,
        } = self;
        let batches = constraints.chunks_exact(S::WIDTH);
        let rest = batches.remainder();
        let mut p_batches = projections.chunks_exact(S::WIDTH * 3);
        let mut out_batches = out.chunks_exact_mut(S::WIDTH);
        for ((batch, p), energies) in batches.zip(&mut p_batches).zip(&mut out_batches) {
            let f = gradients(s, batch, q);
            let distance2 = distances(s, &f, &gather_rows(s, p));
            for ((e, c), d) in energies.iter_mut().zip(batch).zip(distance2.as_ref()) {
                *e = 0.5 * c.weight * d;
            }
        }
        energies_one_by_one(rest, q, p_batches.remainder(), out_batches.into_remainder());
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
