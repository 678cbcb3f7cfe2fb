//! The global step's projection term `B p` (docs/design/formulation.md,
//! "The global step"), computed by
//! scattering each projection into the vertices it acts on, in the order
//! of the stacked projections, instead of gathering each vertex's
//! projections row by row.
//!
//! Why: a vertex's row of `B` names some 45 projections (a tet's three rows
//! for each of the ~15 tets around it), and on a mesh whose vertices are
//! numbered in no spatial order (TetGen's) they sit anywhere in an array of
//! several MB, so the row-by-row gather (`CsrMatrix::row_dot`) waited on a
//! cache miss per entry. Here the projections and the operator are read
//! once, front to back, and the writes go to the right-hand side, one point
//! per free vertex (355 kB for the armadillo's 14,779 vertices: in L2).
//!
//! Same bits as the gather: every output starts at zero and takes
//! `out += p_c * B[f][c]` for its columns `c` in ascending order, which is
//! exactly `row_dot`'s fold; then `constant + out * energy_factor`, as
//! before (unit tests `scatter_is_the_row_gather_bit_for_bit` and
//! `built_from_the_blocks_it_is_the_scatter_of_the_assembled_rows`), with
//! AVX2 where the CPU has it (`kernels.rs`: lane by lane the same
//! operations). On more threads each thread scatters into its own range of
//! outputs (`ranges.rs`) when few groups straddle two ranges; otherwise
//! [`ProjectionOperator`] keeps the row-parallel gather. All give the same
//! bits.

mod kernels;
mod ranges;

use pd_constraints::{ConstraintBlock, CsrMatrix, assembly};
use pd_mesh::Point;
use rayon::prelude::*;

use crate::global::FIXED;
use kernels::{Acc, Group, Scratch, Tet, add_group, add_tet};
use pd_linalg::simd::vectorized;
use ranges::Ranges;

/// More threads scatter into their own ranges of outputs only while the
/// ranges read each group at most this many times on average; above it
/// they gather `B`'s rows (docs/design/performance.md, "The right-hand side `B
/// p`": the measured duplication per mesh).
const MAX_DUPLICATION: f64 = 1.25;

/// `B`'s entries by projection (source) in ascending order, in groups: a
/// group is a run of consecutive projections with the same outputs (a
/// tet's three rows act on the same four vertices), stored with its outputs
/// once and its values output by output, so that each output of a group is
/// loaded and stored once while it takes the group's projections in order.
#[derive(Debug, Clone, Default)]
struct Groups {
    /// Per group: its first projection and one past its last.
    sources: Vec<(u32, u32)>,
    /// Outputs of group `g`: `targets[target_start[g]..target_start[g + 1]]`.
    target_start: Vec<u32>,
    /// Outputs (free vertices) of the groups, in the order the
    /// operator's entries came (a stencil's order).
    targets: Vec<u32>,
    /// The groups' values (`w G^T S`, 1/m^2 scaled by the constraint's
    /// weight), group after group, within a group output by output and for
    /// each output projection by projection.
    values: Vec<f64>,
    /// The maximal runs `a..b` of consecutive groups of a tet's shape
    /// (three projections on four outputs), scattered by a loop that knows
    /// their lengths.
    tet_runs: Vec<(u32, u32)>,
}

/// The projection operator `B` over the free vertices, stored for the
/// scatter (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct ProjectionScatter {
    outputs: usize,
    groups: Groups,
    /// The outputs cut into one range per thread, for a step on more
    /// threads; `None` on one.
    ranges: Option<Ranges>,
    /// One accumulator per output, reused by every call.
    scratch: Scratch,
}

/// `B` for the right-hand side: scattered on one thread; on more, scattered
/// range by range when few elements straddle two threads' vertices, else
/// gathered row by row in parallel (the gather splits across threads
/// without splitting an output's sum; the ranges re-read every element that
/// straddles, on a randomly numbered mesh most of them). All give the same
/// bits.
#[derive(Debug, Clone)]
pub(crate) enum ProjectionOperator {
    /// `B`'s rows for the free vertices, gathered row-parallel.
    Rows(CsrMatrix),
    /// `B` stored for the scatter.
    Scatter(ProjectionScatter),
}

