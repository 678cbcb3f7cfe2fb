//! `pd-probe contact`: the cost of contact per step, at equal iterations:
//! a soft cube resting on a floor (collider contact) and two cubes stacked
//! on it (`contact.bodies = true`), each against the same scene with no
//! contact at all (the body then falls freely: the same matrix, the same
//! iterations, no contact work). Both scenes are run in alternating rounds
//! of 10 steps after a warm-up; the median step time of each over all
//! rounds, and the ratio of the fastest rounds (the least disturbed).

use std::path::Path;

use pd_io::scene::{Scene, Syntax};
use pd_io::stats::upper_median;
use serde_json::Value;

use crate::schema::{Contact, ContactRow};

/// The scene: one cube of `cells` per side resting on the floor, or two
/// stacked (`stack`); `contact` adds the floor and, for the stack,
/// contact between the bodies. A scene TOML text (public for
/// `examples/contact_case.rs`).
pub fn scene(cells: usize, stack: bool, contact: bool) -> String {
    let cube = |size: f64, y: f64| {
        format!(
            "[[body]]\nmesh = {{ generator = \"box\", size = [{size:?}, {size:?}, {size:?}], \
             cells = [{cells}, {cells}, {cells}] }}\ndensity = 1000.0\n\
             constraints = [ {{ kind = \"tet-strain\", stiffness = 1.0e5 }} ]\n\
             translate = [0.0, {y:?}, 0.0]\n"
        )
    };
    let mut text = String::from(
        "[simulation]\ndt = 0.005\nsteps = 1\ngravity = [0.0, -9.81, 0.0]\n\
         integrator = \"backward-euler\"\niterations = 20\nthreads = 1\n\n",
    );
    if contact {
        text.push_str(
            "[[collider]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.0]\n\
             normal = [0.0, 1.0, 0.0]\nfriction = 0.5\n\n[contact]\nthickness = 0.001\n",
        );
        if stack {
            text.push_str("bodies = true\nfriction = 0.5\n");
        }
        text.push('\n');
    }
    text.push_str(&cube(0.2, 0.001));
    if stack {
        text.push_str(&cube(0.2, 0.2015));
    }
    text
}

/// Builds a scene and runs its warm-up.
fn build(text: &str, warmup: usize) -> Result<pd_solver::Simulation, String> {
    let scene = Scene::parse(text, Syntax::Toml, Path::new("contact-bench.toml"))
        .map_err(|e| e.to_string())?;
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    sim.run(warmup).map_err(|e| e.to_string())?;
    Ok(sim)
}

/// Steps per round of [`interleaved`].
const ROUND: usize = 10;

/// One scene's timings over the interleaved rounds.
#[derive(Default)]
struct Timings {
    steps_ms: Vec<f64>,
    rounds_ms: Vec<f64>,
    contacts: usize,
    iterations: usize,
}

impl Timings {
    fn record(&mut self, sim: &mut pd_solver::Simulation, steps: usize) -> Result<(), String> {
        let stats = sim.run(steps).map_err(|e| e.to_string())?;
        let ms: Vec<f64> = stats.iter().map(|s| s.total_seconds * 1e3).collect();
        self.rounds_ms
            .push(ms.iter().sum::<f64>() / ms.len().max(1) as f64);
        self.steps_ms.extend(ms);
        self.contacts = stats.last().map_or(0, |s| s.contacts);
        self.iterations += stats.iter().map(|s| s.iterations).sum::<usize>();
        Ok(())
    }
}

/// Both scenes after `warmup` steps each, then rounds of [`ROUND`] steps of
/// the scene without contact and [`ROUND`] with it in turn, `steps` steps
/// of each in all. Interleaving makes both see the same machine: a single
/// run of each in sequence gave stacked-cube ratios from 1.3x to 2.0x on a
/// quiet machine (the VM's speed drifts over tenths of a second), rounds
/// in turn keep the least-disturbed round's ratio within a few per cent.
fn interleaved(
    without: &str,
    with: &str,
    warmup: usize,
    steps: usize,
) -> Result<(Timings, Timings), String> {
    let mut sims = [build(without, warmup)?, build(with, warmup)?];
    let mut timings = [Timings::default(), Timings::default()];
    let mut done = 0;
    while done < steps {
        let n = ROUND.min(steps - done);
        for (sim, t) in sims.iter_mut().zip(timings.iter_mut()) {
            t.record(sim, n)?;
        }
        done += n;
    }
    let [a, b] = timings;
    Ok((a, b))
}

/// Measures both scenes with and without contact.
///
/// # Errors
/// A scene that fails to build or run.
pub fn measure(cells: usize, warmup: usize, steps: usize) -> Result<Value, String> {
    let mut rows = Vec::new();
    for (label, stack) in [("cube on the floor", false), ("two cubes stacked", true)] {
        let (without, with) = interleaved(
            &scene(cells, stack, false),
            &scene(cells, stack, true),
            warmup,
            steps,
        )?;
        let (without_ms, with_ms) = (
            upper_median(&without.steps_ms),
            upper_median(&with.steps_ms),
        );
        let min_round = |t: &Timings| t.rounds_ms.iter().copied().fold(f64::INFINITY, f64::min);
        let measured = steps.max(1);
        rows.push(ContactRow {
            scene: label.into(),
            cells,
            without_ms,
            with_ms,
            ratio: with_ms / without_ms,
            min_round_without_ms: min_round(&without),
            min_round_with_ms: min_round(&with),
            min_round_ratio: min_round(&with) / min_round(&without),
            contacts: with.contacts,
            iterations_without: without.iterations / measured,
            iterations_with: with.iterations / measured,
        });
    }
    serde_json::to_value(Contact {
        rows,
        steps,
        warmup,
    })
    .map_err(|e| e.to_string())
}
