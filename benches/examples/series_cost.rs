//! `cargo run -p pd-benches --example series_cost -- [REPS]
//! [TETGEN_BASE]`: what a Caughey series damping costs against plain
//! Laplacian damping (`docs/design/damping.md`, "Caughey series"): the
//! structural non-zeros of the global step's Cholesky factor
//! (`Simulation::factor_nnz`) and its stored values, the set-up time, and
//! the step time (one thread, 10 iterations, backward Euler; the fastest
//! of `REPS` (5) runs of 10 steps, the variants' runs interleaved) on the
//! 2k benchmark beam; with a TetGen base (the armadillo), the fill on that
//! mesh too. All coefficients positive (the cost depends on the pattern,
//! not on the values).

use std::time::Instant;

use pd_benches::Beam;
use pd_damping::{Damping, LaplacianDamping};
use pd_mesh::Mesh;
use pd_solver::Simulation;

/// The damping variants compared: name, `a2`, `a3, a4, ...`.
const VARIANTS: [(&str, f64, &[f64]); 3] = [
    ("laplacian", 0.003, &[]),
    ("series, 3 terms", 0.003, &[1e-9]),
    ("series, 4 terms", 0.003, &[1e-9, 1e-15]),
];

fn simulation(beam: &Beam, mesh: Mesh, a2: f64, higher: &[f64]) -> Result<Simulation, String> {
    let damping: Box<dyn Damping> =
        Box::new(LaplacianDamping::with_series(a2, 0.0, false, higher).map_err(|e| e.to_string())?);
    Simulation::new(
        beam.model_on(mesh)?,
        pd_benches::integrator("be")?,
        damping,
        beam.settings(),
    )
    .map_err(|e| e.to_string())
}

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let reps: usize = match args.next() {
        Some(r) => r.parse().map_err(|_| format!("REPS: not a count: {r}"))?,
        None => 5,
    };
    let armadillo = args.next();
    let beam = Beam::default();
    let mesh = beam.mesh()?;
    println!(
        "beam {:?} cells, {} vertices, one thread, {} iterations",
        beam.cells,
        mesh.num_vertices(),
        beam.iterations
    );
    // The variants' runs interleaved, so that a change of the machine's
    // load hits all of them alike; the fastest run of each is kept.
    // `PD_SERIES_VARIANT=k` runs variant `k` alone (for instruction counts
    // under `valgrind --tool=callgrind --toggle-collect='*Simulation::run*'`).
    let only: Option<usize> = std::env::var("PD_SERIES_VARIANT")
        .ok()
        .and_then(|k| k.parse().ok());
    let mut sims = Vec::new();
    for (k, (name, a2, higher)) in VARIANTS.into_iter().enumerate() {
        if only.is_some_and(|o| o != k) {
            continue;
        }
        let start = Instant::now();
        let mut sim = simulation(&beam, mesh.clone(), a2, higher)?;
        let setup = start.elapsed().as_secs_f64();
        sim.run(3).map_err(|e| e.to_string())?;
        sims.push((name, sim, setup, f64::INFINITY));
    }
    for _ in 0..reps {
        for (_, sim, _, fastest) in &mut sims {
            let start = Instant::now();
            sim.run(10).map_err(|e| e.to_string())?;
            *fastest = fastest.min(start.elapsed().as_secs_f64() / 10.0);
        }
    }
    let plain = sims[0].3;
    for (name, sim, setup, fastest) in &sims {
        println!(
            "  {name:16} factor nnz {:9}  stored {:9}  set-up {:7.1} ms  step {:7.3} ms ({:.3}x)",
            sim.factor_nnz(),
            sim.factor_len(),
            setup * 1e3,
            fastest * 1e3,
            fastest / plain
        );
    }
    if let Some(base) = armadillo {
        let mesh = pd_io::tetgen::read_tetgen_base(std::path::Path::new(&base))
            .map_err(|e| format!("{base}: {e}"))?;
        println!("{base}: {} vertices", mesh.num_vertices());
        for (name, a2, higher) in VARIANTS {
            let start = Instant::now();
            let sim = simulation(&beam, mesh.clone(), a2, higher)?;
            println!(
                "  {name:16} factor nnz {:9}  stored {:9}  set-up {:7.1} ms",
                sim.factor_nnz(),
                sim.factor_len(),
                start.elapsed().as_secs_f64() * 1e3
            );
        }
    }
    Ok(())
}
