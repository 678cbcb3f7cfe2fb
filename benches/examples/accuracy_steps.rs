//! `cargo run --release -p pd-benches --example accuracy_steps -- SCENE.toml [STEPS]`:
//! runs a scene (its own steps, or `STEPS`) and prints, per step, the
//! iterations, whether the step met its accuracy target, its estimated
//! error and relative residual, the active contacts and the energies; then
//! the steps that stopped short, the energy created (the largest rise of
//! the total energy, as `summary.json`'s `energy_created_j`, over the
//! largest kinetic plus elastic energy) and the iterations per step. A
//! measurement aid for accuracy runs with contact (docs/design/contact.md,
//! "Friction with an accuracy target").

use std::path::Path;
use std::time::Instant;

use pd_io::scene::{Scene, Syntax};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, steps) = match args.as_slice() {
        [path] => (path, None),
        [path, steps] => (path, Some(steps)),
        _ => return Err("usage: accuracy_steps SCENE.toml [STEPS]".into()),
    };
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let scene = Scene::parse(&text, Syntax::Toml, Path::new(path)).map_err(|e| e.to_string())?;
    let steps = match steps {
        Some(s) => s.parse().map_err(|_| format!("STEPS: {s:?}"))?,
        None => scene.steps,
    };
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    let start = sim.energies();
    let (mut low, mut rise) = (start.total(), 0.0_f64);
    let mut largest = start.kinetic + start.elastic;
    let (mut short, mut iterations) = (Vec::new(), Vec::with_capacity(steps));
    let clock = Instant::now();
    println!("step iterations met estimate residual contacts kinetic_J elastic_J total_J seconds");
    for step in 1..=steps {
        let t = Instant::now();
        let stats = sim.step().map_err(|e| format!("step {step}: {e}"))?;
        let e = sim.energies();
        low = low.min(e.total());
        rise = rise.max(e.total() - low);
        largest = largest.max(e.kinetic + e.elastic);
        iterations.push(stats.iterations);
        if !stats.converged {
            short.push(step);
        }
        println!(
            "{step} {} {} {:.4} {:.2e} {} {:.3} {:.3} {:.3} {:.2}",
            stats.iterations,
            stats.converged,
            stats.estimated_error,
            stats.relative_change,
            stats.contacts,
            e.kinetic,
            e.elastic,
            e.total(),
            t.elapsed().as_secs_f64()
        );
    }
    let total: usize = iterations.iter().sum();
    iterations.sort_unstable();
    let median = iterations.get(iterations.len() / 2).copied().unwrap_or(0);
    let most = iterations.last().copied().unwrap_or(0);
    println!(
        "{} of {steps} steps short of the target {short:?}; energy created {rise:.3} J of {largest:.1} J \
         ({:.2}%); iterations: median {median}, largest {most}, total {total}; {:.1} s",
        short.len(),
        100.0 * rise / largest,
        clock.elapsed().as_secs_f64()
    );
    Ok(())
}
