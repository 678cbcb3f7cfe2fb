//! The "Contact" section of `cargo xtask bench-report`: step time with
//! contact against the same scene without any, at equal iterations
//! (`pd-probe contact`, `benches/src/contact.rs`); target at most 1.5x.

use std::fmt::Write as _;

use pd_benches::schema::Contact;
use serde_json::Value;

use crate::bench_report::typed;

/// Runs `pd-probe contact` for the cube sizes of the mode.
///
/// # Errors
/// A probe that fails.
pub fn measure(
    probe: &dyn Fn(Vec<String>) -> Result<Value, String>,
    quick: bool,
) -> Result<Vec<Contact>, String> {
    let sides: &[usize] = if quick { &[4] } else { &[4, 8] };
    let steps = if quick { "40" } else { "100" };
    let mut runs = Vec::new();
    for side in sides {
        let args = [
            "contact",
            "--side-cells",
            &side.to_string(),
            "--steps",
            steps,
        ];
        runs.push(typed(probe(args.iter().map(|a| a.to_string()).collect())?)?);
    }
    Ok(runs)
}

/// The section's markdown; `note` (from `bench_report::remeasured_note`)
/// goes under the heading.
pub fn markdown(contact: &[Contact], note: &str) -> String {
    let mut md = String::from("## Contact\n\n");
    md.push_str(note);
    md.push_str(
        "Median step time with contact against the same scene with no contact at all (the \
         body then falls freely: same matrix, same 20 iterations, no contact work), backward \
         Euler, 1 thread: a 0.2 m cube resting on a floor plane, and two stacked on it with \
         `contact.bodies = true` (`benches/src/contact.rs`). The two scenes run in alternating \
         rounds of 10 steps in one process, so that both see the same machine; the last column \
         is the ratio of each scene's fastest round (the round least disturbed by the machine). \
         Target: at most 1.5x. `docs/design/contact.md` has load-independent instruction \
         counts.\n\n\
         | scene | vertices per cube | contacts | without (ms) | with (ms) | ratio of medians | ratio of fastest rounds |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for run in contact {
        for row in &run.rows {
            let cells = row.cells + 1;
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.3} | {:.3} | {:.2}x | {:.2}x |",
                row.scene,
                cells * cells * cells,
                row.contacts,
                row.without_ms,
                row.with_ms,
                row.ratio,
                row.min_round_ratio,
            );
        }
    }
    md.push('\n');
    md
}