impl ProjectionOperator {
    /// `B`'s rows for the free vertices (`free`, with `free_index` mapping
    /// a vertex to its position there or to [`FIXED`]) in the form that
    /// suits a step on `threads` threads.
    pub fn new(
        blocks: &[Box<dyn ConstraintBlock>],
        free: &[usize],
        free_index: &[usize],
        threads: usize,
    ) -> Self {
        if let Some(scatter) = ProjectionScatter::from_blocks(blocks, free, free_index) {
            if threads <= 1 {
                return Self::Scatter(scatter);
            }
            if let Some(split) = scatter.split(threads) {
                return Self::Scatter(split);
            }
            // The scatter is dropped before `B` is assembled (peak memory).
        }
        Self::Rows(assembly::projection_operator_rows(
            blocks,
            free_index.len(),
            free,
        ))
    }

    /// `out[f] = constant[f] + (B p)[f] * energy_factor` for every free
    /// vertex `f`; the same bits in either form and for any thread count.
    /// Allocates nothing.
    pub fn rhs(
        &self,
        constant: &[Point],
        projections: &[Point],
        energy_factor: f64,
        out: &mut [Point],
    ) {
        match self {
            Self::Rows(rows) => out.par_iter_mut().enumerate().for_each(|(f, out)| {
                *out = constant[f] + rows.row_dot(f, projections) * energy_factor;
            }),
            Self::Scatter(scatter) => scatter.rhs(constant, projections, energy_factor, out),
        }
    }
}

/// Hands every entry `(row, column, value)` of an operator to its
/// argument, in a fixed order (the same on every call).
type Visit<'a> = dyn FnMut(&mut dyn FnMut(usize, usize, f64)) + 'a;

impl ProjectionScatter {
    /// The scatter form of `B`'s rows for the free vertices, built from the
    /// constraint blocks' entries directly (`free` lists the free vertices,
    /// `free_index` maps a vertex to its position there or to [`FIXED`]),
    /// without assembling `B`: the scatter takes `B`'s place, and building
    /// both would add `B`'s size to the setup's peak memory. When some
    /// vertex's entries do not come with strictly increasing projections
    /// (a stencil naming a vertex twice, whose entries `B` sums) it falls
    /// back to `B` ([`ProjectionScatter::new`]), so the entries are always
    /// `B`'s. `None` for an operator beyond 32-bit offsets (some 4e9
    /// entries, columns or rows: the caller then keeps the row gather).
    pub fn from_blocks(
        blocks: &[Box<dyn ConstraintBlock>],
        free: &[usize],
        free_index: &[usize],
    ) -> Option<Self> {
        let (offsets, total) = assembly::projection_offsets(blocks);
        let mut visit = |entry: &mut dyn FnMut(usize, usize, f64)| {
            for (block, &first_row) in blocks.iter().zip(&offsets) {
                block.for_each_projection_entry(first_row, &mut |vertex, column, value| {
                    let row = free_index[vertex];
                    if row != FIXED {
                        entry(row, column, value);
                    }
                });
            }
        };
        let mut next_column = vec![0usize; free.len()];
        let mut entries = 0usize;
        let mut clean = true;
        visit(&mut |row, column, _| {
            clean &= column >= next_column[row];
            next_column[row] = column + 1;
            entries += 1;
        });
        drop(next_column);
        if !clean {
            let rows = assembly::projection_operator_rows(blocks, free_index.len(), free);
            return Self::new(&rows);
        }
        Self::build(free.len(), total, entries, &mut visit)
    }

    /// The scatter form of `rows` (`B`'s rows for the free vertices, one
    /// column per stacked projection); `None` as for [`Self::from_blocks`].
    pub fn new(rows: &CsrMatrix) -> Option<Self> {
        let mut visit = |entry: &mut dyn FnMut(usize, usize, f64)| {
            for f in 0..rows.nrows() {
                for (c, value) in rows.row(f) {
                    entry(f, c, value);
                }
            }
        };
        Self::build(rows.nrows(), rows.ncols(), rows.nnz(), &mut visit)
    }

