//! The "Gradients" section of the bench report: what a gradient through a
//! whole run costs by the adjoint method (`pd_adjoint`), against its
//! converged forward run, against finite differences (one or two forward
//! runs per scalar) and against a Newton-based adjoint, on the bench beam
//! (`benches/examples/adjoint_cost.rs --json`, release build, one thread).

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use serde::{Deserialize, Serialize};

/// One run of the example, as it prints it with `--json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GradientCost {
    /// Vertices of the beam.
    pub vertices: usize,
    /// Steps of the run.
    pub steps: usize,
    /// The integrator's short name.
    pub integrator: String,
    /// The forward run's iteration method.
    pub forward_method: String,
    /// Scalar parameters of the gradient.
    pub scalars: usize,
    /// Repeats (minimum kept).
    pub repeats: usize,
    /// The bench's own unconverged run of the same steps, s.
    pub plain_s: f64,
    /// Its local-global iterations per step.
    pub plain_iterations: usize,
    /// The converged forward run, s.
    pub forward_s: f64,
    /// Its iterations over all steps.
    pub forward_iterations: usize,
    /// The backward pass, s.
    pub backward_s: f64,
    /// Conjugate-gradient iterations of the backward pass, all steps.
    pub adjoint_iterations: usize,
    /// Load average after the run.
    pub load_after: String,
}

/// Runs the example for each forward method (Anderson, the default, and
/// Newton) on the bench beam.
pub fn measure(root: &Path, quick: bool) -> Result<Vec<GradientCost>, String> {
    let (steps, repeats) = if quick { ("4", "1") } else { ("10", "3") };
    let mut runs = Vec::new();
    for method in ["anderson", "newton"] {
        let output = Command::new(env!("CARGO"))
            .current_dir(root)
            .args([
                "run",
                "--release",
                "--quiet",
                "-p",
                "pd-benches",
                "--example",
                "adjoint_cost",
                "--",
                "--json",
                "--steps",
                steps,
                "--repeats",
                repeats,
                "--forward",
                method,
            ])
            .output()
            .map_err(|e| format!("cargo run --example adjoint_cost: {e}"))?;
        let stdout = String::from_utf8_lossy(&output.stdout);
        if !output.status.success() {
            return Err(format!(
                "adjoint_cost --forward {method} failed: {}",
                String::from_utf8_lossy(&output.stderr).trim()
            ));
        }
        let last = stdout.lines().last().unwrap_or("");
        runs.push(
            serde_json::from_str(last)
                .map_err(|e| format!("adjoint_cost printed bad JSON ({e}): {last}"))?,
        );
    }
    Ok(runs)
}

/// The report's Markdown section; `note` (possibly empty) goes under its
/// heading.
pub fn markdown(runs: &[GradientCost], note: &str) -> String {
    let mut md = String::from("## Gradients through a run\n\n");
    md.push_str(note);
    let Some(first) = runs.first() else {
        md.push_str("Not measured.\n\n");
        return md;
    };
    let _ = writeln!(
        md,
        "The bench beam ({} vertices), {} steps of {} with Laplacian damping from an upward \
         swing, one thread, release build; the gradient of a loss on the free end's positions \
         with respect to `a2`, the strain stiffness, the density and gravity ({} scalars) by \
         `pd_adjoint::loss_and_gradient` (`benches/examples/adjoint_cost.rs`, minimum of {} \
         repeats). The forward run is converged to 1e-10 by the method named; finite \
         differences cost one (one-sided) or two (central) such runs per scalar.\n",
        first.vertices, first.steps, first.integrator, first.scalars, first.repeats
    );
    let _ = writeln!(
        md,
        "| forward method | forward [s] | iterations a step | backward [s] | backward / forward | \
         finite differences, one-sided / central [s] | FD / adjoint |"
    );
    let _ = writeln!(md, "| --- | --- | --- | --- | --- | --- | --- |");
    for r in runs {
        let adjoint = r.forward_s + r.backward_s;
        let one_sided = r.scalars as f64 * r.forward_s;
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.1} | {:.3} | {:.2} | {:.2} / {:.2} | {:.1}x / {:.1}x |",
            r.forward_method,
            r.forward_s,
            r.forward_iterations as f64 / r.steps as f64,
            r.backward_s,
            r.backward_s / r.forward_s,
            one_sided,
            2.0 * one_sided,
            one_sided / adjoint,
            2.0 * one_sided / adjoint
        );
    }
    if let Some(newton) = runs.iter().find(|r| r.forward_method == "newton") {
        // A Newton-based adjoint factorises and solves each step's Hessian
        // once: the cost of one of the forward Newton run's iterations
        // (which does the same work) per step.
        let per_iteration = newton.forward_s / newton.forward_iterations.max(1) as f64;
        let newton_adjoint = per_iteration * newton.steps as f64;
        let _ = writeln!(
            md,
            "\nA Newton-based adjoint (one factorisation and solve of each step's Hessian, priced \
             at one iteration of the forward Newton run: {:.1} ms) would take {:.3} s; the \
             backward pass here takes {:.2} times that. The bench's own unconverged run \
             ({} local-global iterations a step) takes {:.3} s.\n",
            1e3 * per_iteration,
            newton_adjoint,
            first.backward_s / newton_adjoint,
            first.plain_iterations,
            first.plain_s
        );
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_section_states_the_ratios_from_the_examples_json() {
        let run = |method: &str, forward_s: f64, iterations: usize| GradientCost {
            vertices: 2304,
            steps: 10,
            integrator: "be".into(),
            forward_method: method.into(),
            scalars: 6,
            repeats: 3,
            plain_s: 0.1,
            plain_iterations: 10,
            forward_s,
            forward_iterations: iterations,
            backward_s: 0.3,
            adjoint_iterations: 160,
            load_after: "0.5 0.5 0.5".into(),
        };
        let md = markdown(&[run("anderson", 0.2, 166), run("newton", 1.8, 59)], "");
        // Anderson: backward / forward 1.5; FD one-sided 6 x 0.2 = 1.2 s,
        // over the adjoint's 0.5 s: 2.4x.
        assert!(
            md.contains("| anderson | 0.200 | 16.6 | 0.300 | 1.50 | 1.20 / 2.40 | 2.4x / 4.8x |"),
            "{md}"
        );
        // Newton: 1.8 s / 59 iterations = 30.5 ms, times 10 steps.
        assert!(md.contains("30.5 ms) would take 0.305 s"), "{md}");
    }
}
