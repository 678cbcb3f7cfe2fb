//! The "Python" section of the bench report: what a `projdyn` `step(1)`
//! call costs beyond the step itself, measured by
//! `python/benchmarks/step_overhead.py` (one call per step against one call
//! for 100 steps, same scene, same process).
//!
//! The interpreter is `$PD_PYTHON`, else `python3`; the section records why
//! it was not measured when that interpreter cannot import `projdyn`
//! (install it with `pip install ./python` in the environment first).

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use serde::{Deserialize, Serialize};

/// One measurement, as the script prints it with `--json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PythonOverhead {
    /// The scene's file name.
    pub scene: String,
    /// Steps per timed run.
    pub steps: usize,
    /// Timed runs per variant (the median is kept).
    pub repeats: usize,
    /// The interpreter's version.
    pub python: String,
    /// Time per step with one `step(1)` call per step, microseconds.
    pub step1_us: f64,
    /// Time per step with one `step(steps)` call, microseconds.
    pub batched_us: f64,
}

/// The section's content: a measurement, or why there is none.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum PythonSection {
    /// Measured.
    Measured(PythonOverhead),
    /// Not measured, and why.
    Skipped(String),
}

/// Runs the script with `$PD_PYTHON` (else `python3`), `repeats` timed
/// runs per variant.
pub fn measure(root: &Path, repeats: usize) -> PythonSection {
    let python = std::env::var("PD_PYTHON").unwrap_or_else(|_| "python3".into());
    measure_with(&python, root, repeats)
}

/// Runs the script with the interpreter `python`.
fn measure_with(python: &str, root: &Path, repeats: usize) -> PythonSection {
    let script = root.join("python/benchmarks/step_overhead.py");
    let output = Command::new(python)
        .current_dir(root)
        .arg(&script)
        .args(["--repeats", &repeats.to_string(), "--json"])
        .output();
    let output = match output {
        Ok(output) => output,
        Err(e) => return PythonSection::Skipped(format!("cannot run `{python}`: {e}")),
    };
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let last = stderr.lines().last().unwrap_or("no message").trim();
        return PythonSection::Skipped(format!(
            "{python} {} failed ({last}); install the package with `pip install ./python` \
             and point PD_PYTHON at that interpreter",
            script.display()
        ));
    }
    let text = String::from_utf8_lossy(&output.stdout);
    match serde_json::from_str(text.trim()) {
        Ok(overhead) => PythonSection::Measured(overhead),
        Err(e) => PythonSection::Skipped(format!("the script printed bad JSON ({e}): {text}")),
    }
}

/// The report's Markdown section.
pub fn markdown(section: &PythonSection) -> String {
    let mut md = String::from("## Python: the cost of a call\n\n");
    match section {
        PythonSection::Skipped(why) => {
            let _ = writeln!(md, "Not measured: {why}.\n");
        }
        PythonSection::Measured(m) => {
            let overhead = m.step1_us - m.batched_us;
            let _ = writeln!(
                md,
                "`projdyn` on `{}` (Python {}), {} steps per timed run, median of {} runs: \
                 one `step(1)` call per step against one `step({})` call, same process, \
                 same machine, same run (`python/benchmarks/step_overhead.py`).\n",
                m.scene, m.python, m.steps, m.repeats, m.steps
            );
            let _ = writeln!(md, "| calls | time per step [us] |");
            let _ = writeln!(md, "| --- | --- |");
            let _ = writeln!(md, "| `step(1)` x {} | {:.1} |", m.steps, m.step1_us);
            let _ = writeln!(md, "| `step({})` x 1 | {:.1} |", m.steps, m.batched_us);
            let _ = writeln!(
                md,
                "\nOverhead of a call: {:.1} us, {:+.2}% of a step.\n",
                overhead,
                100.0 * overhead / m.batched_us
            );
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_measurement_reads_from_the_scripts_json_and_states_the_overhead() {
        let text = r#"{"scene": "cantilever.toml", "steps": 100, "repeats": 5,
                       "python": "3.13.5", "step1_us": 1050.0, "batched_us": 1000.0}"#;
        let m: PythonOverhead = serde_json::from_str(text).unwrap();
        let md = markdown(&PythonSection::Measured(m));
        assert!(
            md.contains("Overhead of a call: 50.0 us, +5.00% of a step"),
            "{md}"
        );
    }

    #[test]
    fn a_missing_interpreter_is_a_stated_skip_not_a_failure() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let section = measure_with("/nonexistent/python-for-the-report", &root, 1);
        let PythonSection::Skipped(why) = &section else {
            panic!("expected a skip, got {section:?}")
        };
        assert!(why.contains("/nonexistent/python-for-the-report"), "{why}");
        assert!(
            markdown(&section).contains("Not measured: cannot run"),
            "{section:?}"
        );
    }
}
