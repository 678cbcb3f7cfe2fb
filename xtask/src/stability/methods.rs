//! `cargo xtask stability --only methods`: the stability map's method axis.
//! Runs every iteration method (local-global as the baseline,
//! anderson, chebyshev, lbfgs, newton) over a reduced stability matrix and
//! writes `docs/reports/stability-methods.md`: for each method, how its runs ended
//! (completed sane, energy created, diverged, bug: the headings of
//! `stability.rs`), and every case where it ended worse than plain PD with
//! the same budget (completed sane, then energy created, then diverged or
//! a bug).
//!
//! Reduced matrix (the full one is ~74,000 runs per method): every
//! integrator; damping `none`, `laplacian` and `ether-drag` (`rayleigh-lagged`
//! is refused by lbfgs and newton by design, and the explicit filters do not
//! enter the step objective); stiffness 1, 1e6, 1e9 Pa; dt 1e-5, 0.1 s;
//! density 1, 1e5 kg/m^3; coefficient 1e3; iterations 10, 200; every start;
//! the beam and the cloth. Runs in the profile it was built in (no release
//! re-run), on one thread per run, sequentially: 8,640 runs (1,728 per
//! method), about 35 min in the dev profile.
//!
//! `--integrator NAME` (`backward-euler`, `implicit-midpoint`, `bdf2`) runs
//! that integrator's third of the matrix only and writes
//! `docs/reports/stability-methods-NAME.md` instead, leaving the whole axis' report
//! alone.
//!
//! `--predictor NAME` (`extrapolated`, `linear`; docs/design/solver.md "A
//! better start: predictors") runs local-global, anderson, chebyshev and lbfgs
//! with that predictor against the baseline of plain PD started at the inertial
//! target, and writes `docs/reports/stability-methods-predictor-NAME[-INTEGRATOR].md`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use pd_io::scene::IntegratorKind;
use pd_solver::{Predictor, SolverMethod};

use super::{Body, Case, Ending, Start, Tally, presets, run_case};

/// The damping presets of the method axis, by name.
const MODELS: [&str; 3] = ["none", "laplacian", "ether-drag"];

