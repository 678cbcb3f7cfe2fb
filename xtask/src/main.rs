//! Project chores, run as `cargo xtask NAME` (matklad's xtask convention).
//!
//! - `ci`: what `.ci/run` runs (format check, clippy, docs, tests);
//! - `damping-table [--quick]`: measures every damping model with every
//!   integrator on the bundled scenes and writes `docs/reports/damping-table.md`;
//! - `bench-report [--quick] [--mesh BASE]...`: speed, accuracy, scaling,
//!   memory, the machine's limits and real TetGen meshes,
//!   written to `docs/reports/bench-report.md` (+ JSON and PNG figures);
//! - `cpp-compare --reference PATH [--quick] [--repeat N]`: pd against the C++ Eigen /
//!   CHOLMOD reference on the same TetGen meshes, written to
//!   `docs/reports/cpp-comparison.md`;
//! - `stability [--quick] [--shard I/N [--out DIR] | --merge DIR]`: runs
//!   every integrator and damping model over a matrix of extreme parameters
//!   (or one shard of it; docs/reference/cli.md) and writes `docs/reports/stability.md`.
//!
//! Every task checks its options first ([`check_options`]); `--help`
//! prints them all.

mod bench_accuracy_target;
mod bench_contact;
mod bench_cpp;
mod bench_gradients;
mod bench_limits;
mod bench_methods;
mod bench_plot;
mod bench_python;
mod bench_report;
mod damping_table;
mod stability;
mod stability_contact;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

const USAGE: &str = "usage: cargo xtask <task>\n\ntasks:\n  ci                        format check, clippy and docs (warnings are errors), all tests\n  damping-table [--quick]   measure every damping model, write docs/reports/damping-table.md\n  bench-report [--quick] [--mesh BASE]...\n                            speed/accuracy/scaling/limits report: docs/reports/bench-report.md\n  bench-report --only SECTION[,SECTION]\n                            measure those sections again (python, gradients, accuracy-target, contact), keep the rest\n  cpp-compare --reference PATH_TO_PDREF [--quick] [--repeat N] [--mesh BASE]...\n                            pd vs the C++ reference: docs/reports/cpp-comparison.md\n  stability [--quick] [--shard I/N [--out DIR] | --merge DIR]\n                            run the matrix of extreme parameters (or one shard of it, or merge shards), write docs/reports/stability.md (use --release)\n  stability --only contact  the contact axis alone (dev profile), write docs/reports/stability-contact.md\n  stability --only methods [--integrator I] [--predictor P]\n                            the method axis (docs/reports/stability-methods.md)";

/// The options each task takes: those without a value, and those whose
/// value is the next argument.
fn task_options(task: &str) -> Option<(&'static [&'static str], &'static [&'static str])> {
    Some(match task {
        "ci" => (&[], &[]),
        "damping-table" => (&["--quick"], &[]),
        "bench-report" => (&["--quick"], &["--mesh", "--only"]),
        "cpp-compare" => (&["--quick"], &["--reference", "--repeat", "--mesh"]),
        "stability" => (
            &["--quick"],
            &[
                "--shard",
                "--out",
                "--merge",
                "--only",
                "--integrator",
                "--predictor",
            ],
        ),
        _ => return None,
    })
}

