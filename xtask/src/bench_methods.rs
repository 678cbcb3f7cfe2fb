//! The "Iteration methods" section of `cargo xtask bench-report`: error
//! against cost per step for each method of the `[solver]` table and each
//! integrator, with and without Laplacian damping, on the 2,304-vertex beam
//! and a larger one (`pd-probe methods`, `benches/src/methods.rs`).
//!
//! Error: the largest vertex distance to Newton's solution (relative
//! residual 1e-10 every step) after the run, over the body's diagonal.
//! Cost: `work` per step in plain-iteration equivalents (local-global
//! iterations plus objective evaluations times the local step's share of a
//! plain iteration), a deterministic proxy for time; the median wall time
//! per step is reported beside it and is only meaningful on a quiet
//! machine.

use std::fmt::Write as _;
use std::path::Path;

use pd_benches::schema::{Methods, MethodsRow};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::bench_plot::{self, Series};
use crate::bench_report::{json_text, typed};

/// One `pd-probe methods` run with the label of its mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodsRun {
    /// The mesh (`beam 2,304`).
    pub mesh: String,
    /// What the probe measured.
    #[serde(flatten)]
    pub run: Methods,
}

/// An optional number, NaN when it is missing (a run that stopped).
fn number(value: Option<f64>) -> f64 {
    value.unwrap_or(f64::NAN)
}

