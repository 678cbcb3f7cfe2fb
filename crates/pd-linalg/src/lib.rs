//! Sparse linear algebra for Projective Dynamics. [`cholesky`] orders a
//! symmetric sparsity pattern (AMD, geometric nested dissection or METIS,
//! chosen by a cost model of the solve), factorises matrices with that
//! pattern into preallocated buffers with faer, and solves them with three
//! right-hand-side columns at once through pd's own supernodal solve, the
//! same bits for any thread count and instruction set. [`sparse`] holds the
//! compressed-sparse-row operators the constraints assemble ([`CsrMatrix`]),
//! applied to vectors of [`Point`]s. [`simd`] is the one run-time dispatch
//! to AVX-512, AVX2 or plain code that the local step and the solve share.
//! The crate knows nothing of meshes, constraints or time.
//!
//! ```
//! use pd_linalg::cholesky::{LowerPattern, SymbolicFactor};
//! use pd_linalg::Point;
//!
//! // The tridiagonal matrix 2 on the diagonal, -1 beside it (lower triangle).
//! let n = 4;
//! let col_ptr = (0..=n).map(|c| (2 * c).min(2 * n - 1)).collect();
//! let row_idx = (0..n).flat_map(|c| [c, c + 1]).take(2 * n - 1).collect();
//! let values: Vec<f64> = (0..2 * n - 1).map(|k| if k % 2 == 0 { 2.0 } else { -1.0 }).collect();
//! let pattern = LowerPattern { n, col_ptr, row_idx };
//! let mut symbolic = SymbolicFactor::analyse(pattern, &[]).unwrap();
//! let factor = symbolic.factorise(&values).unwrap();
//! // A x = (1, 0, 0, 1) has the solution x = (1, 1, 1, 1) in every column.
//! let mut x = vec![Point::new(1.0, 1.0, 1.0), Point::zeros(), Point::zeros(), Point::new(1.0, 1.0, 1.0)];
//! symbolic.solve_points(&factor, &mut x);
//! assert!(x.iter().all(|p| (p - Point::new(1.0, 1.0, 1.0)).norm() < 1e-12));
//! ```

pub mod cholesky;
#[cfg(test)]
mod fixtures;
pub mod simd;
pub mod sparse;

pub use sparse::{CsrMatrix, Triplet};

/// A point or a row of three right-hand-side columns (x, y, z): the same
/// type as `pd_mesh::Point`.
pub type Point = nalgebra::Vector3<f64>;

/// A factorisation or its symbolic analysis failed; the reason is in words.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{reason}")]
pub struct FactorError {
    /// What went wrong.
    pub reason: String,
}
