//! A CI-sized corner of the stability matrix (`cargo xtask stability` runs
//! the whole of it and writes `docs/reports/stability.md`): every integrator with
//! every damping model, at extreme stiffness, time step, density, damping
//! and iteration count, from inverted, compressed and fast starting states,
//! run the way `pd run` runs a scene: parsed from a scene file, built,
//! stepped and recorded by pd-io's `Recorder` into a folder.
//!
//! The rule: every run either completes or stops with
//! `SolverError::Diverged`, and no NaN or infinity reaches an output, so
//! every number in every file the recorder wrote (metrics, probes, frames,
//! summary, final state) is finite.

use std::path::{Path, PathBuf};

use pd_io::recorder::{Outcome, Recorder};
use pd_io::scene::{Scene, Syntax};
use pd_io::state::write_state;
use pd_solver::SolverError;

/// The damping sections, one per model (coefficients at the large end).
const DAMPING: [&str; 7] = [
    "",
    "[damping]\nmodel = \"ether-drag\"\nrate = 1000.0\n",
    "[damping]\nmodel = \"ether-drag\"\nrate = 1000.0\nimplicit = true\n",
    "[damping]\nmodel = \"pbd\"\nfactor = 1.0\n",
    "[damping]\nmodel = \"rayleigh-lagged\"\nstiffness = 1000.0\n",
    "[damping]\nmodel = \"laplacian\"\nstiffness = 1000.0\n",
    "[damping]\nmodel = \"laplacian\"\nstiffness = 1000.0\npreserve_rotation = true\n",
];

const INTEGRATORS: [&str; 3] = ["backward-euler", "implicit-midpoint", "bdf2"];

/// One corner: stiffness (Pa), time step (s), density (kg/m^3),
/// iterations, whether the body is clamped, and how it starts.
struct Corner {
    stiffness: f64,
    dt: f64,
    density: f64,
    iterations: usize,
    clamped: bool,
    start: Start,
}

#[derive(Clone, Copy)]
enum Start {
    /// Every x mirrored: each tet inside out.
    Inverted,
    /// x scaled by 0.01.
    Compressed,
    /// 100 m/s and 300 rad/s.
    Fast,
}

const CORNERS: [Corner; 3] = [
    Corner {
        stiffness: 1e9,
        dt: 0.1,
        density: 1.0,
        iterations: 1,
        clamped: true,
        start: Start::Inverted,
    },
    Corner {
        stiffness: 1e0,
        dt: 1e-5,
        density: 1e5,
        iterations: 30,
        clamped: false,
        start: Start::Compressed,
    },
    Corner {
        stiffness: 1e9,
        dt: 0.1,
        density: 1e5,
        iterations: 3,
        clamped: false,
        start: Start::Fast,
    },
];