/// The axis' cases of `method` started by `predictor`, for `integrators`.
fn cases(
    (method, predictor): (SolverMethod, Predictor),
    integrators: &[IntegratorKind],
) -> Vec<Case> {
    let mut cases = Vec::new();
    for &integrator in integrators {
        for (model, preset) in presets().iter().enumerate() {
            if !MODELS.contains(&preset.name) {
                continue;
            }
            for stiffness in [1e0, 1e6, 1e9] {
                for dt in [1e-5, 0.1] {
                    for density in [1.0, 1e5] {
                        for iterations in [10, 200] {
                            for start in Start::ALL {
                                for body in [Body::Beam, Body::Cloth] {
                                    cases.push(Case {
                                        integrator,
                                        model,
                                        stiffness,
                                        dt,
                                        density,
                                        coefficient: 1e3,
                                        iterations,
                                        start,
                                        body,
                                        method,
                                        predictor,
                                    });
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    cases
}

/// How well a run ended, for comparing a method with plain PD: completed
/// sane (2) above energy created (1) above stopped by the divergence
/// check or a bug (0).
fn rank(ending: &Ending) -> u8 {
    if ending.sane() {
        2
    } else if ending.created_energy() {
        1
    } else {
        0
    }
}

/// How a run ended, as a report's table cell.
fn describe(ending: &Ending) -> String {
    match ending {
        Ending::Diverged { step, reason } => format!("diverged at step {step}: {reason}"),
        Ending::Bug(e) => format!("bug: {e}"),
        Ending::Completed {
            energy: Some(energy),
            ..
        } if ending.created_energy() => format!(
            "energy created: {:.2}% of its largest kinetic plus elastic energy",
            100.0 * energy.fraction()
        ),
        Ending::Completed { .. } => "completed sane".into(),
    }
}

/// The predictor `--predictor NAME` in `args` selects (inertial without
/// it).
fn predictor(args: &[String]) -> Result<Predictor, String> {
    let Some(i) = args.iter().position(|a| a == "--predictor") else {
        return Ok(Predictor::Inertial);
    };
    let name = args.get(i + 1).map_or("", String::as_str);
    Predictor::parse(name).ok_or_else(|| {
        format!("--predictor: expected one of inertial, extrapolated, linear, got \"{name}\"")
    })
}

/// The integrators `--integrator NAME` in `args` selects (all without it),
/// and the report's path (`stem` = `stability-methods` or, with a
/// predictor, `stability-methods-predictor-NAME`).
fn selection(
    root: &Path,
    args: &[String],
    stem: &str,
) -> Result<(Vec<IntegratorKind>, PathBuf), String> {
    match args.iter().position(|a| a == "--integrator") {
        None => Ok((
            IntegratorKind::ALL.to_vec(),
            root.join(format!("docs/reports/{stem}.md")),
        )),
        Some(i) => {
            let name = args.get(i + 1).map_or("", String::as_str);
            let kind = IntegratorKind::parse(name).ok_or_else(|| {
                format!(
                    "--integrator: expected one of {}, got \"{name}\"",
                    pd_integrators::registry::names().join(", ")
                )
            })?;
            Ok((
                vec![kind],
                root.join(format!("docs/reports/{stem}-{name}.md")),
            ))
        }
    }
}

/// Runs the axis (or the integrators `--integrator` selects) and writes the
/// report.
pub(super) fn run(root: &Path, args: &[String]) -> Result<PathBuf, String> {
    let predictor = predictor(args)?;
    let stem = match predictor {
        Predictor::Inertial => "stability-methods".to_string(),
        p => format!("stability-methods-predictor-{}", p.name()),
    };
    let (integrators, path) = selection(root, args, &stem)?;
    let started = Instant::now();
    let plain = (SolverMethod::LocalGlobal, Predictor::Inertial);
    let baseline: Vec<Ending> = cases(plain, &integrators).iter().map(run_case).collect();
    let variants: Vec<(SolverMethod, Predictor)> = match predictor {
        Predictor::Inertial => SolverMethod::ALL.map(|m| (m, predictor)).to_vec(),
        p => [
            SolverMethod::LocalGlobal,
            SolverMethod::Anderson,
            SolverMethod::Chebyshev,
            SolverMethod::Lbfgs,
        ]
        .map(|m| (m, p))
        .to_vec(),
    };
    let mut out = String::new();
    let mut rows = String::new();
    let mut worse = String::new();
    let mut worse_count = 0;
    for (method, predictor) in variants {
        let cases = cases((method, predictor), &integrators);
        let name = match predictor {
            Predictor::Inertial => method.name().to_string(),
            p => format!("{} ({})", method.name(), p.name()),
        };
        let endings: Vec<Ending> = if (method, predictor) == plain {
            baseline.clone()
        } else {
            cases.iter().map(run_case).collect()
        };
        let mut tally = Tally::default();
        for (case, (ending, plain)) in cases.iter().zip(endings.iter().zip(&baseline)) {
            tally.add(ending);
            if rank(ending) < rank(plain) {
                worse_count += 1;
                let _ = writeln!(
                    worse,
                    "| {name} | {} | {} | {} |",
                    case.cells(),
                    describe(plain),
                    describe(ending)
                );
            }
        }
        let _ = writeln!(
            rows,
            "| {name} | {} | {} | {} | {} | {} | {} |",
            tally.runs, tally.sane, tally.created, tally.inverted, tally.diverged, tally.bugs
        );
    }
    let seconds = started.elapsed().as_secs_f64();
    let machine = crate::bench_report::machine();
    let (mut title, mut command, which) = if integrators.len() == IntegratorKind::ALL.len() {
        (String::new(), String::new(), "every integrator".to_string())
    } else {
        let names: Vec<&str> = integrators.iter().map(|k| k.name()).collect();
        let names = names.join(", ");
        (
            format!(", {names} only"),
            format!(" --integrator {names}"),
            format!("integrator {names} only (the whole axis: docs/reports/stability-methods.md)"),
        )
    };
    if predictor != Predictor::Inertial {
        title = format!(", predictor {}{title}", predictor.name());
        command = format!(" --predictor {}{command}", predictor.name());
    }
    let _ = writeln!(
        out,
        "# Stability map: the method axis{title}\n\n\
         Generated by `cargo xtask stability --only methods{command}` \
         (xtask/src/stability/methods.rs; \
         {profile} profile, one thread per run, {seconds:.0} s on a machine shared with other \
         builds). Each iteration method over a reduced stability matrix (docs/reports/stability.md for \
         the rules): {which}; damping `none`, `laplacian`, `ether-drag` (coefficient \
         1e3); stiffness 1, 1e6, 1e9 Pa; dt 1e-5, 0.1 s; density 1, 1e5 kg/m^3; 10 and 200 \
         iterations; every start (rest, inverted, compressed, fast); the clamped beam and the \
         pinned cloth; 100 steps. `rayleigh-lagged` is left out: lbfgs and newton refuse it by \
         design (docs/design/solver.md). CPU {cpu} with {cores} logical cores.\n\n\
         {rule} \"Completed with inverted elements\" counts the completed runs, sane or not, \
         that ended with an element inside out.\n\n\
         | method | runs | completed sane | energy created | completed with inverted elements \
         | stopped by the divergence check | bugs |\n|---|---|---|---|---|---|---|\n{rows}\n\
         ## Where a method does worse than plain PD\n\n\
         Cases where the method ended worse than plain local-global PD with the same budget \
         (completed sane, then energy created, then stopped by the divergence check or a bug): \
         {worse_count}.\n",
        profile = super::profile_name(),
        cpu = machine.cpu,
        rule = super::energy_rule(),
        cores = machine.logical_cores,
    );
    if predictor != Predictor::Inertial {
        let _ = writeln!(
            out,
            "\nWith the predictor (docs/design/solver.md, \"A better start: predictors\"): local-global, anderson, \
             chebyshev and lbfgs start each step from the `{}` predictor; the baseline (`local-global`) \
             starts at the inertial target, as by default.",
            predictor.name()
        );
    }
    if worse_count > 0 {
        let _ = writeln!(
            out,
            "\n| method | {} | plain PD | the method |\n|{}---|---|---|\n{worse}",
            Case::COLUMNS,
            "---|".repeat(Case::COLUMN_COUNT)
        );
    }
    std::fs::write(&path, out).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}
