//! `pd fit`: fits scene values (damping coefficients or ratios, stiffness,
//! density) to a recorded motion, a `probes.csv` as `pd run` writes it.
//!
//! The loss is the mean over steps `1..=N` and probes of the squared
//! distance between the simulated and the target probe positions, m^2.
//! Every fitted value is positive and is optimised in log space
//! (`z = ln p`) by L-BFGS ([`lbfgs`]). Gradients come from a
//! [`GradientBackend`]: the adjoint method ([`adjoint`]) where the paths
//! and the scene allow it, else central differences in `z`
//! ([`FiniteDifference`]), one forward run per parameter and side.
//!
//! Forward runs are converged: whatever the scene asks, each step runs
//! to an estimated relative error of [`FIT_ACCURACY`], by Newton's method
//! where the scene allows it, so that the loss is a smooth function of the
//! parameters to well below the finite differences' step (a loss from
//! unconverged steps jumps where the iteration count changes).

mod adjoint;
mod decay;
mod lbfgs;
mod paths;

use std::path::{Path, PathBuf};
use std::time::Instant;

use pd_io::probes::ProbeTrack;
use pd_io::scene::{ACCURACY_ITERATIONS, Scene, Syntax};
use pd_mesh::Point;
use pd_solver::{SolverError, SolverMethod};
use serde_json::{Value, json};
use tracing::{debug, info};

use crate::Failure;
use paths::FieldPath;

/// The estimated relative error of each step of a forward run for fitting
/// ([`pd_solver::Settings::accuracy`]). Newton's iterations converge
/// quadratically, so a step usually ends far below it; the loss's noise is
/// then orders of magnitude below the change the finite-difference step
/// [`FD_STEP`] makes.
pub(crate) const FIT_ACCURACY: f64 = 1e-9;

/// The central-difference step in `ln p`: a relative change of 1e-4, whose
/// truncation error (`h^2/6` of the third derivative, ~1e-9 relative) and
/// noise amplification (`1/(2h)` of the loss's noise) are both small.
const FD_STEP: f64 = 1e-4;

/// Largest change of `ln p` in one iteration: a factor of `e`.
const MAX_LOG_STEP: f64 = 1.0;

/// L-BFGS pairs kept (more than the few parameters fitted).
const MEMORY: usize = 10;

/// The file name of the fitted scene in the output folder.
pub(crate) const FITTED_SCENE: &str = "fitted.toml";

/// What `pd fit` is asked.
pub(crate) struct FitOptions {
    pub scene: PathBuf,
    pub target: PathBuf,
    pub fit: Vec<String>,
    pub out: Option<PathBuf>,
    pub max_iterations: usize,
    pub tolerance: f64,
}

/// A loss and its gradient at one point, and what they cost.
#[derive(Debug, Clone)]
pub(crate) struct Evaluation {
    /// The loss, m^2.
    pub loss: f64,
    /// `dloss/dp` for each fitted value `p`, in the loss's units per the
    /// value's.
    pub gradient: Vec<f64>,
    /// Seconds of the forward run giving the loss.
    pub forward_s: f64,
    /// Seconds spent on the gradient beyond that run.
    pub backward_s: f64,
}

/// Where gradients come from: finite differences here; an adjoint method
/// can take its place. A backend works from the [`Problem`]: the scene at
/// given values ([`Problem::scene_at`], set up for converged runs), the
/// probed vertices and the target positions (the loss's data), and the
/// fitted paths; [`fit_with`] runs the fit with it.
pub(crate) trait GradientBackend {
    /// As `fit.json`'s `gradient_method` names it.
    fn name(&self) -> &'static str;

    /// The loss at `values` (one per fitted path), m^2; `f64::INFINITY`
    /// where the run diverges.
    ///
    /// # Errors
    /// The scene with these values is invalid, or a run fails otherwise.
    fn loss(&mut self, values: &[f64]) -> Result<f64, Failure>;

    /// The loss and its gradient at `values`.
    ///
    /// # Errors
    /// As [`GradientBackend::loss`], and a diverging run.
    fn evaluate(&mut self, values: &[f64]) -> Result<Evaluation, Failure>;
}

