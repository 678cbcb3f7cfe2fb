//! `projdyn.Simulation`: a simulation built from a scene file or from a
//! [`Model`] through the scene loader, stepped with the GIL released.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use numpy::PyArray2;
use pd_io::checkpoint::{CheckpointFile, SceneText, checkpoint_from_json, checkpoint_to_json};
use pd_io::recorder::{Outcome, Recorder, write_frame_file};
use pd_io::scene::{MeshSource, Scene, Syntax};
use pd_mesh::Mesh;
use pd_solver::{SolverError, SolverMethod, State};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{points, to_array, to_table, to_toml};
use crate::errors::{catch_panic, io_error, solver_error};
use crate::model::{Model, model_from_json, model_to_json};

/// The name a model-built simulation's scene goes by in messages.
const MODEL_SOURCE: &str = "projdyn.Simulation";

/// A simulation with the scene it was built from.
pub(crate) struct Inner {
    pub(crate) sim: pd_solver::Simulation,
    pub(crate) scene: Scene,
    /// The scene's text (for a model: the scene entries without meshes).
    text: SceneText,
    /// The model of a model-built simulation (for pickling).
    model: Option<Model>,
}

impl Inner {
    /// The checkpoint file of the current state (what `pd run` writes).
    fn checkpoint_file(&self) -> CheckpointFile {
        CheckpointFile {
            scene: self.text.clone(),
            steps_requested: self.scene.steps.max(self.sim.steps()),
            threads: self.scene.settings.threads,
            checkpoint_every: 0,
            checkpoint: self.sim.checkpoint(),
            method: self
                .scene
                .choose_method
                .then(|| self.sim.position_solver_name().to_owned()),
        }
    }
}

/// Builds a scene from its text, with a model's meshes put in place.
fn build(
    text: SceneText,
    meshes: Option<Vec<Mesh>>,
    model: Option<Model>,
    adjust: impl FnOnce(&mut Scene),
) -> PyResult<Inner> {
    let mut scene = Scene::parse(&text.text, text.syntax, &text.source).map_err(io_error)?;
    if let Some(meshes) = &meshes {
        for (body, mesh) in scene.bodies.iter_mut().zip(meshes) {
            body.mesh = MeshSource::Given(mesh.clone());
        }
    }
    adjust(&mut scene);
    let sim = catch_panic(|| scene.build().map_err(io_error))?;
    Ok(Inner {
        sim,
        scene,
        text,
        model,
    })
}

/// A Projective Dynamics simulation: the state of every vertex, stepped in
/// time.
///
/// Make one from a scene file with `Simulation.from_scene(path)` (the same
/// scene format and the same results as `pd run`), or from a `Model` with
/// `Simulation(model, dt=..., ...)`, whose keyword arguments are the keys
/// of the scene's `[simulation]` table (`dt`, `steps`, `integrator`,
/// `gravity`, `iterations`, `tolerance`, `accuracy`, `threads`,
/// `divergence_energy_factor`) and whose dict arguments are its other
/// tables (`damping`, `solver`, `contact`, `output`, `simulation`) and
/// `colliders` the list of its `[[collider]]` entries, in the scene's
/// units.
///
/// `positions` and `velocities` return copies: an array kept from before a
/// `step` does not change, and writing to it does not change the
/// simulation (use `set_state`). `step` releases the GIL, so simulations in
/// several Python threads run in parallel.
///
/// A simulation pickles through the checkpoint format of `pd resume`: the
/// state survives a round trip bit for bit.
#[pyclass(module = "projdyn")]
pub struct Simulation {
    inner: Mutex<Inner>,
}

impl Simulation {
    pub(crate) fn lock(&self) -> PyResult<MutexGuard<'_, Inner>> {
        self.inner.lock().map_err(|_| {
            PyRuntimeError::new_err(
                "this simulation stopped with an internal error earlier; its state cannot be used",
            )
        })
    }

    fn wrap(inner: Inner) -> Self {
        Self {
            inner: Mutex::new(inner),
        }
    }
}

