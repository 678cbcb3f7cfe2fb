//! faer's factorisation errors in words: they display as their `Debug`
//! text (`NonPositivePivot { index: 2 }`), which tells a user nothing.

use faer::linalg::solvers::LltError;
use faer::sparse::FaerError;

/// Why a numeric factorisation failed. The global matrix is positive definite for every
/// valid setting (`crates/pd-solver/tests/global_matrix_spd.rs`), so a pivot that is not
/// positive means coefficients that overflow or lose all precision. The
/// pivot's index is left out: it counts in the elimination order, which
/// names no vertex.
pub(super) fn numeric_failure(error: LltError) -> String {
    match error {
        LltError::NonPositivePivot { .. } => {
            "the global matrix is not positive definite (a pivot of its Cholesky factorisation \
             is not positive): its coefficients are out of range; check dt, masses, stiffness \
             and damping values for extreme magnitudes"
                .into()
        }
    }
}

/// faer's failures that are not numerical, in words.
pub(super) fn resource_failure(error: FaerError) -> &'static str {
    match error {
        FaerError::OutOfMemory => "out of memory",
        FaerError::IndexOverflow => "the matrix is too large to index",
        _ => "faer reported an unknown failure",
    }
}
