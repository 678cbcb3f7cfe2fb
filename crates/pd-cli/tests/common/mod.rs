//! Helpers shared by the CLI tests: tiny scenes and running `pd`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A fresh, empty temporary folder for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pd-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A tiny clamped beam: 4 x 1 x 1 cells (20 vertices, 24 tets), 10 steps
/// of 0.01 s, one thread, frames (VTK and OBJ) every 2 steps, two probes.
/// Small enough that a run takes milliseconds in the dev profile.
pub fn tiny_scene(dir: &Path, name: &str, integrator: &str, damping: &str) -> PathBuf {
    let text = format!(
        r#"[simulation]
dt = 0.01
steps = 10
gravity = [0.0, -9.81, 0.0]
integrator = "{integrator}"
iterations = 5
threads = 1

[damping]
{damping}

[[body]]
mesh = {{ generator = "box", size = [0.4, 0.1, 0.1], cells = [4, 1, 1] }}
density = 1000.0
constraints = [ {{ kind = "tet-strain", stiffness = 1.0e5 }} ]
fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] }} }}
initial_velocity = [0.0, 0.0, 0.5]

[output]
every = 2
formats = ["vtk", "obj"]
probes = [4, 19]
"#
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs `pd ARGS --quiet`.
pub fn pd(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pd"))
        .args(args)
        .arg("--quiet")
        .output()
        .expect("pd runs")
}

/// Runs `pd ARGS --quiet` and checks it succeeds.
pub fn pd_ok(args: &[&str]) -> Output {
    let output = pd(args);
    assert_eq!(
        output.status.code(),
        Some(0),
        "pd {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// stderr as text.
pub fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// A path as a `&str` argument.
pub fn arg(path: &Path) -> &str {
    path.to_str().expect("temporary paths are UTF-8")
}

/// A JSON file's value.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The names in `dir`, sorted.
pub fn file_names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Decodes a PNG: (width, height, RGB or RGBA bytes, bytes per pixel).
pub fn read_png(path: &Path) -> (u32, u32, Vec<u8>, usize) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf, info.color_type.samples())
}
