//! Sparse Cholesky factorisation of the global matrix with faer: symbolic
//! analysis (AMD ordering) once per sparsity pattern, numeric factorisation
//! into a preallocated buffer, and in-place solves with a 3-column
//! right-hand side.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::SolverError;

/// The lower triangle of a symmetric n x n sparsity pattern in compressed
/// sparse column form, row indices sorted within each column.
#[derive(Debug, Clone)]
pub(crate) struct LowerPattern {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
}

impl LowerPattern {
    /// The full symmetric matrix with these lower-triangle `values`.
    pub fn to_symmetric(&self, values: &[f64]) -> pd_constraints::CsrMatrix {
        let mut triplets = Vec::with_capacity(2 * values.len());
        for col in 0..self.n {
            let range = self.col_ptr[col]..self.col_ptr[col + 1];
            for (&row, &value) in self.row_idx[range.clone()].iter().zip(&values[range]) {
                triplets.push(pd_constraints::Triplet::new(row, col, value));
                if row != col {
                    triplets.push(pd_constraints::Triplet::new(col, row, value));
                }
            }
        }
        pd_constraints::CsrMatrix::from_triplets(self.n, self.n, &triplets)
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

/// The symbolic factorisation of one pattern, shared by every numeric
/// factorisation of a matrix with that pattern.
pub(crate) struct SymbolicFactor {
    pattern: LowerPattern,
    symbolic: SymbolicCholesky<usize>,
    scratch: MemBuffer,
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

/// Numeric Cholesky values for one set of matrix values.
#[derive(Debug)]
pub(crate) struct NumericFactor {
    values: Vec<f64>,
}

impl SymbolicFactor {
    /// Orders (AMD) and analyses the pattern; allocates scratch for numeric
    /// factorisations and 3-column solves.
    pub fn analyse(pattern: LowerPattern) -> Result<Self, SolverError> {
        let symbolic = factorize_symbolic_cholesky(
            pattern.symbolic(),
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| SolverError::Factorisation {
            reason: format!("symbolic analysis failed: {e:?}"),
        })?;
        let scratch = MemBuffer::new(StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(3, Par::Seq),
        ]));
        Ok(Self {
            pattern,
            symbolic,
            scratch,
        })
    }

    /// The analysed pattern.
    pub fn pattern(&self) -> &LowerPattern {
        &self.pattern
    }

    /// Number of stored values of the factor `L` (memory: 8 bytes each).
    pub fn factor_len(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Factorises the matrix with this pattern and the given lower-triangle
    /// values (in pattern order).
    pub fn factorise(&mut self, values: &[f64]) -> Result<NumericFactor, SolverError> {
        let mut factor = NumericFactor {
            values: vec![0.0; self.symbolic.len_val()],
        };
        self.refactorise(values, &mut factor)?;
        Ok(factor)
    }

    /// Recomputes `factor` for new values with the same pattern, without
    /// allocating.
    pub fn refactorise(
        &mut self,
        values: &[f64],
        factor: &mut NumericFactor,
    ) -> Result<(), SolverError> {
        let matrix = SparseColMatRef::new(self.pattern.symbolic(), values);
        self.symbolic
            .factorize_numeric_llt(
                &mut factor.values,
                matrix,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut self.scratch),
                Default::default(),
            )
            .map_err(|e| SolverError::Factorisation {
                reason: format!("the global matrix is not positive definite ({e})"),
            })?;
        Ok(())
    }

    /// Solves `A x = b` in place for every column of `rhs`.
    pub fn solve_in_place(&mut self, factor: &NumericFactor, rhs: MatMut<'_, f64>) {
        LltRef::new(&self.symbolic, &factor.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut self.scratch),
        );
    }
}