    /// The operator with `outputs` rows, `columns` columns and `entries`
    /// entries that `visit` lists, each row's in increasing column order;
    /// `None` if its entries, columns or rows do not fit 32-bit offsets.
    fn build(
        outputs: usize,
        columns: usize,
        entries: usize,
        visit: &mut Visit<'_>,
    ) -> Option<Self> {
        if [entries, columns, outputs]
            .iter()
            .any(|&n| u32::try_from(n).is_err())
        {
            return None;
        }
        let groups = Groups::new(visit, &mut vec![0u32; columns]);
        Some(Self {
            outputs,
            groups,
            ranges: None,
            scratch: Scratch::new(outputs),
        })
    }

    /// This operator cut into `threads` ranges of outputs, one per thread
    /// ([`Ranges`]); `None` when that would read the groups more than
    /// [`MAX_DUPLICATION`] times on average (or cannot be cut).
    fn split(self, threads: usize) -> Option<Self> {
        let ranges = Ranges::new(&self.groups, self.outputs, threads)?;
        (ranges.duplication() <= MAX_DUPLICATION).then_some(Self {
            ranges: Some(ranges),
            ..self
        })
    }

    /// `out[f] = constant[f] + (B p)[f] * energy_factor` for every free
    /// vertex `f`: on the calling thread, or one range of outputs per
    /// thread when the operator was [`split`](Self::split). Allocates
    /// nothing.
    pub fn rhs(
        &self,
        constant: &[Point],
        projections: &[Point],
        energy_factor: f64,
        out: &mut [Point],
    ) {
        assert_eq!(out.len(), self.outputs, "one output per free vertex");
        assert_eq!(constant.len(), self.outputs, "one constant per free vertex");
        self.scratch.with(self.outputs, |acc| match &self.ranges {
            None => {
                acc.fill([0.0; 4]);
                self.groups.scatter(projections, acc);
                finish(acc, constant, energy_factor, out);
            }
            Some(ranges) => {
                ranges.rhs(&self.groups, projections, energy_factor, acc, constant, out);
            }
        });
    }
}

/// `out = constant + acc * energy_factor`, output by output (the scatter's
/// last pass, as `constant + sum * energy_factor` in the row gather).
fn finish(acc: &[Acc], constant: &[Point], energy_factor: f64, out: &mut [Point]) {
    for ((o, &c), a) in out.iter_mut().zip(constant).zip(acc) {
        *o = c + Point::new(a[0], a[1], a[2]) * energy_factor;
    }
}

impl Groups {
    /// The entries `visit` lists, by column, grouped; `counts` (one per
    /// column, all zero) is scratch.
    fn new(visit: &mut Visit<'_>, counts: &mut [u32]) -> Self {
        visit(&mut |_, c, _| counts[c] += 1);
        // Column by column first (compressed sparse columns of the rows),
        // then grouped in place: the grouped arrays are never longer.
        let mut columns = Vec::new();
        let mut starts = vec![0u32];
        for (c, count) in counts.iter_mut().enumerate() {
            if *count > 0 {
                columns.push(c as u32);
                starts.push(starts.last().copied().unwrap_or(0) + *count);
                // From here on: the next free slot of column c's entries.
                *count = starts[starts.len() - 2];
            }
        }
        let len = starts.last().copied().unwrap_or(0) as usize;
        let (mut targets, mut values) = (vec![0u32; len], vec![0.0; len]);
        visit(&mut |f, c, value| {
            let at = counts[c] as usize;
            targets[at] = f as u32;
            values[at] = value;
            counts[c] += 1;
        });
        let (sources, target_start) = group(&columns, &starts, &mut targets, &mut values);
        let mut tet_runs: Vec<(u32, u32)> = Vec::new();
        for (g, (&(from, to), ends)) in sources.iter().zip(target_start.windows(2)).enumerate() {
            if to - from == 3 && ends[1] - ends[0] == 4 {
                let g = g as u32;
                match tet_runs.last_mut() {
                    Some(run) if run.1 == g => run.1 = g + 1,
                    _ => tet_runs.push((g, g + 1)),
                }
            }
        }
        Self {
            sources,
            target_start,
            targets,
            values,
            tet_runs,
        }
    }

