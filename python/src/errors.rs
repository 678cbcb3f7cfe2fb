//! Rust errors as Python exceptions: invalid input is `ValueError` (with
//! the scene loader's message), a file the system refuses is `OSError`, a
//! divergence is [`DivergenceError`], and a panic (a bug) is `RuntimeError`,
//! never an abort of the interpreter.

use std::panic::AssertUnwindSafe;

use pd_solver::SolverError;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    projdyn,
    DivergenceError,
    PyRuntimeError,
    "The simulation diverged: a position became non-finite or the energy blew up.\n\n\
     Attributes: `step` (the step that failed, from 1), `time` (s, at the end of that \
     step) and `reason` (what was detected, naming the vertex where there is one). The \
     simulation is left at the last good step."
);

/// A scene or mesh error as a Python exception.
pub(crate) fn io_error(e: pd_io::Error) -> PyErr {
    match e {
        pd_io::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A solver error as a Python exception: [`DivergenceError`] with `step`,
/// `time` and `reason` for a divergence, `ValueError` otherwise.
pub(crate) fn solver_error(py: Python<'_>, e: SolverError) -> PyErr {
    match &e {
        SolverError::Diverged { step, time, reason } => {
            let err = DivergenceError::new_err(e.to_string());
            let value = err.value(py);
            // Setting attributes on a fresh exception object cannot fail
            // short of memory exhaustion; the exception is raised either way.
            let _ = value.setattr("step", *step);
            let _ = value.setattr("time", *time);
            let _ = value.setattr("reason", reason.clone());
            err
        }
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// Runs `f`, turning a panic into `RuntimeError` (a panic is a bug of the
/// simulator, reported rather than ending the interpreter).
pub(crate) fn catch_panic<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match std::panic::catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(PyRuntimeError::new_err(format!(
                "internal error in the simulator (please report it): {message}"
            )))
        }
    }
}