/// The scene text of a model with the given `[simulation]` keys and other
/// tables.
fn model_scene_text(model: &Model, tables: toml::Table) -> PyResult<String> {
    let mut root = tables;
    let bodies = model
        .bodies
        .iter()
        .map(|b| {
            let mut table = b.table.clone();
            // A stand-in the loader accepts; the body's own mesh replaces it.
            let mut mesh = toml::Table::new();
            mesh.insert("generator".into(), toml::Value::String("chain".into()));
            mesh.insert("points".into(), toml::Value::Integer(2));
            mesh.insert("length".into(), toml::Value::Float(1.0));
            table.insert("mesh".into(), toml::Value::Table(mesh));
            toml::Value::Table(table)
        })
        .collect();
    root.insert("body".into(), toml::Value::Array(bodies));
    toml::to_string(&root).map_err(|e| PyValueError::new_err(format!("{MODEL_SOURCE}: {e}")))
}

#[pymethods]
impl Simulation {
    /// A simulation of `model` (a copy: the model may change afterwards).
    ///
    /// Keyword arguments are the keys of the scene's `[simulation]` table,
    /// and `damping`, `solver`, `contact`, `output` and `simulation` its
    /// tables as dicts, `colliders` its `[[collider]]` list; the scene's
    /// defaults apply to what is left out. `steps` is the number of steps
    /// `run` takes by default.
    ///
    /// Raises `ValueError` with the scene loader's message naming the key
    /// (`simulation.dt`, `damping.ratio`, `body[0].constraints[0].stiffness`).
    #[new]
    #[pyo3(signature = (model, *, dt=None, steps=None, integrator=None, gravity=None,
                        iterations=None, tolerance=None, accuracy=None, threads=None,
                        divergence_energy_factor=None, damping=None, solver=None,
                        contact=None, colliders=None, output=None, simulation=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        model: &Model,
        dt: Option<Bound<'_, PyAny>>,
        steps: Option<Bound<'_, PyAny>>,
        integrator: Option<Bound<'_, PyAny>>,
        gravity: Option<Bound<'_, PyAny>>,
        iterations: Option<Bound<'_, PyAny>>,
        tolerance: Option<Bound<'_, PyAny>>,
        accuracy: Option<Bound<'_, PyAny>>,
        threads: Option<Bound<'_, PyAny>>,
        divergence_energy_factor: Option<Bound<'_, PyAny>>,
        damping: Option<Bound<'_, PyAny>>,
        solver: Option<Bound<'_, PyAny>>,
        contact: Option<Bound<'_, PyAny>>,
        colliders: Option<Bound<'_, PyAny>>,
        output: Option<Bound<'_, PyAny>>,
        simulation: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        if model.bodies.is_empty() {
            return Err(PyValueError::new_err(
                "model: the model has no body; add one with Model.add_body",
            ));
        }
        let mut settings = match simulation {
            Some(d) => to_table("simulation", d)?,
            None => toml::Table::new(),
        };
        for (key, value) in [
            ("dt", dt),
            ("steps", steps),
            ("integrator", integrator),
            ("gravity", gravity),
            ("iterations", iterations),
            ("tolerance", tolerance),
            ("accuracy", accuracy),
            ("threads", threads),
            ("divergence_energy_factor", divergence_energy_factor),
        ] {
            let Some(value) = value else { continue };
            let Some(value) = to_toml(key, &value)? else {
                continue;
            };
            if settings.insert(key.into(), value).is_some() {
                return Err(PyValueError::new_err(format!(
                    "{key}: given both as a keyword and in simulation="
                )));
            }
        }
        settings.entry("steps").or_insert(toml::Value::Integer(0));
        let mut tables = toml::Table::new();
        tables.insert("simulation".into(), toml::Value::Table(settings));
        for (key, value) in [
            ("damping", damping),
            ("solver", solver),
            ("contact", contact),
            ("collider", colliders),
            ("output", output),
        ] {
            let argument = if key == "collider" { "colliders" } else { key };
            if let Some(value) = value
                && let Some(v) = to_toml(argument, &value)?
            {
                tables.insert(key.into(), v);
            }
        }
        let text = SceneText {
            source: PathBuf::from(MODEL_SOURCE),
            syntax: Syntax::Toml,
            text: model_scene_text(model, tables)?,
        };
        let meshes = model.bodies.iter().map(|b| b.mesh.clone()).collect();
        let model = model.clone();
        let inner = py.detach(move || build(text, Some(meshes), Some(model), |_| {}))?;
        Ok(Self::wrap(inner))
    }

    /// A simulation of the scene file at `path` (TOML or JSON), at its
    /// initial state: the same scene as `pd run path`, with the same
    /// results. `steps` and `threads` override the scene's, as `pd run
    /// --steps --threads` do; `damping` (a dict with the keys of
    /// `[damping]`) replaces the scene's `[damping]` table, and `solver`
    /// (keys of `[solver]`) sets those keys of its `[solver]` table.
    ///
    /// Raises `ValueError` with the loader's message (file, line, field) for
    /// an invalid scene, `OSError` for a file that cannot be read.
    #[staticmethod]
    #[pyo3(signature = (path, *, steps=None, threads=None, damping=None, solver=None))]
    fn from_scene(
        py: Python<'_>,
        path: PathBuf,
        steps: Option<usize>,
        threads: Option<usize>,
        damping: Option<&Bound<'_, PyDict>>,
        solver: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let mut text =
            std::fs::read_to_string(&path).map_err(|e| io_error(pd_io::Error::io(&path, e)))?;
        if let Some(damping) = damping {
            let table = to_table("damping", damping)?;
            text = set_table(&path, &text, "damping", table, false)?;
        }
        if let Some(solver) = solver {
            let table = to_table("solver", solver)?;
            text = set_table(&path, &text, "solver", table, true)?;
        }
        // Absolute, as `pd run` reads it, so that relative mesh paths resolve
        // from any working folder (and a pickled simulation finds them too).
        let source = std::fs::canonicalize(&path).unwrap_or_else(|_| path.clone());
        let text = SceneText {
            source,
            syntax: Syntax::of(&path),
            text,
        };
        let inner = py.detach(move || {
            build(text, None, None, |scene| {
                if let Some(steps) = steps {
                    scene.steps = steps;
                }
                if let Some(threads) = threads {
                    scene.settings.threads = threads;
                }
            })
        })?;
        Ok(Self::wrap(inner))
    }

    /// Advances `n` time steps (default 1), releasing the GIL while it runs.
    ///
    /// Raises `DivergenceError` (with `step`, `time` and `reason`) if the
    /// simulation diverges; the state is then that of the last good step.
    #[pyo3(signature = (n=1))]
    fn step(&self, py: Python<'_>, n: usize) -> PyResult<()> {
        // The lock is taken inside `catch_panic`: a panic (a bug) unwinds
        // through it and poisons it, so that the simulation, left half-way
        // through a step, refuses to be used again.
        let result = py.detach(|| {
            catch_panic(|| {
                let mut inner = self.lock()?;
                for _ in 0..n {
                    if let Err(e) = inner.sim.step() {
                        return Ok(Err(e));
                    }
                }
                Ok(Ok(()))
            })
        })?;
        result.map_err(|e| solver_error(py, e))
    }

    /// Vertex positions, m: a new (N, 3) float64 array (a copy; later steps
    /// do not change it).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(to_array(py, &self.lock()?.sim.state().positions))
    }

    /// Vertex velocities, m/s: a new (N, 3) float64 array (a copy).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(to_array(py, &self.lock()?.sim.state().velocities))
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self) -> PyResult<f64> {
        Ok(self.lock()?.sim.time())
    }

    /// Steps taken since the start.
    #[getter]
    fn steps(&self) -> PyResult<usize> {
        Ok(self.lock()?.sim.steps())
    }

    /// Time step, s.
    #[getter]
    fn dt(&self) -> PyResult<f64> {
        Ok(self.lock()?.sim.settings().dt)
    }

    /// Number of vertices.
    #[getter]
    fn num_vertices(&self) -> PyResult<usize> {
        Ok(self.lock()?.sim.model().num_vertices())
    }

    /// The scene's number of steps (what `run` takes by default).
    #[getter]
    fn scene_steps(&self) -> PyResult<usize> {
        Ok(self.lock()?.scene.steps)
    }

    /// The iteration method in use (`"local-global"`, `"chebyshev"`, ...).
    #[getter]
    fn method(&self) -> PyResult<&'static str> {
        Ok(self.lock()?.sim.position_solver_name())
    }

    /// Energies of the current state, J: a dict with `kinetic`, `elastic`,
    /// `gravity` and `total`.
    fn energies<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let e = self.lock()?.sim.energies();
        let d = PyDict::new(py);
        d.set_item("kinetic", e.kinetic)?;
        d.set_item("elastic", e.elastic)?;
        d.set_item("gravity", e.gravity)?;
        d.set_item("total", e.total())?;
        Ok(d)
    }

    /// Replaces the state: `positions` (N, 3) in m and `velocities` (N, 3)
    /// in m/s (zero when left out). The arrays are copied.
    #[pyo3(signature = (positions, velocities=None))]
    fn set_state(
        &self,
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        velocities: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let mut inner = self.lock()?;
        let n = inner.sim.model().num_vertices();
        let positions = points("positions", positions, Some(n))?;
        let velocities = match velocities {
            Some(v) => points("velocities", v, Some(n))?,
            None => vec![pd_mesh::Point::zeros(); n],
        };
        inner
            .sim
            .set_state(State {
                positions,
                velocities,
            })
            .map_err(|e| solver_error(py, e))
    }

    /// Writes the current state as one frame file, in the format the
    /// extension of `path` names: `.vtk`, `.vtu` (with velocity and strain),
    /// `.obj` or `.ply`, as the frames of `pd run`.
    fn save_frame(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let inner = self.lock()?;
        py.detach(|| write_frame_file(&path, &inner.sim))
            .map_err(io_error)
    }

    /// Runs to step `steps` (default: the scene's `steps`) and writes the
    /// output folder `out` exactly as `pd run` does: `metrics.csv`,
    /// `probes.csv`, the frames of the scene's `[output]`, `summary.json`
    /// and `final_state.json`. Recording starts at the current state (row
    /// 0, frame 0). Releases the GIL.
    ///
    /// Raises `DivergenceError` after writing the folder (its summary says
    /// where the run stopped) if the simulation diverges.
    #[pyo3(signature = (out, steps=None))]
    fn run(&self, py: Python<'_>, out: PathBuf, steps: Option<usize>) -> PyResult<()> {
        let result = py.detach(|| {
            catch_panic(|| {
                let mut inner = self.lock()?;
                Ok(record_run(&mut inner, &out, steps))
            })
        })?;
        match result {
            Ok(()) => Ok(()),
            Err(RunError::Io(e)) => Err(io_error(e)),
            Err(RunError::Solver(e)) => Err(solver_error(py, e)),
        }
    }

    /// The state as a checkpoint file's text (JSON; `pd resume`'s format).
    fn checkpoint_json(&self) -> PyResult<String> {
        let inner = self.lock()?;
        checkpoint_to_json(Path::new("checkpoint"), &inner.checkpoint_file()).map_err(io_error)
    }

    fn __repr__(&self) -> PyResult<String> {
        let inner = self.lock()?;
        Ok(format!(
            "Simulation({}: {} vertices, step {}, t = {} s)",
            inner.scene.source.display(),
            inner.sim.model().num_vertices(),
            inner.sim.steps(),
            inner.sim.time()
        ))
    }

    /// Pickling: the checkpoint text (and, for a model-built simulation,
    /// the model), restored by rebuilding the scene and restoring the state.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = slf.borrow();
        let inner = this.lock()?;
        let text = checkpoint_to_json(Path::new("checkpoint"), &inner.checkpoint_file())
            .map_err(io_error)?;
        let model = match &inner.model {
            Some(model) => Some(model_to_json(model)?),
            None => None,
        };
        let restore = py
            .import("projdyn._projdyn")?
            .getattr("restore_simulation")?;
        let args = (text, model).into_pyobject(py)?;
        PyTuple::new(py, [restore, args.into_any()])
    }
}

