//! What the batched local-step loops of tet strain (`tet_strain/batch.rs`)
//! and triangle strain (`triangle_strain/batch.rs`) share: the byte ranges
//! they prefetch, projection rows moved into SIMD lanes, and squared
//! distances summed in the order of the one-at-a-time energies.
//!
//! A batch of `WIDTH` elements with `R` rows each is held as `N = 3 R`
//! lane registers: entry `3 r + j` is coordinate `j` of row `r`, lane `l`
//! element `l`. Everything is `inline(always)`, to be compiled inside the
//! dispatcher's `#[target_feature]` function (`polar_batch::lane_sets`).

use std::ops::Range;

use pd_mesh::Point;

use crate::polar_batch::lane_sets::Lanes;

/// The bytes of items `k * len..(k + 1) * len` of the `n` items from
/// `start`, cut at their end (empty past it), for a prefetch: only the
/// addresses are computed, nothing is read.
#[inline(always)]
pub(crate) fn batch_bytes<T>(start: *const T, n: usize, k: usize, len: usize) -> Range<*const u8> {
    let (from, to) = ((k * len).min(n), ((k + 1) * len).min(n));
    start.wrapping_add(from).cast()..start.wrapping_add(to).cast()
}

/// Rows `R l..R l + R` of `p` as lane `l` of a batch (`R = N / 3`; entry
/// `3 r + j` is coordinate `j` of row `r`).
#[inline(always)]
pub(crate) fn gather_rows<S: Lanes, const N: usize>(s: S, p: &[Point]) -> [S::F; N] {
    let rows = N / 3;
    let mut lanes = [s.splat(0.0); N];
    for r in 0..rows {
        for j in 0..3 {
            let mut v = S::Values::default();
            for (l, v) in v.as_mut().iter_mut().enumerate() {
                *v = p[rows * l + r][j];
            }
            lanes[3 * r + j] = s.pack(v);
        }
    }
    lanes
}

/// `sum_r |F_r - P_r|^2` per lane, summed as the one-at-a-time energies
/// sum it (`Constraint::energies_many`'s default): per row
/// `((0 + dx^2) + dy^2) + dz^2` (nalgebra's `norm_squared`, whose
/// `0 + (dx^2 + dy^2) + dz^2` is the same value: the first square is
/// never `-0`), then the rows in order from the first (`Iterator::sum`'s
/// start value changes no non-negative sum).
#[inline(always)]
pub(crate) fn distances<S: Lanes, const N: usize>(s: S, f: &[S::F; N], p: &[S::F; N]) -> S::Values {
    let zero = s.splat(0.0);
    let mut total = zero;
    for r in 0..N / 3 {
        let mut row = zero;
        for j in 0..3 {
            let d = s.sub(f[3 * r + j], p[3 * r + j]);
            row = s.add(row, s.mul(d, d));
        }
        total = if r == 0 { row } else { s.add(total, row) };
    }
    s.values(total)
}

/// The checks every batched kind's tests run: its `project_many`,
/// `energies_many` and `project_many_with_energies` against one
/// constraint at a time, to the bit.
#[cfg(test)]
pub(crate) mod test_support {
    use pd_mesh::Point;

    use crate::Constraint;
    use crate::constraint::apply_operator;
    use crate::{ConstraintBlock, ConstraintSet};

    /// The three checks below with the lanes of every SIMD width this CPU
    /// has.
    pub fn assert_all_bit_identical<C: Constraint>(constraints: &[C], q: &[Point]) {
        crate::polar_batch::lane_sets::for_each_width(|_| {
            assert_bit_identical(constraints, q);
            assert_energy_bit_identical(constraints, q);
            assert_energies_bit_identical(constraints, q);
        });
    }

    fn bits(v: &[Point]) -> Vec<u64> {
        v.iter()
            .flat_map(|p| p.iter().map(|c| c.to_bits()))
            .collect()
    }

    /// `w/2 |G q - p|^2` of one constraint, as the default
    /// `energies_many` computes it.
    fn energy_of<C: Constraint>(c: &C, q: &[Point], p: &[Point]) -> f64 {
        let mut gx = [Point::zeros(); crate::MAX_ROWS];
        apply_operator(c, q, &mut gx[..C::ROWS]);
        let distance2: f64 = (0..C::ROWS).map(|r| (gx[r] - p[r]).norm_squared()).sum();
        0.5 * c.weight() * distance2
    }

