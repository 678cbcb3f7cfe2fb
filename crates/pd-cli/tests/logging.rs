//! Logs go to stderr through `tracing`: `RUST_LOG` filters them, `--quiet`
//! silences everything but errors, and errors show whatever the filter.

mod common;

use std::process::{Command, Output};

use common::{arg, pd_ok, temp_dir, tiny_scene};

fn pd_with_log(rust_log: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pd"))
        .args(args)
        .env("RUST_LOG", rust_log)
        .output()
        .expect("pd runs")
}

#[test]
fn rust_log_and_quiet_control_the_logs() {
    let dir = temp_dir("logging");
    let scene = tiny_scene(&dir, "beam", "backward-euler", "model = \"none\"");
    let run = dir.join("run");
    pd_ok(&["run", arg(&scene), "--out", arg(&run)]);

    let info = pd_with_log("info", &["plot", arg(&run)]);
    assert!(info.status.success());
    assert!(String::from_utf8_lossy(&info.stderr).contains("INFO"));

    let warn = pd_with_log("warn", &["plot", arg(&run)]);
    assert!(warn.status.success());
    assert_eq!(String::from_utf8_lossy(&warn.stderr), "");

    let quiet = pd_with_log("debug", &["plot", arg(&run), "--quiet"]);
    assert!(quiet.status.success());
    assert_eq!(String::from_utf8_lossy(&quiet.stderr), "");

    // Errors are printed even when logs are filtered out.
    let missing = dir.join("missing");
    let error = pd_with_log("off", &["plot", arg(&missing), "--quiet"]);
    assert_eq!(error.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&error.stderr).starts_with("error: "));
}
