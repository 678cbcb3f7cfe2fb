//! `projdyn._projdyn`: the Rust side of the Python package `projdyn`. The
//! package's `__init__.py` re-exports everything here; the stubs in
//! `projdyn/__init__.pyi` document it for editors.
//!
//! A [`Model`] collects bodies (NumPy arrays) and their constraints as the
//! entries of a scene; a [`Simulation`] is built from a scene file or from a
//! model through the scene loader (`pd_io::scene`), so that both are
//! validated and built the same way and report errors with the same
//! messages. Every call that runs the simulator releases the GIL.

mod convert;
mod errors;
mod gradient;
mod model;
mod simulation;

use pyo3::prelude::*;

/// The module `projdyn._projdyn`.
#[pymodule]
fn _projdyn(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<model::Model>()?;
    m.add_class::<simulation::Simulation>()?;
    m.add_function(wrap_pyfunction!(simulation::modes, m)?)?;
    m.add_function(wrap_pyfunction!(gradient::gradient, m)?)?;
    m.add_function(wrap_pyfunction!(simulation::restore_simulation, m)?)?;
    m.add_function(wrap_pyfunction!(model::restore_model, m)?)?;
    m.add(
        "DivergenceError",
        m.py().get_type::<errors::DivergenceError>(),
    )?;
    Ok(())
}
