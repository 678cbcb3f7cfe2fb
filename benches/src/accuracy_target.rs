//! `pd-probe accuracy-target`: what an accuracy target (`[simulation]
//! accuracy = e`) costs and delivers on one scene, per iteration method,
//! and which method the automatic choice picks
//! (docs/design/solver.md, "How far from converged" and "Choosing a method
//! by measurement").
//!
//! For each target, in one process:
//!
//! 1. the automatic choice: [`pd_solver::Simulation::choose_method`] from
//!    the initial state (as `Scene::build` runs it), timed;
//! 2. every method that can run the scene, named: `warmup` steps, then
//!    `steps` measured steps in rounds of [`ROUND`] steps per method in
//!    turn (so that drift in the machine's speed hits every method alike),
//!    each step's time (`StepStats::total_seconds`), iterations and
//!    estimated error recorded, and the state before it kept;
//! 3. after all the timing, each measured step solved again from the same
//!    state by the reference (Newton to a relative residual of
//!    [`NEWTON_TOLERANCE`]; with colliders, which only local-global runs,
//!    local-global to [`LOCAL_GLOBAL_TOLERANCE`]), which gives the step's
//!    true relative error `|x - x*|_M / |y - x*|_M`.
//!
//! `x`, `x*` and `y` are read inside the step, before a collider's
//! projection, by a [`PositionSolver`] that wraps the method and copies the
//! displacement it starts from (the inertial prediction `y - x_n`) and the
//! one it ends at: the quantities the estimate is about.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use pd_io::scene::{ACCURACY_ITERATIONS, Scene, Syntax};
use pd_mesh::Point;
use pd_solver::{
    Checkpoint, PositionSolver, ProbeOutcome, Simulation, SolverError, SolverMethod, StepProblem,
    StepStats,
};
use serde_json::Value;

use crate::schema::{AccuracyTarget, TargetCandidate, TargetChoice, TargetMethod, TargetRun};

/// Measured steps per method and round: rounds of this many steps of each
/// method in turn.
pub const ROUND: usize = 5;

/// Newton's relative residual for the reference solution of a step.
pub const NEWTON_TOLERANCE: f64 = 1e-10;
/// Newton's iteration cap for the reference.
const NEWTON_CAP: usize = 100;
/// Local-global's relative residual for the reference of a scene with
/// colliders.
pub const LOCAL_GLOBAL_TOLERANCE: f64 = 1e-12;
/// Local-global's iteration cap for that reference.
const LOCAL_GLOBAL_CAP: usize = 100_000;

/// The scenes of the measurement.
#[derive(Debug, Clone, PartialEq)]
pub enum TargetScene {
    /// The bench report's clamped beam, `cells` cells (`crate::Beam`).
    Beam {
        /// Cells along x, y, z.
        cells: [usize; 3],
    },
    /// The cloth strip of docs/design/solver.md.
    Strip,
    /// A TetGen mesh (the armadillo) hanging by its highest vertices.
    Hanging {
        /// The TetGen base (`.node` and `.ele`).
        mesh: PathBuf,
    },
    /// The bundled `scenes/contact_stack.toml`.
    ContactStack,
}

/// What one `accuracy-target` measurement runs.
#[derive(Debug, Clone)]
pub struct TargetPlan {
    /// The scene.
    pub scene: TargetScene,
    /// The accuracy targets, each measured on its own.
    pub targets: Vec<f64>,
    /// Steps before the measured ones.
    pub warmup: usize,
    /// Measured steps per method.
    pub steps: usize,
}

/// The vertices of a hanging mesh that hold it: those within this share of
/// the mesh's height of its highest point.
const HELD_SHARE: f64 = 0.01;

/// `[simulation]` of every scene but the contact stack: dt 0.01 s, gravity
/// along -y, one thread, `integrator`.
fn simulation_table(integrator: &str) -> String {
    format!(
        "[simulation]\ndt = 0.01\nsteps = 1\ngravity = [0.0, -9.81, 0.0]\n\
         integrator = \"{integrator}\"\nthreads = 1\n\n"
    )
}

