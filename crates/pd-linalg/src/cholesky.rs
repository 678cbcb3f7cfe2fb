//! Sparse Cholesky factorisation with faer: symbolic analysis once per
//! sparsity pattern (AMD, geometric nested dissection or METIS, whichever a
//! cost model of the solve prefers), numeric factorisation into a
//! preallocated buffer, and in-place solves with a 3-column right-hand
//! side. In `cholesky/`: pd's own supernodal solve (`supernodal.rs`, with
//! its dense kernels in `solve_kernels.rs` and its two-thread split in
//! `solve_tree.rs`), METIS (`metis.rs`) and faer's errors in words
//! (`failure.rs`).

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky, simplicial,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::FactorError;
use failure::{numeric_failure, resource_failure};

mod failure;
#[cfg(feature = "metis")]
mod metis;
#[cfg(test)]
mod probes;
mod solve_kernels;
mod solve_tree;
mod supernodal;

/// The lower triangle of a symmetric n x n sparsity pattern in compressed
/// sparse column form, row indices sorted within each column.
#[derive(Debug, Clone)]
pub struct LowerPattern {
    /// Rows and columns.
    pub n: usize,
    /// Where each column starts in `row_idx`, and the end (`n + 1` entries).
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column, diagonal first.
    pub row_idx: Vec<usize>,
}

impl LowerPattern {
    /// The full symmetric matrix with these lower-triangle `values`.
    pub fn to_symmetric(&self, values: &[f64]) -> crate::CsrMatrix {
        let mut triplets = Vec::with_capacity(2 * values.len());
        for col in 0..self.n {
            let range = self.col_ptr[col]..self.col_ptr[col + 1];
            for (&row, &value) in self.row_idx[range.clone()].iter().zip(&values[range]) {
                triplets.push(crate::Triplet::new(row, col, value));
                if row != col {
                    triplets.push(crate::Triplet::new(col, row, value));
                }
            }
        }
        crate::CsrMatrix::from_triplets(self.n, self.n, &triplets)
    }

    /// Position of entry `(row, col)`, `row >= col`, in the value array.
    pub fn slot(&self, row: usize, col: usize) -> Option<usize> {
        let range = self.col_ptr[col]..self.col_ptr[col + 1];
        self.row_idx[range.clone()]
            .binary_search(&row)
            .ok()
            .map(|within| range.start + within)
    }

    fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx)
    }
}

/// Below this many unknowns AMD alone orders well; nested dissection is not
/// tried.
const DISSECTION_MIN: usize = 2000;

/// Largest part that nested dissection leaves in its natural order.
const DISSECTION_LEAF: usize = 64;

/// The nested-dissection elimination orders worth analysing for `pattern`
/// (old indices in pivot order), none for small systems: the geometric
/// dissection below and, with the `metis` feature, METIS's multilevel nested
/// dissection. [`SymbolicFactor::analyse`] weighs them against AMD by
/// `solve_cost`: the geometric split suits regular box meshes, METIS and AMD
/// irregular ones (docs/design/performance.md). Deterministic: METIS runs with its
/// fixed default seed.
pub fn dissection_candidates(
    pattern: &LowerPattern,
    coordinates: &[crate::Point],
) -> Vec<Vec<usize>> {
    let n = pattern.n;
    if n < DISSECTION_MIN || coordinates.len() != n {
        return Vec::new();
    }
    let (start, neighbours) = adjacency(pattern);
    #[cfg(feature = "metis")]
    let metis_order = metis::node_nd(&start, &neighbours);
    let graph = Graph {
        start,
        neighbours,
        coordinates,
    };
    let mut order = Vec::with_capacity(n);
    let mut side = vec![0u8; n];
    let mut ids: Vec<usize> = (0..n).collect();
    graph.dissect(&mut ids, &mut side, &mut order);
    #[allow(unused_mut)]
    let mut candidates = vec![order];
    #[cfg(feature = "metis")]
    candidates.extend(metis_order);
    candidates
}

