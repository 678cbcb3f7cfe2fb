//! `cargo run -p pd-benches --example predictor_gap -- [--integrator
//! be|im|bdf2] [--damping D] [--steps N] [--cells NX,NY,NZ] [--fits
//! K/M,K/M,...] [--reference-iterations I] [--history-iterations H]`: how good each start of a step
//! is, for the fitted predictor (docs/design/solver.md, "The fitted predictor").
//!
//! The benchmark beam (one thread) runs `N` steps with Anderson at `I`
//! iterations (40: the reference; or `H`, to fit the corrections a
//! budget-limited run would store), keeping the last 36 corrections. Before
//! each step from the fourth, every candidate start `y + p` is measured by
//! a probe simulation restored to the same state with `p` as its stored
//! correction and the extrapolated predictor (so the start is `y + p`),
//! Anderson at `I` iterations: the gap `g(x^0) - g(x*)` over the inertial
//! start's. Printed per step: `linear` (`2 c_n - c_{n-1}`) and the fitted
//! recurrence of order `K` over `M` steps, with the fit's relative
//! residual. A start whose objective is not below `y`'s is replaced by `y`
//! (the predictor's safeguard), so ratios are at most 1.

use pd_benches::{Beam, Options};
use pd_mesh::Point;
use pd_solver::{Checkpoint, Predictor, Simulation, SolverMethod, SolverSpec, fit_recurrence};

fn gram(history: &[&[Point]], masses: &[f64]) -> Vec<f64> {
    let len = history.len();
    let mut g = vec![0.0; len * len];
    for p in 0..len {
        for q in 0..len {
            g[p * len + q] = (history[p].iter().zip(history[q]).zip(masses))
                .map(|((a, b), m)| m * a.dot(b))
                .sum();
        }
    }
    g
}

fn combine(history: &[&[Point]], a: &[f64]) -> Vec<Point> {
    let mut p = vec![Point::zeros(); history[0].len()];
    for (a, c) in a.iter().zip(history) {
        for (p, c) in p.iter_mut().zip(*c) {
            *p += c * *a;
        }
    }
    p
}

fn gap(probe: &mut Simulation, saved: &Checkpoint) -> Result<f64, String> {
    probe.restore(saved).map_err(|e| e.to_string())?;
    probe.step().map_err(|e| e.to_string())?;
    let trace = probe.objective_trace().ok_or("no trace")?;
    Ok(trace[0] - trace[trace.len() - 1])
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = Options::new(&args);
    let integrator = options.value("--integrator").unwrap_or("im");
    let damping = options.value("--damping").unwrap_or("none");
    let steps: usize = options.parse("--steps", 20)?;
    let reference: usize = options.parse("--reference-iterations", 40)?;
    let fits: Vec<(usize, usize)> = options
        .value("--fits")
        .unwrap_or("2/4,3/6,4/8,5/10,6/12,8/16")
        .split(',')
        .map(|f| {
            let (k, m) = f.split_once('/').ok_or(format!("--fits: {f:?}"))?;
            Ok((
                k.parse().map_err(|_| f.to_string())?,
                m.parse().map_err(|_| f.to_string())?,
            ))
        })
        .collect::<Result<_, String>>()?;
    let mut beam = Beam {
        iterations: reference,
        threads: 1,
        ..Beam::default()
    };
    if options.value("--cells").is_some() {
        let cells = options.list("--cells", &[])?;
        beam.cells = cells.try_into().map_err(|_| "--cells needs three counts")?;
    }
    let anderson = SolverSpec {
        method: SolverMethod::Anderson,
        ..SolverSpec::default()
    };
    let history_iterations: usize = options.parse("--history-iterations", reference)?;
    let make = |predictor: Predictor, iterations: usize| -> Result<Simulation, String> {
        let beam = Beam { iterations, ..beam };
        let mut sim = beam.simulation(damping, integrator)?;
        sim.set_position_solver(anderson.create().map_err(|e| e.to_string())?);
        sim.set_predictor(predictor);
        Ok(sim)
    };
    let long = Predictor::Fitted {
        order: 12,
        equations: 24,
    };
    let mut main = make(long, history_iterations)?;
    let mut inertial = make(Predictor::Inertial, reference)?;
    let mut probe = make(Predictor::Extrapolated, reference)?;
    inertial.record_objective(true);
    probe.record_objective(true);
    let masses = main.model().masses().to_vec();
    print!("step linear");
    for (k, m) in &fits {
        print!(" fit{k}/{m} (residual)");
    }
    println!();
    for step in 1..=steps {
        let saved = main.checkpoint();
        let history: Vec<&[Point]> = saved.predictor.correction_history().collect();
        if step >= 4 && history.len() >= 2 {
            let at_y = gap(&mut inertial, &saved)?;
            let mut line = format!("{step}");
            let mut candidate = |p: Vec<Point>| -> Result<f64, String> {
                let mut c = saved.clone();
                c.predictor.correction = p;
                c.predictor.previous.clear();
                c.predictor.history.clear();
                Ok(gap(&mut probe, &c)? / at_y)
            };
            let linear = combine(&history, &[2.0, -1.0]);
            line += &format!(" {:.2e}", candidate(linear)?);
            for &(k, m) in &fits {
                if history.len() < k + m {
                    line += " -";
                    continue;
                }
                let g = gram(&history[..k + m], &masses);
                match fit_recurrence(&g, k, m) {
                    Some(fit) => {
                        let p = combine(&history, &fit.coefficients);
                        line += &format!(" {:.2e} ({:.1e})", candidate(p)?, fit.relative_residual);
                    }
                    None => line += " none",
                }
            }
            println!("{line}");
        }
        main.step().map_err(|e| e.to_string())?;
    }
    Ok(())
}