/// The scene's text, its source path (which anchors relative paths) and a
/// description for the report.
fn scene_text(scene: &TargetScene) -> Result<(String, PathBuf, String), String> {
    let here = PathBuf::from("accuracy-target.toml");
    Ok(match scene {
        TargetScene::Beam { cells } => {
            let beam = crate::Beam {
                cells: *cells,
                ..crate::Beam::default()
            };
            let [sx, sy, sz] = beam.size;
            let text = format!(
                "{}[[body]]\nmesh = {{ generator = \"box\", size = [{sx:?}, {sy:?}, {sz:?}], \
                 cells = [{}, {}, {}] }}\ndensity = {:?}\n\
                 constraints = [ {{ kind = \"tet-strain\", stiffness = {:?} }} ]\n\
                 fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [1.0e-9, 1.0, 1.0] }} }}\n",
                simulation_table("backward-euler"),
                cells[0],
                cells[1],
                cells[2],
                beam.density,
                beam.stiffness,
            );
            let description = format!(
                "the bench beam: {sx} x {sy} x {sz} m, {} x {} x {} cells, tet-strain {:e} Pa, \
                 {} kg/m^3, clamped at x = 0, backward Euler, undamped, dt 0.01 s, from rest",
                cells[0], cells[1], cells[2], beam.stiffness, beam.density
            );
            (text, here, description)
        }
        TargetScene::Strip => {
            let text = format!(
                "{}[damping]\nmodel = \"ether-drag\"\nrate = 2.0\n\n[[body]]\n\
                 mesh = {{ generator = \"cloth\", size = [0.3, 0.05], cells = [30, 5] }}\n\
                 density = 0.2\nconstraints = [\n  {{ kind = \"triangle-strain\", stiffness = 1.0e5 }},\n  \
                 {{ kind = \"bending\", stiffness = 0.5 }},\n]\n\
                 fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [1.0e-6, 1.0, 1.0] }} }}\n",
                simulation_table("backward-euler")
            );
            let description = "the cloth strip: 0.3 x 0.05 m, 30 x 5 quads, triangle-strain \
                               1e5 N/m, bending 0.5 N m, 0.2 kg/m^2, clamped along its x = 0 \
                               short edge, horizontal at rest, backward Euler, ether drag 2/s, \
                               dt 0.01 s"
                .to_string();
            (text, here, description)
        }
        TargetScene::Hanging { mesh } => {
            let read = pd_io::tetgen::read_tetgen_base(mesh).map_err(|e| e.to_string())?;
            let ys = read.vertices().iter().map(|p| p.y);
            let (low, high) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), y| {
                (lo.min(y), hi.max(y))
            });
            let held_from = high - HELD_SHARE * (high - low);
            let held = read.vertices().iter().filter(|p| p.y >= held_from).count();
            let name = mesh
                .file_name()
                .map_or("mesh".into(), |n| n.to_string_lossy().into_owned());
            let text = format!(
                "{}[damping]\nmodel = \"laplacian\"\nstiffness = {LAPLACIAN_A2:?}\n\n[[body]]\n\
                 mesh = {{ file = {path:?} }}\ndensity = 1000.0\n\
                 constraints = [ {{ kind = \"tet-strain\", stiffness = 2.0e5 }} ]\n\
                 fixed = {{ box = {{ min = [-1.0e9, {held_from:?}, -1.0e9], \
                 max = [1.0e9, 1.0e9, 1.0e9] }} }}\n",
                simulation_table("implicit-midpoint"),
                path = mesh.display().to_string(),
            );
            let description = format!(
                "the TetGen {name}, {} tets, tet-strain 2e5 Pa, 1000 kg/m^3, hanging from rest \
                 by its {held} highest vertices (the top {}% of its height) and swinging down, \
                 implicit midpoint, Laplacian damping a2 = {LAPLACIAN_A2} s, dt 0.01 s",
                thousands(read.tets().len()),
                HELD_SHARE * 100.0
            );
            (text, here, description)
        }
        TargetScene::ContactStack => (
            include_str!("../../scenes/contact_stack.toml").to_string(),
            PathBuf::from("scenes/contact_stack.toml"),
            "the bundled scenes/contact_stack.toml: a 0.1 m cube dropped onto a 0.2 m cube \
             resting on the floor (collider and body contact, friction 0.5), tet-strain 1e5 Pa, \
             backward Euler, Laplacian damping a2 = 0.01 s, dt 0.005 s"
                .to_string(),
        ),
    })
}