fn out_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("stability_corners")
        .join(name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The scene text of a corner (state file already written for the
/// deformed starts).
fn scene_text(corner: &Corner, integrator: &str, damping: &str, state: Option<&Path>) -> String {
    let fixed = if corner.clamped {
        "fixed = { box = { min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] } }\n"
    } else {
        ""
    };
    let start = match (corner.start, state) {
        (_, Some(path)) => format!("initial_state = {:?}\n", path.display().to_string()),
        (Start::Fast, None) => {
            "initial_velocity = [100.0, -60.0, 30.0]\nangular_velocity = [0.0, 0.0, 300.0]\n"
                .to_string()
        }
        _ => String::new(),
    };
    format!(
        "[simulation]\ndt = {dt:e}\nsteps = 8\nintegrator = \"{integrator}\"\niterations = {iterations}\nthreads = 1\n\n\
         {damping}\n\
         [[body]]\nmesh = {{ generator = \"box\", size = [1.0, 0.25, 0.25], cells = [2, 1, 1] }}\n\
         density = {density:e}\nconstraints = [ {{ kind = \"tet-strain\", stiffness = {stiffness:e} }} ]\n\
         {fixed}{start}\n\
         [output]\nevery = 1\nformats = [\"vtk\", \"obj\"]\nprobes = [11]\n",
        dt = corner.dt,
        iterations = corner.iterations,
        density = corner.density,
        stiffness = corner.stiffness,
    )
}

/// Every number-like token of every file under `dir` that parses as a
/// non-finite `f64` ("NaN", "inf", ...), with its file.
fn non_finite_numbers(dir: &Path) -> Vec<String> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(path) = stack.pop() {
        if path.is_dir() {
            for entry in std::fs::read_dir(&path).unwrap() {
                stack.push(entry.unwrap().path());
            }
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        for token in text.split(|c: char| c.is_whitespace() || ",[]{}:\"()".contains(c)) {
            if token.parse::<f64>().is_ok_and(|v| !v.is_finite()) {
                found.push(format!("{}: {token}", path.display()));
            }
        }
    }
    found
}

/// Runs one scene through the recorder; returns whether it diverged.
fn run_recorded(dir: &Path, text: &str) -> bool {
    let scene = Scene::parse(text, Syntax::Toml, &dir.join("scene.toml")).unwrap();
    let mut sim = scene.build().unwrap();
    let mut recorder = Recorder::create(&dir.join("out"), &scene, &sim).unwrap();
    let mut outcome = Outcome::Completed;
    for _ in 0..scene.steps {
        match sim.step() {
            Ok(stats) => recorder.record(&sim, &stats).unwrap(),
            Err(e @ SolverError::Diverged { .. }) => {
                outcome = Outcome::Failed(e.to_string());
                break;
            }
            Err(e) => panic!("not the divergence error: {e}\n{text}"),
        }
    }
    let diverged = outcome != Outcome::Completed;
    recorder.finish(&scene, &sim, &outcome).unwrap();
    diverged
}

#[test]
fn corners_complete_or_diverge_and_never_write_a_non_finite_number() {
    let mut diverged = 0;
    let mut runs = 0;
    for (c, corner) in CORNERS.iter().enumerate() {
        for integrator in INTEGRATORS {
            for (d, damping) in DAMPING.iter().enumerate() {
                let dir = out_dir(&format!("c{c}-{integrator}-d{d}"));
                // The deformed starts come from a state file, as a user
                // would give them.
                let state = match corner.start {
                    Start::Fast => None,
                    start => {
                        let rest = Scene::parse(
                            &scene_text(corner, integrator, damping, None),
                            Syntax::Toml,
                            &dir.join("rest.toml"),
                        )
                        .unwrap()
                        .build()
                        .unwrap();
                        let mut positions = rest.state().positions.clone();
                        for p in &mut positions {
                            match start {
                                Start::Inverted => p.x = -p.x,
                                _ => p.x *= 0.01,
                            }
                        }
                        let path = dir.join("start.json");
                        write_state(&path, &positions, &rest.state().velocities).unwrap();
                        Some(path)
                    }
                };
                let text = scene_text(corner, integrator, damping, state.as_deref());
                diverged += usize::from(run_recorded(&dir, &text));
                runs += 1;
                let bad = non_finite_numbers(&dir.join("out"));
                assert!(bad.is_empty(), "{text}\nnon-finite outputs: {bad:?}");
            }
        }
    }
    eprintln!("{runs} corner runs, {diverged} stopped with the divergence error");
}

#[test]
fn the_scan_finds_a_non_finite_number() {
    // The control: the scan is not blind to what it looks for.
    let dir = out_dir("control");
    std::fs::write(dir.join("metrics.csv"), "step,time\n0,0.0\n1,NaN\n2,-inf\n").unwrap();
    std::fs::write(dir.join("summary.json"), "{\"time\": 1e400}").unwrap();
    assert_eq!(non_finite_numbers(&dir).len(), 3);
}
