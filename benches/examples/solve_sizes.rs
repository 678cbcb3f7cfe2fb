//! `cargo run --release -p pd-benches --example solve_sizes -- [REPS]
//! [NX,NY,NZ ...]`: the global step's solve alone (`Simulation::profile_solve`,
//! one thread) on benchmark beams of several sizes, `REPS` (300) solves
//! each after one step; prints the stored values of the factor, the fastest
//! and median solve and the fastest in ns per stored value per pass (a solve
//! reads the factor twice). Factors that stay in the caches against ones
//! that do not tell the kernel's own speed from the memory's
//! (docs/design/performance.md, "The solve against the machine").

use pd_benches::Beam;
use std::time::Instant;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let reps: usize = match args.next() {
        Some(r) => r.parse().map_err(|_| format!("REPS: not a count: {r}"))?,
        None => 300,
    };
    let mut sizes: Vec<[usize; 3]> = Vec::new();
    for arg in args {
        let cells: Vec<usize> = arg
            .split(',')
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| format!("{arg}: expected NX,NY,NZ"))?;
        sizes.push(
            cells
                .try_into()
                .map_err(|_| format!("{arg}: expected three counts"))?,
        );
    }
    if sizes.is_empty() {
        sizes = vec![[32, 8, 8], [60, 12, 12], [80, 14, 14], [100, 16, 16]];
    }
    for cells in sizes {
        let beam = Beam {
            cells,
            ..Beam::default()
        };
        let mut sim = beam.simulation("none", "be")?;
        sim.run(1).map_err(|e| e.to_string())?;
        let mut times = Vec::with_capacity(reps);
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            sim.profile_solve().map_err(|e| e.to_string())?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        let values = sim.factor_len() as f64;
        println!(
            "cells {cells:?}: {values:.0} stored values ({:.2} MB), solve min {:.3} ms, \
             median {:.3} ms, {:.3} ns per value per pass",
            values * 8e-6,
            times[0],
            times[times.len() / 2],
            times[0] * 1e6 / (2.0 * values)
        );
    }
    Ok(())
}
