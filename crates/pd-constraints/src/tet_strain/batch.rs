//! [`TetStrain`]'s [`project_many`](crate::Constraint::project_many) as a
//! batched loop: four elements at a time, from the positions straight into
//! the SIMD lanes and back.
//!
//! Per batch of [`LANES`] elements: gather the deformation gradients into
//! structure-of-arrays lanes (`F = G q` with 4-wide products and sums, in the
//! order of `apply_operator`, so each lane's `F` is bit-identical to the
//! scalar one), run the lane polar iteration of [`crate::polar_batch`], and
//! write each converged lane's rotation into its three output rows; a lane
//! that Newton declined is projected by the scalar [`closest_rotation`].
//! Everything is `inline(always)` below a `pulp::WithSimd::with_simd`, so it
//! is compiled inside pulp's AVX2 `#[target_feature]` function: no closure
//! the compiler could keep out of line (std's `array::from_fn` did) sits on
//! the hot path.

use pd_mesh::Point;
use pulp::f64x4;

use super::{TetStrain, energies_one_by_one, project_one_by_one};
use crate::polar::closest_rotation;
use crate::polar_batch::{Batch, LANES, Simd, lane_matrix, lanes_of, newton_polar_lanes};

/// [`TetStrain`]'s [`project_many`](crate::Constraint::project_many) loop as
/// a `pulp` operation.
/// With `ENERGIES`, each element's energy `w/2 |G q - p|^2` goes into
/// `energies` too (`project_many_with_energies`); without, `energies` is
/// empty and the loop is the plain projection's (compiled without it).
pub(super) struct ProjectBatched<'a, const ENERGIES: bool> {
    pub simd: Simd,
    pub constraints: &'a [TetStrain],
    pub q: &'a [Point],
    pub out: &'a mut [Point],
    pub energies: &'a mut [f64],
}

impl<const ENERGIES: bool> pulp::WithSimd for ProjectBatched<'_, ENERGIES> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let Self {
            simd,
            constraints,
            q,
            out,
            energies,
        } = self;
        let batches = constraints.chunks_exact(LANES);
        let rest = batches.remainder();
        let mut out_batches = out.chunks_exact_mut(LANES * 3);
        let mut energy_batches = energies.chunks_exact_mut(LANES);
        for (batch, rows) in batches.zip(&mut out_batches) {
            let [e0, e1, e2, e3] = batch else {
                // `chunks_exact` yields exactly LANES elements.
                continue;
            };
            if batch.iter().any(TetStrain::has_limits) {
                project_one_by_one(batch, q, rows);
                if ENERGIES && let Some(energy) = energy_batches.next() {
                    energies_one_by_one(batch, q, rows, energy);
                }
                continue;
            }
            let f = gradients(simd, [e0, e1, e2, e3], q);
            let (x, converged) = newton_polar_lanes(simd, &f);
            scatter(&x, converged, &f, rows);
            if ENERGIES && let Some(energy) = energy_batches.next() {
                lane_energies(simd, batch, &f, &x, converged, rows, energy);
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
fn lane_energies(
    s: Simd,
    batch: &[TetStrain],
    f: &Batch,
    x: &Batch,
    converged: [bool; LANES],
    rows: &[Point],
    out: &mut [f64],
) {
    let distance2 = if converged.iter().all(|&c| c) {
        distances(s, f, x)
    } else {
        distances(s, f, &gather_rows(rows))
    };
    for ((e, c), d) in out.iter_mut().zip(batch).zip(distance2) {
        *e = 0.5 * c.weight * d;
    }
}

/// Rows `3 l..3 l + 3` of `rows` as lane `l` of a batch (entry `3 r + j`
/// is coordinate `j` of row `r`, as in [`gradients`]).
#[inline(always)]
fn gather_rows(p: &[Point]) -> Batch {
    let mut lanes = [f64x4(0.0, 0.0, 0.0, 0.0); 9];
    for r in 0..3 {
        for j in 0..3 {
            lanes[3 * r + j] = f64x4(p[r][j], p[3 + r][j], p[6 + r][j], p[9 + r][j]);
        }
    }
    lanes
}

/// `sum_r |F_r - P_r|^2` per lane, summed in the scalar order: per row
/// `((0 + dx^2) + dy^2) + dz^2`, then the rows in order.
#[inline(always)]
fn distances(s: Simd, f: &Batch, p: &Batch) -> [f64; LANES] {
    let zero = s.splat_f64x4(0.0);
    let mut rows = [zero; 3];
    for (r, row) in rows.iter_mut().enumerate() {
        for j in 0..3 {
            let d = s.sub_f64x4(f[3 * r + j], p[3 * r + j]);
            *row = s.add_f64x4(*row, s.mul_f64x4(d, d));
        }
    }
    lanes_of(s.add_f64x4(s.add_f64x4(rows[0], rows[1]), rows[2]))
}

/// [`TetStrain`]'s [`energies_many`](crate::Constraint::energies_many)
/// loop as a `pulp` operation: `w/2 |G q - p|^2` per element, with `G q`
/// from [`gradients`] and the squared distances summed in the scalar
/// order (per row `((0 + dx^2) + dy^2) + dz^2`, then the rows in order),
/// so every energy is bit-identical to the one-at-a-time one.
pub(super) struct EnergiesBatched<'a> {
    pub simd: Simd,
    pub constraints: &'a [TetStrain],
    pub q: &'a [Point],
    pub projections: &'a [Point],
    pub out: &'a mut [f64],
}

impl pulp::WithSimd for EnergiesBatched<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let Self {
            simd: s,
            constraints,
            q,
            projections,
            out,
        } = self;
        let batches = constraints.chunks_exact(LANES);
        let rest = batches.remainder();
        let mut p_batches = projections.chunks_exact(LANES * 3);
        let mut out_batches = out.chunks_exact_mut(LANES);
        for ((batch, p), energies) in batches.zip(&mut p_batches).zip(&mut out_batches) {
            let [e0, e1, e2, e3] = batch else {
                // `chunks_exact` yields exactly LANES elements.
                continue;
            };
            let f = gradients(s, [e0, e1, e2, e3], q);
            let distance2 = distances(s, &f, &gather_rows(p));
            for ((e, c), d) in energies.iter_mut().zip(batch).zip(distance2) {
                *e = 0.5 * c.weight * d;
            }
        }
        energies_one_by_one(rest, q, p_batches.remainder(), out_batches.into_remainder());
    }
}

