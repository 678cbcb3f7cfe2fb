//! `projdyn.gradient`: the gradient of a probe loss on a run with respect
//! to damping coefficients, stiffness, density, the initial state and
//! gravity, by the adjoint method (`pd_adjoint`,
//! docs/design/gradients.md), with the GIL released.

use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pd_adjoint::{AdjointOptions, Parameter, ParameterGradient, ProbeLoss};
use pd_mesh::Point;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::to_array;
use crate::errors::{catch_panic, io_error};
use crate::simulation::Simulation;

/// The loss and its gradient over the next `steps` steps of a simulation.
///
/// The loss is the mean over the steps `1..=steps` and the probes of the
/// squared distance (m^2) between probe vertex `probes[p]` and
/// `targets[s, p]`, `targets` an `(steps, P, 3)` array. `parameters` names
/// what to differentiate by, as the scene names it: `"damping.mass"`
/// (`a1`), `"damping.stiffness"` (`a2`),
/// `"body[i].constraints[j].stiffness"`, `"body[i].density"`, and
/// `"initial positions"`, `"initial velocities"`, `"gravity"`.
///
/// The simulation itself is not stepped: the run starts from a copy of its
/// current state, with each step converged (relative change 1e-10), and the
/// backward pass reuses the run's prefactored matrix. Returns a dict:
/// `loss`, `gradients` (by name: a float, an `(N, 3)` array for the initial
/// state, a `(3,)` array for gravity), `forward_s`, `backward_s`,
/// `adjoint_iterations`, `forward_retries`.
///
/// Raises `ValueError` for a malformed argument and for what the adjoint
/// method does not differentiate (contact, hyperelastic materials, velocity
/// filters, lagged, per-body or rotation-preserving damping), naming it.
#[pyfunction]
#[pyo3(signature = (sim, steps, probes, targets, parameters))]
pub(crate) fn gradient<'py>(
    py: Python<'py>,
    sim: &Bound<'py, Simulation>,
    steps: usize,
    probes: Vec<usize>,
    targets: &Bound<'py, PyAny>,
    parameters: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    if steps == 0 {
        return Err(PyValueError::new_err("steps: must be at least 1"));
    }
    if probes.is_empty() {
        return Err(PyValueError::new_err("probes: give at least one vertex"));
    }
    let parsed = parameters
        .iter()
        .map(|name| {
            name.parse::<Parameter>()
                .map_err(|e| PyValueError::new_err(format!("parameters: {e}")))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let targets = probe_targets(targets, steps, probes.len())?;
    let copy = {
        let sim = sim.borrow();
        let inner = sim.lock()?;
        let n = inner.sim.state().positions.len();
        if let Some(&v) = probes.iter().find(|&&v| v >= n) {
            return Err(PyValueError::new_err(format!(
                "probes: vertex {v} is out of range: the model has {n} vertices"
            )));
        }
        let mut copy = inner.scene.build().map_err(io_error)?;
        copy.restore(&inner.sim.checkpoint())
            .map_err(|e| PyValueError::new_err(format!("sim: {e}")))?;
        copy
    };
    let loss = ProbeLoss {
        vertices: probes,
        targets,
    };
    let result = py.detach(|| {
        catch_panic(|| {
            pd_adjoint::loss_and_gradient(copy, steps, &loss, &parsed, &AdjointOptions::default())
                .map_err(|e| PyValueError::new_err(e.to_string()))
        })
    })?;
    let gradients = PyDict::new(py);
    for (name, g) in parameters.iter().zip(&result.gradients) {
        match g {
            ParameterGradient::Scalar(value) => gradients.set_item(name, value)?,
            ParameterGradient::Points(points) if points.len() == 1 => {
                let p = points[0];
                gradients.set_item(name, PyArray1::from_slice(py, &[p.x, p.y, p.z]))?;
            }
            ParameterGradient::Points(points) => gradients.set_item(name, to_array(py, points))?,
        }
    }
    let out = PyDict::new(py);
    out.set_item("loss", result.loss)?;
    out.set_item("gradients", gradients)?;
    out.set_item("forward_s", result.forward_s)?;
    out.set_item("backward_s", result.backward_s)?;
    out.set_item("adjoint_iterations", result.adjoint_iterations)?;
    out.set_item("forward_retries", result.forward_retries)?;
    Ok(out)
}

/// `targets` as `[step][probe]` points, checked to be `(steps, probes, 3)`.
fn probe_targets(
    targets: &Bound<'_, PyAny>,
    steps: usize,
    probes: usize,
) -> PyResult<Vec<Vec<Point>>> {
    let wrong = |got: String| {
        PyValueError::new_err(format!(
            "targets: expected a ({steps}, {probes}, 3) array of numbers (steps, probes, xyz), \
             got {got}"
        ))
    };
    let numpy = targets.py().import("numpy")?;
    let array = numpy
        .call_method1("asarray", (targets, "float64"))
        .map_err(|e| wrong(e.to_string()))?;
    let array = array
        .cast::<PyArrayDyn<f64>>()
        .map_err(|e| wrong(e.to_string()))?;
    let shape = array.shape().to_vec();
    if shape != [steps, probes, 3] {
        return Err(wrong(format!("shape {shape:?}")));
    }
    let array = numpy.call_method1("ascontiguousarray", (array,))?;
    let array = array.cast::<PyArrayDyn<f64>>()?;
    let readonly = array.readonly();
    let values = readonly.as_slice()?;
    if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "targets: entry {bad} (row-major) is not a finite number"
        )));
    }
    Ok(values
        .chunks_exact(3 * probes)
        .map(|step| {
            step.chunks_exact(3)
                .map(|c| Point::new(c[0], c[1], c[2]))
                .collect()
        })
        .collect())
}
