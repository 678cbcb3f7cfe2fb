//! The `pd` command-line tool: runs Projective Dynamics scenes and turns
//! their results into pictures.
//!
//! - `pd run [SCENE] [--out DIR] [--checkpoint-every K]` runs a scene file
//!   (TOML or JSON) and writes metrics, probes, frames and a summary;
//!   without a scene it runs the bundled cantilever;
//! - `pd resume DIR` continues a run from its last checkpoint;
//! - `pd render DIR` draws a run's surface frames as PNG images and a GIF;
//! - `pd view DIR... [-o FILE]` writes one self-contained HTML page that
//!   shows the runs side by side (WebGL2: turn, zoom, play, scrub);
//! - `pd plot DIR` plots energies and momenta against time (PNG and SVG);
//! - `pd modes SCENE [--count K] [--out DIR]` writes the scene's lowest
//!   elastic modes (frequencies, damping ratios, animated shapes);
//! - `pd compare SCENE --damping a,b,...` (or `--integrator a,b,...`,
//!   `--ratio z1,z2,...`, `--accuracy e1,e2,...`) runs a scene once per
//!   variant and compares them;
//! - `pd fit SCENE --target PROBES.csv --fit PATH,... [--out DIR]` fits
//!   scene values (damping, stiffness, density) to a recorded motion.
//!
//! Logs go to stderr through `tracing`, filtered by `RUST_LOG` (default
//! `info`); `--quiet` prints nothing but errors. Exit codes: 0 success,
//! 2 bad input (scene, mesh, state, checkpoint or frame file, options),
//! 3 divergence, 4 output failure.

mod compare;
mod fit;
mod modes;
mod pictures;
mod run;
mod scenery;
mod view;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use tracing_subscriber::EnvFilter;

#[derive(Parser)]
#[command(
    name = "pd",
    version,
    about = "Projective Dynamics with Laplacian damping"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Print nothing but errors (overrides RUST_LOG).
    #[arg(long, short, global = true)]
    quiet: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write its results.
    Run {
        #[command(flatten)]
        scene: run::SceneOptions,
        /// Write `checkpoint.json` into the output folder every K steps
        /// (0: never), for `pd resume`.
        #[arg(long, value_name = "K", default_value_t = 0)]
        checkpoint_every: usize,
        /// At the end, write `view.html` (as `pd view`) into the output
        /// folder.
        #[arg(long)]
        view: bool,
    },
    /// Continue a run from the checkpoint in its output folder, to the end
    /// of its scene; the results are identical bit for bit to an
    /// uninterrupted run.
    Resume {
        /// The run's output folder (holding `checkpoint.json`).
        dir: PathBuf,
    },
    /// Draw a run's surface frames (`DIR/frames/*.obj`) as PNG images and an
    /// animated GIF in `DIR/render/`.
    Render {
        /// The run's output folder.
        dir: PathBuf,
        /// More runs drawn side by side with the first, with the same camera.
        #[arg(long, value_name = "DIR")]
        panel: Vec<PathBuf>,
        /// Where to write [default: DIR/render].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Width of one panel, pixels.
        #[arg(long, default_value_t = 480)]
        width: u32,
        /// Height of a panel, pixels.
        #[arg(long, default_value_t = 360)]
        height: u32,
        /// Most frames in the GIF (frames are skipped evenly beyond it).
        #[arg(long, default_value_t = 40)]
        gif_frames: usize,
        /// The GIF is the images shrunk by this factor.
        #[arg(long, default_value_t = 2)]
        gif_downscale: u32,
    },
    /// Write one self-contained HTML page (WebGL2, works offline) showing
    /// one or more runs' OBJ frames side by side with one camera and one
    /// clock, their colliders, and their energy and probe curves.
    View {
        /// Output folders of `pd run` (several: side by side).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// The page to write [default: DIR/view.html of the first run].
        #[arg(long, short)]
        out: Option<PathBuf>,
        /// Keep every K-th frame (and the last).
        #[arg(long, value_name = "K", default_value_t = 1)]
        every: usize,
        /// Refuse a page above this size, MB (use --every to thin frames).
        #[arg(long, value_name = "MB", default_value_t = VIEW_MAX_MB)]
        max_mb: f64,
    },
    /// Plot a run's energies and momenta against time (`DIR/metrics.csv`)
    /// as PNG and SVG in `DIR/plots/`.
    Plot {
        /// The run's output folder.
        dir: PathBuf,
    },
    /// Write the scene's lowest elastic modes: `modes.json` (frequencies in
    /// Hz, the damping ratio each mode gets under the scene's damping and
    /// integrator) and each mode shape animated (`mode_NN.pvd`, OBJ frames).
    Modes {
        #[command(flatten)]
        scene: run::SceneOptions,
        /// How many modes (the lowest elastic ones).
        #[arg(long, value_name = "K", default_value_t = 6)]
        count: usize,
    },
    /// Run a scene once per damping model, integrator, damping ratio or
    /// accuracy target (one of these at a time) and compare them: a
    /// side-by-side animation, a plot of total energy, and a table.
    Compare {
        #[command(flatten)]
        scene: run::SceneOptions,
        #[arg(
            long,
            value_delimiter = ',',
            conflicts_with = "integrator",
            help = compare::damping_help()
        )]
        damping: Vec<String>,
        #[arg(long, value_delimiter = ',', help = compare::integrator_help())]
        integrator: Vec<String>,
        /// Damping ratios of the lowest elastic mode, comma separated
        /// (0.01,0.05,0.2): the scene's model if it takes a ratio
        /// (laplacian, rayleigh-lagged), else Laplacian damping, for every
        /// body.
        #[arg(long, value_delimiter = ',', conflicts_with_all = ["damping", "integrator"])]
        ratio: Vec<f64>,
        #[arg(
            long,
            value_delimiter = ',',
            value_name = "E",
            allow_negative_numbers = true,
            value_parser = compare::accuracy_of,
            conflicts_with_all = ["damping", "integrator", "ratio"],
            help = compare::accuracy_help()
        )]
        accuracy: Vec<f64>,
    },
    /// Fit scene values (damping coefficients or ratios, stiffness,
    /// density) to a recorded motion: writes `fit.json` (fitted values,
    /// loss, gradient, timings) and the fitted scene `fitted.toml`.
    Fit {
        /// Scene file (.toml or .json), holding the starting values.
        scene: PathBuf,
        /// The motion to match: a `probes.csv` as `pd run` writes it, with
        /// the scene's probes, steps and time step.
        #[arg(long, value_name = "PROBES.csv")]
        target: PathBuf,
        /// Scene values to fit, comma separated, spelled as the scene
        /// loader's messages spell them: damping.stiffness, damping.mass,
        /// damping.ratio, damping.ratios[k], body[i].density,
        /// body[i].vertex_mass, body[i].constraints[j].stiffness,
        /// body[i].constraints[j].young, body[i].damping.KEY.
        #[arg(long, value_delimiter = ',', required = true, value_name = "PATHS")]
        fit: Vec<String>,
        #[arg(long, help = "Output folder [default: out/fit-<scene name>]")]
        out: Option<PathBuf>,
        /// Most L-BFGS iterations (0: only the loss and gradient at the
        /// scene's values).
        #[arg(long, value_name = "N", default_value_t = 50)]
        max_iterations: usize,
        /// Stop once an iteration lowers the loss by at most this fraction
        /// of it, or the gradient in log parameters (d loss / d ln p) is
        /// at most this times the loss.
        #[arg(long, default_value_t = 1e-6)]
        tolerance: f64,
    },
}

