//! `pd run` and `pd resume`.

use std::path::{Path, PathBuf};
use std::sync::Once;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use pd_io::checkpoint::{
    CHECKPOINT_FILE, CheckpointFile, SceneText, read_checkpoint, write_checkpoint,
};
use pd_io::recorder::{Outcome, Recorder};
use pd_io::scene::{Scene, Syntax};
use pd_solver::{Simulation, SolverError, SolverMethod};
use tracing::{debug, info, warn};

use crate::Failure;

/// The bundled default scene (also at `scenes/cantilever.toml`).
const DEFAULT_SCENE: &str = include_str!("../../../scenes/cantilever.toml");
const DEFAULT_SCENE_NAME: &str = "cantilever (built in: scenes/cantilever.toml)";

/// The scene options `pd run` and `pd compare` share: which scene, where
/// to write, and the command line's overrides of the scene's values.
#[derive(clap::Args)]
pub(crate) struct SceneOptions {
    /// Scene file (.toml or .json). Without one, runs the bundled
    /// cantilever beam.
    pub scene: Option<PathBuf>,
    // The help is an attribute, not a doc comment, so rustdoc does not read
    // `<scene name>` as an HTML tag.
    #[arg(
        long,
        help = "Output folder [default: out/<scene name>; for compare, out/compare-<scene name>; \
                for modes, out/modes-<scene name>]"
    )]
    pub out: Option<PathBuf>,
    /// Override the scene's number of steps (not with `modes`, which runs
    /// none).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Threads for the local step (0: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// A scene with the text it was parsed from and a short name.
pub(crate) struct LoadedScene {
    pub scene: Scene,
    pub text: SceneText,
    pub name: String,
}

/// Reads and validates the scene file of `options`, or the bundled
/// cantilever, and applies the overrides.
pub(crate) fn load_scene(options: &SceneOptions) -> Result<LoadedScene, Failure> {
    let (text, name) = match options.scene.as_deref() {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| Failure::Input(format!("{}: {e}", path.display())))?;
            // Absolute, so that a resumed run finds relative mesh paths from
            // any working folder.
            let source = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
            let name = path
                .file_stem()
                .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
            (
                SceneText {
                    source,
                    syntax: Syntax::of(path),
                    text,
                },
                name,
            )
        }
        None => (
            SceneText {
                source: PathBuf::from(DEFAULT_SCENE_NAME),
                syntax: Syntax::Toml,
                text: DEFAULT_SCENE.to_string(),
            },
            "cantilever".to_string(),
        ),
    };
    let mut scene = Scene::parse(&text.text, text.syntax, &text.source)
        .map_err(|e| Failure::Input(e.to_string()))?;
    if let Some(steps) = options.steps {
        scene.steps = steps;
    }
    if let Some(threads) = options.threads {
        scene.settings.threads = threads;
    }
    Ok(LoadedScene { scene, text, name })
}

/// Builds the simulation of a scene; bad input is exit code 2.
pub(crate) fn build(scene: &Scene) -> Result<Simulation, Failure> {
    let start = Instant::now();
    let (sim, achieved) = scene
        .build_with_ratios()
        .map_err(|e| Failure::Input(e.to_string()))?;
    info!(
        "{}: {} vertices ({} free), {} constraints, {} + {} damping; set up in {:.0} ms",
        scene.source.display(),
        sim.model().num_vertices(),
        sim.num_free_vertices(),
        sim.model().num_constraints(),
        sim.integrator_name(),
        sim.damping_name(),
        start.elapsed().as_secs_f64() * 1e3
    );
    if let Some(choice) = sim.method_choice() {
        info!("{}", choice.describe());
    }
    let d = sim.damping_matrix();
    if !d.is_zero() {
        info!(
            "damping coefficients: mass a1 = {:e} 1/s, Laplacian a2 = {:e} s, lagged a3 = {:e} s",
            d.mass, d.damping_laplacian, d.lagged_stiffness
        );
    }
    if d.has_series() {
        let terms: Vec<String> = d
            .series_coefficients()
            .iter()
            .map(|a| format!("{a:e}"))
            .collect();
        info!(
            "Caughey series a1, a2, a3, ... = [{}] (1/s, s, s^3, s^5, ...)",
            terms.join(", ")
        );
    }
    for a in achieved {
        info!(
            "damping ratio of mode {} ({:.4} Hz) with the fitted series: {:.5}",
            a.mode,
            a.omega / std::f64::consts::TAU,
            a.ratio
        );
    }
    for (b, d) in sim
        .damping_body_coefficients()
        .unwrap_or_default()
        .iter()
        .enumerate()
    {
        info!(
            "body {b} damping: mass a1 = {:e} 1/s, Laplacian a2 = {:e} s",
            d.mass, d.damping_laplacian
        );
    }
    Ok(sim)
}

