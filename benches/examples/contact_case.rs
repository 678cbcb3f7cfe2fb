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
//! - `MODE` = `settled N` or `frozen N`: the scene with contact run
//!   [`SETTLE`] steps to rest, then `N` steps with contact (`settled`) or
//!   with its contact forces frozen (`frozen`,
//!   `Simulation::freeze_contact_forces`: the same deformation and
//!   iterations, contact's forces as a constant load, none of its work);
//!   prints the mean step time. For callgrind, as `with`.
//! - `MODE` = `matched R`: the deformation-matched comparison of
//!   docs/design/contact.md: settled, frozen and contact-free (20 warm-up steps)
//!   scenes, `R` rounds of 10 steps of each in turn, the ratios of the
//!   minimum and median rounds, and how far the frozen run drifted from
//!   the settled one in the last round (largest vertex distance, m). The
//!   settled and frozen rounds all start from the state after [`SETTLE`]
//!   steps (a checkpoint) and one more step with contact.

use std::path::Path;
use std::time::Instant;

use pd_benches::contact::scene;
use pd_io::scene::{Scene, Syntax};
use pd_io::stats::upper_median;
use pd_solver::Simulation;

fn build(cells: usize, stack: bool, contact: bool) -> Result<Simulation, String> {
    let text = scene(cells, stack, contact);
    let scene = Scene::parse(&text, Syntax::Toml, Path::new("contact-case.toml"))
        .map_err(|e| e.to_string())?;
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    sim.run(20).map_err(|e| e.to_string())?;
    Ok(sim)
}

/// Steps the contact scene runs to come to rest before `settled`,
/// `frozen` and `matched` measure (as `pd-probe contact --steps 200`).
const SETTLE: usize = 200;

/// The contact scene after [`SETTLE`] steps, its forces frozen if asked.
fn settled(cells: usize, stack: bool, frozen: bool) -> Result<Simulation, String> {
    let mut sim = build(cells, stack, true)?;
    sim.run(SETTLE - 20).map_err(|e| e.to_string())?;
    if frozen && !sim.freeze_contact_forces(true) {
        return Err("contact is off".into());
    }
    Ok(sim)
}

/// The minimum and upper median of `times` (s), sorted in place.
fn min_median(times: &mut [f64]) -> (f64, f64) {
    times.sort_by(f64::total_cmp);
    (times[0], upper_median(times))
}

/// `matched R`: settled, frozen and contact-free rounds in turn.
fn matched(rounds: usize, cells: usize, stack: bool) -> Result<(), String> {
    let mut sims = [
        settled(cells, stack, false)?,
        settled(cells, stack, true)?,
        build(cells, stack, false)?,
    ];
    // Every round of the settled and frozen scenes starts from the same
    // rested state and one untimed step with contact (frozen forces do not
    // balance the weight exactly: the frozen stack drifts, 0.3 mm in 10
    // steps, 17 mm in 60; and a restore needs a step's start).
    let rest = sims[0].checkpoint();
    let mut times = [vec![], vec![], vec![]];
    for _ in 0..rounds.max(1) {
        for (k, (sim, t)) in sims.iter_mut().zip(times.iter_mut()).enumerate() {
            if k < 2 {
                sim.restore(&rest).map_err(|e| e.to_string())?;
                sim.freeze_contact_forces(false);
                sim.run(1).map_err(|e| e.to_string())?;
                sim.freeze_contact_forces(k == 1);
            }
            t.push(timed(sim, 10)?);
        }
    }
    let drift = (sims[0].state().positions.iter())
        .zip(&sims[1].state().positions)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max);
    let [a, b, c] = times.map(|mut t| min_median(&mut t));
    println!(
        "per step, minimum (median) of rounds of 10: settled {:.4} ({:.4}) ms, \
         frozen {:.4} ({:.4}) ms, without {:.4} ({:.4}) ms",
        a.0 * 1e2,
        a.1 * 1e2,
        b.0 * 1e2,
        b.1 * 1e2,
        c.0 * 1e2,
        c.1 * 1e2
    );
    println!(
        "ratios of minima (medians): settled/without {:.3} ({:.3}), frozen/without {:.3} \
         ({:.3}), settled/frozen {:.3} ({:.3}); frozen drifted {drift:.3e} m",
        a.0 / c.0,
        a.1 / c.1,
        b.0 / c.0,
        b.1 / c.1,
        a.0 / b.0,
        a.1 / b.1
    );
    Ok(())
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
        return Err(
            "usage: contact_case with|without|settled|frozen|alternate|matched N CELLS STACK(0|1)"
                .into(),
        );
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
        "settled" | "frozen" => {
            let mut sim = settled(cells, stack, mode == "frozen")?;
            let seconds = timed(&mut sim, n)?;
            println!("{mode}: {:.4} ms per step", seconds * 1e3 / n.max(1) as f64);
        }
        "matched" => matched(n, cells, stack)?,
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
