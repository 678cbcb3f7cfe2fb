//! `cargo xtask stability [--quick]`: runs every integrator with every
//! damping model over a matrix of extreme parameters and starting states,
//! and writes `docs/reports/stability.md`.
//!
//! The rule checked for every run: it either completes (a finite state and
//! finite energies, its total energy never above the divergence bound), or
//! stops with `SolverError::Diverged`. A run that completes exploded (its
//! total energy above the solver's own divergence bound after some step
//! that returned `Ok`: a bug in the check), a panic, a non-finite value
//! after an `Ok` step, or another error is a bug and is listed in the
//! report; the command then fails. Runs that end with inverted elements are
//! counted and listed too: a stable solve restores an inverted start, so
//! such a run is not called stable, but it is not a bug of the check (the
//! divergence check bounds energy, and an inverted corotational element
//! has bounded energy). A completed run is "completed sane" unless it
//! created energy where it should only dissipate, by the rule of the run
//! summary's warning (`pd_io::recorder::AccuracyWatch::energy_created`,
//! fed the same `metrics.csv` rows a run records): in backward Euler or
//! BDF-2 with any damping, or implicit midpoint with a damping model, a
//! rise of the total energy above its running minimum by more than 1% of
//! the run's largest kinetic plus elastic energy. Such a run is counted
//! under "energy created". Undamped implicit midpoint conserves energy
//! rather than dissipating it, so its runs are not classified by this rule.
//!
//! The matrix (full / `--quick`):
//! - stiffness (tet strain, Pa): 1e0, 1e3, 1e6, 1e9 / 1e0, 1e9;
//! - time step (s): 1e-5, 1e-3, 0.1 / 1e-5, 0.1;
//! - density (kg/m^3): 1, 1e3, 1e5 / 1, 1e5;
//! - damping coefficient `c`: 1e-3, 1, 1e3 / 1e3 (the model's own unit:
//!   a rate in 1/s for ether drag, `a2` in s for Laplacian and lagged
//!   Rayleigh damping; PBD uses the factor `min(c, 1)`);
//! - local-global iterations: 1, 10, 200 / 1, 200;
//! - starting state: at rest; inverted (every x mirrored, so every tet is
//!   inside out); compressed (x scaled by 0.01); fast (100 m/s per vertex in
//!   varied directions);
//! - body: a clamped 1 x 0.25 x 0.25 m beam (2 x 1 x 1 cells, 12 tets), a
//!   free 0.3 m cube (6 tets) and a 0.5 m square cloth of 1 mm thickness
//!   pinned at two corners (4 x 4 quads; `triangle-strain` with `E t` =
//!   stiffness x 1 mm, `bending` with `D = E t^3 / 12`, `rho_A` = density x
//!   1 mm: thin, light, stiff membranes) / the beam and the cloth. Gravity
//!   on, 100 steps.
//!
//! Besides the ending, each completed run records its largest energy rise:
//! the maximum over its steps of `(E(t) - E(0)) / scale`, with `E` the total
//! (kinetic + elastic + gravitational) energy and `scale` the solver's own
//! divergence scale (`Simulation::energy_scale`, docs/design/solver.md).

use std::fmt::Write as _;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::sync::Mutex;

use pd_damping::registry::{self, Preset, Value};
use pd_io::recorder::{AccuracyWatch, ENERGY_WARNING, EnergyCreated, MetricsRow};
use pd_io::scene::{ConstraintSpec, DampingSpec, IntegratorKind, MassSpec, Scene, Syntax};
use pd_solver::{SolverError, State};

mod methods;
mod shard;

/// Steps per run: enough for an instability that grows by 5 % per step to
/// grow a hundredfold, which 10 steps (the first version of this map) were
/// not.
const STEPS: usize = 100;

/// A rise above this fraction of the energy scale is counted in the cells.
const RISE_REPORTED: f64 = 0.01;