/// `pd run`; returns the output folder.
pub(crate) fn run(
    options: &SceneOptions,
    checkpoint_every: usize,
    quiet: bool,
) -> Result<PathBuf, Failure> {
    let loaded = load_scene(options)?;
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(&loaded.name));
    run_loaded(&loaded, &out, checkpoint_every, quiet)?;
    Ok(out)
}

/// Runs a loaded scene into `out` from its start.
pub(crate) fn run_loaded(
    loaded: &LoadedScene,
    out: &Path,
    checkpoint_every: usize,
    quiet: bool,
) -> Result<(), Failure> {
    let mut sim = build(&loaded.scene)?;
    let recorder =
        Recorder::create(out, &loaded.scene, &sim).map_err(|e| Failure::Output(e.to_string()))?;
    // A checkpoint of an earlier run in the same folder no longer matches.
    let stale = out.join(CHECKPOINT_FILE);
    if stale.exists() {
        std::fs::remove_file(&stale)
            .map_err(|e| Failure::Output(format!("{}: {e}", stale.display())))?;
    }
    execute(loaded, &mut sim, recorder, checkpoint_every, quiet)
}

/// `pd resume DIR`.
pub(crate) fn resume(dir: &Path, quiet: bool) -> Result<(), Failure> {
    let path = dir.join(CHECKPOINT_FILE);
    let file = read_checkpoint(&path).map_err(|e| Failure::Input(e.to_string()))?;
    let mut scene = Scene::parse(&file.scene.text, file.scene.syntax, &file.scene.source)
        .map_err(|e| Failure::Input(format!("the scene in {}: {e}", path.display())))?;
    scene.steps = file.steps_requested;
    scene.settings.threads = file.threads;
    let mut sim = match &file.method {
        // The method the run chose goes on: probing again could choose
        // another, and the run would not continue bit for bit.
        Some(method) if scene.choose_method => {
            let mut chosen = scene.clone();
            chosen.solver.method = SolverMethod::parse(method).ok_or_else(|| {
                Failure::Input(format!("{}: unknown method {method:?}", path.display()))
            })?;
            chosen.choose_method = false;
            build(&chosen)?
        }
        _ => build(&scene)?,
    };
    sim.restore(&file.checkpoint)
        .map_err(|e| Failure::Input(format!("{}: {e}", path.display())))?;
    info!(
        "resuming {} at step {} of {} (t = {} s)",
        dir.display(),
        sim.steps(),
        scene.steps,
        sim.time()
    );
    let recorder = Recorder::resume(dir, &scene, &sim).map_err(|e| match e {
        pd_io::Error::Io { .. } => Failure::Output(e.to_string()),
        _ => Failure::Input(e.to_string()),
    })?;
    let loaded = LoadedScene {
        scene,
        text: file.scene,
        name: String::new(),
    };
    execute(&loaded, &mut sim, recorder, file.checkpoint_every, quiet)
}

/// Set by Ctrl-C (SIGINT): the run stops after the step in progress.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Catches Ctrl-C from now on (once per process): the first stops the run
/// after the step in progress, so that its files are whole and say where it
/// stopped; a second one ends the process at once.
fn catch_interrupts() {
    static INSTALLED: Once = Once::new();
    INSTALLED.call_once(|| {
        let handler = || {
            if INTERRUPTED.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
        };
        if let Err(e) = ctrlc::set_handler(handler) {
            debug!("Ctrl-C is not caught ({e}): it ends the run where it is");
        }
    });
}

