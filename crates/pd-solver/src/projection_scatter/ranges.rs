//! The scatter on several threads: each thread owns a contiguous range of
//! outputs (free vertices) and scatters only the groups that act on its
//! range, in ascending order, writing only its own outputs.
//!
//! Same bits whatever the thread count: every output still takes its
//! groups' terms in ascending group order, with the operations of the
//! 1-thread scatter, and a group that straddles two ranges is read by both
//! threads, each adding it into its own outputs only. The price is that
//! re-reading: on a mesh numbered in a spatial order (a generated box)
//! few groups straddle, on a randomly numbered one (TetGen's) almost all
//! do, and there the row gather serves more threads better
//! ([`Ranges::duplication`], `ProjectionOperator::new`).

use std::ops::Range;

use pd_mesh::Point;

use super::Groups;
use super::kernels::{Acc, add_group};
use pd_linalg::simd::vectorized;

/// Marks, in a range's list, a group with outputs outside the range.
const STRADDLES: u32 = 1 << 31;

/// At most this many ranges (a group's ranges are kept in a 64-bit mask).
const MAX_RANGES: usize = 64;

/// The outputs cut into one contiguous range per thread, and per range the
/// groups that act on it.
#[derive(Debug, Clone)]
pub(super) struct Ranges {
    /// Range `r` holds outputs `bounds[r]..bounds[r + 1]`.
    bounds: Vec<u32>,
    /// Per range: the groups with an output in it, ascending, each marked
    /// with [`STRADDLES`] when some of its outputs lie outside.
    lists: Vec<Vec<u32>>,
    /// Per group: where its values start in [`Groups`]' values.
    value_start: Vec<u32>,
}

impl Ranges {
    /// `count` ranges over `outputs` outputs of `groups`, cut so that each
    /// range takes about the same number of terms; `None` for fewer than
    /// two ranges, no entries, or groups beyond 31-bit indices.
    pub fn new(groups: &Groups, outputs: usize, count: usize) -> Option<Self> {
        let count = count.min(MAX_RANGES).min(outputs);
        if count < 2 || u32::try_from(groups.sources.len()).map_or(true, |g| g >= STRADDLES) {
            return None;
        }
        // Work per output: one per term plus one for the output's load and
        // store in each group.
        let mut work = vec![0u64; outputs];
        for (g, &(from, to)) in groups.sources.iter().enumerate() {
            for &t in groups.targets_of(g) {
                work[t as usize] += u64::from(to - from) + 1;
            }
        }
        let total: u64 = work.iter().sum();
        if total == 0 {
            return None;
        }
        let mut bounds = Vec::with_capacity(count + 1);
        bounds.push(0u32);
        let mut prefix = 0u64;
        for (f, &w) in work.iter().enumerate() {
            while bounds.len() < count && prefix * count as u64 >= total * bounds.len() as u64 {
                bounds.push(f as u32);
            }
            prefix += w;
        }
        bounds.resize(count + 1, outputs as u32);
        drop(work);

        let mut lists = vec![Vec::new(); count];
        let mut value_start = Vec::with_capacity(groups.sources.len());
        let mut offset = 0usize;
        for (g, &(from, to)) in groups.sources.iter().enumerate() {
            value_start.push(u32::try_from(offset).ok()?);
            let targets = groups.targets_of(g);
            offset += targets.len() * (to - from) as usize;
            let mut mask = 0u64;
            for &t in targets {
                mask |= 1 << (bounds.partition_point(|&b| b <= t) - 1);
            }
            let flag = if mask.count_ones() > 1 { STRADDLES } else { 0 };
            for (r, list) in lists.iter_mut().enumerate() {
                if mask & (1 << r) != 0 {
                    list.push(g as u32 | flag);
                }
            }
        }
        for list in &mut lists {
            list.shrink_to_fit();
        }
        Some(Self {
            bounds,
            lists,
            value_start,
        })
    }

    /// How many times the ranges read a group, on average: 1 when no group
    /// straddles two ranges, the number of ranges when all straddle all.
    pub fn duplication(&self) -> f64 {
        let reads: usize = self.lists.iter().map(Vec::len).sum();
        reads as f64 / self.value_start.len().max(1) as f64
    }

    /// `out = constant + B p * energy_factor`, each range on its own
    /// thread (rayon's `join`), `acc` (one per output) as scratch.
    pub fn rhs(
        &self,
        groups: &Groups,
        projections: &[Point],
        energy_factor: f64,
        acc: &mut [Acc],
        constant: &[Point],
        out: &mut [Point],
    ) {
        let job = Job {
            ranges: self,
            groups,
            projections,
            energy_factor,
        };
        job.run(0..self.lists.len(), acc, constant, out);
    }
}

/// What every range's thread reads.
struct Job<'a> {
    ranges: &'a Ranges,
    groups: &'a Groups,
    projections: &'a [Point],
    energy_factor: f64,
}

