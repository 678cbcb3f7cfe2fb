//! `cargo run -p pd-benches --example contact_case -- MODE CELLS STACK`:
//! one case of `pd-probe contact` (`benches/src/contact.rs`), for
//! profilers and for a ratio measured in one process.
//!
//! - `MODE` = `with N` or `without N`: builds the scene (`STACK` = 1 for
//!   the two stacked cubes, 0 for one cube), runs 20 warm-up steps and `N`
//!   steps, prints the mean step time in ms. Run under `perf stat` or
//!   `valgrind --tool=callgrind` with two values of `N` and subtract to get
//!   a per-step count free of the set-up.
//! - `MODE` = `alternate R`: builds both scenes, runs 20 warm-up steps of
//!   each, then `R` rounds of 10 steps with contact and 10 without, and
//!   prints the total time of each and their ratio (both see the same
//!   machine load), then the ratio of the medians and of the minima of
//!   the rounds' times (on a loaded machine the minimum is the round least
//!   disturbed by other processes: the least noisy of the three).

use std::path::Path;
use std::time::Instant;

use pd_benches::contact::scene;
use pd_io::scene::{Scene, Syntax};
use pd_solver::Simulation;

fn build(cells: usize, stack: bool, contact: bool) -> Result<Simulation, String> {
    let text = scene(cells, stack, contact);
    let scene = Scene::parse(&text, Syntax::Toml, Path::new("contact-case.toml"))
        .map_err(|e| e.to_string())?;
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    sim.run(20).map_err(|e| e.to_string())?;
    Ok(sim)
}

/// Seconds taken by `steps` steps of `sim`.
fn timed(sim: &mut Simulation, steps: usize) -> Result<f64, String> {
    let t = Instant::now();
    sim.run(steps).map_err(|e| e.to_string())?;
    Ok(t.elapsed().as_secs_f64())
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mode, n, cells, stack] = args.as_slice() else {
        return Err("usage: contact_case with|without|alternate N CELLS STACK(0|1)".into());
    };
    let parse = |s: &str| {
        s.parse::<usize>()
            .map_err(|_| format!("not a count: {s:?}"))
    };
    let (n, cells, stack) = (parse(n)?, parse(cells)?, parse(stack)? == 1);
    match mode.as_str() {
        "with" | "without" => {
            let mut sim = build(cells, stack, mode == "with")?;
            let seconds = timed(&mut sim, n)?;
            println!("{mode}: {:.4} ms per step", seconds * 1e3 / n.max(1) as f64);
        }
        "alternate" => {
            let mut with = build(cells, stack, true)?;
            let mut without = build(cells, stack, false)?;
            let (mut a, mut b) = (Vec::new(), Vec::new());
            for _ in 0..n {
                a.push(timed(&mut with, 10)?);
                b.push(timed(&mut without, 10)?);
            }
            let steps = (10 * n).max(1) as f64;
            let (sum_a, sum_b) = (a.iter().sum::<f64>(), b.iter().sum::<f64>());
            println!(
                "with {:.4} ms, without {:.4} ms per step, ratio {:.3}",
                sum_a * 1e3 / steps,
                sum_b * 1e3 / steps,
                sum_a / sum_b
            );
            a.sort_by(f64::total_cmp);
            b.sort_by(f64::total_cmp);
            if let (Some(&min_a), Some(&min_b)) = (a.first(), b.first()) {
                let (med_a, med_b) = (a[a.len() / 2], b[b.len() / 2]);
                println!(
                    "rounds of 10 steps: median {:.4} / {:.4} ms per step (ratio {:.3}), \
                     minimum {:.4} / {:.4} ms (ratio {:.3})",
                    med_a * 1e2,
                    med_b * 1e2,
                    med_a / med_b,
                    min_a * 1e2,
                    min_b * 1e2,
                    min_a / min_b
                );
            }
        }
        _ => return Err(format!("unknown mode {mode:?}")),
    }
    Ok(())
}
