//! Project chores, run as `cargo xtask NAME` (matklad's xtask convention).
//!
//! - `ci`: what `.ci/run` runs (format check, clippy, docs, tests);
//! - `damping-table [--quick]`: measures every damping model with every
//!   integrator on the bundled scenes and writes `docs/damping-table.md`;
//! - `bench-report [--quick] [--mesh BASE]...`: speed, accuracy, scaling,
//!   memory, the machine's limits and real TetGen meshes,
//!   written to `docs/bench-report.md` (+ JSON and PNG figures);
//! - `cpp-compare --reference PATH [--quick] [--repeat N]`: pd against the C++ Eigen /
//!   CHOLMOD reference on the same TetGen meshes, written to
//!   `docs/cpp-comparison.md`;
//! - `stability [--quick] [--shard I/N [--out DIR] | --merge DIR]`: runs
//!   every integrator and damping model over a matrix of extreme parameters
//!   (or one shard of it; docs/tools.md) and writes `docs/stability.md`.

mod bench_contact;
mod bench_cpp;
mod bench_limits;
mod bench_methods;
mod bench_plot;
mod bench_report;
mod damping_table;
mod stability;
mod stability_contact;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("ci") => run_all(&[
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
        Some("damping-table") => report(damping_table::run(
            &workspace_root(),
            args.iter().any(|a| a == "--quick"),
        )),
        Some("bench-report") => {
            let root = workspace_root();
            // `--mesh BASE` (repeatable): TetGen meshes for the "Real meshes"
            // section; the shared armadillo by default.
            let mut meshes: Vec<PathBuf> = args
                .windows(2)
                .filter(|w| w[0] == "--mesh")
                .map(|w| PathBuf::from(&w[1]))
                .collect();
            if meshes.is_empty() {
                meshes = bench_limits::default_meshes(&root);
            }
            report(bench_report::run(
                &root,
                args.iter().any(|a| a == "--quick"),
                &meshes,
            ))
        }
        Some("cpp-compare") => report(bench_cpp::run(&workspace_root(), &args[1..])),
        Some("stability") => stability::main(&workspace_root(), &args[1..]),
        _ => {
            eprintln!(
                "usage: cargo xtask <task>\n\ntasks:\n  ci                        format check, clippy and docs (warnings are errors), all tests\n  damping-table [--quick]   measure every damping model, write docs/damping-table.md\n  bench-report [--quick] [--mesh BASE]...\n                            speed/accuracy/scaling/limits report: docs/bench-report.md\n  cpp-compare --reference PATH_TO_PDREF [--quick] [--repeat N] [--mesh BASE]...\n                            pd vs the C++ reference: docs/cpp-comparison.md\n  stability [--quick] [--shard I/N [--out DIR] | --merge DIR]\n                            run the matrix of extreme parameters (or one shard of it, or merge shards), write docs/stability.md (use --release)\n  stability --only contact  the contact axis alone (dev profile), write docs/stability-contact.md"
            );
            ExitCode::from(2)
        }
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
