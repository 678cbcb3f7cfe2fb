//! Ctrl-C (SIGINT) stops `pd run` after a whole step: exit code 130, every
//! row up to that step, `summary.json` saying `interrupted` and where, and
//! with checkpoints on, a checkpoint at that very step for `pd resume`.

mod common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{arg, json, temp_dir, tiny_scene};

#[test]
fn ctrl_c_stops_after_a_whole_step_with_a_checkpoint_there() {
    let dir = temp_dir("interrupt");
    let scene = tiny_scene(&dir, "beam", "bdf2", "model = \"none\"");
    let out = dir.join("out");
    // Far more steps than run before the signal arrives.
    let child = Command::new(env!("CARGO_BIN_EXE_pd"))
        .args(["run", arg(&scene), "--out", arg(&out), "--quiet"])
        .args(["--steps", "100000000", "--checkpoint-every", "7"])
        .stderr(Stdio::piped())
        .spawn()
        .expect("pd runs");
    // Wait for a few dozen rows, so that the run is inside its step loop.
    let metrics = out.join("metrics.csv");
    let start = Instant::now();
    while std::fs::read_to_string(&metrics).map_or(0, |t| t.lines().count()) < 40 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no rows written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(killed.success());
    let output = child.wait_with_output().unwrap();
    let message = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(130), "{message}");

    let summary = json(&out.join("summary.json"));
    assert_eq!(summary["status"], "interrupted", "{summary}");
    let steps = summary["steps"].as_u64().unwrap();
    assert!(
        message.contains(&format!("after step {steps} of 100000000")),
        "{message}"
    );
    // The initial row and one per step, the last one whole.
    let text = std::fs::read_to_string(&metrics).unwrap();
    assert_eq!(text.lines().count() as u64, 1 + 1 + steps);
    assert!(text.ends_with('\n'));
    // The checkpoint is at the interrupted step (whether or not it is a
    // multiple of 7) and holds the final state, bit for bit.
    let checkpoint = json(&out.join("checkpoint.json"));
    assert_eq!(checkpoint["steps"].as_u64(), Some(steps));
    let last = json(&out.join("final_state.json"));
    assert_eq!(checkpoint["positions"], last["positions"]);
    assert_eq!(checkpoint["velocities"], last["velocities"]);
    std::fs::remove_dir_all(&dir).unwrap();
}