/// How a command can fail, each with its exit code.
#[derive(Debug)]
pub(crate) enum Failure {
    Input(String),
    Diverged(String),
    Output(String),
    /// Ctrl-C: the run stopped after a whole step.
    Interrupted(String),
}

impl Failure {
    fn code(&self) -> u8 {
        match self {
            Failure::Input(_) => 2,
            Failure::Diverged(_) => 3,
            Failure::Output(_) => 4,
            // 128 + SIGINT, as shells report a process a Ctrl-C ended.
            Failure::Interrupted(_) => 130,
        }
    }

    pub(crate) fn message(&self) -> &str {
        match self {
            Failure::Input(m)
            | Failure::Diverged(m)
            | Failure::Output(m)
            | Failure::Interrupted(m) => m,
        }
    }
}

/// `pd run --view`'s page size limit, MB (as `pd view`'s default).
const VIEW_MAX_MB: f64 = 50.0;

fn init_logging(quiet: bool) {
    let filter = if quiet {
        EnvFilter::new("error")
    } else {
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"))
    };
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .without_time()
        .init();
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.quiet);
    let quiet = cli.quiet;
    let result = match cli.command {
        Command::Run {
            scene,
            checkpoint_every,
            view,
        } => run::run(&scene, checkpoint_every, quiet).and_then(|out| {
            if view {
                let options = view::ViewOptions {
                    every: 1,
                    max_mb: VIEW_MAX_MB,
                };
                view::view(std::slice::from_ref(&out), &out.join("view.html"), &options)
            } else {
                Ok(())
            }
        }),
        Command::View {
            dirs,
            out,
            every,
            max_mb,
        } => {
            let out = out.unwrap_or_else(|| dirs[0].join("view.html"));
            view::view(&dirs, &out, &view::ViewOptions { every, max_mb })
        }
        Command::Resume { dir } => run::resume(&dir, quiet),
        Command::Render {
            dir,
            panel,
            out,
            width,
            height,
            gif_frames,
            gif_downscale,
        } => {
            let mut dirs = vec![dir];
            dirs.extend(panel);
            let out = out.unwrap_or_else(|| dirs[0].join("render"));
            let panels: Vec<(String, PathBuf)> = dirs
                .into_iter()
                .map(|d| (pictures::label_of(&d), d))
                .collect();
            pictures::render(
                &panels,
                &out,
                &pictures::RenderOptions {
                    width,
                    height,
                    gif_frames,
                    gif_downscale,
                },
            )
        }
        Command::Plot { dir } => pictures::plot(&dir),
        Command::Modes { scene, count } => modes::modes(&scene, count),
        Command::Compare {
            scene,
            damping,
            integrator,
            ratio,
            accuracy,
        } => compare::compare(
            &scene,
            &compare::Variants {
                damping,
                integrator,
                ratio,
                accuracy,
            },
            quiet,
        ),
        Command::Fit {
            scene,
            target,
            fit,
            out,
            max_iterations,
            tolerance,
        } => fit::fit(&fit::FitOptions {
            scene,
            target,
            fit,
            out,
            max_iterations,
            tolerance,
        })
        .map(|_| ()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            // Printed directly (not through tracing) so that --quiet and
            // RUST_LOG never hide it.
            eprintln!("error: {}", failure.message());
            ExitCode::from(failure.code())
        }
    }
}
