//! `cargo xtask damping-table`: runs every damping model with every
//! integrator on the bundled scenes and writes `docs/damping-table.md`.
//!
//! Measured per (integrator, model):
//! - on `scenes/spinning_body.toml` (a free block flying and spinning):
//!   the fraction of linear momentum and of spin (angular momentum about the
//!   centre of mass) left after 200 steps, and the total energy change;
//! - on `scenes/cantilever_release.toml` (a cantilever released from its
//!   sagged shape, no gravity): the decay time of the first bending mode,
//!   the first time at which the mechanical energy has fallen to `e^-2` of
//!   its start (for one mode, energy decays as `e^{-2t/tau}`);
//! - on the same scene, the fastest of 40 timings of one step taken from the
//!   same state (the released shape), and its ratio to `none` with the
//!   same integrator. Timing steps along each model's own trajectory would
//!   mix in the state-dependence of the projections (a less deformed beam
//!   projects faster), which is not the model's cost.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use pd_damping::rigid::RigidFit;
use pd_io::scene::{DampingSpec, IntegratorKind, Scene};

/// The models of the table, with the coefficients it uses.
fn models() -> Vec<(&'static str, DampingSpec)> {
    vec![
        ("none", DampingSpec::None),
        (
            "ether-drag, rate 1/s",
            DampingSpec::EtherRate {
                rate: 1.0,
                implicit: false,
            },
        ),
        (
            "ether-drag, implicit 1/s",
            DampingSpec::EtherRate {
                rate: 1.0,
                implicit: true,
            },
        ),
        ("pbd, factor 0.05", DampingSpec::Pbd { factor: 0.05 }),
        (
            "rayleigh-lagged, 0.003 s",
            DampingSpec::RayleighLagged {
                mass: 0.0,
                stiffness: 0.003,
            },
        ),
        (
            "laplacian, 0.003 s",
            DampingSpec::Laplacian {
                stiffness: 0.003,
                mass: 0.0,
                preserve_rotation: false,
            },
        ),
        (
            "laplacian, 0.003 s, preserve_rotation",
            DampingSpec::Laplacian {
                stiffness: 0.003,
                mass: 0.0,
                preserve_rotation: true,
            },
        ),
    ]
}

struct Row {
    momentum_kept: f64,
    spin_kept: f64,
    energy_change: f64,
    decay_time: Option<f64>,
    fastest_step_ms: f64,
}

fn spin_and_momentum(sim: &pd_solver::Simulation) -> (f64, f64) {
    let s = sim.state();
    let all: Vec<usize> = (0..s.positions.len()).collect();
    let fit = RigidFit::of(&all, sim.model().masses(), &s.positions, &s.velocities);
    (fit.angular_momentum.norm(), sim.linear_momentum().norm())
}

fn measure(
    root: &Path,
    integrator: IntegratorKind,
    damping: &DampingSpec,
    quick: bool,
) -> Result<Row, String> {
    let load = |name: &str| -> Result<Scene, String> {
        let mut scene = Scene::load(&root.join("scenes").join(name)).map_err(|e| e.to_string())?;
        scene.integrator = integrator;
        scene.damping = damping.clone();
        Ok(scene)
    };
    let spinning = load("spinning_body.toml")?;
    let mut sim = spinning.build().map_err(|e| e.to_string())?;
    let (spin0, p0) = spin_and_momentum(&sim);
    let e0 = sim.energies().total();
    sim.run(if quick { 50 } else { spinning.steps })
        .map_err(|e| e.to_string())?;
    let (spin1, p1) = spin_and_momentum(&sim);
    let e1 = sim.energies().total();

    let release = load("cantilever_release.toml")?;
    let start = release.build().map_err(|e| e.to_string())?.energies();
    let target = (start.kinetic + start.elastic) * (-2.0f64).exp();
    // Time on one thread: on this 2-core machine the rayon pool's wake-ups
    // scattered identical steps by +-20%, more than the effects measured.
    let mut timed = release.clone();
    timed.settings.threads = 1;
    let mut sim = timed.build().map_err(|e| e.to_string())?;
    let initial = sim.state().clone();
    let mut times = Vec::new();
    for _ in 0..40 {
        sim.set_state(initial.clone()).map_err(|e| e.to_string())?;
        let t0 = Instant::now();
        sim.step().map_err(|e| e.to_string())?;
        times.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    let mut sim = release.build().map_err(|e| e.to_string())?;
    let mut decay_time = None;
    for _ in 0..(if quick { 100 } else { release.steps }) {
        sim.step().map_err(|e| e.to_string())?;
        if decay_time.is_none() {
            let e = sim.energies();
            if e.kinetic + e.elastic <= target {
                decay_time = Some(sim.time());
            }
        }
    }
    // The minimum: the cost of the step without interference from the rest
    // of the machine (the median scattered by +-20% between identical runs).
    let fastest = times.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(Row {
        momentum_kept: p1 / p0,
        spin_kept: spin1 / spin0,
        energy_change: (e1 - e0) / e0,
        decay_time,
        fastest_step_ms: fastest,
    })
}

/// Runs the table and writes it; returns the path written.
pub fn run(root: &Path, quick: bool) -> Result<std::path::PathBuf, String> {
    let mut out = String::new();
    writeln!(
        out,
        "# Damping models, measured\n\n\
         Generated by `cargo xtask damping-table{}` (dev profile: dependencies at\n\
         opt-level 3, workspace crates at 2; timings on 1 thread) on\n\
         this machine. Do not edit by hand. What the columns mean is in\n\
         `xtask/src/damping_table.rs` and `docs/damping.md`.\n\n\
         - *p kept*, *spin kept*: linear momentum and angular momentum about the\n  \
         centre of mass left after the `spinning_body` run (1 = kept);\n\
         - *energy change*: total energy change over that run;\n\
         - *decay time*: first time the `cantilever_release` beam's mechanical\n  \
         energy falls to e^-2 of its start (the first mode's decay time tau);\n\
         - *step ms*, *ratio*: fastest of 40 timings of one step of `cantilever_release`\n  \
         (525 vertices, 1920 tets, 10 iterations) taken from the same\n  \
         state (so BDF-2 takes its backward Euler start-up step), and its ratio\n  \
         to `none` with the same integrator, measured in the same run.\n",
        if quick { " --quick" } else { "" }
    )
    .expect("writing to a String cannot fail");
    for integrator in IntegratorKind::ALL {
        writeln!(out, "\n## {}\n", integrator.name()).expect("infallible");
        writeln!(
            out,
            "| model | p kept | spin kept | energy change | decay time [s] | step ms | ratio |"
        )
        .expect("infallible");
        writeln!(out, "|---|---|---|---|---|---|---|").expect("infallible");
        let mut baseline = None;
        for (label, spec) in models() {
            eprintln!("{} + {label}", integrator.name());
            let row = measure(root, integrator, &spec, quick)?;
            let base = *baseline.get_or_insert(row.fastest_step_ms);
            writeln!(
                out,
                "| {label} | {:.4} | {:.4} | {:+.2}% | {} | {:.2} | {:.3} |",
                row.momentum_kept,
                row.spin_kept,
                100.0 * row.energy_change,
                row.decay_time
                    .map_or_else(|| "> run".to_string(), |t| format!("{t:.2}")),
                row.fastest_step_ms,
                row.fastest_step_ms / base
            )
            .expect("infallible");
        }
    }
    let path = root.join("docs/damping-table.md");
    std::fs::write(&path, out).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}
