//! `cargo run --release -p pd-benches --example krylov_bound -- [--integrator
//! be|im|bdf2] [--damping D] [--cells NX,NY,NZ] [--probe-steps 1,5,10,20]
//! [--trajectory METHOD:BUDGET] [--plain K] [--cg K] [--budgets 1,2,...]
//! [--reference-tolerance T] [--timing R] [--lagged]`, or with `--oracle
//! K,nK+K,... [--steps N] [--run-reference-tolerance T]`: the Krylov bound
//! of a step's iterations with the prefactored PD matrix as preconditioner
//! (docs/design/solver.md, "The Krylov bound").
//!
//! Per step (without `--oracle`): the benchmark beam (one thread) runs
//! with `METHOD` at `BUDGET` iterations and the linear predictor (default
//! `anderson:8`, the bench report's pick for implicit midpoint). Before
//! each probed step its state (with the predictor's corrections) is saved,
//! and from it:
//!
//! - Newton to a relative residual of `T` (1e-11) gives the step's
//!   converged solution `x*`;
//! - [`pd_solver::KrylovProbe`], with the linear predictor, starts where
//!   the trajectory's method starts (`x0`) and measures `|x - x*|_M` for
//!   `K` plain local-global iterations, the plain map on the quadratic model
//!   at `x*`, and preconditioned CG (up to `K` iterations) on four
//!   linearisations, with the Ritz values of `A^{-1} H`; with `--timing R`
//!   also the costs of the operations (fastest of `R`), with `--lagged` CG
//!   preconditioned with the PSD Hessian factorised at the first probed
//!   step;
//! - Anderson with the linear predictor at each budget of `--budgets`: its
//!   error after the step, and its iterations and objective evaluations.
//!
//! Printed per step: the errors relative to the start's, plain PD-20's
//! error, the first CG iteration at or below it, Anderson's least budget at
//! or below it, rates per iteration, and the extreme Ritz values.
//!
//! Whole runs (`--oracle`): the final positions after `N` (20) steps
//! against Newton's run at `T` (1e-10) from `y`, as `pd-probe methods`
//! measures them, for plain PD-20 from `y`, Anderson with the linear
//! predictor at each budget, and the probe as a method: `K` is the oracle
//! (each step `K` CG iterations on the model at its own `x*`), `nK+K+...`
//! a truncated Newton bound (the true Hessian at the start, free, and one
//! outer iteration per count: a new gradient and that many CG iterations).

use std::sync::{Arc, Mutex};

use pd_benches::{Beam, Options};
use pd_mesh::Point;
use pd_solver::{
    Checkpoint, KrylovProbe, KrylovRecord, Predictor, Settings, Simulation, SolverMethod,
    SolverSpec,
};

struct Setup<'a> {
    beam: &'a Beam,
    mesh: &'a pd_mesh::Mesh,
    integrator: &'a str,
    damping: &'a str,
}

impl Setup<'_> {
    fn simulation(
        &self,
        method: SolverMethod,
        predictor: Predictor,
        settings: Settings,
    ) -> Result<Simulation, String> {
        let mut sim = Simulation::new(
            self.beam.model_on(self.mesh.clone())?,
            pd_benches::integrator(self.integrator)?,
            pd_benches::damping(self.damping)?,
            settings,
        )
        .map_err(|e| e.to_string())?;
        let spec = SolverSpec {
            method,
            ..SolverSpec::default()
        };
        sim.set_position_solver(spec.create().map_err(|e| e.to_string())?);
        sim.set_predictor(predictor);
        Ok(sim)
    }
}

fn mass_distance(masses: &[f64], a: &[Point], b: &[Point]) -> f64 {
    masses
        .iter()
        .zip(a.iter().zip(b))
        .map(|(m, (a, b))| m * (a - b).norm_squared())
        .sum::<f64>()
        .sqrt()
}

