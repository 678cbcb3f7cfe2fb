//! The "Speed against an accuracy target" section of `cargo xtask
//! bench-report`: on four scenes, per iteration method, the step's
//! estimated error against its true error, what `accuracy = 1e-2` and
//! `1e-3` cost, and which method the automatic choice picks and how far
//! it is from the fastest (`pd-probe accuracy-target`,
//! `benches/src/accuracy_target.rs`).

use std::fmt::Write as _;
use std::path::PathBuf;

use pd_benches::schema::{
    AccuracyTarget, TRUE_ERROR_FLOOR, TargetMethod, TargetRun, TargetSummary,
};
use serde_json::Value;

use crate::bench_report::typed;

/// The accuracy targets measured.
const TARGETS: &str = "0.01,0.001";

/// The automatic choice's goal: its step at most this many times the
/// fastest method's.
const WITHIN: f64 = 1.25;

/// One scene of a mode: the probe's `--scene` and extra arguments, its
/// warm-up and measured steps.
struct Planned {
    args: Vec<String>,
    warmup: usize,
    steps: usize,
}

/// The scenes of the mode: the bench beam (the quick mode's smaller one),
/// the cloth strip, the first mesh of `meshes` (the armadillo) if any, the
/// contact stack. The mesh's steps are few: Newton (as a method and as
/// every step's reference) takes about a second a step on the armadillo.
fn plan(quick: bool, meshes: &[PathBuf]) -> Vec<Planned> {
    let strings = |list: &[&str]| list.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let cells = if quick { "20,4,4" } else { "35,7,7" };
    let (warmup, steps) = if quick { (2, 5) } else { (3, 20) };
    let mut plan = vec![
        Planned {
            args: strings(&["--scene", "beam", "--cells", cells]),
            warmup,
            steps,
        },
        Planned {
            args: strings(&["--scene", "strip"]),
            warmup,
            steps,
        },
    ];
    if let Some(mesh) = meshes.first() {
        plan.push(Planned {
            args: vec![
                "--scene".into(),
                "mesh".into(),
                "--mesh".into(),
                mesh.display().to_string(),
            ],
            warmup: if quick { 1 } else { 2 },
            steps: if quick { 2 } else { 4 },
        });
    }
    // The top cube lands at about step 20; the measured steps cover the
    // landing and the settling after it.
    plan.push(Planned {
        args: strings(&["--scene", "contact-stack"]),
        warmup: 10,
        steps: if quick { 20 } else { 60 },
    });
    plan
}

/// Runs `pd-probe accuracy-target` for every scene of the mode.
///
/// # Errors
/// A probe that fails.
pub fn measure(
    probe: &dyn Fn(Vec<String>) -> Result<Value, String>,
    quick: bool,
    meshes: &[PathBuf],
) -> Result<Vec<AccuracyTarget>, String> {
    let mut runs = Vec::new();
    for planned in plan(quick, meshes) {
        let mut args = vec!["accuracy-target".to_string()];
        args.extend(planned.args);
        args.extend([
            "--targets".into(),
            TARGETS.into(),
            "--warmup".into(),
            planned.warmup.to_string(),
            "--steps".into(),
            planned.steps.to_string(),
        ]);
        runs.push(typed(probe(args)?)?);
    }
    Ok(runs)
}

/// A table's header row and rule: `scene | target` and then `columns`.
fn head(md: &mut String, columns: &[&str]) {
    let _ = writeln!(md, "| scene | target | {} |", columns.join(" | "));
    let _ = writeln!(md, "|{}", " --- |".repeat(columns.len() + 2));
}

/// Every method of every target of every scene, in order.
fn rows(
    runs: &[AccuracyTarget],
) -> impl Iterator<Item = (&AccuracyTarget, &TargetRun, &TargetMethod)> {
    runs.iter().flat_map(|run| {
        run.targets
            .iter()
            .flat_map(move |target| target.methods.iter().map(move |m| (run, target, m)))
    })
}

/// `k of n`.
fn of(k: usize, n: usize) -> String {
    format!("{k} of {n}")
}

