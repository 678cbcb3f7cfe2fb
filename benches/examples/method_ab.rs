//! `cargo run --release -p pd-benches --example method_ab -- METHOD BUDGET
//! [--predictor P|fittedK/M] [--integrator be|im|bdf2] [--damping D] [--steps N]
//! [--warmup W] [--cells NX,NY,NZ] [--window W] [--rho R|auto]`: runs the benchmark beam
//! (one thread) with one iteration method and budget and prints, on one
//! line, the median and mean wall time per step (ms) after `W` warm-up
//! steps (and the medians of its local and global phases' times), the local-global iterations and objective evaluations per step,
//! and an FNV-1a hash of every final position and velocity bit. For quick
//! A/B comparisons of a method's cost (run the two builds alternately) and
//! for checking that a change keeps its results bit for bit.

use pd_benches::{Beam, Options};
use pd_io::stats::median;
use pd_solver::{Predictor, SolverMethod, SolverSpec};

/// A predictor name, or `fittedK/M` (the fitted predictor of order `K`
/// over `M` steps).
fn parse_predictor(text: &str) -> Option<Predictor> {
    let Some((k, m)) = text.strip_prefix("fitted").and_then(|t| t.split_once('/')) else {
        return Predictor::parse(text);
    };
    let (order, equations) = (k.parse().ok()?, m.parse().ok()?);
    ((1..=Predictor::MAX_ORDER).contains(&order)
        && (order..=Predictor::MAX_EQUATIONS).contains(&equations))
    .then_some(Predictor::Fitted { order, equations })
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = Options::new(&args);
    let (Some(method), Some(budget)) = (args.first(), args.get(1)) else {
        return Err("usage: method_ab METHOD BUDGET [options]".into());
    };
    let method = SolverMethod::parse(method).ok_or(format!("unknown method {method:?}"))?;
    let budget: usize = budget.parse().map_err(|_| format!("BUDGET: {budget:?}"))?;
    let predictor = options.value("--predictor").unwrap_or("inertial");
    let predictor = parse_predictor(predictor).ok_or(format!("unknown predictor {predictor:?}"))?;
    let integrator = options.value("--integrator").unwrap_or("be");
    let damping = options.value("--damping").unwrap_or("none");
    let steps: usize = options.parse("--steps", 40)?;
    let warmup: usize = options.parse("--warmup", 5)?;
    let mut beam = Beam {
        iterations: budget,
        threads: 1,
        ..Beam::default()
    };
    if options.value("--cells").is_some() {
        let cells = options.list("--cells", &[])?;
        beam.cells = cells.try_into().map_err(|_| "--cells needs three counts")?;
    }
    let mut sim = beam.simulation(damping, integrator)?;
    let spec = SolverSpec {
        method,
        window: options.parse("--window", SolverSpec::default().window)?,
        rho: options.spectral_radius("--rho")?,
        ..SolverSpec::default()
    };
    sim.set_position_solver(spec.create().map_err(|e| e.to_string())?);
    sim.set_predictor(predictor);
    sim.run(warmup).map_err(|e| e.to_string())?;
    let stats = sim.run(steps).map_err(|e| e.to_string())?;
    let times: Vec<f64> = stats.iter().map(|s| s.total_seconds * 1e3).collect();
    let local: Vec<f64> = stats.iter().map(|s| s.local_seconds * 1e3).collect();
    let global: Vec<f64> = stats.iter().map(|s| s.global_seconds * 1e3).collect();
    let n = stats.len().max(1) as f64;
    let iterations = stats.iter().map(|s| s.iterations as f64).sum::<f64>() / n;
    let evaluations = stats
        .iter()
        .map(|s| s.objective_evaluations as f64)
        .sum::<f64>()
        / n;
    println!(
        "{} {budget} {} {integrator} {damping}: median {:.3} ms mean {:.3} ms \
         (local {:.3}, global {:.3}), \
         {iterations:.2} iterations {evaluations:.2} evaluations a step, hash {:016x}",
        method.name(),
        predictor.name(),
        median(&times),
        times.iter().sum::<f64>() / n,
        median(&local),
        median(&global),
        pd_benches::state_hash(sim.state())
    );
    Ok(())
}