/// The first index (1-based iteration count) whose error is at most `bar`.
fn first_below(errors: &[f64], bar: f64) -> Option<usize> {
    errors.iter().position(|&e| e <= bar).map(|k| k + 1)
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = Options::new(&args);
    let integrator = options.value("--integrator").unwrap_or("im");
    let damping = options.value("--damping").unwrap_or("none");
    let probe_steps = options.list("--probe-steps", &[1, 5, 10, 20])?;
    let plain: usize = options.parse("--plain", 30)?;
    let cg_iterations: usize = options.parse("--cg", 40)?;
    let budgets = options.list("--budgets", &[1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 15, 20])?;
    let tolerance: f64 = options.parse("--reference-tolerance", 1e-11)?;
    let (method, budget) = options
        .value("--trajectory")
        .unwrap_or("anderson:8")
        .split_once(':')
        .ok_or("--trajectory METHOD:BUDGET")?;
    let method = SolverMethod::parse(method).ok_or(format!("unknown method {method:?}"))?;
    let budget: usize = budget.parse().map_err(|_| format!("budget {budget:?}"))?;
    let mut beam = Beam {
        threads: 1,
        ..Beam::default()
    };
    if options.value("--cells").is_some() {
        let cells = options.list("--cells", &[])?;
        beam.cells = cells.try_into().map_err(|_| "--cells needs three counts")?;
    }
    let mesh = beam.mesh()?;
    let setup = Setup {
        beam: &beam,
        mesh: &mesh,
        integrator,
        damping,
    };
    let with = |iterations: usize, tolerance: f64| Settings {
        iterations,
        tolerance,
        ..beam.settings()
    };
    let linear = Predictor::Linear;
    let mut trajectory = setup.simulation(method, linear, with(budget, 0.0))?;
    let mut reference = setup.simulation(
        SolverMethod::Newton,
        Predictor::Inertial,
        with(100, tolerance),
    )?;
    let record = Arc::new(Mutex::new(KrylovRecord {
        plain_iterations: plain,
        cg_iterations,
        timing_repetitions: options.parse("--timing", 0)?,
        lagged_preconditioner: options.flag("--lagged"),
        ..KrylovRecord::default()
    }));
    let mut probe = setup.simulation(SolverMethod::LocalGlobal, linear, with(1, 0.0))?;
    probe.set_position_solver(Box::new(KrylovProbe::new(Arc::clone(&record))));
    let mut anderson: Vec<(usize, Simulation)> = budgets
        .iter()
        .map(|&b| {
            Ok((
                b,
                setup.simulation(SolverMethod::Anderson, linear, with(b, 0.0))?,
            ))
        })
        .collect::<Result<_, String>>()?;
    let masses = trajectory.model().masses().to_vec();
    if options.value("--oracle").is_some() {
        let oracle: Vec<(bool, Vec<usize>)> = options
            .value("--oracle")
            .unwrap_or("")
            .split(',')
            .map(|item| {
                let (newton, counts) = match item.strip_prefix('n') {
                    Some(rest) => (true, rest),
                    None => (false, item),
                };
                let counts = counts
                    .split('+')
                    .map(|k| k.parse().map_err(|_| format!("--oracle: {item:?}")))
                    .collect::<Result<Vec<usize>, String>>()?;
                Ok((newton, counts))
            })
            .collect::<Result<_, String>>()?;
        let steps: usize = options.parse("--steps", 20)?;
        let run_tolerance: f64 = options.parse("--run-reference-tolerance", 1e-10)?;
        return oracle_runs(&setup, &oracle, &budgets, steps, (tolerance, run_tolerance));
    }
    println!(
        "# {} vertices, integrator {integrator}, damping {damping}, trajectory {}:{budget} + linear",
        mesh.num_vertices(),
        method.name()
    );
    let last = probe_steps.iter().copied().max().unwrap_or(0);
    for step in 1..=last {
        if probe_steps.contains(&step) {
            let saved: Checkpoint = trajectory.checkpoint();
            let x_n = saved.state.positions.clone();
            reference.restore(&saved).map_err(|e| e.to_string())?;
            let stats = reference.step().map_err(|e| e.to_string())?;
            let x_star = reference.state().positions.clone();
            record.lock().map_err(|e| e.to_string())?.reference =
                x_star.iter().zip(&x_n).map(|(a, b)| a - b).collect();
            probe.restore(&saved).map_err(|e| e.to_string())?;
            probe.step().map_err(|e| e.to_string())?;
            let r = record.lock().map_err(|e| e.to_string())?.clone();
            let e0 = r.start_error;
            let pd20 = r.plain_errors[19.min(r.plain_errors.len() - 1)];
            println!(
                "\nstep {step}: Newton {} iterations (converged {}, residual {:.1e}); \
                 predicted start {}; |x0 - x*|_M = {e0:.3e}, |dx*|_M = {:.3e}",
                stats.iterations,
                stats.converged,
                stats.relative_change,
                r.predicted,
                mass_distance(&masses, &x_star, &x_n),
            );
            let rel = |e: &[f64]| {
                e.iter()
                    .map(|e| format!("{:.2e}", e / e0))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            if !r.costs.is_empty() {
                let iteration = r.costs[0].1;
                println!(
                    "  costs (fastest of {}; ms, and over a plain iteration): {}",
                    r.timing_repetitions,
                    r.costs
                        .iter()
                        .map(|(name, t)| format!("{name} {:.3} ({:.3})", t * 1e3, t / iteration))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
            println!(
                "  plain PD, error / e0 by iteration: {}",
                rel(&r.plain_errors)
            );
            println!(
                "  plain map on the model at x*:      {}",
                rel(&r.model_plain_errors)
            );
            let rate = |e: &[f64], from: usize, to: usize| {
                (e[to - 1] / e[from - 1]).powf(1.0 / (to - from) as f64)
            };
            println!(
                "  plain PD-20: {:.3e} ({:.2e} of e0); rate per iteration 1-10 {:.3}, 10-20 {:.3}",
                pd20,
                pd20 / e0,
                (r.plain_errors[9] / e0).powf(0.1),
                rate(&r.plain_errors, 10, 20)
            );
            for run in &r.runs {
                let reach = first_below(&run.errors, pd20);
                let n = run.errors.len();
                let cg_rate = if n >= 6 {
                    rate(&run.errors, 1, 6)
                } else {
                    f64::NAN
                };
                println!(
                    "  CG {}: reaches PD-20 at {} (of {n}{}), rate 1-6 {:.3}, errors / e0 {}",
                    run.name,
                    reach.map_or("-".into(), |k| k.to_string()),
                    if run.indefinite { ", indefinite" } else { "" },
                    cg_rate,
                    rel(&run.errors[..n.min(15)])
                );
                if run.name == "true@x*" {
                    let small: Vec<String> =
                        run.ritz.iter().take(8).map(|v| format!("{v:.3}")).collect();
                    println!(
                        "    smallest Ritz values: {}; below 0.5: {}, below 0.7: {}, of {}",
                        small.join(" "),
                        run.ritz.iter().filter(|&&v| v < 0.5).count(),
                        run.ritz.iter().filter(|&&v| v < 0.7).count(),
                        run.ritz.len()
                    );
                }
                if let Some(exact) = run.exact_error {
                    println!(
                        "    direct solve of the linearised system: {:.2e} of e0",
                        exact / e0
                    );
                }
                let extremes = |k: usize| {
                    run.extreme_ritz
                        .get(k - 1)
                        .map_or("-".into(), |(a, b)| format!("[{a:.4}, {b:.4}]"))
                };
                println!(
                    "    Ritz extremes of A^-1 H after 3, 5, 10, all: {} {} {} [{:.4}, {:.4}]",
                    extremes(3),
                    extremes(5),
                    extremes(10),
                    run.ritz.first().copied().unwrap_or(f64::NAN),
                    run.ritz.last().copied().unwrap_or(f64::NAN)
                );
            }
            let mut and_errors = Vec::new();
            for (b, sim) in &mut anderson {
                sim.restore(&saved).map_err(|e| e.to_string())?;
                let stats = sim.step().map_err(|e| e.to_string())?;
                let e = mass_distance(&masses, &sim.state().positions, &x_star);
                and_errors.push((*b, e, stats.iterations, stats.objective_evaluations));
            }
            println!(
                "  anderson + linear (budget: error / e0, iterations + evaluations): {}",
                and_errors
                    .iter()
                    .map(|(b, e, i, v)| format!("{b}: {:.2e} ({i}+{v})", e / e0))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            let reach = and_errors.iter().find(|(_, e, _, _)| *e <= pd20);
            println!(
                "  anderson reaches PD-20 at budget {}",
                reach.map_or("-".into(), |(b, ..)| b.to_string())
            );
        }
        trajectory.step().map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// The largest vertex distance between two position sets over the body's
/// diagonal (the error of `pd-probe methods`).
fn run_error(mesh: &pd_mesh::Mesh, a: &[Point], b: &[Point]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in mesh.vertices() {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max)
        / diagonal
}

/// `--oracle K,nK+K,...`: whole runs, measured as `pd-probe methods`
/// measures them (the final positions against Newton's run at a relative
/// residual of `tolerances.1`, from `y`): plain PD-20 from `y`, Anderson
/// with the linear predictor at each budget, and for each entry the probe
/// as a method from the linear predictor's start: `(false, [K])` the oracle
/// (`K` CG iterations on the quadratic model at the step's own converged
/// solution, from Newton at `tolerances.0`), `(true, counts)` the
/// truncated Newton bound.
fn oracle_runs(
    setup: &Setup<'_>,
    oracle: &[(bool, Vec<usize>)],
    budgets: &[usize],
    steps: usize,
    (tolerance, run_tolerance): (f64, f64),
) -> Result<(), String> {
    let with = |iterations: usize, tolerance: f64| Settings {
        iterations,
        tolerance,
        ..setup.beam.settings()
    };
    let mut reference = setup.simulation(
        SolverMethod::Newton,
        Predictor::Inertial,
        with(100, run_tolerance),
    )?;
    reference.run(steps).map_err(|e| e.to_string())?;
    let truth = reference.state().positions.clone();
    let error = |sim: &Simulation| run_error(setup.mesh, &sim.state().positions, &truth);
    println!(
        "# {} vertices, integrator {}, damping {}, {steps} steps: error of the final positions",
        setup.mesh.num_vertices(),
        setup.integrator,
        setup.damping
    );
    let mut plain = setup.simulation(
        SolverMethod::LocalGlobal,
        Predictor::Inertial,
        with(20, 0.0),
    )?;
    plain.run(steps).map_err(|e| e.to_string())?;
    println!("plain PD-20 from y: {:.3e}", error(&plain));
    for &b in budgets {
        let mut sim = setup.simulation(SolverMethod::Anderson, Predictor::Linear, with(b, 0.0))?;
        let stats = sim.run(steps).map_err(|e| e.to_string())?;
        let per_step = |f: &dyn Fn(&pd_solver::StepStats) -> usize| {
            stats.iter().map(f).sum::<usize>() as f64 / stats.len() as f64
        };
        println!(
            "anderson + linear, {b}: {:.3e} ({:.2} iterations, {:.2} evaluations a step)",
            error(&sim),
            per_step(&|s| s.iterations),
            per_step(&|s| s.objective_evaluations)
        );
    }
    let mut step_reference = setup.simulation(
        SolverMethod::Newton,
        Predictor::Inertial,
        with(100, tolerance),
    )?;
    for (is_newton, schedule) in oracle {
        let newton = if *is_newton {
            schedule.clone()
        } else {
            Vec::new()
        };
        let record = Arc::new(Mutex::new(KrylovRecord {
            finish: Some(schedule[0]),
            newton: newton.clone(),
            ..KrylovRecord::default()
        }));
        let mut sim =
            setup.simulation(SolverMethod::LocalGlobal, Predictor::Linear, with(1, 0.0))?;
        sim.set_position_solver(Box::new(KrylovProbe::new(Arc::clone(&record))));
        for _ in 0..steps {
            let saved = sim.checkpoint();
            step_reference.restore(&saved).map_err(|e| e.to_string())?;
            step_reference.step().map_err(|e| e.to_string())?;
            record.lock().map_err(|e| e.to_string())?.reference = step_reference
                .state()
                .positions
                .iter()
                .zip(&saved.state.positions)
                .map(|(a, b)| a - b)
                .collect();
            sim.step().map_err(|e| e.to_string())?;
        }
        if newton.is_empty() {
            println!("oracle CG at x*, {}: {:.3e}", schedule[0], error(&sim));
        } else {
            println!(
                "truncated Newton, H(x0), CG iterations {newton:?}: {:.3e}",
                error(&sim)
            );
        }
    }
    Ok(())
}