impl Job<'_> {
    /// The ranges `r` (whose outputs `acc`, `constant` and `out` hold),
    /// halved until one range is left.
    fn run(&self, r: Range<usize>, acc: &mut [Acc], constant: &[Point], out: &mut [Point]) {
        if r.len() == 1 {
            return self.range(r.start, acc, constant, out);
        }
        let mid = r.start + r.len() / 2;
        let at = (self.ranges.bounds[mid] - self.ranges.bounds[r.start]) as usize;
        let (acc_a, acc_b) = acc.split_at_mut(at);
        let (constant_a, constant_b) = constant.split_at(at);
        let (out_a, out_b) = out.split_at_mut(at);
        rayon::join(
            || self.run(r.start..mid, acc_a, constant_a, out_a),
            || self.run(mid..r.end, acc_b, constant_b, out_b),
        );
    }

    /// Range `r`: its groups into its outputs.
    fn range(&self, r: usize, acc: &mut [Acc], constant: &[Point], out: &mut [Point]) {
        let Self { ranges, groups, .. } = *self;
        let first = ranges.bounds[r];
        acc.fill([0.0; 4]);
        vectorized(
            #[inline(always)]
            |simd| {
                for &entry in &ranges.lists[r] {
                    let g = (entry & !STRADDLES) as usize;
                    let group = groups.group(g, ranges.value_start[g] as usize, self.projections);
                    if entry & STRADDLES == 0 {
                        add_group::<false>(simd, &group, first, acc);
                    } else {
                        add_group::<true>(simd, &group, first, acc);
                    }
                }
            },
        );
        super::finish(acc, constant, self.energy_factor, out);
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{bits, element_operator, inputs, operator};
    use super::super::{MAX_DUPLICATION, ProjectionScatter};
    use super::*;
    use pd_constraints::{CsrMatrix, Triplet};

    #[test]
    fn every_range_count_gives_the_bits_of_one_thread() {
        let (n, columns) = (300, 900);
        let random = operator(n, columns);
        let (elements, _) = element_operator(n, 700);
        for b in [random, elements] {
            let (projections, constant) = inputs(b.nrows(), b.ncols());
            let one = ProjectionScatter::new(&b).unwrap();
            let mut expected = vec![Point::zeros(); n];
            one.rhs(&constant, &projections, 0.73, &mut expected);
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .unwrap();
            for count in [2, 3, 5, 64, 1000] {
                let ranges = Ranges::new(&one.groups, n, count).unwrap();
                assert_eq!(ranges.lists.len(), count.min(MAX_RANGES));
                // Straddling groups exist, so the checked path runs.
                assert!(ranges.duplication() > 1.0, "{count} ranges");
                let split = ProjectionScatter {
                    ranges: Some(ranges),
                    ..one.clone()
                };
                let mut out = vec![Point::new(9.0, 9.0, 9.0); n];
                pool.install(|| split.rhs(&constant, &projections, 0.73, &mut out));
                assert_eq!(bits(&out), bits(&expected), "{count} ranges");
            }
        }
    }

    /// Element `e` acts on rows `e..e + 4` (a mesh numbered in a spatial
    /// order): two ranges share only the elements at their border.
    fn banded(rows: usize) -> CsrMatrix {
        let elements = rows - 3;
        let triplets: Vec<Triplet> = (0..elements)
            .flat_map(|e| {
                (0..3).flat_map(move |k| {
                    (0..4).map(move |r| Triplet::new(e + r, 3 * e + k, (e + k + r) as f64 * 0.1))
                })
            })
            .collect();
        CsrMatrix::from_triplets(rows, 3 * elements, &triplets)
    }

    #[test]
    fn the_ranges_are_kept_only_when_few_groups_straddle() {
        let b = banded(400);
        let one = ProjectionScatter::new(&b).unwrap();
        // Every element is a tet's shape: one run of the fixed-length loop.
        assert_eq!(one.groups.tet_runs, [(0, 397)]);
        let split = one.split(2).unwrap();
        let ranges = split.ranges.as_ref().unwrap();
        // Exactly the three elements across the border are read twice.
        assert_eq!(ranges.duplication(), (397.0 + 3.0) / 397.0);
        let (projections, constant) = inputs(b.nrows(), b.ncols());
        let (mut a, mut c) = (vec![Point::zeros(); 400], vec![Point::zeros(); 400]);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(|| split.rhs(&constant, &projections, 1.1, &mut a));
        ProjectionScatter::new(&b)
            .unwrap()
            .rhs(&constant, &projections, 1.1, &mut c);
        assert_eq!(bits(&a), bits(&c));
        // Shuffled elements straddle almost always: no ranges.
        let (shuffled, _) = element_operator(300, 700);
        let one = ProjectionScatter::new(&shuffled).unwrap();
        let duplication = Ranges::new(&one.groups, 300, 2).unwrap().duplication();
        assert!(duplication > MAX_DUPLICATION, "{duplication}");
        assert!(one.split(2).is_none());
    }

    #[test]
    fn the_ranges_balance_the_terms() {
        let b = banded(1000);
        let one = ProjectionScatter::new(&b).unwrap();
        let ranges = Ranges::new(&one.groups, 1000, 4).unwrap();
        // The band's rows carry equal work but for the ends: quarters.
        for (r, &bound) in ranges.bounds.iter().enumerate() {
            assert!(bound.abs_diff(250 * r as u32) <= 2, "{:?}", ranges.bounds);
        }
    }
}