/// `n steps` (`1 step`).
fn steps(n: usize) -> String {
    format!("{n} step{}", if n == 1 { "" } else { "s" })
}

/// A relative error as the tables write it.
fn error(value: f64) -> String {
    if value.is_nan() {
        "n/a".into()
    } else if value == 0.0 {
        // The method's step is the reference's, bit for bit.
        "0".into()
    } else {
        format!("{value:.2e}")
    }
}

/// The fastest method of a target: the smallest median step among the
/// methods whose estimate met the target on every measured step (among
/// all that ran if none did): `(method, summary)`.
fn fastest(run: &TargetRun) -> Option<(&str, TargetSummary)> {
    let ran: Vec<(&str, TargetSummary)> = run
        .methods
        .iter()
        .filter(|m| m.error.is_none())
        .filter_map(|m| Some((m.method.as_str(), m.summary(run.target)?)))
        .collect();
    let met: Vec<_> = ran
        .iter()
        .copied()
        .filter(|(_, s)| s.met_target == s.steps)
        .collect();
    let pool = if met.is_empty() { ran } else { met };
    pool.into_iter()
        .min_by(|a, b| a.1.step_ms_median.total_cmp(&b.1.step_ms_median))
}

/// The chosen method's summary at a target.
fn chosen(run: &TargetRun) -> Option<TargetSummary> {
    let method = run.methods.iter().find(|m| m.method == run.choice.chosen)?;
    method.summary(run.target)
}

/// The probe's mean time a step of `method`, if it measured one (ms).
fn probe_ms(run: &TargetRun, method: &str) -> Option<f64> {
    run.choice
        .candidates
        .iter()
        .find(|c| c.method == method)
        .and_then(|c| c.step_ms)
}