/// The scene text `text` (of the file `path`) with its table `key`
/// replaced by `table` or, with `merge`, with the keys of `table` set in
/// it; in the file's syntax.
fn set_table(
    path: &Path,
    text: &str,
    key: &str,
    table: toml::Table,
    merge: bool,
) -> PyResult<String> {
    let invalid = |e: String| PyValueError::new_err(format!("{}: {e}", path.display()));
    let mut scene: toml::Table = match Syntax::of(path) {
        Syntax::Toml => toml::from_str(text).map_err(|e| invalid(e.message().to_string()))?,
        Syntax::Json => serde_json::from_str(text).map_err(|e| invalid(e.to_string()))?,
    };
    let entry = scene
        .entry(key)
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    match entry {
        toml::Value::Table(existing) if merge => existing.extend(table),
        other => *other = toml::Value::Table(table),
    }
    match Syntax::of(path) {
        Syntax::Toml => toml::to_string(&scene).map_err(|e| invalid(e.to_string())),
        Syntax::Json => serde_json::to_string(&scene).map_err(|e| invalid(e.to_string())),
    }
}

/// Why a recorded run stopped early.
enum RunError {
    Io(pd_io::Error),
    Solver(SolverError),
}

/// `Simulation.run`: the recorder of `pd run` around the steps.
fn record_run(inner: &mut Inner, out: &Path, steps: Option<usize>) -> Result<(), RunError> {
    let mut scene = inner.scene.clone();
    if let Some(steps) = steps {
        scene.steps = steps;
    }
    let mut recorder = Recorder::create(out, &scene, &inner.sim).map_err(RunError::Io)?;
    // A checkpoint of an earlier `pd run` in the same folder is not this run's.
    let stale = out.join(pd_io::checkpoint::CHECKPOINT_FILE);
    if stale.exists() {
        std::fs::remove_file(&stale).map_err(|e| RunError::Io(pd_io::Error::io(&stale, e)))?;
    }
    let mut failure = None;
    while inner.sim.steps() < scene.steps {
        match inner.sim.step() {
            Ok(stats) => recorder.record(&inner.sim, &stats).map_err(RunError::Io)?,
            Err(e) => {
                failure = Some(e);
                break;
            }
        }
    }
    let outcome = match &failure {
        None => Outcome::Completed,
        Some(e) => Outcome::Failed(e.to_string()),
    };
    recorder
        .finish(&scene, &inner.sim, &outcome)
        .map_err(RunError::Io)?;
    failure.map_or(Ok(()), |e| Err(RunError::Solver(e)))
}