    /// Group `g`'s projections, outputs and values (which start at
    /// `value_start`).
    #[inline(always)]
    fn group<'a>(&'a self, g: usize, value_start: usize, projections: &'a [Point]) -> Group<'a> {
        let (from, to) = self.sources[g];
        let targets = self.targets_of(g);
        let len = targets.len() * (to - from) as usize;
        Group {
            projections: &projections[from as usize..to as usize],
            targets,
            values: &self.values[value_start..value_start + len],
        }
    }

    /// Group `g`'s outputs.
    #[inline(always)]
    fn targets_of(&self, g: usize) -> &[u32] {
        &self.targets[self.target_start[g] as usize..self.target_start[g + 1] as usize]
    }

    /// Adds every group's terms into `acc` (one accumulator per output),
    /// group by group in order: the runs of tets through a loop of fixed
    /// lengths, the groups between them one by one.
    fn scatter(&self, projections: &[Point], acc: &mut [Acc]) {
        let end = self.sources.len() as u32;
        vectorized(
            #[inline(always)]
            |simd| {
                let (mut g, mut value_start) = (0, 0);
                for &(a, b) in self.tet_runs.iter().chain([(end, end)].iter()) {
                    for g in g..a as usize {
                        let group = self.group(g, value_start, projections);
                        value_start += group.values.len();
                        add_group::<false>(simd, &group, 0, acc);
                    }
                    let (a, b) = (a as usize, b as usize);
                    let from = self.target_start[a] as usize;
                    let targets = self.targets[from..from + 4 * (b - a)].chunks_exact(4);
                    let values = &self.values[value_start..value_start + 12 * (b - a)];
                    for ((&(first, _), targets), values) in self.sources[a..b]
                        .iter()
                        .zip(targets)
                        .zip(values.chunks_exact(12))
                    {
                        let first = first as usize;
                        // The lengths are the run's: the conversions cannot fail.
                        let tet = Tet {
                            projections: projections[first..first + 3]
                                .try_into()
                                .expect("three projections"),
                            targets: targets.try_into().expect("four targets"),
                            values: values.try_into().expect("twelve values"),
                        };
                        add_tet::<false>(simd, &tet, 0, acc);
                    }
                    value_start += 12 * (b - a);
                    g = b;
                }
            },
        );
    }
}