/// The section's Markdown.
/// `note` (from `bench_report::remeasured_note`) goes under the heading.
pub fn markdown(runs: &[AccuracyTarget], note: &str) -> String {
    let mut md = String::from("## Speed against an accuracy target\n\n");
    if runs.is_empty() {
        return md;
    }
    md.push_str(note);
    let _ = writeln!(
        md,
        "With `[simulation] accuracy = e` each step iterates until its own estimate of its \
         relative error (`StepStats::estimated_error`, an estimate of `|x - x*|_M / |y - x*|_M`, \
         `x*` the exact minimiser of the step objective, `y` the inertial prediction) is at most \
         `e`, `iterations` (here {}) being the cap; with no method named, \
         `Simulation::choose_method` picks the fastest by a timed probe of 3 steps from the \
         initial state (docs/design/solver.md, \"How far from converged\" and \"Choosing a \
         method by measurement\"). Measured here per method (`pd-probe accuracy-target`, \
         `benches/src/accuracy_target.rs`), 1 thread, on these scenes:\n",
        runs[0].iteration_cap
    );
    for run in runs {
        let _ = writeln!(
            md,
            "- **{}** ({} vertices): {}; warm-up {}, then {} measured steps per method and \
             target; reference: {} to a relative residual of {:e} ({} of its steps above it, \
             median {} iterations).",
            run.scene,
            run.n_verts,
            run.description,
            steps(run.warmup),
            run.steps,
            run.reference_method,
            run.reference_tolerance,
            run.reference_unconverged_steps,
            run.reference_iterations_median
        );
    }
    let _ = writeln!(
        md,
        "\nEvery method that can run the scene runs it named, with its default parameters, \
         from rest; after the warm-up the methods' measured steps run in rounds of {} steps \
         per method in turn, in one process, so that drift in the machine's speed hits all \
         alike. Step time: the median of `StepStats::total_seconds` over the measured steps. \
         True error: each measured step solved again from the same state (the same \
         integrator, damping and `y`) by the reference, `|x - x*|_M / |y - x*|_M` with `x` \
         and `x*` taken before any collider's projection. Only local-global runs colliders, so \
         the contact scene has one method and a local-global reference. The section's \
         measurements took {:.0} s.\n",
        pd_benches::accuracy_target::ROUND,
        runs.iter().map(|r| r.wall_seconds).sum::<f64>()
    );

    let _ = writeln!(md, "### The estimate against the true error\n");
    let _ = writeln!(
        md,
        "Ratio estimate / truth per measured step, over the steps whose true error is above \
         {TRUE_ERROR_FLOOR:e} (below, the reference's own error counts; Newton's steps mostly \
         end there). Below 1 the step under-reports its error: it stops believing itself \
         within the target when it is not.\n"
    );
    head(
        &mut md,
        &[
            "method",
            "steps compared",
            "median ratio",
            "smallest",
            "largest",
            "below 1",
            "below 0.5",
        ],
    );
    let ratio = |r: f64| {
        if r.is_nan() {
            "n/a".to_string()
        } else {
            format!("{r:.2}")
        }
    };
    for (run, target, method) in rows(runs) {
        let Some(s) = method.summary(target.target) else {
            continue;
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            run.scene,
            target.target,
            method.method,
            of(s.compared, s.steps),
            ratio(s.ratio_median),
            ratio(s.ratio_min),
            ratio(s.ratio_max),
            s.below_one,
            s.below_half
        );
    }

    let _ = writeln!(md, "\n### What a target costs\n");
    let _ = writeln!(
        md,
        "Median step time and iterations (Newton: Newton iterations) over the measured steps; \
         the true error the steps achieved; on how many steps the estimate met the target \
         within the cap, and on how many the true error did.\n"
    );
    head(
        &mut md,
        &[
            "method",
            "step [ms]",
            "iterations",
            "true error, median",
            "true error, largest",
            "estimate met the target",
            "true error within it",
        ],
    );
    for (run, target, method) in rows(runs) {
        let failed =
            (method.error.as_deref()).map_or(String::new(), |e| format!(" (stopped: {e})"));
        let Some(s) = method.summary(target.target) else {
            if !failed.is_empty() {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | failed{failed} | | | | | |",
                    run.scene, target.target, method.method
                );
            }
            continue;
        };
        let _ = writeln!(
            md,
            "| {} | {} | {}{failed} | {:.2} | {} | {} | {} | {} | {} |",
            run.scene,
            target.target,
            method.method,
            s.step_ms_median,
            s.iterations_median,
            error(s.true_error_median),
            error(s.true_error_max),
            of(s.met_target, s.steps),
            of(s.true_within_target, s.steps)
        );
    }
    for run in runs {
        let excluded: Vec<&str> = run
            .targets
            .first()
            .map(|t| {
                t.methods
                    .iter()
                    .filter(|m| m.excluded.is_some())
                    .map(|m| m.method.as_str())
                    .collect()
            })
            .unwrap_or_default();
        if !excluded.is_empty() {
            let _ = writeln!(
                md,
                "\n{}: {} cannot run the scene (refused when it is built; each reason is in \
                 `report.json`).",
                run.scene,
                excluded.join(", ")
            );
        }
    }

    md.push_str(&choice_markdown(runs));
    md
}

/// The automatic choice's table and its verdict.
fn choice_markdown(runs: &[AccuracyTarget]) -> String {
    let mut md = String::from("\n### The automatic choice\n\n");
    let _ = writeln!(
        md,
        "`Simulation::choose_method` at each target from the scene's initial state, as \
         building the scene runs it, timed whole (probe). A run that chose a method continues \
         bit for bit as one naming it, so the chosen method's step time is its named run's \
         above; fastest: the method with the smallest median step among those whose estimate \
         met the target on every measured step (among all if none did). Goal: the automatic \
         choice within {WITHIN}x of the fastest.\n"
    );
    head(
        &mut md,
        &[
            "chosen",
            "probe [ms]",
            "fastest",
            "chosen step [ms]",
            "fastest step [ms]",
            "auto / fastest",
            &format!("within {WITHIN}x"),
        ],
    );
    let mut verdicts = Vec::new();
    let mut misses = Vec::new();
    for run in runs {
        for target in &run.targets {
            let (Some((fast, f)), Some(c)) = (fastest(target), chosen(target)) else {
                continue;
            };
            let ratio = c.step_ms_median / f.step_ms_median;
            let ok = ratio <= WITHIN;
            verdicts.push(ok);
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.0} | {fast} | {:.2} | {:.2} | {ratio:.2} | {} |",
                run.scene,
                target.target,
                target.choice.chosen,
                target.choice.probe_ms,
                c.step_ms_median,
                f.step_ms_median,
                if ok { "yes" } else { "**no**" }
            );
            if !ok {
                misses.push(miss(run, target, fast, f, c, ratio));
            }
        }
    }
    let within = verdicts.iter().filter(|ok| **ok).count();
    let _ = writeln!(
        md,
        "\nThe automatic choice is within {WITHIN}x of the fastest method on {} scene and \
         target pairs.",
        of(within, verdicts.len())
    );
    for line in misses {
        let _ = writeln!(md, "\n{line}");
    }
    let _ = writeln!(
        md,
        "\nThe probe's own line for every candidate is in `report.json` under \
         `accuracy_target` (`choice.candidates`).\n"
    );
    md
}

