//! `pd run` fails with the documented exit code and a message that says
//! where: 2 for bad input, 3 for divergence, 4 when the output cannot be
//! written. A failed run keeps what it wrote before the failure.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `crates/pd-cli/tests/data`.
fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("data")
        .join(name)
}

/// A fresh, empty folder under the system's temporary folder, unique to
/// this process and `test`.
fn scratch_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pd-cli-exit-codes-{}-{test}", std::process::id()));
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `pd run SCENE --out OUT --quiet`.
fn pd_run(scene: &Path, out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pd"))
        .arg("run")
        .arg(scene)
        .arg("--out")
        .arg(out)
        .arg("--quiet")
        .output()
        .expect("pd runs")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn missing_scene_file_is_bad_input() {
    let dir = scratch_dir("missing_scene");
    let scene = dir.join("no-such-scene.toml");
    let output = pd_run(&scene, &dir.join("out"));
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(2), "stderr: {message}");
    assert!(message.contains(&scene.display().to_string()), "{message}");
    assert!(
        !dir.join("out").exists(),
        "nothing is written for bad input"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn unknown_key_is_bad_input_naming_file_and_line() {
    let dir = scratch_dir("unknown_key");
    let scene = fixture("unknown_key.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    let line = 1 + text
        .lines()
        .position(|l| l.starts_with("constraints") && l.contains("stifness"))
        .unwrap();
    let output = pd_run(&scene, &dir.join("out"));
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(2), "stderr: {message}");
    assert!(
        message.contains(&format!("{}:{line}:", scene.display())),
        "expected {}:{line} in: {message}",
        scene.display()
    );
    assert!(message.contains("stifness"), "{message}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn divergence_exits_3_and_keeps_the_rows_written_before_it() {
    // diverging.toml explains why it diverges, and at which step.
    const FAILING_STEP: usize = 9;
    let dir = scratch_dir("diverging");
    let out = dir.join("out");
    let output = pd_run(&fixture("diverging.toml"), &out);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(3), "stderr: {message}");
    assert!(
        message.contains(&format!("diverged at step {FAILING_STEP}")),
        "{message}"
    );

    // The initial row and one row per completed step, each whole and finite.
    let metrics = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    let mut lines = metrics.lines();
    let columns = lines.next().unwrap().split(',').count();
    let rows: Vec<Vec<f64>> = lines
        .map(|line| {
            line.split(',')
                .map(|v| {
                    v.parse()
                        .unwrap_or_else(|e| panic!("`{v}` in `{line}`: {e}"))
                })
                .collect()
        })
        .collect();
    assert_eq!(
        rows.len(),
        FAILING_STEP,
        "rows for steps 0 to {}",
        FAILING_STEP - 1
    );
    for (step, row) in rows.iter().enumerate() {
        assert_eq!(row.len(), columns, "row {step}");
        assert_eq!(row[0], step as f64, "row {step}");
        assert!(row.iter().all(|v| v.is_finite()), "row {step}: {row:?}");
    }
    assert!(metrics.ends_with('\n'), "the last row is complete");

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["status"], "failed", "{summary}");
    assert_eq!(summary["steps"], FAILING_STEP - 1, "{summary}");
    let error = summary["error"].as_str().expect("an error message");
    assert!(
        error.contains(&format!("diverged at step {FAILING_STEP}")),
        "{error}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn output_folder_that_cannot_be_created_exits_4() {
    let dir = scratch_dir("bad_output");
    let file = dir.join("a-file");
    std::fs::write(&file, "not a folder\n").unwrap();
    let out = file.join("out");
    // The bundled scene: valid input, so only the output can fail.
    let output = Command::new(env!("CARGO_BIN_EXE_pd"))
        .args(["run", "--quiet", "--out"])
        .arg(&out)
        .output()
        .expect("pd runs");
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(4), "stderr: {message}");
    assert!(message.contains(&out.display().to_string()), "{message}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_gravity_whose_square_overflows_is_refused() {
    // overflowing_energy_scale.toml: 3e155 m/s^2, whose square (and the
    // divergence check's energy scale) would overflow. It is refused when
    // the scene loads (exit 2, naming the field), before anything is
    // written. (A step with an infinite energy is never recorded: the
    // diverging scene's step 9, above.)
    let dir = scratch_dir("overflowing_energy_scale");
    let out = dir.join("out");
    let output = pd_run(&fixture("overflowing_energy_scale.toml"), &out);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(2), "stderr: {message}");
    assert!(message.contains("simulation.gravity"), "{message}");
    assert!(
        !out.exists(),
        "nothing is written for a scene refused at load"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