/// What one supernode costs a 3-column solve, in stored values: the fixed
/// work of visiting it (a small dense triangular solve, an update product and
/// the scatter of its rows) measured as the time of this many stored values.
/// Fitted on this machine to the solve times of three orderings of three
/// meshes (docs/design/performance.md, "Choosing the ordering"): 1.76 ns per stored
/// value and 0.123 us per supernode, about 70 values.
const SUPERNODE_COST: usize = 70;

/// The modelled cost of one solve with `symbolic`'s factor, in stored
/// values: `stored + SUPERNODE_COST x supernodes`. Less fill alone is not a
/// faster solve: METIS's orders of regular grids and of the armadillo store
/// fewer values than the alternatives but in two to four times as many
/// supernodes, most of them under 8 columns wide.
fn solve_cost(symbolic: &SymbolicCholesky<usize>) -> usize {
    symbolic.len_val() + SUPERNODE_COST * supernode_count(symbolic)
}

/// Number of supernodes of `symbolic`'s factor (0 for a simplicial one).
fn supernode_count(symbolic: &SymbolicCholesky<usize>) -> usize {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(s) => s.n_supernodes(),
        SymbolicCholeskyRaw::Simplicial(_) => 0,
    }
}

/// The adjacency of `pattern`'s graph (both triangles, no diagonal) as
/// `(start, neighbours)`: vertex `v`'s neighbours are
/// `neighbours[start[v]..start[v + 1]]`.
fn adjacency(pattern: &LowerPattern) -> (Vec<usize>, Vec<usize>) {
    let n = pattern.n;
    let mut start = vec![0usize; n + 1];
    for col in 0..n {
        for &row in &pattern.row_idx[pattern.col_ptr[col]..pattern.col_ptr[col + 1]] {
            if row != col {
                start[row + 1] += 1;
                start[col + 1] += 1;
            }
        }
    }
    for v in 0..n {
        start[v + 1] += start[v];
    }
    let mut next = start.clone();
    let mut neighbours = vec![0usize; start[n]];
    for col in 0..n {
        for &row in &pattern.row_idx[pattern.col_ptr[col]..pattern.col_ptr[col + 1]] {
            if row != col {
                neighbours[next[row]] = col;
                next[row] += 1;
                neighbours[next[col]] = row;
                next[col] += 1;
            }
        }
    }
    (start, neighbours)
}

/// Adjacency and coordinates for the geometric dissection.
struct Graph<'a> {
    start: Vec<usize>,
    neighbours: Vec<usize>,
    coordinates: &'a [crate::Point],
}

impl Graph<'_> {
    /// Appends a geometric nested-dissection order of `ids` to `order`. Each
    /// part is split at the median of its longest coordinate extent; the
    /// vertices of the lower half that touch the upper half form the
    /// separator, which is eliminated after both halves (recursively).
    fn dissect(&self, ids: &mut [usize], side: &mut [u8], order: &mut Vec<usize>) {
        if ids.len() <= DISSECTION_LEAF {
            order.extend_from_slice(ids);
            return;
        }
        let (lo, hi) = ids.iter().fold(
            (
                crate::Point::repeat(f64::INFINITY),
                crate::Point::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), &v| (lo.inf(&self.coordinates[v]), hi.sup(&self.coordinates[v])),
        );
        let axis = (hi - lo).imax();
        let mid = ids.len() / 2;
        ids.select_nth_unstable_by(mid, |&a, &b| {
            self.coordinates[a][axis]
                .total_cmp(&self.coordinates[b][axis])
                .then(a.cmp(&b))
        });
        const LOWER: u8 = 1;
        const UPPER: u8 = 2;
        const SEPARATOR: u8 = 3;
        for &v in &ids[..mid] {
            side[v] = LOWER;
        }
        for &v in &ids[mid..] {
            side[v] = UPPER;
        }
        for &v in &ids[..mid] {
            if self.neighbours[self.start[v]..self.start[v + 1]]
                .iter()
                .any(|&u| side[u] == UPPER)
            {
                side[v] = SEPARATOR;
            }
        }
        let mut lower: Vec<usize> = ids.iter().copied().filter(|&v| side[v] == LOWER).collect();
        let mut upper: Vec<usize> = ids[mid..].to_vec();
        let separator: Vec<usize> = ids[..mid]
            .iter()
            .copied()
            .filter(|&v| side[v] == SEPARATOR)
            .collect();
        for &v in ids.iter() {
            side[v] = 0;
        }
        // Without progress (everything on the separator), stop splitting.
        if lower.is_empty() {
            order.extend_from_slice(ids);
            return;
        }
        self.dissect(&mut lower, side, order);
        self.dissect(&mut upper, side, order);
        order.extend_from_slice(&separator);
    }
}