/// The scene to fit, as a value tree, and the motion to match.
pub(crate) struct Problem {
    /// The scene file.
    source: PathBuf,
    /// The scene as data.
    tree: Value,
    /// The fitted paths.
    pub paths: Vec<FieldPath>,
    /// Their values in the scene.
    pub start: Vec<f64>,
    /// The probed vertices.
    probes: Vec<usize>,
    /// Target probe positions, `[step 1..=N][probe]`, m (empty for a
    /// decay target).
    targets: Vec<Vec<Point>>,
    /// A decay description instead of a recording.
    decay: Option<decay::Decay>,
    /// Steps of each forward run.
    steps: usize,
    /// The iteration method of the forward runs.
    method: SolverMethod,
}

impl Problem {
    /// Reads the scene and the target and checks they match.
    ///
    /// # Errors
    /// Unreadable or invalid scene or target, an unsupported or unset path,
    /// a target whose probes, steps or times are not the scene's.
    pub(crate) fn new(scene: &Path, target: &Path, fit: &[String]) -> Result<Self, Failure> {
        let paths = paths::parse_list(fit).map_err(Failure::Input)?;
        let text = std::fs::read_to_string(scene)
            .map_err(|e| Failure::Input(format!("{}: {e}", scene.display())))?;
        let syntax = Syntax::of(scene);
        // The loader's own checks (and messages) first.
        let parsed =
            Scene::parse(&text, syntax, scene).map_err(|e| Failure::Input(e.to_string()))?;
        let tree = match syntax {
            Syntax::Toml => text
                .parse::<toml::Table>()
                .map_err(|e| e.to_string())
                .and_then(|t| serde_json::to_value(t).map_err(|e| e.to_string())),
            Syntax::Json => serde_json::from_str(&text).map_err(|e| e.to_string()),
        }
        .map_err(|e| Failure::Input(format!("{}: {e}", scene.display())))?;
        let start = paths
            .iter()
            .map(|p| p.read(&tree, scene))
            .collect::<Result<Vec<_>, _>>()
            .map_err(Failure::Input)?;
        // A `.toml` or `.json` target is a decay description; anything
        // else is a recording (`probes.csv`).
        let is_description = target
            .extension()
            .is_some_and(|e| e == "toml" || e == "json");
        let (targets, decay) = if is_description {
            let decay =
                decay::Decay::read(target, parsed.output.probes.len()).map_err(Failure::Input)?;
            (Vec::new(), Some(decay))
        } else {
            let track = ProbeTrack::read(target).map_err(|e| Failure::Input(e.to_string()))?;
            (check_target(&track, &parsed).map_err(Failure::Input)?, None)
        };
        let mut problem = Self {
            source: scene.to_path_buf(),
            tree,
            paths,
            start,
            probes: parsed.output.probes.clone(),
            targets,
            decay,
            steps: parsed.steps,
            method: SolverMethod::Newton,
        };
        // Newton's method where the scene allows it (it refuses contact,
        // lagged and per-body damping), else the method the scene names,
        // else Anderson's, else plain local-global.
        let named = (!parsed.choose_method).then_some(parsed.solver.method);
        let candidates = [
            Some(SolverMethod::Newton),
            named,
            Some(SolverMethod::Anderson),
        ];
        let mut refused = Vec::new();
        for method in candidates.into_iter().flatten() {
            problem.method = method;
            match problem.scene_at(&problem.start)?.build() {
                Ok(_) => return Ok(problem),
                Err(e) => refused.push(format!("{}: {e}", method.name())),
            }
        }
        problem.method = SolverMethod::LocalGlobal;
        problem.scene_at(&problem.start)?.build().map_err(|e| {
            refused.push(format!("local-global: {e}"));
            Failure::Input(format!(
                "no iteration method runs the scene for fitting: {}",
                refused.join("; ")
            ))
        })?;
        Ok(problem)
    }

    /// The scene's value tree with `values` at the fitted paths.
    fn tree_at(&self, values: &[f64]) -> Value {
        let mut tree = self.tree.clone();
        for (path, &value) in self.paths.iter().zip(values) {
            path.write(&mut tree, value);
        }
        tree
    }