/// The hanging mesh's Laplacian damping coefficient `a2` (s).
const LAPLACIAN_A2: f64 = 0.003;

/// The scene's label in the report.
fn label(scene: &TargetScene) -> String {
    match scene {
        TargetScene::Beam { cells } => format!(
            "beam {}",
            thousands((cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1))
        ),
        TargetScene::Strip => "cloth strip".into(),
        TargetScene::Hanging { mesh } => mesh
            .file_name()
            .map_or("mesh".into(), |n| n.to_string_lossy().into_owned()),
        TargetScene::ContactStack => "contact_stack".into(),
    }
}

/// `n` with a comma between thousands (`2,304`), as the report's labels
/// write counts.
fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// What a step's wrapped method saw: the displacement it started from and
/// the one it ended at.
#[derive(Debug, Default)]
struct Seen {
    start: Vec<Point>,
    end: Vec<Point>,
}

/// A method that records [`Seen`] around the wrapped one and otherwise is
/// it: every question of [`PositionSolver`] is passed on.
#[derive(Debug)]
struct Recording {
    inner: Box<dyn PositionSolver>,
    seen: Arc<Mutex<Seen>>,
}

impl Recording {
    /// Wraps `sim`'s method; the returned handle reads what it saw.
    fn wrap(sim: &mut Simulation, method: SolverMethod) -> Result<Arc<Mutex<Seen>>, String> {
        let spec = pd_solver::SolverSpec {
            method,
            ..pd_solver::SolverSpec::default()
        };
        let seen = Arc::new(Mutex::new(Seen::default()));
        sim.set_position_solver(Box::new(Recording {
            inner: spec.create().map_err(|e| e.to_string())?,
            seen: Arc::clone(&seen),
        }));
        Ok(seen)
    }
}

/// Copies `from` into `into`, reusing its allocation.
fn keep(into: &mut Vec<Point>, from: &[Point]) {
    into.clear();
    into.extend_from_slice(from);
}

impl PositionSolver for Recording {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        let mut seen = self.seen.lock().unwrap_or_else(PoisonError::into_inner);
        keep(&mut seen.start, step.displacement());
        let result = self.inner.find_positions(step);
        keep(&mut seen.end, step.displacement());
        result
    }

    fn handles_contact(&self) -> bool {
        self.inner.handles_contact()
    }

    fn handles_materials(&self) -> bool {
        self.inner.handles_materials()
    }

    fn handles_lagged_damping(&self) -> bool {
        self.inner.handles_lagged_damping()
    }

    fn handles_per_body_damping(&self) -> bool {
        self.inner.handles_per_body_damping()
    }

    fn estimate_needs_contraction(&self) -> bool {
        self.inner.estimate_needs_contraction()
    }

    fn check_settings(&self) -> Result<(), SolverError> {
        self.inner.check_settings()
    }

    fn carried(&self) -> Vec<f64> {
        self.inner.carried()
    }

    fn check_carried(&self, values: &[f64]) -> Result<(), String> {
        self.inner.check_carried(values)
    }

    fn restore_carried(&mut self, values: &[f64]) {
        self.inner.restore_carried(values)
    }
}

/// `scene` built on one thread with `method` and the stopping rule `stop`
/// (`accuracy`, `tolerance`, `iterations`).
fn build_with(
    scene: &Scene,
    method: SolverMethod,
    stop: (f64, f64, usize),
) -> Result<Simulation, String> {
    let mut scene = scene.clone();
    let (accuracy, tolerance, iterations) = stop;
    scene.settings.accuracy = accuracy;
    scene.settings.tolerance = tolerance;
    scene.settings.iterations = iterations;
    scene.settings.threads = 1;
    scene.choose_method = false;
    scene.solver.method = method;
    scene.build().map_err(|e| e.to_string())
}