/// Structural non-zeros of the Cholesky factor of `pattern` (diagonal
/// included) after the symmetric permutation `inverse` (`inverse[old] =
/// new`): the column counts of the elimination tree, O(nnz(L)) time.
fn exact_factor_nnz(pattern: &LowerPattern, inverse: &[usize]) -> usize {
    let n = pattern.n;
    // The permuted pattern's upper triangle in column form (faer's
    // elimination-tree routine reads the upper triangle; rows need not be
    // sorted).
    let mut col_ptr = vec![0usize; n + 1];
    for col in 0..n {
        for &row in &pattern.row_idx[pattern.col_ptr[col]..pattern.col_ptr[col + 1]] {
            col_ptr[inverse[row].max(inverse[col]) + 1] += 1;
        }
    }
    for j in 0..n {
        col_ptr[j + 1] += col_ptr[j];
    }
    let mut next = col_ptr.clone();
    let mut row_idx = vec![0usize; col_ptr[n]];
    for col in 0..n {
        for &row in &pattern.row_idx[pattern.col_ptr[col]..pattern.col_ptr[col + 1]] {
            let (a, b) = (inverse[row], inverse[col]);
            let column = a.max(b);
            row_idx[next[column]] = a.min(b);
            next[column] += 1;
        }
    }
    let upper = SymbolicSparseColMatRef::new_unsorted_checked(n, n, &col_ptr, None, &row_idx);
    let mut etree = vec![0isize; n];
    let mut col_counts = vec![0usize; n];
    let mut scratch = MemBuffer::new(simplicial::prefactorize_symbolic_cholesky_scratch::<usize>(
        n,
        row_idx.len(),
    ));
    simplicial::prefactorize_symbolic_cholesky(
        &mut etree,
        &mut col_counts,
        upper,
        MemStack::new(&mut scratch),
    );
    col_counts.iter().sum()
}

/// The symbolic factorisation of one pattern, shared by every numeric
/// factorisation of a matrix with that pattern.
pub struct SymbolicFactor {
    /// Shared with the global system that owns the operators (one copy).
    pattern: Arc<LowerPattern>,
    symbolic: SymbolicCholesky<usize>,
    factor_nnz: usize,
    /// Scratch of the numeric factorisation (faer's update matrices), only
    /// while it is wanted: a model whose matrix is constant factorises once
    /// and drops it ([`SymbolicFactor::release_factor_scratch`]), one that
    /// refactorises every step keeps it.
    factor_scratch: Option<MemBuffer>,
    /// Scratch of faer's solve (simplicial factors, or more than three
    /// columns).
    solve_scratch: MemBuffer,
    /// The 3-column solve for supernodal factors (faer's for simplicial).
    fast_solve: Option<supernodal::SupernodalSolve>,
    /// The right-hand side as points, for `fast_solve`.
    points: Vec<crate::Point>,
    /// The right-hand side as three columns, for faer's solve of points
    /// ([`SymbolicFactor::solve_points`]; empty when `fast_solve` serves).
    columns: faer::Mat<f64>,
}