/// Checks `args` (after the task's name) against the task's options: an
/// option the task does not know, a stray value or a missing one is an
/// error that names it, so that a typo does not silently start a long
/// run with the defaults.
fn check_options(task: &str, args: &[String]) -> Result<(), String> {
    let (flags, valued) = task_options(task).ok_or_else(|| format!("unknown task {task:?}"))?;
    let mut rest = args.iter();
    while let Some(arg) = rest.next() {
        if flags.contains(&arg.as_str()) {
            continue;
        }
        if valued.contains(&arg.as_str()) {
            match rest.next() {
                Some(value) if !value.starts_with("--") => continue,
                _ => return Err(format!("{task}: {arg} needs a value")),
            }
        }
        return Err(if arg.starts_with('-') {
            format!("{task}: unknown option {arg}")
        } else {
            format!("{task}: unexpected argument {arg:?}")
        });
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "--help" || a == "-h") {
        println!("{USAGE}");
        return ExitCode::SUCCESS;
    }
    let Some(task) = args.first() else {
        eprintln!("{USAGE}");
        return ExitCode::from(2);
    };
    if let Err(e) = check_options(task, &args[1..]) {
        eprintln!("error: {e}\n\n{USAGE}");
        return ExitCode::from(2);
    }
    match task.as_str() {
        "ci" => run_all(&[
            &["fmt", "--all", "--", "--check"],
            &[
                "clippy",
                "--workspace",
                "--all-targets",
                "--",
                "-D",
                "warnings",
            ],
            &["doc", "--workspace", "--no-deps"],
            &["test", "--workspace"],
        ]),
        "damping-table" => report(damping_table::run(
            &workspace_root(),
            args.iter().any(|a| a == "--quick"),
        )),
        "bench-report" => {
            let root = workspace_root();
            // `--mesh BASE` (repeatable): TetGen meshes for the "Real meshes"
            // and "Speed against an accuracy target" sections; the shared
            // armadillo by default.
            let mut meshes: Vec<PathBuf> = args
                .windows(2)
                .filter(|w| w[0] == "--mesh")
                .map(|w| PathBuf::from(&w[1]))
                .collect();
            if meshes.is_empty() {
                meshes = bench_limits::default_meshes(&root);
            }
            // `--only a,b`: measure those sections again, keep the rest.
            if let Some(only) = args.windows(2).find(|w| w[0] == "--only") {
                let names: Vec<String> = only[1].split(',').map(str::to_string).collect();
                return report(bench_report::run_only(&root, &names, &meshes));
            }
            report(bench_report::run(
                &root,
                args.iter().any(|a| a == "--quick"),
                &meshes,
            ))
        }
        "cpp-compare" => report(bench_cpp::run(&workspace_root(), &args[1..])),
        "stability" => stability::main(&workspace_root(), &args[1..]),
        _ => unreachable!("check_options knows only the tasks above"),
    }
}

/// Prints where a report went, or the error: the ending of every task
/// that writes a report.
pub(crate) fn report(result: Result<PathBuf, String>) -> ExitCode {
    match result {
        Ok(path) => {
            eprintln!("wrote {}", path.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The workspace root: the parent of this crate's folder.
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives inside the workspace")
        .to_path_buf()
}

fn run_all(commands: &[&[&str]]) -> ExitCode {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    for args in commands {
        eprintln!("$ cargo {}", args.join(" "));
        let mut command = Command::new(&cargo);
        command.args(*args);
        if args.first() == Some(&"doc") {
            // Broken links and malformed docs are errors, as in `.ci/run`.
            command.env("RUSTDOCFLAGS", "-D warnings");
        }
        match command.status() {
            Ok(status) if status.success() => {}
            Ok(_) => return ExitCode::FAILURE,
            Err(e) => {
                eprintln!("cannot run {cargo}: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    ExitCode::SUCCESS
}

/// `list` as owned arguments, for the tests of argument parsing here and
/// in `stability/shard.rs`.
#[cfg(test)]
fn strings(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

#[cfg(test)]
mod tests {
    use super::{check_options, strings as args};

    #[test]
    fn known_options_pass() {
        assert!(
            check_options(
                "bench-report",
                &args(&["--quick", "--mesh", "a", "--mesh", "b"])
            )
            .is_ok()
        );
        assert!(
            check_options("cpp-compare", &args(&["--reference", "x", "--repeat", "3"])).is_ok()
        );
        assert!(check_options("stability", &args(&["--shard", "1/4", "--out", "d"])).is_ok());
        assert!(check_options("ci", &[]).is_ok());
    }

    #[test]
    fn unknown_options_typos_and_missing_values_are_errors_that_name_them() {
        let cases: [(&str, &[&str], &str); 6] = [
            ("bench-report", &["--quik"], "unknown option --quik"),
            ("stability", &["--bogus"], "unknown option --bogus"),
            ("cpp-compare", &["--reference"], "--reference needs a value"),
            (
                "bench-report",
                &["--mesh", "--quick"],
                "--mesh needs a value",
            ),
            ("damping-table", &["quick"], "unexpected argument \"quick\""),
            ("benchreport", &[], "unknown task \"benchreport\""),
        ];
        for (task, list, expected) in cases {
            let error = check_options(task, &args(list)).unwrap_err();
            assert!(error.contains(expected), "{task} {list:?}: {error}");
        }
    }
}