    /// `project` of one constraint's `G q`.
    fn project_one<C: Constraint>(c: &C, q: &[Point]) -> Vec<Point> {
        let mut gx = [Point::zeros(); crate::MAX_ROWS];
        apply_operator(c, q, &mut gx[..C::ROWS]);
        let mut one = vec![Point::zeros(); C::ROWS];
        c.project(&gx[..C::ROWS], &mut one);
        one
    }

    /// Every element's rows from `project_many` equal `project` of its
    /// `G q` to the bit.
    fn assert_bit_identical<C: Constraint>(constraints: &[C], q: &[Point]) {
        let mut batched = vec![Point::zeros(); C::ROWS * constraints.len()];
        C::project_many(constraints, q, &mut batched);
        for (i, (c, rows)) in constraints
            .iter()
            .zip(batched.chunks_exact(C::ROWS))
            .enumerate()
        {
            let one = project_one(c, q);
            assert_eq!(
                bits(rows),
                bits(&one),
                "element {i}: batched {rows:?} vs one {one:?}"
            );
        }
    }

    /// `ConstraintSet::energy_range`, which projects in batches, gives the
    /// one-at-a-time sum `sum w/2 |G q - P(G q)|^2` to the bit; the list is
    /// taken three times so that the range spans several energy batches
    /// and ends in a partial one.
    fn assert_energy_bit_identical<C: Constraint>(constraints: &[C], q: &[Point]) {
        let repeated: Vec<C> = (0..3).flat_map(|_| constraints.iter().cloned()).collect();
        let one_by_one: f64 = repeated
            .iter()
            .map(|c| energy_of(c, q, &project_one(c, q)))
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
    fn assert_energies_bit_identical<C: Constraint>(constraints: &[C], q: &[Point]) {
        let repeated: Vec<C> = (0..3).flat_map(|_| constraints.iter().cloned()).collect();
        let (n, rows) = (repeated.len(), C::ROWS);
        let mut projected = vec![Point::zeros(); rows * n];
        C::project_many(&repeated, q, &mut projected);
        let unrelated: Vec<Point> = (0..rows * n)
            .map(|i| Point::new(i as f64 * 0.37 - 1.0, 0.5, -(i as f64) * 0.11))
            .collect();
        for p in [&projected, &unrelated] {
            let mut batched = vec![0.0; n];
            C::energies_many(&repeated, q, p, &mut batched);
            for (i, (c, p)) in repeated.iter().zip(p.chunks_exact(rows)).enumerate() {
                let one = energy_of(c, q, p);
                assert_eq!(
                    batched[i].to_bits(),
                    one.to_bits(),
                    "element {i}: {} vs {one}",
                    batched[i]
                );
            }
        }
        // One pass: the same projections and the same energies.
        let mut fused_rows = vec![Point::zeros(); rows * n];
        let mut fused = vec![0.0; n];
        C::project_many_with_energies(&repeated, q, &mut fused_rows, &mut fused);
        let mut separate = vec![0.0; n];
        C::energies_many(&repeated, q, &projected, &mut separate);
        assert_eq!(bits(&fused_rows), bits(&projected));
        let energy_bits = |v: &[f64]| -> Vec<u64> { v.iter().map(|e| e.to_bits()).collect() };
        assert_eq!(energy_bits(&fused), energy_bits(&separate));
        let set = ConstraintSet::new(repeated);
        let bound = set.energy_bound_range(q, 0, &projected);
        let mut fused_rows = vec![Point::zeros(); rows * n];
        let fused_bound = set.project_energy_range(q, 0, &mut fused_rows);
        assert_eq!(bits(&fused_rows), bits(&projected));
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
        C::energies_many(set.constraints(), q, &projected, &mut energies);
        let mut worst = (0, 0.0);
        for (i, &e) in energies.iter().enumerate() {
            if !(e <= worst.1) {
                worst = (i, e);
            }
        }
        assert_eq!(bound.worst, worst.0);
    }
}