/// Steps `sim` to the scene's end, recording and checkpointing, then writes
/// the summary and final state. Ctrl-C stops it after a whole step, with a
/// checkpoint there when checkpoints are on.
fn execute(
    loaded: &LoadedScene,
    sim: &mut Simulation,
    mut recorder: Recorder,
    checkpoint_every: usize,
    quiet: bool,
) -> Result<(), Failure> {
    let scene = &loaded.scene;
    let progress = if quiet {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::new(scene.steps as u64).with_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} steps, {elapsed} elapsed, eta {eta}",
            )
            .expect("the template is valid"),
        );
        bar.set_position(sim.steps() as u64);
        bar
    };
    let checkpoint_path = recorder.dir().join(CHECKPOINT_FILE);
    let checkpoint = |sim: &Simulation| {
        let file = CheckpointFile {
            scene: loaded.text.clone(),
            steps_requested: scene.steps,
            threads: scene.settings.threads,
            checkpoint_every,
            checkpoint: sim.checkpoint(),
            method: scene
                .choose_method
                .then(|| sim.position_solver_name().to_owned()),
        };
        write_checkpoint(&checkpoint_path, &file).map_err(|e| Failure::Output(e.to_string()))?;
        debug!("checkpoint at step {}", sim.steps());
        Ok(())
    };
    catch_interrupts();
    let mut failure = None;
    let mut fallback_logged = false;
    while sim.steps() < scene.steps {
        if INTERRUPTED.load(Ordering::SeqCst) {
            // A checkpoint at this step, unless the last one is at it.
            if checkpoint_every > 0
                && !sim.steps().is_multiple_of(checkpoint_every)
                && let Err(e) = checkpoint(sim)
            {
                failure = Some(e);
                break;
            }
            failure = Some(Failure::Interrupted(format!(
                "interrupted (Ctrl-C) after step {} of {} (t = {} s){}",
                sim.steps(),
                scene.steps,
                sim.time(),
                if checkpoint_every > 0 && sim.steps() > 0 {
                    "; `pd resume` continues from there"
                } else {
                    ""
                }
            )));
            break;
        }
        match sim.step() {
            Ok(stats) => {
                if stats.contact_solve_fallback && !fallback_logged {
                    fallback_logged = true;
                    warn!(
                        "step {}: its {} collider contacts do not fit the contact solve's memory \
                         budget ({} MiB for the columns of the step matrix's inverse it caches); \
                         such steps take one Uzawa step per contact and iteration instead, which \
                         converges more slowly (docs/design/contact.md, \"Friction with an \
                         accuracy target\")",
                        sim.steps(),
                        stats.contacts,
                        pd_solver::contact::DEFAULT_DELASSUS_MEMORY >> 20
                    );
                }
                if let Err(e) = recorder.record(sim, &stats) {
                    failure = Some(Failure::Output(e.to_string()));
                    break;
                }
                if checkpoint_every > 0
                    && sim.steps().is_multiple_of(checkpoint_every)
                    && let Err(e) = checkpoint(sim)
                {
                    failure = Some(e);
                    break;
                }
            }
            Err(e @ SolverError::Diverged { .. }) => {
                failure = Some(Failure::Diverged(e.to_string()));
                break;
            }
            Err(e) => {
                failure = Some(Failure::Input(e.to_string()));
                break;
            }
        }
        progress.inc(1);
    }
    progress.finish_and_clear();

    let outcome = match &failure {
        None => Outcome::Completed,
        Some(Failure::Interrupted(m)) => Outcome::Interrupted(m.clone()),
        Some(f) => Outcome::Failed(f.message().to_string()),
    };
    let median_step_ms = recorder.median_step_ms();
    let frames = recorder.frames();
    let dir = recorder.dir().to_path_buf();
    // Logged once, after the run; `summary.json` carries the same text.
    let warnings = recorder.warnings(sim);
    let summary = recorder
        .finish(scene, sim, &outcome)
        .map_err(|e| Failure::Output(e.to_string()))?;
    // No step timed (none ran, or the first failed): no median to show.
    let median = if median_step_ms.is_nan() {
        "no step timed".to_string()
    } else {
        format!("median step {median_step_ms:.2} ms")
    };
    info!(
        "{} of {} steps ({:.3} s simulated), {median}; {} frames, metrics and {} in {}",
        sim.steps(),
        scene.steps,
        sim.time(),
        frames,
        summary
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        dir.display()
    );
    for warning in &warnings {
        warn!("{warning}");
    }
    failure.map_or(Ok(()), Err)
}