    /// The scene with `values`, set up for converged forward runs.
    ///
    /// # Errors
    /// The values make the scene invalid (the loader's message).
    pub(crate) fn scene_at(&self, values: &[f64]) -> Result<Scene, Failure> {
        let text = self.tree_at(values).to_string();
        let mut scene = Scene::parse(&text, Syntax::Json, &self.source).map_err(|e| {
            Failure::Input(format!("at the parameters {}: {e}", self.describe(values)))
        })?;
        scene.settings.accuracy = FIT_ACCURACY;
        scene.settings.tolerance = 0.0;
        scene.settings.iterations = ACCURACY_ITERATIONS;
        scene.choose_method = false;
        scene.solver.method = self.method;
        Ok(scene)
    }

    /// One forward run at `values`: the loss, or `None` if it diverged.
    ///
    /// # Errors
    /// The scene is invalid at `values`, or a step fails other than by
    /// diverging.
    pub(crate) fn forward(&self, values: &[f64]) -> Result<Option<f64>, Failure> {
        if let Some(decay) = &self.decay {
            return Ok(self
                .simulated_decay(values)?
                .map(|lost| (lost - decay.lost_per_cycle).powi(2)));
        }
        let scene = self.scene_at(values)?;
        let mut sim = scene.build().map_err(|e| {
            Failure::Input(format!("at the parameters {}: {e}", self.describe(values)))
        })?;
        let mut sum = 0.0;
        for target in &self.targets {
            match sim.step() {
                Ok(_) => {}
                Err(SolverError::Diverged { .. }) => return Ok(None),
                Err(e) => return Err(Failure::Input(e.to_string())),
            }
            let positions = &sim.state().positions;
            sum += self
                .probes
                .iter()
                .zip(target)
                .map(|(&v, x)| (positions[v] - x).norm_squared())
                .sum::<f64>();
        }
        Ok(Some(sum / (self.targets.len() * self.probes.len()) as f64))
    }

    /// The fraction of its amplitude the decay target's probe loses per
    /// cycle in a run at `values` (`None` if it diverged).
    ///
    /// # Errors
    /// As [`Problem::forward`]; a run too short for one cycle.
    fn simulated_decay(&self, values: &[f64]) -> Result<Option<f64>, Failure> {
        let Some(decay) = &self.decay else {
            return Ok(None);
        };
        let scene = self.scene_at(values)?;
        let mut sim = scene.build().map_err(|e| {
            Failure::Input(format!("at the parameters {}: {e}", self.describe(values)))
        })?;
        let vertex = self.probes[decay.probe];
        let mut track = vec![sim.state().positions[vertex]];
        for _ in 0..self.steps {
            match sim.step() {
                Ok(_) => {}
                Err(SolverError::Diverged { .. }) => return Ok(None),
                Err(e) => return Err(Failure::Input(e.to_string())),
            }
            track.push(sim.state().positions[vertex]);
        }
        decay::lost_per_cycle(&track, decay.direction)
            .map(Some)
            .map_err(|e| {
                Failure::Input(format!("at the parameters {}: {e}", self.describe(values)))
            })
    }

    /// Whether the target is a decay description.
    pub(crate) fn has_decay_target(&self) -> bool {
        self.decay.is_some()
    }

    /// The loss's unit in messages: m^2 for a recording, none for a decay
    /// description (a squared fraction).
    fn loss_unit(&self) -> &'static str {
        if self.decay.is_some() { "" } else { " m^2" }
    }

    /// The probed vertices and the target positions `[step 1..=N][probe]`.
    pub(crate) fn loss_data(&self) -> (&[usize], &[Vec<Point>]) {
        (&self.probes, &self.targets)
    }

    /// `path = value, ...`, for messages.
    pub(crate) fn describe(&self, values: &[f64]) -> String {
        self.paths
            .iter()
            .zip(values)
            .map(|(p, v)| format!("{} = {v:.6e}", p.text))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The scene file text with `values`, as TOML, file paths made
    /// absolute so that it loads from any folder.
    fn fitted_toml(&self, values: &[f64]) -> Result<String, String> {
        let mut tree = self.tree_at(values);
        remove_nulls(&mut tree);
        let folder = self
            .source
            .parent()
            .map_or_else(PathBuf::new, Path::to_path_buf);
        paths::absolute_file_paths(&mut tree, &folder);
        let body = toml::to_string(&tree).map_err(|e| e.to_string())?;
        Ok(format!(
            "# {} with the values fitted by `pd fit`:\n{}\n\n{body}",
            self.source.display(),
            values
                .iter()
                .zip(&self.paths)
                .map(|(v, p)| format!("#   {} = {v}", p.text))
                .collect::<Vec<_>>()
                .join("\n")
        ))
    }
}