/// Why the choice missed at one target: the probe's figures beside the
/// measured steps'.
fn miss(
    run: &AccuracyTarget,
    target: &TargetRun,
    fast: &str,
    f: TargetSummary,
    c: TargetSummary,
    ratio: f64,
) -> String {
    let chosen = &target.choice.chosen;
    let probe = |method: &str| {
        probe_ms(target, method).map_or("was stopped or not kept".into(), |ms| {
            format!("took {ms:.2} ms a step")
        })
    };
    format!(
        "{} at {}: chose {chosen}, {ratio:.2}x the fastest, {fast}. In the probe (the 2 \
         timed steps after the first, from rest) {chosen} {} and {fast} {}; over the measured \
         steps after the warm-up {chosen} takes {:.2} ms a step ({} iterations) and {fast} \
         {:.2} ms ({} iterations).",
        run.scene,
        target.target,
        probe(chosen),
        probe(fast),
        c.step_ms_median,
        c.iterations_median,
        f.step_ms_median,
        f.iterations_median
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use pd_benches::schema::{TargetCandidate, TargetChoice};

    fn method(name: &str, step_ms: f64, met: bool) -> TargetMethod {
        TargetMethod {
            method: name.into(),
            excluded: None,
            error: None,
            step_ms: vec![step_ms; 3],
            iterations: vec![4; 3],
            met_target: vec![met; 3],
            estimated_error: vec![0.005; 3],
            true_error: vec![0.004; 3],
        }
    }

    fn candidate(name: &str, step_ms: Option<f64>) -> TargetCandidate {
        TargetCandidate {
            method: name.into(),
            outcome: if step_ms.is_some() {
                "measured"
            } else {
                "slower"
            }
            .into(),
            step_ms,
            iterations: step_ms.map(|_| 4.0),
            text: String::new(),
        }
    }

    /// A choice 1.5x the fastest is reported as a miss with the probe's
    /// figures; a method that missed the target is not the fastest even
    /// when its steps are quicker.
    #[test]
    fn a_slow_choice_is_reported_with_its_probe() {
        let run = AccuracyTarget {
            scene: "beam 20".into(),
            targets: vec![TargetRun {
                target: 0.01,
                choice: TargetChoice {
                    chosen: "chebyshev".into(),
                    measured: true,
                    probe_ms: 12.0,
                    candidates: vec![
                        candidate("chebyshev", Some(1.0)),
                        candidate("anderson", None),
                    ],
                },
                methods: vec![
                    method("local-global", 0.5, false),
                    method("anderson", 2.0, true),
                    method("chebyshev", 3.0, true),
                    TargetMethod::excluded("newton", "no".into()),
                ],
            }],
            ..AccuracyTarget::default()
        };
        let md = markdown(&[run], "");
        assert!(
            md.contains(
                "| beam 20 | 0.01 | chebyshev | 12 | anderson | 3.00 | 2.00 | 1.50 | **no** |"
            ),
            "{md}"
        );
        assert!(md.contains("on 0 of 1 scene and target pairs"), "{md}");
        assert!(
            md.contains("chebyshev took 1.00 ms a step and anderson was stopped"),
            "{md}"
        );
        assert!(md.contains("beam 20: newton cannot run the scene"), "{md}");
    }
}