/// `cargo xtask stability [--quick]`: in a dev build, re-runs itself as a
/// release build (the matrix is tens of thousands of runs); in a release
/// build, runs the matrix and writes `docs/reports/stability.md`.
pub fn main(root: &Path, args: &[String]) -> ExitCode {
    // The method axis: its own reduced matrix and report.
    if args
        .windows(2)
        .any(|w| w[0] == "--only" && w[1] == "methods")
    {
        return crate::report(methods::run(root, args));
    }
    // The contact axis alone, in this build (docs/reports/stability-contact.md).
    if args
        .windows(2)
        .any(|w| w[0] == "--only" && w[1] == "contact")
    {
        return crate::report(crate::stability_contact::run(root));
    }
    let quick = args.iter().any(|a| a == "--quick");
    let mode = match shard::Mode::parse(root, args) {
        Ok(mode) => mode,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    if cfg!(debug_assertions) {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut command = Command::new(&cargo);
        command.args(["run", "--release", "--package", "xtask", "--", "stability"]);
        command.args(args);
        eprintln!("re-running as a release build");
        return match command.status() {
            Ok(status) if status.success() => ExitCode::SUCCESS,
            Ok(_) => ExitCode::FAILURE,
            Err(e) => {
                eprintln!("cannot run {cargo}: {e}");
                ExitCode::FAILURE
            }
        };
    }
    crate::report(run(root, quick, &mode))
}

const BEAM: &str = r#"
[simulation]
dt = 0.01
steps = 10
[[body]]
mesh = { generator = "box", size = [1.0, 0.25, 0.25], cells = [2, 1, 1] }
density = 1000.0
constraints = [ { kind = "tet-strain", stiffness = 1.0e5 } ]
fixed = { box = { min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] } }
"#;

const CUBE: &str = r#"
[simulation]
dt = 0.01
steps = 10
[[body]]
mesh = { generator = "box", size = [0.3, 0.3, 0.3], cells = [1, 1, 1] }
density = 1000.0
constraints = [ { kind = "tet-strain", stiffness = 1.0e5 } ]
"#;

const CLOTH: &str = r#"
[simulation]
dt = 0.01
steps = 10
[[body]]
mesh = { generator = "cloth", size = [0.5, 0.5], cells = [4, 4] }
density = 1.0
constraints = [ { kind = "triangle-strain", stiffness = 1.0e2 } ]
fixed = { vertices = [0, 4] }
"#;

/// Thickness of the stability map's cloth, m.
const CLOTH_THICKNESS: f64 = 1e-3;

/// The body of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Body {
    Beam,
    Cube,
    Cloth,
}

impl Body {
    const ALL: [Self; 3] = [Self::Beam, Self::Cube, Self::Cloth];

    fn name(self) -> &'static str {
        match self {
            Self::Beam => "clamped beam",
            Self::Cube => "free cube",
            Self::Cloth => "pinned cloth",
        }
    }

    /// The body's scene, mass and constraints for the case's parameters.
    fn scene(self, case: &Case) -> Result<Scene, String> {
        let text = match self {
            Self::Beam => BEAM,
            Self::Cube => CUBE,
            Self::Cloth => CLOTH,
        };
        let mut scene = Scene::parse(text, Syntax::Toml, Path::new("stability.toml"))
            .map_err(|e| e.to_string())?;
        let body = &mut scene.bodies[0];
        if self == Self::Cloth {
            let e_t = case.stiffness * CLOTH_THICKNESS;
            body.mass = MassSpec::Density(case.density * CLOTH_THICKNESS);
            body.constraints = vec![
                ConstraintSpec::TriangleStrain {
                    stiffness: e_t,
                    limits: None,
                },
                ConstraintSpec::Bending {
                    stiffness: e_t * CLOTH_THICKNESS * CLOTH_THICKNESS / 12.0,
                },
            ];
        } else {
            body.mass = MassSpec::Density(case.density);
            body.constraints = vec![ConstraintSpec::TetStrain {
                stiffness: case.stiffness,
                limits: None,
            }];
        }
        Ok(scene)
    }
}

/// How a run starts.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Start {
    Rest,
    Inverted,
    Compressed,
    Fast,
}

impl Start {
    const ALL: [Self; 4] = [Self::Rest, Self::Inverted, Self::Compressed, Self::Fast];

    fn name(self) -> &'static str {
        match self {
            Self::Rest => "rest",
            Self::Inverted => "inverted",
            Self::Compressed => "compressed",
            Self::Fast => "fast",
        }
    }

    /// The starting state from the rest state.
    fn apply(self, rest: &State) -> State {
        let mut state = rest.clone();
        for (i, (x, v)) in state
            .positions
            .iter_mut()
            .zip(&mut state.velocities)
            .enumerate()
        {
            match self {
                Self::Rest => {}
                Self::Inverted => x.x = -x.x,
                Self::Compressed => x.x *= 0.01,
                Self::Fast => {
                    // Directions spread over the sphere (golden-angle spiral).
                    let t = i as f64 * 2.399_963_229_728_653;
                    let z = 1.0 - 2.0 * ((i % 7) as f64 + 0.5) / 7.0;
                    let r = (1.0 - z * z).sqrt();
                    v.x = 100.0 * r * t.cos();
                    v.y = 100.0 * r * t.sin();
                    v.z = 100.0 * z;
                }
            }
        }
        state
    }
}