impl std::fmt::Debug for SymbolicFactor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SymbolicFactor")
            .field("n", &self.pattern.n)
            .field("pattern_len", &self.pattern.row_idx.len())
            .field("factor_len", &self.symbolic.len_val())
            .finish_non_exhaustive()
    }
}

/// Numeric Cholesky values for one set of matrix values, in faer's layout
/// or, after [`SymbolicFactor::pack`], packed.
#[derive(Debug)]
pub struct NumericFactor {
    values: Vec<f64>,
    /// Empty in faer's layout; when packed, where each supernode's values
    /// start and, last, their total (`supernodal_solve.rs`).
    packed_ptr: Vec<usize>,
}

impl NumericFactor {
    /// Whether the values are packed.
    fn is_packed(&self) -> bool {
        !self.packed_ptr.is_empty()
    }
}

impl SymbolicFactor {
    /// Orders and analyses the pattern; allocates scratch for numeric
    /// factorisations and 3-column solves. The ordering is AMD or one of the
    /// `candidates` (elimination orders, old indices in pivot order),
    /// whichever has the lowest `solve_cost` (ties keep the earlier, AMD
    /// first): one symbolic analysis per candidate, deterministic.
    pub fn analyse(
        pattern: impl Into<Arc<LowerPattern>>,
        candidates: &[Vec<usize>],
    ) -> Result<Self, FactorError> {
        let pattern = pattern.into();
        fn analyse(
            pattern: &LowerPattern,
            ordering: SymmetricOrdering<'_, usize>,
        ) -> Result<SymbolicCholesky<usize>, FactorError> {
            factorize_symbolic_cholesky(
                pattern.symbolic(),
                Side::Lower,
                ordering,
                CholeskySymbolicParams::default(),
            )
            .map_err(|e| FactorError {
                reason: format!("symbolic analysis failed: {}", resource_failure(e)),
            })
        }
        let mut symbolic = analyse(&pattern, SymmetricOrdering::Amd)?;
        let mut cost = solve_cost(&symbolic);
        for forward in candidates {
            let mut inverse = vec![0; forward.len()];
            for (new, &old) in forward.iter().enumerate() {
                inverse[old] = new;
            }
            let perm = faer::perm::PermRef::new_checked(forward, &inverse, pattern.n);
            let candidate = analyse(&pattern, SymmetricOrdering::Custom(perm))?;
            let candidate_cost = solve_cost(&candidate);
            if candidate_cost < cost {
                (symbolic, cost) = (candidate, candidate_cost);
            }
        }
        Ok(Self::with_symbolic(pattern, symbolic))
    }

    /// The factor of `pattern` with the symbolic analysis `symbolic` (its
    /// ordering already chosen): structural count, scratch, solve plan.
    fn with_symbolic(pattern: Arc<LowerPattern>, symbolic: SymbolicCholesky<usize>) -> Self {
        let factor_nnz = match symbolic.perm() {
            Some(perm) => exact_factor_nnz(&pattern, perm.arrays().1),
            None => exact_factor_nnz(&pattern, &(0..pattern.n).collect::<Vec<_>>()),
        };
        let solve_scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
        let fast_solve = supernodal::SupernodalSolve::new(&symbolic);
        let columns = match fast_solve {
            Some(_) => faer::Mat::zeros(0, 0),
            None => faer::Mat::zeros(pattern.n, 3),
        };
        Self {
            points: vec![crate::Point::zeros(); pattern.n],
            columns,
            pattern,
            symbolic,
            factor_nnz,
            factor_scratch: None,
            solve_scratch,
            fast_solve,
        }
    }

    /// The elimination order chosen (old indices in pivot order), if any.
    pub fn order(&self) -> Option<Vec<usize>> {
        self.symbolic.perm().map(|perm| perm.arrays().0.to_vec())
    }

    /// Number of supernodes of the factor (0 for a simplicial factor).
    pub fn supernodes(&self) -> usize {
        supernode_count(&self.symbolic)
    }