/// The meshes (cells of the beam, label) and steps of one mode.
fn plan(quick: bool) -> (Vec<([usize; 3], &'static str)>, usize) {
    if quick {
        (vec![([20, 4, 4], "beam 525")], 10)
    } else {
        (
            vec![([35, 7, 7], "beam 2,304"), ([50, 10, 10], "beam 6,171")],
            20,
        )
    }
}

/// The iteration budgets of plain PD and the accelerated methods: fine
/// enough below 20 that the speed-up (the least work reaching plain PD-20's
/// error) is not rounded to the next coarse budget (with 5 and 10 only,
/// Anderson's 2.2x at 8 iterations read as 1.8x).
const BUDGETS: &str = "2,3,4,5,6,8,10,12,15,20,30";

/// Runs every measurement through `probe` (one `pd-probe` process each).
///
/// # Errors
/// A probe that fails.
pub fn measure(
    probe: &dyn Fn(Vec<String>) -> Result<Value, String>,
    quick: bool,
) -> Result<Vec<MethodsRun>, String> {
    let (meshes, steps) = plan(quick);
    let mut runs = Vec::new();
    for (cells, label) in meshes {
        for damping in ["none", "laplacian"] {
            for integrator in pd_integrators::registry::short_names() {
                eprintln!("  methods: {label}, {integrator}, damping {damping}");
                let cells = format!("{},{},{}", cells[0], cells[1], cells[2]);
                let run = probe(
                    [
                        "methods",
                        "--cells",
                        &cells,
                        "--integrator",
                        integrator,
                        "--model",
                        damping,
                        "--steps",
                        &steps.to_string(),
                        "--threads",
                        "1",
                        "--budgets",
                        BUDGETS,
                        "--predicted",
                        &PREDICTED.join(","),
                    ]
                    .iter()
                    .map(|s| s.to_string())
                    .collect(),
                )?;
                runs.push(MethodsRun {
                    mesh: label.into(),
                    run: typed(run)?,
                });
            }
        }
    }
    Ok(runs)
}

/// A row's cost per step in plain-iteration equivalents.
fn work(row: &MethodsRow, local_fraction: f64) -> f64 {
    number(row.iterations_per_step) + number(row.evaluations_per_step) * local_fraction
}

/// The cheapest row of `method` whose error is at most `target`:
/// `(work, step_ms)`.
fn cheapest(
    rows: &[MethodsRow],
    method: &str,
    target: f64,
    local_fraction: f64,
) -> Option<(f64, f64)> {
    rows.iter()
        .filter(|r| r.method == method && number(r.position_error_rel) <= target)
        .map(|r| (work(r, local_fraction), number(r.step_ms_median)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

const METHODS: [&str; 5] = ["local-global", "anderson", "chebyshev", "lbfgs", "newton"];

/// The methods measured again with the linear predictor (`[solver]
/// predictor = "linear"`, docs/design/solver.md "A better start: predictors"), as
/// `pd-probe methods --predicted` names them; their rows are named
/// `anderson+linear`. Plain PD's shows what the start alone gains.
const PREDICTED: [&str; 4] = [
    "anderson:linear",
    "chebyshev:linear",
    "lbfgs:linear",
    "local-global:linear",
];

/// The section's Markdown.
pub fn markdown(runs: &[MethodsRun]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "## Iteration methods\n");
    let Some(first) = runs.first() else {
        return md;
    };
    let _ = writeln!(
        md,
        "Each method of `[solver]` (docs/design/solver.md) on the clamped beam, {} steps of {} s, 1 \
         thread, without damping and with Laplacian damping (the `laplacian` preset). Error: the \
         largest vertex distance to Newton's solution (relative residual {:e} every step) over the \
         diagonal. Work: cost per step in plain local-global iterations (iterations + objective \
         evaluations x the local step's share of an iteration), a deterministic proxy for time; \
         the median wall time per step is noisy unless the machine was quiet. Speed-up: the work \
         of plain PD with 20 iterations over the least work with which the method reaches the \
         same error or better (budgets {BUDGETS}; Newton 1, 2, 3, 5); Newton's \
         by time only, since its work leaves out the 3n x 3n factorisation of each iteration. \
         The last four columns start each step at the linear predictor `y + 2 c_n - c_(n-1)` \
         (`[solver] predictor = \"linear\"`, docs/design/solver.md) instead of the inertial target \
         `y`, against the same PD-20 (inertial) baseline; plain PD's column shows what the \
         start alone gains.\n",
        first.run.steps,
        json_text(first.run.dt),
        first.run.reference_tolerance,
    );
    let _ = writeln!(
        md,
        "| mesh | integrator | damping | error of PD-20 | anderson | chebyshev | lbfgs | newton \
         | anderson, linear predictor | chebyshev, linear predictor | lbfgs, linear predictor \
         | local-global, linear predictor |"
    );
    let _ = writeln!(
        md,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for run in runs {
        let rows = &run.run.rows;
        let fraction = run.run.local_fraction;
        let Some(plain) = rows
            .iter()
            .find(|r| r.method == "local-global" && r.budget == 20)
        else {
            continue;
        };
        let target = number(plain.position_error_rel);
        let base = work(plain, fraction);
        let mut cells = Vec::new();
        let base_ms = number(plain.step_ms_median);
        let predicted: Vec<String> = PREDICTED.iter().map(|p| p.replace(':', "+")).collect();
        let columns = METHODS[1..]
            .iter()
            .copied()
            .chain(predicted.iter().map(String::as_str));
        for method in columns {
            cells.push(match cheapest(rows, method, target, fraction) {
                // Newton's work leaves out its 3n x 3n factorisation per
                // iteration, which dominates: only its time compares.
                Some((_, ms)) if method == "newton" => {
                    format!("{:.2}x by time ({ms:.1} ms)", base_ms / ms)
                }
                Some((w, ms)) => format!("{:.1}x ({w:.1} it, {ms:.1} ms)", base / w),
                None => "not reached".into(),
            });
        }
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2e} ({:.1} ms) | {} |",
            run.mesh,
            run.run.integrator,
            run.run.damping,
            target,
            number(plain.step_ms_median),
            cells.join(" | ")
        );
    }
    let _ = writeln!(
        md,
        "\n![error against work per step](bench-report/methods.png)\n\n\
         Position error against work per step, one panel per integrator (first mesh, no \
         damping), one curve per method; each curve's points are its iteration budgets. The raw \
         rows (every mesh and damping, with wall times) are in `report.json` under `methods`.\n"
    );
    md
}

/// Writes `methods.png` into `dir`.
///
/// # Errors
/// A plot that cannot be written.
pub fn figure(dir: &Path, runs: &[MethodsRun]) -> Result<(), String> {
    let Some(mesh) = runs.first().map(|r| &r.mesh) else {
        return Ok(());
    };
    let mut panels: Vec<(String, Vec<Series>)> = Vec::new();
    for run in runs
        .iter()
        .filter(|r| &r.mesh == mesh && r.run.damping == "none")
    {
        let rows = &run.run.rows;
        let fraction = run.run.local_fraction;
        let series = METHODS
            .iter()
            .map(|&method| Series {
                name: method.to_string(),
                points: rows
                    .iter()
                    .filter(|r| r.method == method)
                    .map(|r| (work(r, fraction), number(r.position_error_rel)))
                    .collect(),
            })
            .collect();
        let name = run.run.integrator.to_uppercase();
        panels.push((format!("{name}: position error"), series));
    }
    let panels: Vec<(&str, &[Series])> = panels
        .iter()
        .map(|(label, series)| (label.as_str(), series.as_slice()))
        .collect();
    bench_plot::log_log(
        &dir.join("methods.png"),
        "Iteration methods: error against work per step",
        "work per step [plain iterations]",
        &panels,
    )
}