/// As [`build_with`], the method wrapped in a [`Recording`].
fn build(
    scene: &Scene,
    method: SolverMethod,
    stop: (f64, f64, usize),
) -> Result<(Simulation, Arc<Mutex<Seen>>), String> {
    let mut sim = build_with(scene, method, stop)?;
    let seen = Recording::wrap(&mut sim, method)?;
    Ok((sim, seen))
}

/// One method's run at one target.
struct MethodRun {
    method: SolverMethod,
    sim: Simulation,
    seen: Arc<Mutex<Seen>>,
    /// The state before each measured step.
    starts: Vec<Checkpoint>,
    /// The displacement each measured step ended at.
    ends: Vec<Vec<Point>>,
    stats: Vec<StepStats>,
    error: Option<String>,
}

impl MethodRun {
    /// Runs `n` more steps, recording each; an error ends the run.
    fn steps(&mut self, n: usize, measured: bool) {
        for _ in 0..n {
            if self.error.is_some() {
                return;
            }
            let start = measured.then(|| self.sim.checkpoint());
            match self.sim.step() {
                Ok(stats) if measured => {
                    self.starts.extend(start);
                    let seen = self.seen.lock().unwrap_or_else(PoisonError::into_inner);
                    self.ends.push(seen.end.clone());
                    self.stats.push(stats);
                }
                Ok(_) => {}
                Err(e) => self.error = Some(e.to_string()),
            }
        }
    }
}

/// The reference: the scene solved to convergence.
struct Reference {
    sim: Simulation,
    seen: Arc<Mutex<Seen>>,
    unconverged: usize,
    iterations: Vec<f64>,
}

impl Reference {
    /// The true relative error of a step that started at `start` and
    /// ended at displacement `end`.
    fn true_error(&mut self, start: &Checkpoint, end: &[Point]) -> Result<f64, String> {
        self.sim.restore(start).map_err(|e| e.to_string())?;
        let stats = self.sim.step().map_err(|e| e.to_string())?;
        self.unconverged += usize::from(!stats.converged);
        self.iterations.push(stats.iterations as f64);
        let seen = self.seen.lock().unwrap_or_else(PoisonError::into_inner);
        let (y, exact) = (&seen.start, &seen.end);
        let model = self.sim.model();
        Ok(model.mass_distance(end, exact) / model.mass_distance(y, exact))
    }
}

/// The automatic choice at the scene's initial state, timed.
fn choice(scene: &Scene, target: f64) -> Result<TargetChoice, String> {
    let stop = (target, 0.0, ACCURACY_ITERATIONS);
    let mut sim = build_with(scene, SolverMethod::default(), stop)?;
    let began = Instant::now();
    let choice = sim.choose_method().map_err(|e| e.to_string())?;
    let probe_ms = began.elapsed().as_secs_f64() * 1e3;
    let timed = (pd_solver::PROBE_STEPS - 1) as f64;
    let candidates = choice
        .candidates
        .iter()
        .map(|c| {
            let (outcome, step_ms, iterations) = match &c.outcome {
                ProbeOutcome::Measured {
                    seconds,
                    iterations,
                } => (
                    "measured",
                    Some(seconds * 1e3 / timed),
                    Some(*iterations as f64 / timed),
                ),
                ProbeOutcome::Excluded { .. } => ("excluded", None, None),
                ProbeOutcome::Slower { .. } => ("slower", None, None),
                ProbeOutcome::MissedTarget { .. } => ("missed-target", None, None),
                ProbeOutcome::Failed { .. } => ("failed", None, None),
            };
            TargetCandidate {
                method: c.method.name().into(),
                outcome: outcome.into(),
                step_ms,
                iterations,
                text: c.describe(),
            }
        })
        .collect();
    Ok(TargetChoice {
        chosen: choice.chosen.name().into(),
        measured: choice.measured(),
        probe_ms,
        candidates,
    })
}

