//! `pd run --checkpoint-every K` then `pd resume DIR` gives results
//! identical bit for bit to an uninterrupted run: for every integrator
//! (BDF-2 needs its history restored) and with damping models of each
//! kind (constant matrix, lagged matrix refactorised from the state,
//! explicit velocity filter).

mod common;

use std::path::Path;

use common::{arg, pd, pd_ok, stderr, temp_dir, tiny_scene};

/// The metrics columns that depend on the simulation only (the last three
/// are wall-clock timings, which differ between any two runs).
const DETERMINISTIC_COLUMNS: usize = 13;

fn metrics_without_timings(dir: &Path) -> Vec<String> {
    std::fs::read_to_string(dir.join("metrics.csv"))
        .unwrap()
        .lines()
        .map(|l| {
            l.split(',')
                .take(DETERMINISTIC_COLUMNS)
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect()
}

fn frame_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<_> = std::fs::read_dir(dir.join("frames"))
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            (
                path.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&path).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

fn assert_same_results(reference: &Path, other: &Path) {
    for file in ["final_state.json", "probes.csv", "frames.pvd"] {
        let read = |dir: &Path| std::fs::read(dir.join(file)).ok();
        if file == "frames.pvd" && read(reference).is_none() {
            // Written only with the vtu format.
            continue;
        }
        assert!(
            read(reference) == read(other),
            "{file} differs between {} and {}",
            reference.display(),
            other.display()
        );
    }
    assert_eq!(
        metrics_without_timings(reference),
        metrics_without_timings(other)
    );
    let (a, b) = (frame_files(reference), frame_files(other));
    assert_eq!(
        a.iter().map(|f| &f.0).collect::<Vec<_>>(),
        b.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for (fa, fb) in a.iter().zip(&b) {
        assert!(fa.1 == fb.1, "frame {} differs", fa.0);
    }
}

/// Keeps the first `rows` lines of a file and appends a half-written line,
/// as a run killed mid-write leaves it.
fn cut(path: &Path, lines: usize) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut kept: String = text.split_inclusive('\n').take(lines).collect();
    kept.push_str("9,0.09,1.2");
    std::fs::write(path, kept).unwrap();
}

fn check_resume(integrator: &str, damping: &str, every: &str) {
    check_resume_with_edits(integrator, damping, every, &[]);
}

/// `edits`: (old, new) replacements in the tiny scene's text.
fn check_resume_with_edits(integrator: &str, damping: &str, every: &str, edits: &[(&str, &str)]) {
    let dir = temp_dir(&format!(
        "resume-{integrator}-{}-{every}-{}",
        damping.len(),
        edits.iter().map(|(_, new)| new.len()).sum::<usize>()
    ));
    let scene = tiny_scene(&dir, "scene", integrator, damping);
    let mut text = std::fs::read_to_string(&scene).unwrap();
    for (old, new) in edits {
        assert!(text.contains(old), "{old}");
        text = text.replace(old, new);
    }
    std::fs::write(&scene, &text).unwrap();
    let (whole, interrupted) = (dir.join("whole"), dir.join("interrupted"));
    pd_ok(&[
        "run",
        arg(&scene),
        "--out",
        arg(&interrupted),
        "--checkpoint-every",
        every,
    ]);
    // A run that chose its method by measurement reports the probe. The
    // choice is timed, so two runs can choose differently on a busy
    // machine: the uninterrupted run names the method this one chose (a
    // chosen run is bit for bit a run naming its method, tests/accuracy_mode.rs
    // of pd-solver), which leaves the checkpoint and the resume to match.
    let first = common::json(&interrupted.join("summary.json"));
    let chose = !first["accuracy"]["method_probe"].is_null();
    assert_eq!(chose, edits.iter().any(|(_, new)| new.contains("accuracy")));
    let whole_scene = if chose {
        let method = first["accuracy"]["method"].as_str().unwrap();
        let named = dir.join("named.toml");
        std::fs::write(&named, format!("{text}\n[solver]\nmethod = \"{method}\"\n")).unwrap();
        named
    } else {
        scene.clone()
    };
    pd_ok(&["run", arg(&whole_scene), "--out", arg(&whole)]);
    // Checkpointing itself changes nothing.
    assert_same_results(&whole, &interrupted);

    // Pretend the run was killed during step 10, after its last checkpoint
    // (step 8 or 9): step 9's rows are complete, step 10's half written,
    // frame 5 (step 10) and the final files missing.
    cut(&interrupted.join("metrics.csv"), 1 + 10);
    cut(&interrupted.join("probes.csv"), 1 + 10);
    for entry in std::fs::read_dir(interrupted.join("frames")).unwrap() {
        let path = entry.unwrap().path();
        if path.file_stem().is_some_and(|s| s == "frame_00005") {
            std::fs::remove_file(path).unwrap();
        }
    }
    std::fs::remove_file(interrupted.join("final_state.json")).unwrap();
    std::fs::remove_file(interrupted.join("summary.json")).unwrap();

    pd_ok(&["resume", arg(&interrupted)]);
    assert_same_results(&whole, &interrupted);
    let summary = std::fs::read_to_string(interrupted.join("summary.json")).unwrap();
    assert!(summary.contains("\"status\": \"completed\""), "{summary}");
    // The accuracy figures cover the steps before the checkpoint too (read
    // back from metrics.csv), as the uninterrupted run's do.
    let (mut resumed, mut straight) = (
        common::json(&interrupted.join("summary.json")),
        common::json(&whole.join("summary.json")),
    );
    // The resumed run took the method from the checkpoint and probed
    // nothing.
    assert!(resumed["accuracy"]["method_probe"].is_null());
    for summary in [&mut resumed, &mut straight] {
        summary["accuracy"]
            .as_object_mut()
            .unwrap()
            .remove("method_probe");
    }
    assert_eq!(resumed["accuracy"], straight["accuracy"]);
    assert_eq!(resumed["warnings"], straight["warnings"]);
}

/// A free spinning body under the rotation-preserving damping: its
/// projection maps reference lever arms from step to step, which the
/// checkpoint carries (`rotation`).
#[test]
fn implicit_midpoint_with_rotation_preserving_damping_of_a_free_body() {
    check_resume_with_edits(
        "implicit-midpoint",
        "model = \"laplacian\"\nstiffness = 0.01\npreserve_rotation = true",
        "4",
        &[(
            "fixed = { box = { min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] } }",
            "angular_velocity = [0.5, 1.0, 4.0]",
        )],
    );
}

#[test]
fn backward_euler_without_damping() {
    check_resume("backward-euler", "model = \"none\"", "4");
}

#[test]
fn implicit_midpoint_with_lagged_rayleigh() {
    check_resume(
        "implicit-midpoint",
        "model = \"rayleigh-lagged\"\nstiffness = 0.003",
        "4",
    );
}

#[test]
fn bdf2_with_laplacian_damping() {
    check_resume(
        "bdf2",
        "model = \"laplacian\"\nstiffness = 0.003\npreserve_rotation = true",
        "4",
    );
}

#[test]
fn bdf2_with_explicit_ether_drag() {
    check_resume("bdf2", "model = \"ether-drag\"\nrate = 1.0", "4");
}

#[test]
fn checkpoint_between_frames() {
    // Checkpoints at steps 3, 6, 9 while frames are every 2 steps: the
    // resumed run keeps frames 0-4 and rewrites only frame 5.
    check_resume("bdf2", "model = \"none\"", "3");
}

#[test]
fn every_frame_format_and_the_paraview_series() {
    // The resumed run rebuilds `frames.pvd` (frame times read back from
    // metrics.csv) so that it lists every frame exactly as an
    // uninterrupted run's does.
    check_resume_with_edits(
        "implicit-midpoint",
        "model = \"laplacian\"\nstiffness = 0.003",
        "4",
        &[(
            "formats = [\"vtk\", \"obj\"]",
            "formats = [\"vtk\", \"obj\", \"vtu\", \"ply\"]",
        )],
    );
}

/// With `accuracy` and no `[solver] method`, the run chooses its method by
/// measurement; the resumed run keeps that method (from the checkpoint)
/// and the contraction its error estimate carries, so it stops every step
/// where the uninterrupted run did.
#[test]
fn accuracy_with_the_method_chosen_by_measurement() {
    check_resume_with_edits(
        "implicit-midpoint",
        "model = \"laplacian\"\nstiffness = 0.003",
        "3",
        &[("iterations = 5", "accuracy = 0.01")],
    );
}

#[test]
fn bad_checkpoints_are_input_errors() {
    let dir = temp_dir("resume-bad");
    let scene = tiny_scene(&dir, "scene", "bdf2", "model = \"none\"");
    let out = dir.join("out");

    // No checkpoint at all.
    pd_ok(&["run", arg(&scene), "--out", arg(&out)]);
    let output = pd(&["resume", arg(&out)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("checkpoint.json"),
        "{}",
        stderr(&output)
    );

    // A damaged checkpoint.
    pd_ok(&[
        "run",
        arg(&scene),
        "--out",
        arg(&out),
        "--checkpoint-every",
        "3",
    ]);
    let checkpoint = out.join("checkpoint.json");
    let good = std::fs::read_to_string(&checkpoint).unwrap();
    std::fs::write(&checkpoint, &good[..good.len() / 3]).unwrap();
    let output = pd(&["resume", arg(&out)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));

    // The scene text edited inside the checkpoint.
    std::fs::write(
        &checkpoint,
        good.replace("iterations = 5", "iterations = 6"),
    )
    .unwrap();
    let output = pd(&["resume", arg(&out)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("scene.hash"),
        "{}",
        stderr(&output)
    );

    // A checkpoint of another model: its fingerprint differs (what a mesh
    // file changed since the run gives), one hex digit changed here.
    let key = "\"model\":\"fnv1a64:";
    let at = good.find(key).expect("the checkpoint records its model") + key.len();
    let digit = if &good[at..at + 1] == "0" { "1" } else { "0" };
    let other = format!("{}{digit}{}", &good[..at], &good[at + 1..]);
    std::fs::write(&checkpoint, other).unwrap();
    let output = pd(&["resume", arg(&out)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("another model"),
        "{}",
        stderr(&output)
    );

    // metrics.csv shorter than the checkpoint (the checkpoint is at step 9).
    std::fs::write(&checkpoint, &good).unwrap();
    cut(&out.join("metrics.csv"), 1 + 5);
    let output = pd(&["resume", arg(&out)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("metrics.csv"),
        "{}",
        stderr(&output)
    );
}

/// The tiny scene with a floor under the beam and a cube resting on its
/// free end (`contact.bodies = true`): contacts with the floor and between
/// the bodies are active at every checkpoint, so the resumed run is
/// bit-identical only if their warm-started forces are saved.
#[test]
fn contact_with_colliders_and_between_bodies() {
    let dir = temp_dir("resume-contact");
    let scene = tiny_scene(&dir, "scene", "bdf2", "model = \"none\"");
    let text = std::fs::read_to_string(&scene).unwrap();
    let contact = r#"
[[collider]]
shape = "plane"
point = [0.0, -0.003, 0.0]
normal = [0.0, 1.0, 0.0]
friction = 0.5

[contact]
bodies = true
thickness = 0.001
friction = 0.5

[[body]]
mesh = { generator = "box", size = [0.05, 0.05, 0.05], cells = [1, 1, 1] }
density = 1000.0
constraints = [ { kind = "tet-strain", stiffness = 1.0e5 } ]
translate = [0.03, 0.1005, 0.03]

[output]"#;
    std::fs::write(&scene, text.replace("\n[output]", contact)).unwrap();
    let (whole, interrupted) = (dir.join("whole"), dir.join("interrupted"));
    pd_ok(&["run", arg(&scene), "--out", arg(&whole)]);
    pd_ok(&[
        "run",
        arg(&scene),
        "--out",
        arg(&interrupted),
        "--checkpoint-every",
        "4",
    ]);
    assert_same_results(&whole, &interrupted);
    let checkpoint = std::fs::read_to_string(interrupted.join("checkpoint.json")).unwrap();
    // Both kinds of contact are in the checkpoint (step 8).
    assert!(
        checkpoint.contains("\"contact\":{\"colliders\":[{"),
        "no collider contact saved"
    );
    assert!(
        !checkpoint.contains("\"pairs\":[]"),
        "no contact between bodies saved"
    );
    // Killed during step 10: as in `check_resume_with_edits`.
    cut(&interrupted.join("metrics.csv"), 1 + 10);
    cut(&interrupted.join("probes.csv"), 1 + 10);
    for entry in std::fs::read_dir(interrupted.join("frames")).unwrap() {
        let path = entry.unwrap().path();
        if path.file_stem().is_some_and(|s| s == "frame_00005") {
            std::fs::remove_file(path).unwrap();
        }
    }
    std::fs::remove_file(interrupted.join("final_state.json")).unwrap();
    std::fs::remove_file(interrupted.join("summary.json")).unwrap();
    pd_ok(&["resume", arg(&interrupted)]);
    assert_same_results(&whole, &interrupted);
}