/// The deformation gradients of four elements, one per lane: entry `(r, c)`
/// of lane `l` is `sum_k q[v_k][r] G[c][k]` of element `l`, summed from 0 in
/// the order `k = 0..4` exactly as `apply_operator` does (no fused
/// multiply-add), so every lane is bit-identical to the scalar `F`.
#[inline(always)]
fn gradients(s: Simd, elements: [&TetStrain; LANES], q: &[Point]) -> Batch {
    let zero = s.splat_f64x4(0.0);
    let operator = operator_lanes(s, elements);
    // Vertex by vertex: each entry still sums its terms in the order
    // `k = 0..4`, and only one vertex's three position lanes are live.
    let mut f = [zero; 9];
    for k in 0..4 {
        // Written out: `array::map` with a closure may stay out of line.
        let [a, b, c, d] = [
            q[elements[0].vertices[k] as usize],
            q[elements[1].vertices[k] as usize],
            q[elements[2].vertices[k] as usize],
            q[elements[3].vertices[k] as usize],
        ];
        for r in 0..3 {
            let p = f64x4(a[r], b[r], c[r], d[r]);
            for (column, g) in operator.iter().enumerate() {
                let acc = &mut f[3 * column + r];
                *acc = s.add_f64x4(*acc, s.mul_f64x4(p, g[k]));
            }
        }
    }
    f
}

/// The operator `G` of four elements in lanes: entry `[c][k]` holds
/// `G[c][k]` of each element. The stored `B^T` entries (`G[c][1..4]`) are
/// moved in lane by lane (building them from 128-bit pairs and shuffles
/// instead ran more instructions: LLVM turned the shuffles into broadcasts
/// and blends); the first column is recomputed
/// per lane exactly as [`first_entry`](super::first_entry) sums it (the
/// fold of `Iterator::sum` from its start value, then the sign flipped), so
/// every lane holds the scalar `operator(c, k)` to the bit.
#[inline(always)]
fn operator_lanes(s: Simd, [a, b, c, d]: [&TetStrain; LANES]) -> [[f64x4; 4]; 3] {
    let flat = |e: &TetStrain, i: usize| e.inverse_t[i / 3][i % 3];
    let mut lanes = [s.splat_f64x4(0.0); 9];
    for (i, lane) in lanes.iter_mut().enumerate() {
        *lane = f64x4(flat(a, i), flat(b, i), flat(c, i), flat(d, i));
    }
    // `Iterator::sum`'s start value (the fold's first operand) and the sign
    // bit that `-x` flips.
    let start = s.splat_f64x4(std::iter::empty::<f64>().sum());
    let sign = s.splat_f64x4(-0.0);
    let mut g = [[s.splat_f64x4(0.0); 4]; 3];
    for (row, g) in g.iter_mut().enumerate() {
        let [b0, b1, b2] = [lanes[3 * row], lanes[3 * row + 1], lanes[3 * row + 2]];
        let sum = s.add_f64x4(s.add_f64x4(s.add_f64x4(start, b0), b1), b2);
        *g = [pulp::Simd::xor_f64s(s, sum, sign), b0, b1, b2];
    }
    g
}