    /// The analysed pattern.
    pub fn pattern(&self) -> &LowerPattern {
        &self.pattern
    }

    /// Number of stored values of the factor `L` (memory: 8 bytes each).
    pub fn factor_len(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Number of values a factor stores once [`Self::pack`]ed (what the
    /// global system keeps and a solve reads): [`Self::factor_len`] less the
    /// upper triangles of the supernodes' diagonal blocks, which faer's
    /// layout stores as padding; [`Self::factor_len`] when the factor would
    /// not be packed.
    pub fn packed_len(&self) -> usize {
        match self.fast_solve {
            Some(_) => supernodal::packed_len(&self.symbolic).unwrap_or(self.factor_len()),
            None => self.factor_len(),
        }
    }

    /// Structural non-zeros of `L` in the chosen order, diagonal included,
    /// without the explicit zeros that supernode amalgamation stores: the
    /// count CHOLMOD reports as `lnz`, comparable across solvers (the
    /// stored values, [`Self::factor_len`], are what a solve reads).
    pub fn factor_nnz(&self) -> usize {
        self.factor_nnz
    }

    /// Factorises the matrix with this pattern and the given lower-triangle
    /// values (in pattern order).
    pub fn factorise(&mut self, values: &[f64]) -> Result<NumericFactor, FactorError> {
        let mut factor = NumericFactor {
            values: vec![0.0; self.symbolic.len_val()],
            packed_ptr: Vec::new(),
        };
        self.refactorise(values, &mut factor)?;
        Ok(factor)
    }

    /// Drops the numeric factorisation's scratch until the next
    /// factorisation needs it again (it allocates it then): for a matrix
    /// that is factorised once, so that the scratch does not stay through
    /// the steps (13 MB of the 95k-vertex beam's).
    pub fn release_factor_scratch(&mut self) {
        self.factor_scratch = None;
    }

    /// Stores `factor` packed for the 3-column solve (nothing without one,
    /// or if it is packed already): each supernode's diagonal block without
    /// its upper triangle, which faer's layout stores as padding that every
    /// solve pass loads with the lower triangle's cache lines (15-16 % of
    /// the values of the armadillo's and the beams' factors). Compacted in
    /// place and the buffer shrunk, so memory never holds a second copy.
    /// For a factor solved with three columns at a time and refactorised
    /// rarely: faer's solves ([`Self::solve_in_place`] with other column
    /// counts, [`Self::solve_in_place_wide`]) copy a packed factor back to
    /// faer's layout at every call, and [`Self::refactorise`] regrows it.
    pub fn pack(&self, factor: &mut NumericFactor) {
        if self.fast_solve.is_none() || factor.is_packed() {
            return;
        }
        if let Some(packed_ptr) = supernodal::pack(&self.symbolic, &mut factor.values) {
            factor.values.truncate(packed_ptr[packed_ptr.len() - 1]);
            factor.values.shrink_to_fit();
            factor.packed_ptr = packed_ptr;
        }
    }

    /// `factor`'s values in faer's layout: the values themselves, or a
    /// copy of a packed factor unpacked.
    fn faer_values<'a>(&self, factor: &'a NumericFactor) -> std::borrow::Cow<'a, [f64]> {
        match factor.is_packed() {
            false => std::borrow::Cow::Borrowed(&factor.values),
            true => std::borrow::Cow::Owned(supernodal::unpack(
                &self.symbolic,
                &factor.values,
                &factor.packed_ptr,
            )),
        }
    }

