//! `cargo run --release -p pd-benches --example adjoint_cost -- [--cells
//! NX,NY,NZ] [--steps N] [--repeats R] [--integrator be|im|bdf2] [--forward
//! METHOD] [--json]`: what a
//! gradient by the adjoint method (`pd_adjoint::loss_and_gradient`) costs on
//! the bench beam (one thread, Laplacian damping `a2 = 0.003 s`, swinging up
//! from rest under gravity; the forward run by `METHOD`, Anderson by
//! default, as `AdjointOptions` has it), against its forward run and against finite
//! differences (docs/design/gradients.md, "Cost").
//!
//! Each repeat also times the bench's own forward run of the same steps
//! (local-global with its fixed iteration budget, not converged), then runs the loss and its gradient with respect to `a2`, the
//! strain stiffness, the density and gravity (6 scalars), and records the
//! forward and backward wall times; the minimum over the repeats is
//! reported (the machine may be shared: the load average is printed before
//! and after). Finite differences cost one forward run per scalar
//! (one-sided) or two (central). With `--json` the summary is one JSON
//! object on the last line (what `cargo xtask bench-report` reads).

use pd_adjoint::{AdjointOptions, Parameter, ProbeLoss, loss_and_gradient};
use pd_benches::{Beam, Options};
use pd_mesh::Point;
use pd_solver::State;

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = Options::new(&args);
    options.only(&[
        "--cells",
        "--steps",
        "--repeats",
        "--integrator",
        "--forward",
        "--json",
    ])?;
    let json = options.flag("--json");
    let forward_method = options.value("--forward").unwrap_or("anderson");
    let forward_method = pd_solver::SolverMethod::parse(forward_method)
        .ok_or(format!("--forward: unknown method {forward_method:?}"))?;
    let cells: Vec<usize> = options.list("--cells", &[35, 7, 7])?;
    let [cx, cy, cz] = cells[..] else {
        return Err("--cells takes three counts".into());
    };
    let steps: usize = options.parse("--steps", 20)?;
    let repeats: usize = options.parse("--repeats", 3)?;
    let integrator = options.value("--integrator").unwrap_or("be");
    let beam = Beam {
        cells: [cx, cy, cz],
        threads: 1,
        ..Beam::default()
    };
    let build = || -> Result<pd_solver::Simulation, String> {
        let mut sim = beam.simulation("laplacian", integrator)?;
        let positions = sim.state().positions.clone();
        let velocities = positions
            .iter()
            .map(|x| Point::new(0.0, x.x, 0.0))
            .collect();
        sim.set_state(State {
            positions,
            velocities,
        })
        .map_err(|e| e.to_string())?;
        Ok(sim)
    };
    let sim = build()?;
    let rest = sim.model().rest_positions().to_vec();
    let tip: Vec<usize> = (0..rest.len())
        .filter(|&v| rest[v].x >= beam.size[0] - 1e-9)
        .collect();
    let loss = ProbeLoss {
        vertices: tip.clone(),
        targets: vec![tip.iter().map(|&v| rest[v]).collect(); steps],
    };
    let parameters = [
        Parameter::DampingStiffness,
        Parameter::ConstraintStiffness {
            body: 0,
            constraint: 0,
        },
        Parameter::Density { body: 0 },
        Parameter::ExternalForce,
    ];
    let scalars = 6;
    println!(
        "bench beam {cx}x{cy}x{cz} cells, {} vertices, {steps} steps, {integrator}, \
         laplacian damping; load before: {}",
        rest.len(),
        load()
    );
    let (mut forward, mut backward, mut plain) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let (mut forward_iterations, mut adjoint_iterations) = (0, 0);
    for repeat in 0..repeats {
        // The bench's own run of the same steps: local-global, a fixed
        // budget of iterations per step, not converged.
        let mut sim = build()?;
        let start = std::time::Instant::now();
        sim.run(steps).map_err(|e| e.to_string())?;
        plain = plain.min(start.elapsed().as_secs_f64());
        let result = loss_and_gradient(
            build()?,
            steps,
            &loss,
            &parameters,
            &AdjointOptions {
                forward_method,
                ..AdjointOptions::default()
            },
        )
        .map_err(|e| e.to_string())?;
        println!(
            "repeat {repeat}: forward {:.3} s ({} iterations, {:.1} ms each), backward {:.3} s, adjoint iterations {} \
             ({:.1} per step), fallback steps {}, forward steps retried by Newton {}, \
             unconverged forward steps {}",
            result.forward_s,
            result.forward_iterations,
            1e3 * result.forward_s / result.forward_iterations.max(1) as f64,
            result.backward_s,
            result.adjoint_iterations,
            result.adjoint_iterations as f64 / steps as f64,
            result.fallback_steps,
            result.forward_retries,
            result.unconverged_steps
        );
        if result.forward_s < forward {
            forward_iterations = result.forward_iterations;
        }
        forward = forward.min(result.forward_s);
        backward = backward.min(result.backward_s);
        adjoint_iterations = result.adjoint_iterations;
    }
    if json {
        println!(
            "{{\"vertices\": {}, \"steps\": {steps}, \"integrator\": \"{integrator}\", \
             \"forward_method\": \"{}\", \"scalars\": {scalars}, \"repeats\": {repeats}, \
             \"plain_s\": {plain}, \"plain_iterations\": {}, \"forward_s\": {forward}, \
             \"forward_iterations\": {forward_iterations}, \"backward_s\": {backward}, \
             \"adjoint_iterations\": {adjoint_iterations}, \"load_after\": \"{}\"}}",
            rest.len(),
            forward_method.name(),
            beam.iterations,
            load()
        );
        return Ok(());
    }
    println!(
        "minimum: plain forward ({} local-global iterations a step) {plain:.3} s; backward / \
         plain forward {:.2}",
        beam.iterations,
        backward / plain
    );
    println!(
        "minimum: forward {forward:.3} s, backward {backward:.3} s, backward/forward {:.2}; \
         finite differences of {scalars} scalars: {:.3} s one-sided, {:.3} s central \
         ({:.1}x / {:.1}x the adjoint's forward + backward); load after: {}",
        backward / forward,
        scalars as f64 * forward,
        2.0 * scalars as f64 * forward,
        scalars as f64 * forward / (forward + backward),
        2.0 * scalars as f64 * forward / (forward + backward),
        load()
    );
    Ok(())
}