/// Writes lane `l`'s projection into rows `3 l..3 l + 3` of `rows`: the
/// columns of the converged iterate `x`, or of the scalar
/// [`closest_rotation`] of the lane's `F` where Newton declined it.
/// (Recomputing a declined element's `F` from `q` instead, so that the
/// lanes of `F` need not outlive the Newton loop, ran more instructions.)
#[inline(always)]
fn scatter(x: &Batch, converged: [bool; LANES], f: &Batch, rows: &mut [Point]) {
    let Ok(rows) = <&mut [Point; 3 * LANES]>::try_from(rows) else {
        // `chunks_exact_mut(3 * LANES)` yields exactly this many rows.
        return;
    };
    let mut values = [[0.0; LANES]; 9];
    for (v, x) in values.iter_mut().zip(x) {
        *v = lanes_of(*x);
    }
    for (l, &converged) in converged.iter().enumerate() {
        if converged {
            for c in 0..3 {
                rows[3 * l + c] =
                    Point::new(values[3 * c][l], values[3 * c + 1][l], values[3 * c + 2][l]);
            }
        } else {
            let target = closest_rotation(&lane_matrix(f, l));
            for c in 0..3 {
                rows[3 * l + c] = target.column(c).into_owned();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix3;
    use proptest::prelude::*;

    use super::*;
    use crate::Constraint;
    use crate::constraint::apply_operator;

    /// Every element's rows from `project_many` equal `project` of its
    /// `G q` to the bit.
    fn assert_bit_identical(constraints: &[TetStrain], q: &[Point]) {
        let mut batched = vec![Point::zeros(); 3 * constraints.len()];
        TetStrain::project_many(constraints, q, &mut batched);
        let mut gx = [Point::zeros(); 3];
        for (i, (c, rows)) in constraints.iter().zip(batched.chunks_exact(3)).enumerate() {
            apply_operator(c, q, &mut gx);
            let mut one = [Point::zeros(); 3];
            c.project(&gx, &mut one);
            let same = rows
                .iter()
                .flat_map(|p| p.iter())
                .zip(one.iter().flat_map(|p| p.iter()))
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "element {i}: batched {rows:?} vs one {one:?}");
        }
    }

    /// `ConstraintSet::energy_range`, which projects in batches, gives the
    /// one-at-a-time sum `sum w/2 |G q - P(G q)|^2` to the bit; the list is
    /// taken three times so that the range spans several energy batches
    /// and ends in a partial one.
    fn assert_energy_bit_identical(constraints: &[TetStrain], q: &[Point]) {
        use crate::{ConstraintBlock, ConstraintSet};
        let repeated: Vec<TetStrain> = (0..3).flat_map(|_| constraints.iter().cloned()).collect();
        let mut gx = [Point::zeros(); 3];
        let one_by_one: f64 = repeated
            .iter()
            .map(|c| {
                apply_operator(c, q, &mut gx);
                let mut p = [Point::zeros(); 3];
                c.project(&gx, &mut p);
                let distance2: f64 = (0..3).map(|r| (gx[r] - p[r]).norm_squared()).sum();
                0.5 * c.weight() * distance2
            })
            .sum();
        let n = repeated.len();
        let batched = ConstraintSet::new(repeated).energy_range(q, 0..n);
        assert_eq!(
            batched.to_bits(),
            one_by_one.to_bits(),
            "{batched} vs {one_by_one}"
        );
    }

    /// `energies_many` (SIMD lanes and the remainder) equals the
    /// one-at-a-time `w/2 |G q - p|^2` of each element to the bit, from
    /// the elements' own projections and from unrelated rows;
    /// `project_many_with_energies` and `project_energy_range` give the
    /// projections and energies of the two passes to the bit; and
    /// `ConstraintSet::energy_bound_range`, which sums them a batch at a
    /// time, equals `energy_range`'s sum and names the same largest term
    /// as a one-by-one scan (the list taken three times, so that several
    /// batches and a partial one are summed).
    fn assert_energies_bit_identical(constraints: &[TetStrain], q: &[Point]) {
        use crate::{ConstraintBlock, ConstraintSet};
        let repeated: Vec<TetStrain> = (0..3).flat_map(|_| constraints.iter().cloned()).collect();
        let n = repeated.len();
        let mut projected = vec![Point::zeros(); 3 * n];
        TetStrain::project_many(&repeated, q, &mut projected);
        let unrelated: Vec<Point> = (0..3 * n)
            .map(|i| Point::new(i as f64 * 0.37 - 1.0, 0.5, -(i as f64) * 0.11))
            .collect();
        for p in [&projected, &unrelated] {
            let mut batched = vec![0.0; n];
            TetStrain::energies_many(&repeated, q, p, &mut batched);
            let mut gx = [Point::zeros(); 3];
            for (i, (c, rows)) in repeated.iter().zip(p.chunks_exact(3)).enumerate() {
                apply_operator(c, q, &mut gx);
                let distance2: f64 = (0..3).map(|r| (gx[r] - rows[r]).norm_squared()).sum();
                let one = 0.5 * c.weight() * distance2;
                assert_eq!(
                    batched[i].to_bits(),
                    one.to_bits(),
                    "element {i}: {} vs {one}",
                    batched[i]
                );
            }
        }
        // One pass: the same projections and the same energies.
        let mut rows = vec![Point::zeros(); 3 * n];
        let mut fused = vec![0.0; n];
        TetStrain::project_many_with_energies(&repeated, q, &mut rows, &mut fused);
        let mut separate = vec![0.0; n];
        TetStrain::energies_many(&repeated, q, &projected, &mut separate);
        let bits = |v: &[Point]| -> Vec<u64> {
            v.iter()
                .flat_map(|p| p.iter().map(|c| c.to_bits()))
                .collect()
        };
        assert_eq!(bits(&rows), bits(&projected));
        let energy_bits = |v: &[f64]| -> Vec<u64> { v.iter().map(|e| e.to_bits()).collect() };
        assert_eq!(energy_bits(&fused), energy_bits(&separate));
        let set = ConstraintSet::new(repeated);
        let bound = set.energy_bound_range(q, 0, &projected);
        let mut rows = vec![Point::zeros(); 3 * n];
        let fused_bound = set.project_energy_range(q, 0, &mut rows);
        assert_eq!(bits(&rows), bits(&projected));
        assert_eq!(fused_bound.total.to_bits(), bound.total.to_bits());
        assert_eq!(fused_bound.worst, bound.worst);
        let total = set.energy_range(q, 0..n);
        assert_eq!(
            bound.total.to_bits(),
            total.to_bits(),
            "{} vs {total}",
            bound.total
        );
        let mut energies = vec![0.0; n];
        TetStrain::energies_many(set.constraints(), q, &projected, &mut energies);
        let mut worst = (0, 0.0);
        for (i, &e) in energies.iter().enumerate() {
            if !(e <= worst.1) {
                worst = (i, e);
            }
        }
        assert_eq!(bound.worst, worst.0);
    }

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
        /// strain-limited element at a random place and a remainder of
        /// fewer than four.
        #[test]
        fn gathered_batches_are_bit_identical(
            rest in prop::array::uniform8(prop::array::uniform3(-1.0..1.0f64)),
            strain in prop::array::uniform9(-1.0..1.0f64),
            strain_size in prop::sample::select(vec![0.0, 1e-3, 0.1, 1.0, 3.0]),
            noise in prop::array::uniform8(prop::array::uniform3(-0.05..0.05f64)),
            noise_size in prop::sample::select(vec![0.0, 1e-4, 1.0, 10.0]),
            log_scale in prop::sample::select(vec![-250.0, -3.0, 0.0, 2.5, 250.0]),
            limited in 0usize..16,
        ) {
            let a = std::array::from_fn(|i| {
                f64::from(u8::from(i % 4 == 0)) + strain[i] * strain_size
            });
            let noise = noise.map(|n| n.map(|v| v * noise_size));
            let (constraints, q) = elements_and_positions(&rest, a, &noise, log_scale, limited);
            assert_bit_identical(&constraints, &q);
            assert_energy_bit_identical(&constraints, &q);
            assert_energies_bit_identical(&constraints, &q);
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
            assert_bit_identical(&constraints, &q);
            assert_energy_bit_identical(&constraints, &q);
            assert_energies_bit_identical(&constraints, &q);
        }
    }
}