    /// Recomputes `factor` for new values with the same pattern, without
    /// allocating once the factorisation scratch exists (the first call
    /// after [`SymbolicFactor::analyse`] or a release allocates it), except
    /// that a packed factor regrows to faer's length (faer overwrites every
    /// value) and is packed again.
    pub fn refactorise(
        &mut self,
        values: &[f64],
        factor: &mut NumericFactor,
    ) -> Result<(), FactorError> {
        let packed = factor.is_packed();
        if packed {
            factor.values.resize(self.symbolic.len_val(), 0.0);
            factor.packed_ptr = Vec::new();
        }
        let matrix = SparseColMatRef::new(self.pattern.symbolic(), values);
        let symbolic = &self.symbolic;
        let scratch = self.factor_scratch.get_or_insert_with(|| {
            MemBuffer::new(
                symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            )
        });
        self.symbolic
            .factorize_numeric_llt(
                &mut factor.values,
                matrix,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(scratch),
                Default::default(),
            )
            .map_err(|e| FactorError {
                reason: numeric_failure(e),
            })?;
        if packed {
            self.pack(factor);
        }
        Ok(())
    }

    /// Solves `A x = b` in place for any number of columns of `rhs`, with
    /// scratch allocated for them (the modal analysis's block solves).
    pub fn solve_in_place_wide(&self, factor: &NumericFactor, rhs: MatMut<'_, f64>) {
        let mut scratch = MemBuffer::new(
            self.symbolic
                .solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq),
        );
        LltRef::new(&self.symbolic, &self.faer_values(factor)).solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut scratch),
        );
    }

    /// Solves `A x = b` in place for `rhs` given as one point per row (the
    /// global step's x, y and z at once): the supernodal solve without the
    /// copies to and from columns, or faer's solve of three columns.
    pub fn solve_points(&mut self, factor: &NumericFactor, rhs: &mut [crate::Point]) {
        if let Some(fast) = &mut self.fast_solve {
            fast.solve(&self.symbolic, factor, rhs);
            return;
        }
        let mut columns = std::mem::replace(&mut self.columns, faer::Mat::zeros(0, 0));
        for (r, p) in rhs.iter().enumerate() {
            for k in 0..3 {
                columns[(r, k)] = p[k];
            }
        }
        self.solve_in_place(factor, columns.as_mut());
        for (r, p) in rhs.iter_mut().enumerate() {
            *p = crate::Point::new(columns[(r, 0)], columns[(r, 1)], columns[(r, 2)]);
        }
        self.columns = columns;
    }

    /// Solves `A x = b` in place for every column of `rhs`.
    pub fn solve_in_place(&mut self, factor: &NumericFactor, mut rhs: MatMut<'_, f64>) {
        if let (Some(fast), 3) = (&mut self.fast_solve, rhs.ncols()) {
            for (r, p) in self.points.iter_mut().enumerate() {
                *p = crate::Point::new(rhs[(r, 0)], rhs[(r, 1)], rhs[(r, 2)]);
            }
            fast.solve(&self.symbolic, factor, &mut self.points);
            for (r, p) in self.points.iter().enumerate() {
                for k in 0..3 {
                    rhs[(r, k)] = p[k];
                }
            }
            return;
        }
        LltRef::new(&self.symbolic, &self.faer_values(factor)).solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut self.solve_scratch),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Point;

    /// The lower pattern and values of `I + graph Laplacian` of an
    /// `m x m x m` grid with 6-neighbour edges, and the grid coordinates.
    fn grid(m: usize) -> (LowerPattern, Vec<f64>, Vec<Point>) {
        let index = |i: usize, j: usize, k: usize| i + m * (j + m * k);
        let n = m * m * m;
        let (mut col_ptr, mut row_idx, mut values) = (vec![0], Vec::new(), Vec::new());
        let mut coordinates = Vec::with_capacity(n);
        for k in 0..m {
            for j in 0..m {
                for i in 0..m {
                    coordinates.push(Point::new(i as f64, j as f64, k as f64));
                    let mut below = vec![];
                    if i + 1 < m {
                        below.push(index(i + 1, j, k));
                    }
                    if j + 1 < m {
                        below.push(index(i, j + 1, k));
                    }
                    if k + 1 < m {
                        below.push(index(i, j, k + 1));
                    }
                    row_idx.push(index(i, j, k));
                    values.push(7.0);
                    for r in below {
                        row_idx.push(r);
                        values.push(-1.0);
                    }
                    col_ptr.push(row_idx.len());
                }
            }
        }
        (
            LowerPattern {
                n,
                col_ptr,
                row_idx,
            },
            values,
            coordinates,
        )
    }

    #[test]
    fn candidates_are_permutations_and_the_cheapest_solves_exactly() {
        let (pattern, values, coordinates) = grid(14);
        let candidates = dissection_candidates(&pattern, &coordinates);
        assert_eq!(
            candidates.len(),
            if cfg!(feature = "metis") { 2 } else { 1 }
        );
        for order in &candidates {
            let mut seen = vec![false; pattern.n];
            for &v in order {
                assert!(!seen[v], "vertex {v} twice");
                seen[v] = true;
            }
            assert!(seen.iter().all(|&s| s));
        }

        // The choice is the cheapest of AMD and every candidate alone.
        let mut best = SymbolicFactor::analyse(pattern.clone(), &candidates).unwrap();
        let cost = |f: &SymbolicFactor| solve_cost(&f.symbolic);
        let amd = SymbolicFactor::analyse(pattern.clone(), &[]).unwrap();
        assert!(cost(&best) <= cost(&amd));
        for order in &candidates {
            let single =
                SymbolicFactor::analyse(pattern.clone(), std::slice::from_ref(order)).unwrap();
            assert!(cost(&best) <= cost(&single));
        }
        assert_eq!(
            cost(&best),
            best.factor_len() + SUPERNODE_COST * best.supernodes()
        );
        // Solve A x = A x_true for a known x_true; A is diagonally dominant
        // (condition number < 2), so round-off stays near 1e-15.
        let factor = best.factorise(&values).unwrap();
        let full = pattern.to_symmetric(&values);
        let truth: Vec<Point> = (0..pattern.n)
            .map(|v| Point::new(v as f64, (v % 7) as f64, 1.0))
            .collect();
        let mut rhs_points = vec![Point::zeros(); pattern.n];
        full.mul_points(&truth, &mut rhs_points);
        let mut rhs = faer::Mat::from_fn(pattern.n, 3, |r, c| rhs_points[r][c]);
        best.solve_in_place(&factor, rhs.as_mut());
        for (v, t) in truth.iter().enumerate() {
            for c in 0..3 {
                assert!((rhs[(v, c)] - t[c]).abs() < 1e-9 * (1.0 + t[c].abs()));
            }
        }
    }

    /// pd's supernodal 3-column solve against faer's on the orders the
    /// solver uses (AMD, geometric, METIS) of a 14^3 grid: the same
    /// arithmetic in another order, so they agree to round-off. The matrix
    /// is diagonally dominant (condition number < 2), so both stay within
    /// a few ulps of the exact solution: 1e-13 relative is 500 ulps.
    #[test]
    fn supernodal_solve_matches_faer() {
        let (pattern, values, coordinates) = grid(14);
        let mut orders: Vec<Vec<Vec<usize>>> = vec![Vec::new()];
        orders.extend(
            dissection_candidates(&pattern, &coordinates)
                .into_iter()
                .map(|o| vec![o]),
        );
        for candidates in orders {
            let mut factor = SymbolicFactor::analyse(pattern.clone(), &candidates).unwrap();
            assert!(
                factor.fast_solve.is_some(),
                "a 2,744-unknown grid is supernodal"
            );
            let numeric = factor.factorise(&values).unwrap();
            let b = faer::Mat::from_fn(pattern.n, 3, |r, c| ((r * 5 + c * 3) % 11) as f64 - 5.0);
            let mut ours = b.clone();
            factor.solve_in_place(&numeric, ours.as_mut());
            let fast = factor.fast_solve.take();
            let mut theirs = b.clone();
            factor.solve_in_place(&numeric, theirs.as_mut());
            factor.fast_solve = fast;
            for r in 0..pattern.n {
                for c in 0..3 {
                    let (a, t) = (ours[(r, c)], theirs[(r, c)]);
                    assert!(
                        (a - t).abs() <= 1e-13 * (1.0 + t.abs()),
                        "row {r} column {c}: {a} vs {t}"
                    );
                }
            }
        }
    }

    #[test]
    fn split_supernodal_solve_is_the_same_on_one_and_two_threads() {
        let (pattern, values, coordinates) = grid(14);
        for order in dissection_candidates(&pattern, &coordinates) {
            let mut factor = SymbolicFactor::analyse(pattern.clone(), &[order]).unwrap();
            let numeric = factor.factorise(&values).unwrap();
            assert!(
                factor.fast_solve.as_ref().is_some_and(|f| f.is_split()),
                "a dissection order of a 2,744-unknown grid has two subtrees worth a thread each"
            );
            let b = faer::Mat::from_fn(pattern.n, 3, |r, c| ((r * 7 + c * 5) % 13) as f64 - 6.0);
            let solved = |threads: usize, factor: &mut SymbolicFactor| {
                let mut x = b.clone();
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| factor.solve_in_place(&numeric, x.as_mut()));
                x
            };
            let (one, two) = (solved(1, &mut factor), solved(2, &mut factor));
            for r in 0..pattern.n {
                for c in 0..3 {
                    assert_eq!(one[(r, c)].to_bits(), two[(r, c)].to_bits(), "row {r}");
                }
            }
        }
    }

    #[test]
    fn packed_len_is_what_pack_keeps() {
        // The count the global system reports (`GlobalSystem::factor_len`)
        // must be the packed factor's length, and below faer's stored count
        // by exactly the diagonal blocks' strict upper triangles.
        let (pattern, values, coordinates) = grid(14);
        for order in dissection_candidates(&pattern, &coordinates) {
            let mut factor = SymbolicFactor::analyse(pattern.clone(), &[order]).unwrap();
            let mut numeric = factor.factorise(&values).unwrap();
            assert_eq!(numeric.values.len(), factor.factor_len());
            factor.pack(&mut numeric);
            assert!(numeric.is_packed());
            assert_eq!(numeric.values.len(), factor.packed_len());
            let SymbolicCholeskyRaw::Supernodal(supernodal) = factor.symbolic.raw() else {
                panic!("a dissection order of a 2,744-unknown grid is supernodal");
            };
            let padding: usize = (supernodal.supernode_begin().iter())
                .zip(supernodal.supernode_end())
                .map(|(begin, end)| (end - begin) * (end - begin - 1) / 2)
                .sum();
            assert_eq!(factor.packed_len() + padding, factor.factor_len());
        }
    }

    #[test]
    fn exact_factor_nnz_counts_the_fill_of_an_arrow() {
        // The arrow matrix (first row and column full, plus the diagonal)
        // eliminated first-vertex-first fills completely: n (n + 1) / 2
        // non-zeros; eliminated with the hub last it does not fill: 2n - 1.
        let n = 6;
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::new();
        for col in 0..n {
            row_idx.push(col);
            if col == 0 {
                row_idx.extend(1..n);
            }
            col_ptr.push(row_idx.len());
        }
        let pattern = LowerPattern {
            n,
            col_ptr,
            row_idx,
        };
        let identity: Vec<usize> = (0..n).collect();
        assert_eq!(exact_factor_nnz(&pattern, &identity), n * (n + 1) / 2);
        let hub_last: Vec<usize> = (0..n).map(|old| (old + n - 1) % n).collect();
        assert_eq!(exact_factor_nnz(&pattern, &hub_last), 2 * n - 1);
        let amd = SymbolicFactor::analyse(pattern, &[]).unwrap();
        assert_eq!(amd.factor_nnz(), 2 * n - 1);
        assert!(amd.factor_len() >= amd.factor_nnz());
    }

    #[test]
    fn small_systems_keep_amd_only() {
        let (pattern, _, coordinates) = grid(5);
        assert!(dissection_candidates(&pattern, &coordinates).is_empty());
    }
}