/// The damping models of the matrix: every preset of the registry, named
/// by its preset name, its strength parameter set to the coefficient.
/// The cargo profile this xtask was built in, as the generated reports
/// name it.
pub(crate) fn profile_name() -> &'static str {
    if cfg!(debug_assertions) {
        "dev"
    } else {
        "release"
    }
}

fn presets() -> &'static [Preset] {
    registry::presets()
}

/// Preset `preset` with its model's strength parameter (`rate`, `factor`,
/// `stiffness`) set to `c`, clamped to the parameter's maximum (PBD's
/// factor: `min(c, 1)`); a model without one (`none`) as it is.
fn damping(preset: &Preset, c: f64) -> Result<DampingSpec, String> {
    let spec = preset.spec().map_err(|e| e.to_string())?;
    let model = spec.model();
    match model.strength.and_then(|name| model.parameter(name)) {
        None => Ok(spec),
        Some(parameter) => {
            let value = parameter.maximum.map_or(c, |maximum| c.min(maximum));
            spec.with(parameter.name, Value::Number(value))
                .map_err(|e| e.to_string())
        }
    }
}

/// Whether the matrix's coefficient axis applies to preset `index`.
fn has_strength(index: usize) -> bool {
    registry::model(presets()[index].model).is_some_and(|m| m.strength.is_some())
}

/// One run of the matrix.
#[derive(Debug, Clone, Copy)]
struct Case {
    integrator: IntegratorKind,
    model: usize,
    stiffness: f64,
    dt: f64,
    density: f64,
    coefficient: f64,
    iterations: usize,
    start: Start,
    body: Body,
    /// The iteration method (local-global outside the method axis).
    method: pd_solver::SolverMethod,
    /// Where each step starts (inertial outside `--only methods --predictor`).
    predictor: pd_solver::Predictor,
}

impl Case {
    /// The column names of [`Case::cells`], for a Markdown table.
    const COLUMNS: &str =
        "integrator | model | c | stiffness | dt | density | iterations | start | body";
    const COLUMN_COUNT: usize = 9;

    /// The case's parameters as Markdown table cells.
    fn cells(&self) -> String {
        format!(
            "{} | {} | {:e} | {:e} | {:e} | {:e} | {} | {} | {}",
            self.integrator.name(),
            presets()[self.model].name,
            self.coefficient,
            self.stiffness,
            self.dt,
            self.density,
            self.iterations,
            self.start.name(),
            self.body.name(),
        )
    }
}

