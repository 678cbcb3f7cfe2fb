//! Project chores, run as `cargo xtask NAME` (matklad's xtask convention).
//!
//! Tasks: `ci` runs what `.ci/run` runs (format check, clippy, tests).

use std::process::{Command, ExitCode};

fn main() -> ExitCode {
    let task = std::env::args().nth(1);
    match task.as_deref() {
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
            &["test", "--workspace"],
        ]),
        _ => {
            eprintln!(
                "usage: cargo xtask <task>\n\ntasks:\n  ci    format check, clippy (warnings are errors), all tests"
            );
            ExitCode::from(2)
        }
    }
}

fn run_all(commands: &[&[&str]]) -> ExitCode {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    for args in commands {
        eprintln!("$ cargo {}", args.join(" "));
        match Command::new(&cargo).args(*args).status() {
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
