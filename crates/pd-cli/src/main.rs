//! The `pd` command-line tool: runs Projective Dynamics scenes.
//!
//! `pd run [SCENE] [--out DIR]` runs a scene file (TOML or JSON) and writes
//! metrics, probes, frames and a summary; without a scene it runs the
//! bundled cantilever. Exit codes: 0 success, 2 bad input (scene, mesh,
//! state file), 3 divergence, 4 output failure.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use pd_io::recorder::{Outcome, Recorder};
use pd_io::scene::{Scene, Syntax};
use pd_solver::SolverError;

/// The bundled default scene (also at `scenes/cantilever.toml`).
const DEFAULT_SCENE: &str = include_str!("../../../scenes/cantilever.toml");
const DEFAULT_SCENE_NAME: &str = "cantilever (built in: scenes/cantilever.toml)";

#[derive(Parser)]
#[command(
    name = "pd",
    version,
    about = "Projective Dynamics with Laplacian damping"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write its results.
    Run {
        /// Scene file (.toml or .json). Without one, runs the bundled
        /// cantilever beam.
        scene: Option<PathBuf>,
        /// Output folder [default: out/<scene name>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override the scene's number of steps.
        #[arg(long)]
        steps: Option<usize>,
        /// Threads for the local step (0: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
    },
}

/// How a run can fail, each with its exit code.
enum Failure {
    Input(String),
    Diverged(String),
    Output(String),
}

impl Failure {
    fn code(&self) -> u8 {
        match self {
            Failure::Input(_) => 2,
            Failure::Diverged(_) => 3,
            Failure::Output(_) => 4,
        }
    }

    fn message(&self) -> &str {
        match self {
            Failure::Input(m) | Failure::Diverged(m) | Failure::Output(m) => m,
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run {
            scene,
            out,
            steps,
            threads,
            quiet,
        } => run(scene.as_deref(), out, steps, threads, quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            eprintln!("error: {}", failure.message());
            ExitCode::from(failure.code())
        }
    }
}

fn run(
    scene_path: Option<&Path>,
    out: Option<PathBuf>,
    steps: Option<usize>,
    threads: Option<usize>,
    quiet: bool,
) -> Result<(), Failure> {
    let (mut scene, name) = match scene_path {
        Some(path) => (
            Scene::load(path).map_err(|e| Failure::Input(e.to_string()))?,
            path.file_stem()
                .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned()),
        ),
        None => (
            Scene::parse(DEFAULT_SCENE, Syntax::Toml, Path::new(DEFAULT_SCENE_NAME))
                .map_err(|e| Failure::Input(format!("the bundled scene is invalid: {e}")))?,
            "cantilever".to_string(),
        ),
    };
    if let Some(steps) = steps {
        scene.steps = steps;
    }
    if let Some(threads) = threads {
        scene.settings.threads = threads;
    }
    let out = out.unwrap_or_else(|| Path::new("out").join(&name));

    let build_start = Instant::now();
    let mut sim = scene.build().map_err(|e| Failure::Input(e.to_string()))?;
    let build_seconds = build_start.elapsed().as_secs_f64();
    let mut recorder =
        Recorder::create(&out, &scene, &sim).map_err(|e| Failure::Output(e.to_string()))?;
    if !quiet {
        eprintln!(
            "{}: {} vertices ({} free), {} constraints, {} + {} damping; set up in {:.0} ms",
            scene.source.display(),
            sim.model().num_vertices(),
            sim.num_free_vertices(),
            sim.model().num_constraints(),
            sim.integrator_name(),
            sim.damping_name(),
            build_seconds * 1e3
        );
    }

    let progress = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(scene.steps as u64).with_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} steps, {elapsed} elapsed, eta {eta}",
            )
            .expect("the template is valid"),
        )
    };
    let mut failure = None;
    for _ in 0..scene.steps {
        match sim.step() {
            Ok(stats) => {
                if let Err(e) = recorder.record(&sim, &stats) {
                    failure = Some(Failure::Output(e.to_string()));
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
        Some(f) => Outcome::Failed(f.message().to_string()),
    };
    let median_ms = recorder.median_step_ms();
    let frames = recorder.frames();
    let dir = recorder.dir().to_path_buf();
    let summary = recorder
        .finish(&scene, &sim, &outcome)
        .map_err(|e| Failure::Output(e.to_string()))?;
    if !quiet {
        eprintln!(
            "{} of {} steps ({:.3} s simulated), median step {:.2} ms; {} frames, metrics and {} in {}",
            sim.steps(),
            scene.steps,
            sim.time(),
            median_ms,
            frames,
            summary
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            dir.display()
        );
    }
    failure.map_or(Ok(()), Err)
}
