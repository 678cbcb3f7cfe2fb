//! The batched local-step loops of the kinds that project in SIMD lanes
//! (tet strain, `tet_strain/batch.rs`; triangle strain,
//! `triangle_strain/batch.rs`), written once over [`LaneKind`]: the loop
//! over batches with its prefetches and its one-at-a-time fallbacks, the
//! energies from the lanes, projection rows moved into SIMD lanes, and
//! squared distances summed in the order of the one-at-a-time energies.
//!
//! A batch of `WIDTH` elements with `R` rows each is held as `N = 3 R`
//! lane registers: entry `3 r + j` is coordinate `j` of row `r`, lane `l`
//! element `l`. Everything is `inline(always)`, to be compiled inside the
//! dispatcher's `#[target_feature]` function (`polar_batch::lane_sets`).

use std::ops::Range;

use pd_mesh::Point;

use crate::Constraint;
use crate::constraint::{energies_one_by_one, project_one_by_one};
use crate::polar_batch::lane_sets::{Lanes, WithLanes, vectorize};

/// Batches ahead of the one projected whose elements are prefetched, and
/// whose output rows are prefetched for writing (docs/design/performance.md,
/// "Prefetching the next elements": the elements
/// arrive from memory at 527,280 tets, and the hardware prefetcher alone
/// left the loop waiting; a no-op on the 4-lane path).
const ELEMENTS_AHEAD: usize = 2;
const ROWS_AHEAD: usize = 1;

/// A constraint kind whose projection runs in SIMD lanes, `N = 3 ROWS`
/// lane registers per batch. Every method must be `#[inline(always)]`.
pub(crate) trait LaneKind<const N: usize>: Constraint {
    /// Whether a batch holding this element goes one at a time (strain
    /// limits, where a kind's lanes do not implement them).
    fn one_at_a_time(&self) -> bool;
    /// `G q` of a batch, one element per lane, summed exactly as
    /// `apply_operator` sums it (each lane bit-identical to the scalar).
    fn gradients<S: Lanes>(s: S, batch: &[Self], q: &[Point]) -> [S::F; N];
    /// The projection of every lane (lane `l` element `batch[l]`'s), and
    /// the bits of the lanes that hold the scalar projection to the bit
    /// (the others must be projected by the scalar code).
    fn project_lanes<S: Lanes>(s: S, batch: &[Self], f: &[S::F; N]) -> ([S::F; N], u32);
    /// Writes lane `l`'s projection into rows `R l..R l + R` of `rows`:
    /// `p`'s where `exact` has bit `l`, else the scalar projection of the
    /// lane's `f` by `batch[l]`.
    fn scatter<S: Lanes>(
        s: S,
        batch: &[Self],
        p: &[S::F; N],
        exact: u32,
        f: &[S::F; N],
        rows: &mut [Point],
    );
}

/// [`Constraint::project_many`] in lanes; `false` (nothing written) if
/// the CPU has no SIMD lanes.
pub(crate) fn project_many<C: LaneKind<N>, const N: usize>(
    constraints: &[C],
    q: &[Point],
    out: &mut [Point],
) -> bool {
    vectorize(ProjectBatched::<C, N, false> {
        constraints,
        q,
        out,
        energies: &mut [],
    })
    .is_some()
}

/// [`Constraint::project_many_with_energies`] in lanes, each batch's
/// energies from its lanes of `G q` and of the projection (no second
/// gather); `false` if the CPU has no SIMD lanes.
pub(crate) fn project_many_with_energies<C: LaneKind<N>, const N: usize>(
    constraints: &[C],
    q: &[Point],
    out: &mut [Point],
    energies: &mut [f64],
) -> bool {
    vectorize(ProjectBatched::<C, N, true> {
        constraints,
        q,
        out,
        energies,
    })
    .is_some()
}