/// The rule of the "energy created" heading, as the reports state it: the
/// energy warning of a run's summary (`AccuracyWatch::energy_created`).
pub(crate) fn energy_rule() -> String {
    format!(
        "A completed run is **completed sane** unless it **created energy**: in a setting \
         that should only dissipate (backward Euler or BDF-2 with any damping, implicit \
         midpoint with a damping model), its total energy (kinetic + elastic + \
         gravitational) rose above its running minimum by more than {:.0}% of its largest \
         kinetic plus elastic energy. Gravity's work is in the total as potential energy, \
         and a fixed collider does no work, so no external work explains such a rise. This \
         is the rule, and the code, of the energy warning of a run's `summary.json` \
         (`energy_created_j`, `docs/guide/03-accuracy-and-solvers.md`). Undamped implicit \
         midpoint conserves energy rather than dissipating it (its rises are exchange and \
         round-off, not creation): its runs are not classified by this rule, and a \
         completed one counts as completed sane.",
        100.0 * ENERGY_WARNING
    )
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
enum Ending {
    /// Every step ran; the state and energies are finite. `rise`: the
    /// largest `(E(t) - E(0)) / scale` over the run (0 if the energy never
    /// rose above its start); `inverted`: elements inside out at the end;
    /// `energy`: the energy the run created, as its summary's accuracy
    /// watch measures it (`None` where the setting need not dissipate).
    Completed {
        rise: f64,
        inverted: usize,
        energy: Option<EnergyCreated>,
    },
    /// Stopped with `SolverError::Diverged` at `step`, for `reason`.
    Diverged { step: usize, reason: String },
    /// A panic, a non-finite value after an `Ok` step, or another error.
    Bug(String),
}

impl Ending {
    /// Whether the run completed but created energy where it should only
    /// dissipate: the run summary's energy warning
    /// ([`EnergyCreated::warns`]).
    fn created_energy(&self) -> bool {
        matches!(self, Self::Completed { energy: Some(e), .. } if e.warns())
    }

    /// Whether the run completed sane: every step ran and it created no
    /// energy.
    fn sane(&self) -> bool {
        matches!(self, Self::Completed { .. }) && !self.created_energy()
    }
}

fn finite(state: &State) -> bool {
    state
        .positions
        .iter()
        .chain(&state.velocities)
        .all(|p| p.iter().all(|c| c.is_finite()))
}

/// Tetrahedra with a negative signed volume in the current state.
fn inverted_elements(sim: &pd_solver::Simulation) -> usize {
    let x = &sim.state().positions;
    sim.model()
        .bodies()
        .iter()
        .flat_map(|body| {
            body.mesh
                .tets()
                .iter()
                .map(move |t| t.map(|v| v + body.offset))
        })
        .filter(|t| {
            (x[t[1]] - x[t[0]])
                .cross(&(x[t[2]] - x[t[0]]))
                .dot(&(x[t[3]] - x[t[0]]))
                < 0.0
        })
        .count()
}

fn run_case(case: &Case) -> Ending {
    let outcome = catch_unwind(AssertUnwindSafe(|| -> Result<Ending, String> {
        let mut scene = case.body.scene(case)?;
        scene.settings.dt = case.dt;
        scene.settings.iterations = case.iterations;
        scene.settings.threads = 1;
        scene.integrator = case.integrator;
        scene.solver.method = case.method;
        scene.predictor = case.predictor;
        scene.damping = damping(&presets()[case.model], case.coefficient)?;
        let mut sim = scene.build().map_err(|e| e.to_string())?;
        let start = case.start.apply(sim.state());
        sim.set_state(start).map_err(|e| e.to_string())?;
        let initial = sim.energies().total();
        let scale = sim.energy_scale();
        if !(initial.is_finite() && scale > 0.0 && scale.is_finite()) {
            return Ok(Ending::Bug(format!(
                "initial energy {initial}, energy scale {scale}"
            )));
        }
        let mut rise = 0.0f64;
        let bound = sim.settings().divergence_energy_factor;
        // The rows a run records, for the energy created (row 0: the start).
        let mut watch = AccuracyWatch::default();
        watch.observe(&MetricsRow::of(&sim, None));
        for _ in 0..STEPS {
            match sim.step() {
                Ok(stats) => {
                    let row = MetricsRow::of(&sim, Some(&stats));
                    if !finite(sim.state())
                        || !row.total.is_finite()
                        || !stats.total_seconds.is_finite()
                    {
                        return Ok(Ending::Bug(format!(
                            "non-finite output after step {}: energies {:?}",
                            sim.steps(),
                            sim.energies()
                        )));
                    }
                    watch.observe(&row);
                    rise = rise.max((row.total - initial) / scale);
                    if rise > bound {
                        return Ok(Ending::Bug(format!(
                            "completed step {} exploded: total energy {:.3e} J is {rise:.3e} x \
                             the energy scale above its start, past the divergence bound {bound}",
                            sim.steps(),
                            row.total
                        )));
                    }
                }
                Err(SolverError::Diverged { step, reason, .. }) => {
                    if !finite(sim.state()) {
                        return Ok(Ending::Bug("diverged with a non-finite state".into()));
                    }
                    return Ok(Ending::Diverged { step, reason });
                }
                Err(e) => return Ok(Ending::Bug(e.to_string())),
            }
        }
        Ok(Ending::Completed {
            rise,
            inverted: inverted_elements(&sim),
            energy: watch.energy_created(&sim),
        })
    }));
    match outcome {
        Ok(Ok(ending)) => ending,
        Ok(Err(setup)) => Ending::Bug(format!("setup failed: {setup}")),
        Err(panic) => Ending::Bug(format!(
            "panic: {}",
            panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default()
        )),
    }
}

/// The axes of the matrix.
struct Axes {
    stiffness: Vec<f64>,
    dt: Vec<f64>,
    density: Vec<f64>,
    coefficient: Vec<f64>,
    iterations: Vec<usize>,
    bodies: Vec<Body>,
}

impl Axes {
    fn new(quick: bool) -> Self {
        if quick {
            Self {
                stiffness: vec![1e0, 1e9],
                dt: vec![1e-5, 0.1],
                density: vec![1.0, 1e5],
                coefficient: vec![1e3],
                iterations: vec![1, 200],
                bodies: vec![Body::Beam, Body::Cloth],
            }
        } else {
            Self {
                stiffness: vec![1e0, 1e3, 1e6, 1e9],
                dt: vec![1e-5, 1e-3, 0.1],
                density: vec![1.0, 1e3, 1e5],
                coefficient: vec![1e-3, 1.0, 1e3],
                iterations: vec![1, 10, 200],
                bodies: Body::ALL.to_vec(),
            }
        }
    }

    fn cases(&self) -> Vec<Case> {
        let mut cases = Vec::new();
        for integrator in IntegratorKind::ALL {
            for model in 0..presets().len() {
                // The coefficient does not apply to `none`: one value.
                let coefficients = if has_strength(model) {
                    &self.coefficient[..]
                } else {
                    &self.coefficient[..1]
                };
                for &stiffness in &self.stiffness {
                    for &dt in &self.dt {
                        for &density in &self.density {
                            for &coefficient in coefficients {
                                for &iterations in &self.iterations {
                                    for start in Start::ALL {
                                        for &body in &self.bodies {
                                            cases.push(Case {
                                                integrator,
                                                model,
                                                stiffness,
                                                dt,
                                                density,
                                                coefficient,
                                                iterations,
                                                start,
                                                body,
                                                method: pd_solver::SolverMethod::LocalGlobal,
                                                predictor: pd_solver::Predictor::Inertial,
                                            });
                                        }
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        cases
    }
}

/// Counts of a set of runs.
#[derive(Debug, Clone, Copy, Default)]
struct Tally {
    runs: usize,
    /// Completed runs that created no energy ([`Ending::sane`]).
    sane: usize,
    /// Completed runs that created energy ([`Ending::created_energy`]).
    created: usize,
    /// Completed runs the energy-created rule applies to (every run but
    /// those of undamped implicit midpoint).
    classified: usize,
    /// The largest energy created among the completed runs, as a fraction
    /// of the run's largest kinetic plus elastic energy.
    largest_created: f64,
    /// Completed runs whose energy rose by more than `RISE_REPORTED`.
    rose: usize,
    /// The largest rise among the completed runs.
    largest_rise: f64,
    /// Completed runs that ended with an inverted element.
    inverted: usize,
    diverged: usize,
    bugs: usize,
}

impl Tally {
    /// The tally of the `results` that `keep` selects.
    fn of<'a>(
        results: impl IntoIterator<Item = &'a (Case, Ending)>,
        keep: impl Fn(&Case) -> bool,
    ) -> Self {
        let mut tally = Self::default();
        for (case, ending) in results {
            if keep(case) {
                tally.add(ending);
            }
        }
        tally
    }

    fn add(&mut self, ending: &Ending) {
        self.runs += 1;
        self.sane += usize::from(ending.sane());
        self.created += usize::from(ending.created_energy());
        match ending {
            Ending::Completed {
                rise,
                inverted,
                energy,
            } => {
                self.inverted += usize::from(*inverted > 0);
                self.rose += usize::from(*rise > RISE_REPORTED);
                self.largest_rise = self.largest_rise.max(*rise);
                if let Some(energy) = energy {
                    self.classified += 1;
                    self.largest_created = self.largest_created.max(energy.fraction());
                }
            }
            Ending::Diverged { .. } => self.diverged += 1,
            Ending::Bug(_) => self.bugs += 1,
        }
    }

    /// The energy created as summary cells: the count and the largest
    /// fraction in percent, or `-` where no completed run is classified.
    fn created_cells(&self) -> String {
        if self.classified == 0 {
            return "- | -".into();
        }
        format!("{} | {:.1}", self.created, 100.0 * self.largest_created)
    }

    /// `sane% +created% (grew%)`, or `-` without runs; bugs are flagged.
    fn cell(&self) -> String {
        if self.runs == 0 {
            return "-".into();
        }
        let pct = |k: usize| 100.0 * k as f64 / self.runs as f64;
        // Truncated, not rounded: 3 failures in 2592 runs must not read 100.
        let mut text = if self.sane == self.runs {
            "100".to_string()
        } else {
            format!("{:.1}", (pct(self.sane) * 10.0).floor() / 10.0)
        };
        if self.created > 0 {
            // Rounded up: 1 run in 2592 must not read 0.0.
            write!(text, " +{:.1}", (pct(self.created) * 10.0).ceil() / 10.0).expect("infallible");
        }
        if self.rose > 0 {
            write!(text, " ({:.1})", pct(self.rose)).expect("infallible");
        }
        if self.bugs > 0 {
            write!(text, " **{} bug**", self.bugs).expect("infallible");
        }
        text
    }
}

fn row_label(integrator: IntegratorKind, model: usize) -> String {
    format!("{} | {}", integrator.name(), presets()[model].name)
}

/// Writes one table: rows integrator x model, a column per value of an axis.
fn axis_table(
    out: &mut String,
    title: &str,
    labels: &[String],
    results: &[(Case, Ending)],
    column_of: impl Fn(&Case) -> usize,
) {
    writeln!(out, "\n### By {title}\n").expect("infallible");
    writeln!(out, "| integrator | model | {} |", labels.join(" | ")).expect("infallible");
    writeln!(out, "|---|---|{}", "---|".repeat(labels.len())).expect("infallible");
    for integrator in IntegratorKind::ALL {
        for model in 0..presets().len() {
            let cells: Vec<String> = (0..labels.len())
                .map(|column| {
                    Tally::of(results, |case| {
                        case.integrator == integrator
                            && case.model == model
                            && column_of(case) == column
                    })
                    .cell()
                })
                .collect();
            writeln!(
                out,
                "| {} | {} |",
                row_label(integrator, model),
                cells.join(" | ")
            )
            .expect("infallible");
        }
    }
}

/// Writes the table `title` of the runs with the largest `figure` (a
/// column headed `heading`, written by `format`): the first 12, then each
/// integrator's own first 4, as the overall list is dominated by one
/// integrator (docs/design/properties.md). Nothing without runs.
fn largest_runs(
    out: &mut String,
    title: &str,
    heading: &str,
    mut runs: Vec<(&Case, f64)>,
    format: impl Fn(f64) -> String,
) {
    if runs.is_empty() {
        return;
    }
    runs.sort_by(|a, b| b.1.total_cmp(&a.1));
    writeln!(
        out,
        "\n## {title}\n\n| {heading} | {} |\n|---|{}",
        Case::COLUMNS,
        "---|".repeat(Case::COLUMN_COUNT)
    )
    .expect("infallible");
    let own = |integrator| {
        runs.iter()
            .filter(move |(case, _)| case.integrator == integrator)
            .take(4)
    };
    let first = runs.iter().take(12);
    for (case, figure) in first.chain(IntegratorKind::ALL.into_iter().flat_map(own)) {
        writeln!(out, "| {} | {} |", format(*figure), case.cells()).expect("infallible");
    }
}

fn position<T: PartialEq>(values: &[T], value: &T) -> usize {
    values
        .iter()
        .position(|v| v == value)
        .expect("a case's value is on its axis")
}

fn labels<T: std::fmt::LowerExp>(values: &[T]) -> Vec<String> {
    values.iter().map(|v| format!("{v:e}")).collect()
}

/// Runs the matrix on every core and writes the report; returns its path,
/// or an error naming the number of bugs found.
fn run(root: &Path, quick: bool, mode: &shard::Mode) -> Result<PathBuf, String> {
    let axes = Axes::new(quick);
    let cases = axes.cases();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mine: Vec<usize> = (0..cases.len()).filter(|&i| mode.runs(i)).collect();
    eprintln!(
        "{} of {} runs on {threads} threads",
        mine.len(),
        cases.len()
    );
    let started = std::time::Instant::now();
    let next = Mutex::new(0usize);
    let results = Mutex::new(Vec::with_capacity(cases.len()));
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    let index = {
                        let mut next = next.lock().expect("no thread panics holding it");
                        let index = *next;
                        *next += 1;
                        index
                    };
                    let Some(&index) = mine.get(index) else { break };
                    let ending = run_case(&cases[index]);
                    results
                        .lock()
                        .expect("no thread panics holding it")
                        .push((index, ending));
                }
            });
        }
    });
    let mut results = results.into_inner().expect("threads joined");
    results.sort_by_key(|(index, _)| *index);
    let mut seconds = started.elapsed().as_secs_f64();
    match mode {
        shard::Mode::Whole => {}
        shard::Mode::Shard { .. } => {
            return shard::write(mode, quick, cases.len(), seconds, &results);
        }
        shard::Mode::Merge(dir) => (results, seconds) = shard::read(dir, quick, cases.len())?,
    }
    let results: Vec<(Case, Ending)> = results
        .into_iter()
        .map(|(index, ending)| (cases[index], ending))
        .collect();

    let machine = crate::bench_report::machine();
    let mut out = String::new();
    writeln!(
        out,
        "# Stability at the extremes\n\n\
         Generated by `cargo xtask stability{}` ({} runs of {STEPS} steps, {seconds:.0} s on\n\
         {threads} threads, CPU {} with {} logical cores, {} build). Do not edit by hand:\n\
         the matrix and the rules are in `xtask/src/stability.rs`; `docs/design/properties.md`\n\
         explains how this relates to the tests.\n\n\
         Every run must either complete (a finite state and energies, the total energy\n\
         never above the divergence bound) or stop with the solver's divergence error\n\
         (`SolverError::Diverged`: a step fails when its total energy, kinetic + gravitational\n\
         + elastic, exceeds the initial energy by more than 1000 times the system's energy\n\
         scale, `docs/design/solver.md`). A run that completes exploded (above that bound: the check\n\
         missed it), a panic, a NaN or infinity after a step that returned `Ok`, or any other\n\
         error is a bug, and the command fails.\n\n\
         {}\n\n\
         Every run is exactly one of completed sane, energy created, diverged or bug. Completed\n\
         runs (sane or not) that end with elements still inside out are also counted apart\n\
         (\"ended inverted\"): not called stable, not a bug of the check.\n\n\
         Matrix: stiffness {} Pa; time step {} s; density {} kg/m^3; damping\n\
         coefficient `c` {} (a rate in 1/s for ether drag, `a2` in s for Laplacian and\n\
         lagged Rayleigh, PBD factor `min(c, 1)`; `none` runs once per cell); iterations {};\n\
         starting state at rest, inverted (x mirrored: every tet inside out), compressed (x\n\
         scaled by 0.01), fast (100 m/s per vertex); bodies: {}. Gravity on.\n\n\
         Each cell: the percentage of its runs that completed sane; after `+`, the percentage\n\
         that completed but created energy (rounded up), when there are any; the rest stopped\n\
         with the divergence error. In parentheses, the percentage whose total energy rose, at\n\
         some step, above its start by more than {RISE_REPORTED} of the energy scale (kinetic + elastic\n\
         energy at the start, plus the work gravity does over the body's size, plus the kinetic\n\
         energy of moving the body by its size in 1 s), when there are any. The summary gives\n\
         the largest such rise in units of that scale; the divergence error fires at 1000.\n\
         Theory promises no energy bound for these nonconvex (corotational) energies and\n\
         unconverged solves; the guarantees that do hold are property tests\n\
         (`docs/design/properties.md`).\n",
        if quick { " --quick" } else { "" },
        results.len(),
        machine.cpu,
        machine.logical_cores,
        profile_name(),
        energy_rule(),
        labels(&axes.stiffness).join(", "),
        labels(&axes.dt).join(", "),
        labels(&axes.density).join(", "),
        labels(&axes.coefficient).join(", "),
        axes.iterations
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(", "),
        if quick {
            "a clamped 1 x 0.25 x 0.25 m beam (12 tets) and a 0.5 m cloth of 1 mm \
             (32 triangles; E t = stiffness x 1 mm, D = E t^3/12, rho_A = density x 1 mm) \
             pinned at two corners"
        } else {
            "a clamped 1 x 0.25 x 0.25 m beam (12 tets), a free 0.3 m cube (6 tets) and a 0.5 m \
             cloth of 1 mm (32 triangles; E t = stiffness x 1 mm, D = E t^3/12, rho_A = density \
             x 1 mm) pinned at two corners"
        },
    )
    .expect("infallible");

    let bugs: Vec<&(Case, Ending)> = results
        .iter()
        .filter(|(_, e)| matches!(e, Ending::Bug(_)))
        .collect();
    writeln!(
        out,
        "\n## Summary\n\n\
         | integrator | runs | completed sane | energy created | ended inverted | diverged | bugs |\n\
         |---|---|---|---|---|---|---|"
    )
    .expect("infallible");
    for integrator in IntegratorKind::ALL {
        let t = Tally::of(&results, |case| case.integrator == integrator);
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} |",
            integrator.name(),
            t.runs,
            t.sane,
            t.created,
            t.inverted,
            t.diverged,
            t.bugs
        )
        .expect("infallible");
    }
    writeln!(
        out,
        "\nBy damping model (\"largest created\": the largest energy created among the\n\
         completed runs, in % of the run's largest kinetic plus elastic energy; `-` where\n\
         the rule does not apply):\n\n\
         | integrator | model | runs | completed sane | energy created | largest created (%) | energy rose > {RISE_REPORTED} x scale | largest rise (x scale) | ended inverted | diverged | bugs (incl. completed exploded) |\n|---|---|---|---|---|---|---|---|---|---|---|"
    )
    .expect("infallible");
    for integrator in IntegratorKind::ALL {
        for model in 0..presets().len() {
            let t = Tally::of(&results, |case| {
                case.integrator == integrator && case.model == model
            });
            writeln!(
                out,
                "| {} | {} | {} | {} | {} | {:.3} | {} | {} | {} |",
                row_label(integrator, model),
                t.runs,
                t.sane,
                t.created_cells(),
                t.rose,
                t.largest_rise,
                t.inverted,
                t.diverged,
                t.bugs
            )
            .expect("infallible");
        }
    }
    if bugs.is_empty() {
        writeln!(
            out,
            "\nNo run broke the rule: no panic, no NaN or infinity reached the state or the\nenergies, and every failure was the divergence error."
        )
        .expect("infallible");
    } else {
        writeln!(out, "\n## Bugs\n").expect("infallible");
        for (case, ending) in &bugs {
            writeln!(out, "- `{case:?}`: {ending:?}").expect("infallible");
        }
    }

    let created: Vec<(&Case, f64)> = results
        .iter()
        .filter_map(|(case, ending)| match ending {
            Ending::Completed {
                energy: Some(energy),
                ..
            } if ending.created_energy() => Some((case, 100.0 * energy.fraction())),
            _ => None,
        })
        .collect();
    largest_runs(
        &mut out,
        "The runs that created the most energy",
        "created (% of kinetic + elastic)",
        created,
        |x| format!("{x:.1}"),
    );
    let rises: Vec<(&Case, f64)> = results
        .iter()
        .filter_map(|(case, ending)| match ending {
            Ending::Completed { rise, .. } if *rise > RISE_REPORTED => Some((case, *rise)),
            _ => None,
        })
        .collect();
    largest_runs(
        &mut out,
        "The largest energy rises",
        "rise (x scale)",
        rises,
        |x| format!("{x:.3e}"),
    );

    let diverged: Vec<(&Case, usize, &str)> = results
        .iter()
        .filter_map(|(case, ending)| match ending {
            Ending::Diverged { step, reason } => Some((case, *step, reason.as_str())),
            _ => None,
        })
        .collect();
    if !diverged.is_empty() {
        writeln!(
            out,
            "\n## The runs that diverged\n\n| {} | step | reason |\n|---|{}",
            Case::COLUMNS,
            "---|".repeat(Case::COLUMN_COUNT + 1)
        )
        .expect("infallible");
        for (case, step, reason) in &diverged {
            writeln!(
                out,
                "| {} | {step} | {} |",
                case.cells(),
                reason.replace('|', "/")
            )
            .expect("infallible");
        }
    }

    writeln!(out, "\n## Where each combination is stable").expect("infallible");
    axis_table(
        &mut out,
        "stiffness (Pa)",
        &labels(&axes.stiffness),
        &results,
        |c| position(&axes.stiffness, &c.stiffness),
    );
    axis_table(
        &mut out,
        "time step (s)",
        &labels(&axes.dt),
        &results,
        |c| position(&axes.dt, &c.dt),
    );
    axis_table(
        &mut out,
        "density (kg/m^3)",
        &labels(&axes.density),
        &results,
        |c| position(&axes.density, &c.density),
    );
    axis_table(
        &mut out,
        "damping coefficient",
        &labels(&axes.coefficient),
        &results,
        |c| position(&axes.coefficient, &c.coefficient),
    );
    let iteration_labels: Vec<String> = axes.iterations.iter().map(|i| i.to_string()).collect();
    axis_table(&mut out, "iterations", &iteration_labels, &results, |c| {
        position(&axes.iterations, &c.iterations)
    });
    let start_labels: Vec<String> = Start::ALL.iter().map(|s| s.name().to_string()).collect();
    axis_table(&mut out, "starting state", &start_labels, &results, |c| {
        position(&Start::ALL, &c.start)
    });
    if axes.bodies.len() > 1 {
        let names: Vec<String> = axes.bodies.iter().map(|b| b.name().to_string()).collect();
        axis_table(&mut out, "body", &names, &results, |c| {
            position(&axes.bodies, &c.body)
        });
    }

    let path = root.join("docs/reports/stability.md");
    std::fs::write(&path, out).map_err(|e| format!("{}: {e}", path.display()))?;
    if bugs.is_empty() {
        Ok(path)
    } else {
        Err(format!(
            "{} runs broke the rule; see {}",
            bugs.len(),
            path.display()
        ))
    }
}