/// Every method at one target: see the module documentation.
fn target_run(
    scene: &Scene,
    plan: &TargetPlan,
    target: f64,
    reference: &mut Reference,
) -> Result<TargetRun, String> {
    eprintln!("    accuracy {target}: the automatic choice");
    let choice = choice(scene, target)?;
    let mut runs = Vec::new();
    let mut methods = Vec::new();
    for method in SolverMethod::ALL {
        match build(scene, method, (target, 0.0, ACCURACY_ITERATIONS)) {
            Ok((sim, seen)) => runs.push(MethodRun {
                method,
                sim,
                seen,
                starts: Vec::new(),
                ends: Vec::new(),
                stats: Vec::new(),
                error: None,
            }),
            Err(reason) => methods.push(TargetMethod::excluded(method.name(), reason)),
        }
    }
    eprintln!(
        "    accuracy {target}: warm-up and {} measured steps",
        plan.steps
    );
    for run in &mut runs {
        run.steps(plan.warmup, false);
    }
    let mut done = 0;
    while done < plan.steps {
        let n = ROUND.min(plan.steps - done);
        for run in &mut runs {
            run.steps(n, true);
        }
        done += n;
    }
    eprintln!("    accuracy {target}: the reference of every measured step");
    for run in runs {
        let mut true_error = Vec::with_capacity(run.stats.len());
        for (start, end) in run.starts.iter().zip(&run.ends) {
            true_error.push(reference.true_error(start, end)?);
        }
        let stats = &run.stats;
        methods.push(TargetMethod {
            method: run.method.name().into(),
            excluded: None,
            error: run.error,
            step_ms: stats.iter().map(|s| s.total_seconds * 1e3).collect(),
            iterations: stats.iter().map(|s| s.iterations).collect(),
            met_target: stats.iter().map(|s| s.converged).collect(),
            estimated_error: stats.iter().map(|s| s.estimated_error).collect(),
            true_error,
        });
    }
    let order = |name: &str| SolverMethod::ALL.iter().position(|m| m.name() == name);
    methods.sort_by_key(|m| order(&m.method));
    Ok(TargetRun {
        target,
        choice,
        methods,
    })
}

/// Runs the plan.
///
/// # Errors
/// A scene that does not build, a reference step that fails.
pub fn measure(plan: &TargetPlan) -> Result<Value, String> {
    let began = Instant::now();
    let (text, source, description) = scene_text(&plan.scene)?;
    let scene = Scene::parse(&text, Syntax::Toml, Path::new(&source)).map_err(|e| e.to_string())?;
    let contact = scene.contact.is_some();
    let (method, tolerance, cap) = if contact {
        (
            SolverMethod::LocalGlobal,
            LOCAL_GLOBAL_TOLERANCE,
            LOCAL_GLOBAL_CAP,
        )
    } else {
        (SolverMethod::Newton, NEWTON_TOLERANCE, NEWTON_CAP)
    };
    let (sim, seen) = build(&scene, method, (0.0, tolerance, cap))?;
    let n_verts = sim.model().num_vertices();
    let mut reference = Reference {
        sim,
        seen,
        unconverged: 0,
        iterations: Vec::new(),
    };
    let mut targets = Vec::new();
    for &target in &plan.targets {
        targets.push(target_run(&scene, plan, target, &mut reference)?);
    }
    serde_json::to_value(AccuracyTarget {
        scene: label(&plan.scene),
        description,
        n_verts,
        dt: scene.settings.dt,
        warmup: plan.warmup,
        steps: plan.steps,
        iteration_cap: ACCURACY_ITERATIONS,
        reference_method: method.name().into(),
        reference_tolerance: tolerance,
        reference_unconverged_steps: reference.unconverged,
        reference_iterations_median: pd_io::stats::median(&reference.iterations),
        targets,
        wall_seconds: began.elapsed().as_secs_f64(),
    })
    .map_err(|e| e.to_string())
}