/// JSON `null` is "not set" in a scene; TOML has no null.
fn remove_nulls(value: &mut Value) {
    match value {
        Value::Object(map) => {
            map.retain(|_, v| !v.is_null());
            map.values_mut().for_each(remove_nulls);
        }
        Value::Array(items) => items.iter_mut().for_each(remove_nulls),
        _ => {}
    }
}

/// The target positions `[step 1..=N][probe]` of `track`, checked against
/// the scene: the same probes, rows for steps 0 to `simulation.steps`, at
/// the scene's times.
fn check_target(track: &ProbeTrack, scene: &Scene) -> Result<Vec<Vec<Point>>, String> {
    let file = track.path.display();
    let header_line = track.rows[0].line.saturating_sub(1).max(1);
    if track.probes != scene.output.probes {
        return Err(format!(
            "{file}:{header_line}: the target records probes {:?}, the scene's output.probes \
             are {:?}; they must be the same vertices in the same order",
            track.probes, scene.output.probes
        ));
    }
    let first = &track.rows[0];
    if first.step != 0 {
        return Err(format!(
            "{file}:{}: the target starts at step {}; it must start at step 0 (the initial \
             state), as pd run writes it",
            first.line, first.step
        ));
    }
    let last = track.rows.last().expect("a track has rows");
    if last.step != scene.steps {
        return Err(format!(
            "{file}:{}: the target ends at step {}, the scene runs {} steps \
             (simulation.steps); they must be the same",
            last.line, last.step, scene.steps
        ));
    }
    let dt = scene.settings.dt;
    for row in &track.rows {
        let expected = row.step as f64 * dt;
        // The run sums `dt` step by step: rounding of ~1e-16 per step.
        if (row.time - expected).abs() > 1e-9 * expected.max(dt) {
            return Err(format!(
                "{file}:{}: time {} s at step {}, the scene's step {} is at {expected} s \
                 (simulation.dt = {dt} s); the target must have the scene's time step",
                row.line, row.time, row.step, row.step
            ));
        }
    }
    Ok(track.rows[1..]
        .iter()
        .map(|r| r.positions.clone())
        .collect())
}

/// Central differences in `ln p`.
pub(crate) struct FiniteDifference<'a> {
    problem: &'a Problem,
}

impl GradientBackend for FiniteDifference<'_> {
    fn name(&self) -> &'static str {
        "finite-difference"
    }

    fn loss(&mut self, values: &[f64]) -> Result<f64, Failure> {
        Ok(self.problem.forward(values)?.unwrap_or(f64::INFINITY))
    }

    fn evaluate(&mut self, values: &[f64]) -> Result<Evaluation, Failure> {
        let diverged = || {
            Failure::Diverged(format!(
                "the run diverged near the parameters {}",
                self.problem.describe(values)
            ))
        };
        let start = Instant::now();
        let loss = self.problem.forward(values)?.ok_or_else(diverged)?;
        let forward_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let mut gradient = Vec::with_capacity(values.len());
        for i in 0..values.len() {
            // `None` where the scene refuses the moved value (a ratio next
            // to where the fitted damping would turn indefinite, say).
            let side = |sign: f64| -> Result<Option<f64>, Failure> {
                let mut moved = values.to_vec();
                moved[i] *= (sign * FD_STEP).exp();
                match self.problem.forward(&moved) {
                    Ok(loss) => loss.ok_or_else(diverged).map(Some),
                    Err(Failure::Input(message)) => {
                        debug!("difference point refused: {message}");
                        Ok(None)
                    }
                    Err(e) => Err(e),
                }
            };
            // d loss / d ln p: central, or one-sided next to a value the
            // scene refuses (first order, error FD_STEP/2 of the second
            // log-derivative); then per unit of p.
            let log_derivative = match (side(1.0)?, side(-1.0)?) {
                (Some(plus), Some(minus)) => (plus - minus) / (2.0 * FD_STEP),
                (Some(plus), None) => (plus - loss) / FD_STEP,
                (None, Some(minus)) => (loss - minus) / FD_STEP,
                (None, None) => {
                    return Err(Failure::Input(format!(
                        "{} cannot be moved by a factor exp(+-{FD_STEP}) at the parameters {}:                          the scene refuses both",
                        self.problem.paths[i].text,
                        self.problem.describe(values)
                    )));
                }
            };
            gradient.push(log_derivative / values[i]);
        }
        Ok(Evaluation {
            loss,
            gradient,
            forward_s,
            backward_s: start.elapsed().as_secs_f64(),
        })
    }
}

