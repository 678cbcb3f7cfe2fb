//! The local step: every constraint projected in parallel, each writing only
//! its own rows of the stacked projection vector.

use std::ops::Range;

use pd_constraints::{ConstraintBlock, EnergyBound, assembly};
use pd_mesh::Point;
use rayon::prelude::*;

/// Constraints per parallel task: large enough that the per-task cost (one
/// virtual call, one rayon job) is negligible, small enough to balance.
const CHUNK: usize = 256;

/// The constraint blocks and where their rows sit in the stacked projections.
#[derive(Debug)]
pub(crate) struct LocalStep {
    blocks: Vec<Box<dyn ConstraintBlock>>,
    offsets: Vec<usize>,
    total_rows: usize,
}

impl LocalStep {
    pub fn new(blocks: Vec<Box<dyn ConstraintBlock>>) -> Self {
        let (offsets, total_rows) = assembly::projection_offsets(&blocks);
        Self {
            blocks,
            offsets,
            total_rows,
        }
    }

    pub fn blocks(&self) -> &[Box<dyn ConstraintBlock>] {
        &self.blocks
    }

    pub fn total_rows(&self) -> usize {
        self.total_rows
    }

    /// Projects every constraint at `q` into `projections`. On more than
    /// one thread every chunk is a task of its own that an idle thread can
    /// steal (rayon otherwise stops splitting after a few levels and runs
    /// runs of some 50 chunks in one task, so a thread that starts late or
    /// runs slower leaves the other idle at the end for up to a run:
    /// docs/design/performance.md, "Two threads in the local step").
    /// Each chunk writes its own rows, so the bits are the same either way.
    pub fn project(&self, q: &[Point], projections: &mut [Point]) {
        let max_len = if rayon::current_num_threads() > 1 {
            1
        } else {
            usize::MAX
        };
        for (block, &offset) in self.blocks.iter().zip(&self.offsets) {
            let rows = block.rows_per_constraint();
            let mine = &mut projections[offset..offset + block.len() * rows];
            mine.par_chunks_mut(CHUNK * rows)
                .with_max_len(max_len)
                .enumerate()
                .for_each(|(chunk, out)| block.project_range(q, chunk * CHUNK, out));
        }
    }

    /// [`LocalStep::project`] and then the energy at `q` from those
    /// projections (J; [`LocalStep::energy_bound`]'s total, which is then
    /// the energy itself), in one pass over the constraints
    /// ([`ConstraintBlock::project_energy_range`]) with the same results to
    /// the bit. `partials` (one per [`LocalStep::num_chunks`]) is scratch.
    pub fn project_with_energy(
        &self,
        q: &[Point],
        projections: &mut [Point],
        partials: &mut [EnergyBound],
    ) -> f64 {
        let mut first_chunk = 0;
        for (block, &offset) in self.blocks.iter().zip(&self.offsets) {
            let rows = block.rows_per_constraint();
            let chunks = block.len().div_ceil(CHUNK);
            let mine = &mut projections[offset..offset + block.len() * rows];
            partials[first_chunk..first_chunk + chunks]
                .par_iter_mut()
                .zip(mine.par_chunks_mut(CHUNK * rows))
                .enumerate()
                .for_each(|(chunk, (out, p))| {
                    *out = block.project_energy_range(q, chunk * CHUNK, p);
                });
            first_chunk += chunks;
        }
        self.merge_partials(partials).0.total
    }

    /// Number of parallel tasks of a pass over every constraint: the length
    /// of the buffer [`LocalStep::energy_bound`] needs.
    pub fn num_chunks(&self) -> usize {
        self.blocks.iter().map(|b| b.len().div_ceil(CHUNK)).sum()
    }

    /// An upper bound of the constraint energy at `q` (J) from the last
    /// local step's `projections` (no projection is computed; see
    /// [`ConstraintBlock::energy_bound_range`]), and where its largest term
    /// is: `(bound, block index, constraint index, term)`. `partials` (one
    /// entry per [`LocalStep::num_chunks`]) is scratch; chunks are fixed and
    /// summed in order, so the result does not depend on the thread count.
    pub fn energy_bound(
        &self,
        q: &[Point],
        projections: &[Point],
        partials: &mut [EnergyBound],
    ) -> (EnergyBound, usize) {
        let mut first_chunk = 0;
        for (block, &offset) in self.blocks.iter().zip(&self.offsets) {
            let rows = block.rows_per_constraint();
            let chunks = block.len().div_ceil(CHUNK);
            let mine = &projections[offset..offset + block.len() * rows];
            partials[first_chunk..first_chunk + chunks]
                .par_iter_mut()
                .zip(mine.par_chunks(CHUNK * rows))
                .enumerate()
                .for_each(|(chunk, (out, p))| {
                    *out = block.energy_bound_range(q, chunk * CHUNK, p);
                });
            first_chunk += chunks;
        }
        self.merge_partials(partials)
    }

    /// The per-chunk `partials` of a pass over every constraint summed in a
    /// fixed order (chunks in order within a block, then the blocks in
    /// order), and the block holding the largest term.
    fn merge_partials(&self, partials: &[EnergyBound]) -> (EnergyBound, usize) {
        let mut total = EnergyBound::default();
        let mut worst_block = 0;
        let mut first_chunk = 0;
        for (index, block) in self.blocks.iter().enumerate() {
            let chunks = block.len().div_ceil(CHUNK);
            let mut bound = EnergyBound::default();
            for partial in &partials[first_chunk..first_chunk + chunks] {
                bound.merge(partial);
            }
            // The rule of `EnergyBound::merge`: a larger or NaN term wins.
            if !(bound.worst_energy <= total.worst_energy) {
                worst_block = index;
            }
            total.merge(&bound);
            first_chunk += chunks;
        }
        (total, worst_block)
    }

    /// Total constraint energy at `q` (J). Partial sums over fixed chunks are
    /// added in order, so the result does not depend on the thread count.
    pub fn energy(&self, q: &[Point]) -> f64 {
        self.blocks
            .iter()
            .map(|block| {
                let chunks: Vec<Range<usize>> = (0..block.len())
                    .step_by(CHUNK)
                    .map(|s| s..(s + CHUNK).min(block.len()))
                    .collect();
                let partial: Vec<f64> = chunks
                    .into_par_iter()
                    .map(|range| block.energy_range(q, range))
                    .collect();
                partial.iter().sum::<f64>()
            })
            .sum()
    }
}
