//! The packed layout of a supernodal factor (`SymbolicFactor::pack`):
//! each supernode's columns from their diagonal entry down, without the
//! upper triangle of the diagonal block that faer's layout stores as
//! padding. `Block` (`solve_kernels.rs`) reads both layouts.

use faer::sparse::linalg::cholesky::SymbolicCholesky;

use super::super::NumericFactor;
use super::super::solve_kernels::Block;
use super::Structure;

impl<'a> Structure<'a> {
    /// This view for `factor`'s layout.
    pub(super) fn in_layout_of(self, factor: &'a NumericFactor) -> Self {
        match factor.is_packed() {
            false => self,
            true => Self {
                value_ptr: &factor.packed_ptr,
                packed: true,
                ..self
            },
        }
    }

    /// Supernode `s`'s columns in `values`.
    #[inline(always)]
    pub(super) fn block<'v>(&self, values: &'v [f64], s: usize) -> Block<'v> {
        let c = self.end[s] - self.begin[s];
        let ld = c + self.row_len[s];
        Block::new(&values[self.value_ptr[s]..], ld, c, self.packed)
    }

    /// Where each supernode's values start in the packed layout, and after
    /// the last (the packed length).
    fn packed_ptr(&self) -> Vec<usize> {
        let mut ptr = Vec::with_capacity(self.begin.len() + 1);
        ptr.push(0);
        for s in 0..self.begin.len() {
            let c = self.end[s] - self.begin[s];
            ptr.push(ptr[s] + Block::stored(c + self.row_len[s], c, true));
        }
        ptr
    }
}

/// Compacts `values`, a supernodal factor in faer's layout with
/// `symbolic`'s structure, into the packed one in place (each column's run
/// moves left or stays, so one pass in increasing order overwrites only
/// values already moved) and returns the packed supernodes' starts; the
/// caller shrinks the buffer. `None` for a simplicial factor.
pub(in crate::cholesky) fn pack(
    symbolic: &SymbolicCholesky<usize>,
    values: &mut [f64],
) -> Option<Vec<usize>> {
    let structure = Structure::of(symbolic)?;
    let packed_ptr = structure.packed_ptr();
    for s in 0..structure.begin.len() {
        let c = structure.end[s] - structure.begin[s];
        let ld = c + structure.row_len[s];
        let (from, mut to) = (structure.value_ptr[s], packed_ptr[s]);
        for j in 0..c {
            values.copy_within(from + j * (ld + 1)..from + (j + 1) * ld, to);
            to += ld - j;
        }
        debug_assert_eq!(to, packed_ptr[s + 1]);
    }
    Some(packed_ptr)
}

/// How many values [`pack`] leaves of a factor with `symbolic`'s
/// structure; `None` for a simplicial factor (never packed).
pub(in crate::cholesky) fn packed_len(symbolic: &SymbolicCholesky<usize>) -> Option<usize> {
    Structure::of(symbolic).map(|structure| structure.packed_ptr()[structure.begin.len()])
}

/// The inverse of [`pack`]: `packed`'s values in faer's layout, the
/// padding zero (for faer's solves of a packed factor).
pub(in crate::cholesky) fn unpack(
    symbolic: &SymbolicCholesky<usize>,
    packed: &[f64],
    packed_ptr: &[usize],
) -> Vec<f64> {
    let structure = Structure::of(symbolic).expect("only a supernodal factor is packed");
    let mut values = vec![0.0; symbolic.len_val()];
    for s in 0..structure.begin.len() {
        let c = structure.end[s] - structure.begin[s];
        let ld = c + structure.row_len[s];
        let block = Block::new(&packed[packed_ptr[s]..], ld, c, true);
        for j in 0..c {
            let start = structure.value_ptr[s] + j * (ld + 1);
            values[start..start + ld - j].copy_from_slice(block.column(j));
        }
    }
    values
}