/// The log-space objective L-BFGS minimises, keeping the timings.
struct LogObjective<'a, B: GradientBackend> {
    backend: B,
    problem: &'a Problem,
    evaluations: Vec<Evaluation>,
    losses: usize,
}

impl<B: GradientBackend> lbfgs::Objective for LogObjective<'_, B> {
    type Error = Failure;

    fn value(&mut self, z: &[f64]) -> Result<f64, Failure> {
        self.losses += 1;
        let values: Vec<f64> = z.iter().map(|z| z.exp()).collect();
        match self.backend.loss(&values) {
            // A trial value the scene refuses (a ratio no coefficients
            // reach, say) is a point the line search backs away from.
            Err(Failure::Input(message)) => {
                debug!("trial point refused: {message}");
                Ok(f64::INFINITY)
            }
            other => other,
        }
    }

    fn value_and_gradient(&mut self, z: &[f64]) -> Result<(f64, Vec<f64>), Failure> {
        let values: Vec<f64> = z.iter().map(|z| z.exp()).collect();
        let evaluation = self.backend.evaluate(&values)?;
        let log_gradient = evaluation
            .gradient
            .iter()
            .zip(&values)
            .map(|(g, p)| g * p)
            .collect();
        let loss = evaluation.loss;
        self.evaluations.push(evaluation);
        Ok((loss, log_gradient))
    }

    fn progress(&mut self, iteration: &lbfgs::Iteration) {
        let values: Vec<f64> = iteration.z.iter().map(|z| z.exp()).collect();
        info!(
            "iteration {}: loss {:.6e}{unit}, |gradient| {:.3e}{unit} (largest d loss / d ln p), \
             ln p moved by up to {:.3e}; {}",
            iteration.number,
            iteration.value,
            iteration
                .gradient
                .iter()
                .fold(0.0_f64, |m, g| m.max(g.abs())),
            iteration.change,
            self.problem.describe(&values),
            unit = self.problem.loss_unit(),
        );
    }
}

/// `pd fit`; returns the output folder.
pub(crate) fn fit(options: &FitOptions) -> Result<PathBuf, Failure> {
    if !(options.tolerance >= 0.0 && options.tolerance < 1.0) {
        return Err(Failure::Input(format!(
            "--tolerance must be in [0, 1), got {}",
            options.tolerance
        )));
    }
    let problem = Problem::new(&options.scene, &options.target, &options.fit)?;
    let out = options.out.clone().unwrap_or_else(|| {
        let name = options
            .scene
            .file_stem()
            .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
        Path::new("out").join(format!("fit-{name}"))
    });
    match adjoint::Adjoint::new(&problem) {
        Ok(backend) => fit_with(options, &problem, backend, &out)?,
        Err(why) => {
            info!("gradients by finite differences: {why}");
            fit_with(
                options,
                &problem,
                FiniteDifference { problem: &problem },
                &out,
            )?;
        }
    }
    Ok(out)
}

