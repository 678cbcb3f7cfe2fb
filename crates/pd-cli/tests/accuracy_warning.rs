//! `pd run` warns, once and in `summary.json`, when a run's steps are far
//! from converged, and stays silent when they are not; `summary.json`
//! always carries the `"accuracy"` object.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::{arg, json, temp_dir, tiny_scene};

/// Runs `pd run SCENE --out OUT` with the default logging (warnings shown).
fn run(scene: &Path, out: &Path) -> Output {
    let output = Command::new(env!("CARGO_BIN_EXE_pd"))
        .args(["run", arg(scene), "--out", arg(out)])
        .env_remove("RUST_LOG")
        .output()
        .expect("pd runs");
    assert_eq!(
        output.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// The lines of stderr and stdout that are warnings.
fn warning_lines(output: &Output) -> Vec<String> {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    text.lines()
        .filter(|l| l.contains("WARN"))
        .map(str::to_owned)
        .collect()
}

/// The cloth strip of docs/design/solver.md (0.3 x 0.05 m, 30 x 5 quads,
/// `triangle-strain` 1e5 N/m, `bending` 0.5 N m, 0.2 kg/m^2, clamped
/// along x = 0) at 10 plain iterations: its steps leave nearly all of
/// their correction undone (true relative error about 1,
/// crates/pd-solver/tests/accuracy_estimate.rs).
fn strip_scene(dir: &Path) -> std::path::PathBuf {
    let text = r#"[simulation]
dt = 0.01
steps = 20
integrator = "backward-euler"
iterations = 10
threads = 1

[damping]
model = "none"

[[body]]
mesh = { generator = "cloth", size = [0.3, 0.05], cells = [30, 5] }
density = 0.2
constraints = [
  { kind = "triangle-strain", stiffness = 1.0e5 },
  { kind = "bending", stiffness = 0.5 },
]
fixed = { box = { min = [-1.0, -1.0, -1.0], max = [1e-6, 1.0, 1.0] } }
"#;
    let path = dir.join("strip.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn an_unconverged_run_is_warned_about_once() {
    let dir = temp_dir("accuracy-warning");
    let out = dir.join("out");
    let output = run(&strip_scene(&dir), &out);
    let summary = json(&out.join("summary.json"));
    assert_eq!(summary["status"], "completed");
    let accuracy = &summary["accuracy"];
    let median = accuracy["estimated_error_median"].as_f64().unwrap();
    assert!(median > 0.1, "{accuracy}");
    assert!(accuracy["estimated_error_max"].as_f64().unwrap() >= median);
    assert!(accuracy["target"].is_null());
    assert_eq!(accuracy["method"], "local-global");
    assert_eq!(accuracy["iterations_median"].as_f64(), Some(10.0));
    // Backward Euler dissipates: the energy created is measured.
    assert!(accuracy["energy_created_j"].as_f64().unwrap() >= 0.0);

    let warnings: Vec<&str> = summary["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(!warnings.is_empty(), "{summary}");
    assert!(warnings[0].contains("far from converged"), "{warnings:?}");
    assert!(warnings[0].contains("accuracy = 0.01"), "{warnings:?}");
    // The unconverged strip also gains energy in undamped backward Euler,
    // which only dissipates (measured: 0.15 J, 99% of its largest kinetic
    // plus elastic energy, far above the 1% that warns).
    assert!(
        warnings.iter().any(|w| w.contains("J of energy")),
        "{warnings:?}"
    );
    // Logged once each, with the same text.
    let logged = warning_lines(&output);
    assert_eq!(logged.len(), warnings.len(), "{logged:?}");
    for (line, warning) in logged.iter().zip(&warnings) {
        assert!(line.contains(warning), "{line} / {warning}");
    }
}

#[test]
fn a_converged_run_is_not_warned_about() {
    let dir = temp_dir("accuracy-no-warning");
    let scene = tiny_scene(&dir, "tiny", "backward-euler", "model = \"none\"");
    // The tiny beam run to an accuracy target: every step stops at it.
    let text = std::fs::read_to_string(&scene)
        .unwrap()
        .replace("iterations = 5", "accuracy = 0.001\niterations = 2000");
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out");
    let output = run(&scene, &out);
    let summary = json(&out.join("summary.json"));
    let accuracy = &summary["accuracy"];
    assert_eq!(accuracy["target"].as_f64(), Some(0.001));
    assert!(
        accuracy["estimated_error_max"].as_f64().unwrap() <= 0.001,
        "{accuracy}"
    );
    assert!(accuracy["iterations_median"].as_f64().unwrap() < 2000.0);
    assert_eq!(summary["warnings"].as_array().map(Vec::len), Some(0));
    assert!(
        warning_lines(&output).is_empty(),
        "{:?}",
        warning_lines(&output)
    );

    // Undamped implicit midpoint keeps energy: no energy-created figure.
    let scene = tiny_scene(&dir, "midpoint", "implicit-midpoint", "model = \"none\"");
    let out = dir.join("out-midpoint");
    run(&scene, &out);
    let summary = json(&out.join("summary.json"));
    assert!(
        summary["accuracy"]["energy_created_j"].is_null(),
        "{summary}"
    );
}