/// Unpickles a [`Simulation`]: rebuilds its scene and restores the state.
#[pyfunction]
#[pyo3(signature = (checkpoint, model=None))]
pub(crate) fn restore_simulation(
    py: Python<'_>,
    checkpoint: &str,
    model: Option<&str>,
) -> PyResult<Simulation> {
    let file = checkpoint_from_json(Path::new("checkpoint"), checkpoint).map_err(io_error)?;
    let model = model.map(model_from_json).transpose()?;
    let meshes = model
        .as_ref()
        .map(|m| m.bodies.iter().map(|b| b.mesh.clone()).collect());
    let inner = py.detach(move || {
        let mut inner = build(file.scene.clone(), meshes, model, |scene| {
            scene.steps = file.steps_requested;
            scene.settings.threads = file.threads;
            // The method the simulation chose goes on, as `pd resume` does.
            if let Some(method) = file.method.as_deref().and_then(SolverMethod::parse)
                && scene.choose_method
            {
                scene.solver.method = method;
                scene.choose_method = false;
            }
        })?;
        inner
            .sim
            .restore(&file.checkpoint)
            .map_err(|e| PyValueError::new_err(format!("checkpoint: {e}")))?;
        Ok::<_, PyErr>(inner)
    })?;
    Ok(Simulation::wrap(inner))
}