/// Fits `problem` with gradients from `backend`, then writes `out`.
fn fit_with<B: GradientBackend>(
    options: &FitOptions,
    problem: &Problem,
    backend: B,
    out: &Path,
) -> Result<(), Failure> {
    let mut objective = LogObjective {
        backend,
        problem,
        evaluations: Vec::new(),
        losses: 0,
    };
    let backend_name = objective.backend.name();
    let z0: Vec<f64> = problem.start.iter().map(|p| p.ln()).collect();
    let start = lbfgs::Objective::value_and_gradient(&mut objective, &z0)?;
    info!(
        "start: loss {:.6e}{} over {} steps and {} probes; {} ({backend_name} gradients, \
         forward runs converged by {} to {FIT_ACCURACY:e})",
        start.0,
        problem.loss_unit(),
        problem.steps,
        problem.probes.len(),
        problem.describe(&problem.start),
        problem.method.name(),
    );
    let settings = lbfgs::Settings {
        max_iterations: options.max_iterations,
        gradient_tolerance: options.tolerance,
        loss_tolerance: options.tolerance,
        max_step: MAX_LOG_STEP,
        memory: MEMORY,
    };
    let minimum = lbfgs::minimise(&mut objective, &z0, start.clone(), &settings)?;
    // Without an iteration, the scene's values as given (not exp(ln p)).
    let values: Vec<f64> = if minimum.iterations == 0 {
        problem.start.clone()
    } else {
        minimum.z.iter().map(|z| z.exp()).collect()
    };
    info!(
        "stopped after {} iterations ({}): loss {:.6e}{}; {}",
        minimum.iterations,
        minimum.stop.describe(),
        minimum.value,
        problem.loss_unit(),
        problem.describe(&values)
    );
    let evaluations = &objective.evaluations;
    let mean = |f: fn(&Evaluation) -> f64| {
        evaluations.iter().map(f).sum::<f64>() / evaluations.len().max(1) as f64
    };
    let by_path = |numbers: &[f64]| -> serde_json::Map<String, Value> {
        problem
            .paths
            .iter()
            .zip(numbers)
            .map(|(p, v)| (p.text.clone(), json!(v)))
            .collect()
    };
    let gradient: Vec<f64> = minimum
        .gradient
        .iter()
        .zip(&values)
        .map(|(g, p)| g / p)
        .collect();
    let report = json!({
        "scene": options.scene.display().to_string(),
        "target": options.target.display().to_string(),
        "parameters": by_path(&values),
        "initial_parameters": by_path(&problem.start),
        "loss": minimum.value,
        "initial_loss": start.0,
        "iterations": minimum.iterations,
        "stopped": minimum.stop.describe(),
        "tolerance": options.tolerance,
        "gradient": by_path(&gradient),
        "gradient_log": by_path(&minimum.gradient),
        "gradient_method": backend_name,
        "finite_difference_step": FD_STEP,
        "forward_accuracy": FIT_ACCURACY,
        "forward_method": problem.method.name(),
        "timing": {
            "forward_s": mean(|e| e.forward_s),
            "backward_s": mean(|e| e.backward_s),
            "gradient_evaluations": evaluations.len(),
            "loss_evaluations": objective.losses,
        },
        "fitted_scene": FITTED_SCENE,
        "target_kind": if problem.decay.is_some() { "decay" } else { "recording" },
    });
    let mut report = report;
    if let Some(decay) = &problem.decay {
        report["decay"] = json!({
            "probe": decay.probe,
            "direction": decay.direction.map(|d| [d.x, d.y, d.z]),
            "lost_per_cycle": decay.lost_per_cycle,
            "simulated_lost_per_cycle": problem.simulated_decay(&values)?,
        });
    }
    write_results(problem, &values, &report, out)
}

/// Writes the fitted scene (checked to load) and `fit.json` into `out`,
/// each atomically.
fn write_results(
    problem: &Problem,
    values: &[f64],
    report: &Value,
    out: &Path,
) -> Result<(), Failure> {
    let scene_path = out.join(FITTED_SCENE);
    let fitted = problem
        .fitted_toml(values)
        .map_err(|e| Failure::Output(format!("{}: {e}", scene_path.display())))?;
    Scene::parse(&fitted, Syntax::Toml, &scene_path)
        .map_err(|e| Failure::Output(format!("the fitted scene does not load: {e}")))?;
    std::fs::create_dir_all(out).map_err(|e| Failure::Output(format!("{}: {e}", out.display())))?;
    let write = |path: &Path, text: &str| {
        pd_io::write_atomically(path, |w| std::io::Write::write_all(w, text.as_bytes()))
            .map_err(|e| Failure::Output(e.to_string()))
    };
    write(&scene_path, &fitted)?;
    let text = serde_json::to_string_pretty(report).expect("a JSON value always serialises");
    write(&out.join("fit.json"), &format!("{text}\n"))?;
    info!("fit.json and {FITTED_SCENE} in {}", out.display());
    Ok(())
}
