//! `pd compare --accuracy e1,e2,...`: each variant meets its accuracy
//! target, as its own `metrics.csv` records it, a tighter target costs more
//! iterations, the table reports each run's accuracy, and bad targets are
//! refused before anything runs.

mod common;

use std::path::{Path, PathBuf};

use common::{arg, json, pd, pd_ok, stderr, temp_dir};
// The one median of the project (unit-tested in pd-io), applied here to
// the values the files hold.
use pd_io::stats::median;

/// The bundled cantilever (no `accuracy`, `iterations = 10`, no tolerance).
fn cantilever() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cantilever.toml")
}

/// The step rows (row 0, the initial state, left out) of a run's
/// `metrics.csv` as `(iterations, estimated_error)`, read by column name.
fn iterations_and_errors(dir: &Path) -> Vec<(usize, f64)> {
    let text = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let (step, iterations, error) = (
        column("step"),
        column("iterations"),
        column("estimated_error"),
    );
    lines
        .map(|line| line.split(',').collect::<Vec<_>>())
        .filter(|fields| fields[step] != "0")
        .map(|fields| {
            (
                fields[iterations].parse().unwrap(),
                fields[error].parse().unwrap(),
            )
        })
        .collect()
}

#[test]
fn accuracy_variants_meet_their_targets_and_tighter_costs_more() {
    let dir = temp_dir("compare-accuracy");
    let out = dir.join("out");
    pd_ok(&[
        "compare",
        arg(&cantilever()),
        "--steps",
        "10",
        "--accuracy",
        "0.1,0.01",
        "--out",
        arg(&out),
    ]);
    let table = json(&out.join("comparison.json"));
    let rows = table["variants"].as_array().unwrap();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["variant"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["accuracy-0.1", "accuracy-0.01"]);

    let mut total_iterations = Vec::new();
    for (row, target) in rows.iter().zip([0.1, 0.01]) {
        let run = out.join(row["variant"].as_str().unwrap());
        let steps = iterations_and_errors(&run);
        assert_eq!(steps.len(), 10, "{}", run.display());
        // The scene sets no `accuracy`, so the cap is the default one of a
        // scene with `accuracy` and no `iterations`, not the scene's 10.
        let cap = json(&run.join("summary.json"))["iterations"]
            .as_u64()
            .unwrap() as usize;
        assert_eq!(cap, 10_000);

        // Steps that stopped before the cap stopped on the target. At
        // least half of them must have, so that their median says
        // something about the run (the cantilever needs tens of plain
        // iterations for 1%, far below the cap, so in fact all do).
        let errors: Vec<f64> = steps
            .iter()
            .filter(|(iterations, _)| *iterations < cap)
            .map(|&(_, error)| error)
            .collect();
        assert!(errors.len() * 2 >= steps.len(), "{steps:?}");
        // No tolerance: the stopping rule compares this very estimate with
        // the target, and the file holds it to the last bit.
        assert!(median(&errors) <= target, "target {target}: {steps:?}");
        total_iterations.push(steps.iter().map(|(i, _)| i).sum::<usize>());

        // The table reports the run's target, method and errors as its
        // files hold them: the largest is one of the column's values and
        // the median the same function of the same values, so both compare
        // exactly.
        let accuracy = &row["accuracy"];
        assert_eq!(accuracy["target"].as_f64(), Some(target), "{row}");
        assert!(!accuracy["method"].as_str().unwrap().is_empty(), "{row}");
        let all: Vec<f64> = steps.iter().map(|&(_, e)| e).collect();
        assert_eq!(
            accuracy["estimated_error_max"].as_f64(),
            Some(all.iter().copied().fold(f64::MIN, f64::max)),
            "{row}"
        );
        assert_eq!(
            accuracy["estimated_error_median"].as_f64(),
            Some(median(&all)),
            "{row}"
        );
        assert!(accuracy["energy_created_j"].is_number(), "{row}");
    }
    assert!(
        total_iterations[1] > total_iterations[0],
        "iterations for 0.1 and 0.01: {total_iterations:?}"
    );

    let md = std::fs::read_to_string(out.join("comparison.md")).unwrap();
    let header = md.lines().next().unwrap();
    for column in [
        "accuracy target",
        "method",
        "median iterations",
        "median estimated error",
        "largest estimated error",
        "energy created J",
        "median step ms",
    ] {
        assert!(header.contains(column), "{header}");
    }
    assert_eq!(
        md.lines().filter(|l| l.starts_with("| accuracy-")).count(),
        2
    );
}

#[test]
fn bad_accuracy_targets_are_refused_naming_the_option() {
    let dir = temp_dir("compare-accuracy-bad");
    let out = dir.join("out");
    let scene = cantilever();
    for bad in ["0", "1", "NaN", "-0.1", "abc", "0.1,inf"] {
        let output = pd(&[
            "compare",
            arg(&scene),
            "--steps",
            "1",
            "--accuracy",
            bad,
            "--out",
            arg(&out),
        ]);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(2), "{bad}: {message}");
        let value = bad.rsplit(',').next().unwrap();
        assert!(
            message.contains("--accuracy") && message.contains(value),
            "{bad}: {message}"
        );
        assert!(!out.exists(), "{bad}: a variant ran");
    }

    // One axis at a time, as for the other axes.
    let output = pd(&[
        "compare",
        arg(&scene),
        "--accuracy",
        "0.1",
        "--ratio",
        "0.05",
    ]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(2), "{message}");
    assert!(
        message.contains("--accuracy") && message.contains("--ratio"),
        "{message}"
    );

    let output = pd(&[
        "compare",
        arg(&scene),
        "--accuracy",
        "0.1,0.1",
        "--out",
        arg(&out),
    ]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(stderr(&output).contains("twice"), "{}", stderr(&output));
}