/// Groups the columns (`columns`, ascending, with entries
/// `starts[k]..starts[k + 1]` of `targets` and `values`) into runs of
/// consecutive columns with the same targets, in place: each group's
/// targets are kept once and its values reordered target by target.
/// Returns each group's column range and the start of its targets.
fn group(
    columns: &[u32],
    starts: &[u32],
    targets: &mut Vec<u32>,
    values: &mut [f64],
) -> (Vec<(u32, u32)>, Vec<u32>) {
    let same_targets = |a: usize, b: usize, targets: &[u32]| {
        targets[starts[a] as usize..starts[a + 1] as usize]
            == targets[starts[b] as usize..starts[b + 1] as usize]
    };
    let (mut sources, mut target_start) = (Vec::new(), vec![0u32]);
    let mut scratch = Vec::new();
    let mut written = 0;
    let mut k = 0;
    while k < columns.len() {
        let mut next = k + 1;
        while next < columns.len()
            && columns[next] == columns[next - 1] + 1
            && same_targets(k, next, targets)
        {
            next += 1;
        }
        let (from, to) = (starts[k] as usize, starts[next] as usize);
        let width = starts[k + 1] as usize - from;
        let height = next - k;
        // Column-major (target fastest) to target-major.
        scratch.clear();
        scratch.extend_from_slice(&values[from..to]);
        for t in 0..width {
            for c in 0..height {
                values[from + t * height + c] = scratch[c * width + t];
            }
        }
        targets.copy_within(from..from + width, written);
        written += width;
        sources.push((columns[k], columns[next - 1] + 1));
        target_start.push(written as u32);
        k = next;
    }
    targets.truncate(written);
    targets.shrink_to_fit();
    (sources, target_start)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pd_constraints::Triplet;

    /// A random-looking operator: rows of varying length over scattered
    /// columns (some rows empty), and projections of mixed magnitude so
    /// that a different summation order would round differently.
    pub(super) fn operator(rows: usize, columns: usize) -> CsrMatrix {
        let mut triplets = Vec::new();
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for r in 0..rows {
            if r % 11 == 3 {
                continue;
            }
            for _ in 0..(next() % 40) {
                let c = (next() % columns as u64) as usize;
                let v = (next() % 2001) as f64 / 1000.0 - 1.0;
                triplets.push(Triplet::new(r, c, v * 10f64.powi((next() % 7) as i32 - 3)));
            }
        }
        CsrMatrix::from_triplets(rows, columns, &triplets)
    }

    /// An operator made of elements, as the assembly makes one: element
    /// `e` owns `rows_per` consecutive columns (1 to 4 by element), all
    /// acting on the same few rows, so that the scatter forms groups of
    /// every height; the element order is shuffled against the row order.
    pub(super) fn element_operator(rows: usize, elements: usize) -> (CsrMatrix, usize) {
        let mut triplets = Vec::new();
        let mut column = 0;
        for e in 0..elements {
            let rows_per = 1 + e % 4;
            let stencil: Vec<usize> = (0..4)
                .map(|k| (e * 37 + k * 101 + k * k * e) % rows)
                .collect();
            for c in column..column + rows_per {
                for (k, &r) in stencil.iter().enumerate() {
                    if !stencil[..k].contains(&r) {
                        let v = ((e * 7 + c * 3 + k) % 19) as f64 / 7.0 - 1.3;
                        triplets.push(Triplet::new(r, c, v * 10f64.powi((c % 5) as i32 - 2)));
                    }
                }
            }
            column += rows_per;
        }
        (CsrMatrix::from_triplets(rows, column, &triplets), column)
    }

    pub(super) fn bits(points: &[Point]) -> Vec<[u64; 3]> {
        points
            .iter()
            .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
            .collect()
    }

    /// Projections and constants of mixed magnitude (a different order of
    /// summation would round differently).
    pub(super) fn inputs(n: usize, columns: usize) -> (Vec<Point>, Vec<Point>) {
        let projections = (0..columns)
            .map(|i| {
                let t = i as f64;
                Point::new(
                    (t * 0.37).sin() * 1e3,
                    (t * 1.3).cos(),
                    (t * 0.11).sin() * 1e-2,
                )
            })
            .collect();
        let constant = (0..n)
            .map(|i| Point::new(i as f64 * 0.1, -(i as f64), 1.0 / (1.0 + i as f64)))
            .collect();
        (projections, constant)
    }

    #[test]
    fn scatter_is_the_row_gather_bit_for_bit() {
        let (n, columns) = (300, 900);
        check_against_gather(&operator(n, columns));
        let (b, _) = element_operator(n, 700);
        check_against_gather(&b);
    }

    /// The scatter of `b` gives the bits of the row gather.
    fn check_against_gather(b: &CsrMatrix) {
        let (n, columns) = (b.nrows(), b.ncols());
        let (projections, constant) = inputs(n, columns);
        let factor = 0.73;
        let gathered: Vec<Point> = (0..n)
            .map(|f| constant[f] + b.row_dot(f, &projections) * factor)
            .collect();
        let scatter = ProjectionScatter::new(b).unwrap();
        // On every instruction set this CPU has (AVX-512, AVX2, plain).
        #[cfg(target_arch = "x86_64")]
        let widths = pd_linalg::simd::widths();
        #[cfg(not(target_arch = "x86_64"))]
        let widths = [usize::MAX];
        for width in widths {
            #[cfg(target_arch = "x86_64")]
            pd_linalg::simd::limit_width(width);
            let mut out = vec![Point::new(9.0, 9.0, 9.0); n];
            scatter.rhs(&constant, &projections, factor, &mut out);
            assert_eq!(bits(&out), bits(&gathered), "{width} lanes");
        }
        #[cfg(target_arch = "x86_64")]
        pd_linalg::simd::limit_width(usize::MAX);
        // And the operator's own dispatch on more threads: the row gather.
        let operator = ProjectionOperator::Rows(b.clone());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let mut parallel = vec![Point::zeros(); n];
        pool.install(|| operator.rhs(&constant, &projections, factor, &mut parallel));
        assert_eq!(bits(&parallel), bits(&gathered));
    }

    /// Tets of a box moved off the grid, attachments and energy elements
    /// (which stream their entries through the trait's default), as the
    /// assembly's tests build them.
    fn mixed_blocks() -> (Vec<Box<dyn ConstraintBlock>>, usize) {
        use pd_constraints::{
            Attachment, ConstraintSet, MaterialKind, MaterialSet, MaterialTet, TetStrain,
        };
        let mesh = pd_mesh::generators::box_tets([1.0, 0.7, 0.4], [3, 2, 2]).unwrap();
        let rest: Vec<Point> = mesh
            .vertices()
            .iter()
            .enumerate()
            .map(|(i, p)| {
                p + Point::new(0.01 * (i as f64).sin(), 0.013 * (i as f64 * 1.7).cos(), 0.0)
            })
            .collect();
        let tets = mesh
            .tets()
            .iter()
            .map(|&t| TetStrain::new(&rest, t, 1.7e5, None).unwrap())
            .collect();
        let attachments = [0, 5, 7]
            .iter()
            .map(|&v| Attachment::new(v, Point::new(0.1, 0.2, 0.3), 1e3).unwrap())
            .collect();
        let materials = mesh.tets()[..4]
            .iter()
            .map(|&t| MaterialTet::new(mesh.vertices(), t).unwrap())
            .collect();
        let blocks: Vec<Box<dyn ConstraintBlock>> = vec![
            Box::new(ConstraintSet::new(tets)),
            Box::new(ConstraintSet::new(attachments)),
            Box::new(MaterialSet::new(MaterialKind::NeoHookean, 1e5, 0.3, materials).unwrap()),
        ];
        (blocks, rest.len())
    }

    #[test]
    fn built_from_the_blocks_it_is_the_scatter_of_the_assembled_rows() {
        let (blocks, n) = mixed_blocks();
        let (_, total) = assembly::projection_offsets(&blocks);
        // Every third vertex fixed (vertex 5 carries an attachment).
        let free: Vec<usize> = (0..n).filter(|v| v % 3 != 2).collect();
        let mut free_index = vec![FIXED; n];
        for (f, &v) in free.iter().enumerate() {
            free_index[v] = f;
        }
        let rows = assembly::projection_operator_rows(&blocks, n, &free);
        let projections: Vec<Point> = (0..total)
            .map(|i| Point::new((i as f64 * 0.7).sin(), (i as f64).cos() * 1e2, 0.3))
            .collect();
        let constant = vec![Point::new(0.5, -0.25, 2.0); free.len()];
        for threads in [1, 2] {
            let ProjectionOperator::Scatter(streamed) =
                ProjectionOperator::new(&blocks, &free, &free_index, 1)
            else {
                panic!("one thread scatters");
            };
            let assembled = ProjectionScatter::new(&rows).unwrap();
            let operator = ProjectionOperator::new(&blocks, &free, &free_index, threads);
            let mut a = vec![Point::zeros(); free.len()];
            let mut b = vec![Point::zeros(); free.len()];
            let mut c = vec![Point::zeros(); free.len()];
            streamed.rhs(&constant, &projections, 1.3, &mut a);
            assembled.rhs(&constant, &projections, 1.3, &mut b);
            operator.rhs(&constant, &projections, 1.3, &mut c);
            assert_eq!(bits(&a), bits(&b));
            assert_eq!(bits(&a), bits(&c), "{threads} threads");
            // The tets' three rows each form groups of three projections.
            assert!(streamed.groups.sources.iter().any(|s| s.1 - s.0 == 3));
        }
    }

    #[test]
    fn an_operator_without_rows_or_entries_gives_the_constant() {
        let empty = ProjectionScatter::new(&CsrMatrix::from_triplets(0, 5, &[])).unwrap();
        empty.rhs(&[], &[Point::zeros(); 5], 1.0, &mut []);
        let zero = ProjectionScatter::new(&CsrMatrix::from_triplets(3, 5, &[])).unwrap();
        let constant = [Point::new(1.0, 2.0, 3.0); 3];
        let mut out = [Point::zeros(); 3];
        zero.rhs(&constant, &[Point::zeros(); 5], 2.0, &mut out);
        assert_eq!(out, constant);
    }
}