/// [`Constraint::energies_many`] in lanes; `false` if the CPU has no SIMD
/// lanes.
pub(crate) fn energies_many<C: LaneKind<N>, const N: usize>(
    constraints: &[C],
    q: &[Point],
    projections: &[Point],
    out: &mut [f64],
) -> bool {
    vectorize(EnergiesBatched::<C, N> {
        constraints,
        q,
        projections,
        out,
    })
    .is_some()
}

/// The projection loop as a lane operation. With `ENERGIES`, each
/// element's energy `w/2 |G q - p|^2` goes into `energies` too; without,
/// `energies` is empty and the loop is the plain projection's (compiled
/// without it).
struct ProjectBatched<'a, C, const N: usize, const ENERGIES: bool> {
    constraints: &'a [C],
    q: &'a [Point],
    out: &'a mut [Point],
    energies: &'a mut [f64],
}

impl<C: LaneKind<N>, const N: usize, const ENERGIES: bool> WithLanes
    for ProjectBatched<'_, C, N, ENERGIES>
{
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
        let mut out_batches = out.chunks_exact_mut(S::WIDTH * C::ROWS);
        let mut energy_batches = energies.chunks_exact_mut(S::WIDTH);
        for (b, (batch, rows)) in batches.zip(&mut out_batches).enumerate() {
            let ahead = b + ELEMENTS_AHEAD;
            s.prefetch::<false>(batch_bytes(elements, n_elements, ahead, S::WIDTH));
            let ahead = b + ROWS_AHEAD;
            s.prefetch::<true>(batch_bytes(rows_out, n_rows, ahead, C::ROWS * S::WIDTH));
            if batch.iter().any(C::one_at_a_time) {
                project_one_by_one(batch, q, rows);
                if ENERGIES && let Some(energy) = energy_batches.next() {
                    energies_one_by_one(batch, q, rows, energy);
                }
                continue;
            }
            let f = C::gradients(s, batch, q);
            let (p, exact) = C::project_lanes(s, batch, &f);
            C::scatter(s, batch, &p, exact, &f, rows);
            if ENERGIES && let Some(energy) = energy_batches.next() {
                // The lanes' projection where every lane holds the scalar
                // one, else the rows just written.
                let distance2 = if exact == (1 << S::WIDTH) - 1 {
                    distances(s, &f, &p)
                } else {
                    distances(s, &f, &gather_rows(s, rows))
                };
                write_energies(batch, distance2.as_ref(), energy);
            }
        }
        let rows = out_batches.into_remainder();
        project_one_by_one(rest, q, rows);
        if ENERGIES {
            energies_one_by_one(rest, q, rows, energy_batches.into_remainder());
        }
    }
}

/// The energies loop as a lane operation: `w/2 |G q - p|^2` per element,
/// with `G q` from [`LaneKind::gradients`] and the squared distances
/// summed in the scalar order, so every energy is bit-identical to the
/// one-at-a-time one.
struct EnergiesBatched<'a, C, const N: usize> {
    constraints: &'a [C],
    q: &'a [Point],
    projections: &'a [Point],
    out: &'a mut [f64],
}

impl<C: LaneKind<N>, const N: usize> WithLanes for EnergiesBatched<'_, C, N> {
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
        let mut p_batches = projections.chunks_exact(S::WIDTH * C::ROWS);
        let mut out_batches = out.chunks_exact_mut(S::WIDTH);
        for ((batch, p), energies) in batches.zip(&mut p_batches).zip(&mut out_batches) {
            let f = C::gradients(s, batch, q);
            let distance2 = distances(s, &f, &gather_rows(s, p));
            write_energies(batch, distance2.as_ref(), energies);
        }
        energies_one_by_one(rest, q, p_batches.remainder(), out_batches.into_remainder());
    }
}

/// `w/2 d` per element, as the one-at-a-time energies compute it.
#[inline(always)]
fn write_energies<C: Constraint>(batch: &[C], distance2: &[f64], out: &mut [f64]) {
    for ((e, c), d) in out.iter_mut().zip(batch).zip(distance2) {
        *e = 0.5 * c.weight() * d;
    }
}

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
        pd_linalg::simd::for_each_simd_width(|_| {
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