/// The lowest elastic modes of a simulation's model at rest, or of the
/// scene file at a path: a dict with the keys of `pd modes`'s
/// `modes.json` (frequencies, damping ratios under the scene's damping and
/// integrator at its time step, ...), without the animations.
#[pyfunction]
#[pyo3(signature = (sim_or_scene, count=6))]
pub(crate) fn modes<'py>(
    py: Python<'py>,
    sim_or_scene: &Bound<'py, PyAny>,
    count: usize,
) -> PyResult<Bound<'py, PyAny>> {
    if count == 0 {
        return Err(PyValueError::new_err("count: must be at least 1"));
    }
    let report = if let Ok(sim) = sim_or_scene.cast::<Simulation>() {
        let sim = sim.borrow();
        let inner = sim.lock()?;
        py.detach(|| catch_panic(|| modes_of(&inner, count)))?
    } else if let Ok(path) = sim_or_scene.extract::<PathBuf>() {
        let sim = Simulation::from_scene(py, path, None, None, None, None)?;
        let inner = sim.lock()?;
        py.detach(|| catch_panic(|| modes_of(&inner, count)))?
    } else {
        return Err(PyTypeError::new_err(
            "sim_or_scene: expected a Simulation or the path of a scene file",
        ));
    };
    py.import("json")?.call_method1("loads", (report,))
}

fn modes_of(inner: &Inner, count: usize) -> PyResult<String> {
    let analysis = pd_modes::elastic_modes(inner.sim.model(), count).map_err(|e| {
        PyValueError::new_err(format!(
            "{}: modal analysis: {e}",
            inner.scene.source.display()
        ))
    })?;
    let report = pd_io::modes_report::modes_report(&inner.scene, &inner.sim, &analysis, false);
    Ok(report.to_string())
}
