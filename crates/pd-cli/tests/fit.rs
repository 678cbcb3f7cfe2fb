//! `pd fit`: recovering known scene values from a recording `pd run` made,
//! the gradient it reports against central differences of `pd run`
//! outputs, and its errors.
//!
//! The scene is the bundled `scenes/fit_beam.toml` (20 vertices, 100
//! steps): its steps are converged to 1e-9 by Newton's method, as `pd fit`
//! runs its own, so its `probes.csv` is exactly the motion its values give.

mod common;

use std::path::{Path, PathBuf};

use common::{arg, json, pd, pd_ok, stderr, temp_dir};

/// The fitted values: Laplacian `a2`, mass `a1`, tet-strain stiffness.
const FIT: &str = "damping.stiffness,damping.mass,body[0].constraints[0].stiffness";

/// The bundled scene and its true values, as written in it.
fn beam() -> (String, [(&'static str, f64); 3]) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/fit_beam.toml");
    let text = std::fs::read_to_string(path).unwrap();
    (
        text,
        [
            ("stiffness = 1.5e-4", 1.5e-4),
            ("mass = 0.6", 0.6),
            ("stiffness = 1.0e5", 1.0e5),
        ],
    )
}

/// The beam with each value multiplied by its factor, written to `dir/name`.
fn beam_scaled(dir: &Path, name: &str, factors: [f64; 3]) -> PathBuf {
    let (mut text, values) = beam();
    for ((written, value), factor) in values.iter().zip(factors) {
        let key = written.split(" = ").next().unwrap();
        assert!(
            text.contains(written),
            "the scene no longer has `{written}`"
        );
        text = text.replacen(written, &format!("{key} = {:e}", value * factor), 1);
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `pd run SCENE --out DIR`; returns `DIR/probes.csv`.
fn record(scene: &Path, out: &Path) -> PathBuf {
    pd_ok(&["run", arg(scene), "--out", arg(out)]);
    out.join("probes.csv")
}

/// Probe positions `[step][probe]` of a probes.csv, steps 1 onwards.
fn positions(path: &Path) -> Vec<Vec<[f64; 3]>> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(2) // the header and step 0
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|f| f.parse().unwrap()).collect();
            v[2..].chunks(6).map(|c| [c[0], c[1], c[2]]).collect()
        })
        .collect()
}

/// The loss as `pd fit` defines it (docs/reference/cli.md): the mean over
/// steps 1..=N and probes of the squared distance, m^2.
fn loss(run: &Path, target: &Path) -> f64 {
    let (a, b) = (positions(run), positions(target));
    assert_eq!(a.len(), b.len());
    let mut sum = 0.0;
    let mut count = 0;
    for (x, y) in a.iter().zip(&b) {
        for (p, q) in x.iter().zip(y) {
            sum += (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>();
            count += 1;
        }
    }
    sum / f64::from(count)
}

#[test]
fn known_values_are_recovered_from_four_times_off() {
    let dir = temp_dir("fit-recover");
    let target = record(
        &beam_scaled(&dir, "truth.toml", [1.0; 3]),
        &dir.join("truth"),
    );
    // a2 and k 4x too large, a1 4x too small.
    let start = beam_scaled(&dir, "start.toml", [4.0, 0.25, 4.0]);
    let out = dir.join("fit");
    let output = pd(&[
        "fit",
        arg(&start),
        "--target",
        arg(&target),
        "--fit",
        FIT,
        "--out",
        arg(&out),
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let report = json(&out.join("fit.json"));
    let (_, truth) = beam();
    let names = FIT.split(',');
    for (name, (_, value)) in names.zip(truth) {
        let fitted = report["parameters"][name].as_f64().unwrap();
        // Within 1% from 4x off, as pd fit promises on this beam.
        // Measured: every value within 1e-7 relative after 37 iterations
        // (the recording is exact, so the minimum is the truth; the fit
        // stops where no step lowers the loss, at ~1e-20 m^2).
        assert!(
            (fitted / value - 1.0).abs() < 0.01,
            "{name}: fitted {fitted}, true {value}\n{report:#}"
        );
    }
    assert_eq!(report["gradient_method"], "adjoint");
    assert!(report["iterations"].as_u64().unwrap() >= 1);
    assert!(report["timing"]["forward_s"].as_f64().unwrap() > 0.0);
    assert!(report["timing"]["backward_s"].as_f64().unwrap() > 0.0);
    // The loss fell from the start's by orders of magnitude (measured: from
    // 8e-3 to 3e-20 m^2); 1e-6 of it means the motion is matched to 0.1% of
    // the start's misfit.
    let (initial, fitted) = (
        report["initial_loss"].as_f64().unwrap(),
        report["loss"].as_f64().unwrap(),
    );
    assert!(fitted < 1e-6 * initial, "{initial} -> {fitted}");

    // The fitted scene loads, and runs the motion the fit matched.
    let rerun = record(&out.join("fitted.toml"), &dir.join("rerun"));
    let reproduced = loss(&rerun, &target);
    // The same converged runs as the fit's own: the loss `pd fit` reported,
    // up to rounding of the summation (1e-12 relative) and a floor of
    // 1e-24 m^2 (1e-12 m RMS) for a loss of rounding size itself.
    assert!(
        (reproduced - fitted).abs() <= 1e-12 * fitted + 1e-24,
        "fit.json {fitted}, pd run of fitted.toml {reproduced}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_gradient_at_the_start_matches_central_differences_of_pd_run() {
    let dir = temp_dir("fit-gradient");
    let target = record(
        &beam_scaled(&dir, "truth.toml", [1.0; 3]),
        &dir.join("truth"),
    );
    let factors = [4.0, 0.25, 4.0];
    let start = beam_scaled(&dir, "start.toml", factors);
    let out = dir.join("fit");
    pd_ok(&[
        "fit",
        arg(&start),
        "--target",
        arg(&target),
        "--fit",
        FIT,
        "--out",
        arg(&out),
        "--max-iterations",
        "0",
    ]);
    let report = json(&out.join("fit.json"));
    assert_eq!(report["iterations"], 0);
    // Without an iteration the scene's values are reported as given.
    assert_eq!(report["parameters"], report["initial_parameters"]);
    assert_eq!(
        report["initial_parameters"]["damping.mass"].as_f64(),
        Some(0.6 * 0.25)
    );
    let start_loss = loss(&record(&start, &dir.join("start")), &target);
    // The same runs: the loss agrees to summation rounding.
    let reported = report["loss"].as_f64().unwrap();
    assert!(
        (reported / start_loss - 1.0).abs() < 1e-12,
        "{reported} {start_loss}"
    );
    let (_, truth) = beam();
    // Relative step of the test's own central difference (10x `pd fit`'s
    // 1e-4), so that the two do not share their errors.
    let h = 1e-3;
    for (i, name) in FIT.split(',').enumerate() {
        let value = truth[i].1 * factors[i];
        let side = |sign: f64| {
            let mut f = factors;
            f[i] *= 1.0 + sign * h;
            let scene = beam_scaled(&dir, &format!("p{i}{sign}.toml"), f);
            loss(&record(&scene, &dir.join(format!("p{i}{sign}"))), &target)
        };
        let central = (side(1.0) - side(-1.0)) / (2.0 * h * value);
        let reported = report["gradient"][name].as_f64().unwrap();
        // Both are central differences of the same smooth loss (converged
        // runs: noise ~1e-9 relative): their truncation errors are
        // ~h^2/6 of the loss's third log-derivative over its first, about
        // 2e-7 here for h = 1e-3; the loss's noise over 2h adds ~1e-6.
        // 1e-4 relative leaves room for both. Measured: within 1e-6.
        assert!(
            (reported / central - 1.0).abs() < 1e-4,
            "{name}: pd fit {reported:e}, central difference of pd run {central:e}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_paths_mismatched_targets_and_missing_files_are_refused() {
    let dir = temp_dir("fit-errors");
    let scene = beam_scaled(&dir, "beam.toml", [1.0; 3]);
    let target = record(&scene, &dir.join("run"));
    let fit = |fit: &str, target: &Path| {
        let output = pd(&[
            "fit",
            arg(&scene),
            "--target",
            arg(target),
            "--fit",
            fit,
            "--out",
            arg(&dir.join("out")),
        ]);
        assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
        stderr(&output)
    };

    // A path that is not a fittable value: the list of supported ones.
    let err = fit("damping.model", &target);
    assert!(
        err.contains("`damping.model` is not a scene value pd fit can fit")
            && err.contains("body[i].constraints[j].stiffness")
            && err.contains("damping.ratios[k]"),
        "{err}"
    );
    // A supported path the scene does not set.
    let err = fit("damping.ratio", &target);
    assert!(
        err.contains("beam.toml: damping.ratio: the scene does not set it"),
        "{err}"
    );
    let err = fit("body[1].density", &target);
    assert!(
        err.contains("body[1].density: the scene does not set it"),
        "{err}"
    );

    // The target's probes are not the scene's.
    let text = std::fs::read_to_string(&target).unwrap();
    let fewer: Vec<String> = text
        .lines()
        .map(|l| l.split(',').take(8).collect::<Vec<_>>().join(","))
        .collect();
    let probes = dir.join("fewer.csv");
    std::fs::write(&probes, fewer.join("\n")).unwrap();
    let err = fit("damping.mass", &probes);
    assert!(
        err.contains(
            "fewer.csv:1: the target records probes [4], the scene's output.probes are [4, 12, 19]"
        ),
        "{err}"
    );
    // Another time step: the first row whose time is not the scene's.
    let slower = text.replacen("\n1,0.01,", "\n1,0.02,", 1);
    let times = dir.join("times.csv");
    std::fs::write(&times, slower).unwrap();
    let err = fit("damping.mass", &times);
    assert!(err.contains("times.csv:3: time 0.02 s at step 1"), "{err}");
    // Fewer steps than the scene runs.
    let short: Vec<&str> = text.lines().take(51).collect();
    let steps = dir.join("steps.csv");
    std::fs::write(&steps, short.join("\n")).unwrap();
    let err = fit("damping.mass", &steps);
    assert!(
        err.contains("steps.csv:51: the target ends at step 49, the scene runs 100 steps"),
        "{err}"
    );
    // A row cut short.
    let cut = text.replacen("\n2,", "\n2,0.02,1\n2,", 1);
    let malformed = dir.join("malformed.csv");
    std::fs::write(&malformed, cut).unwrap();
    let err = fit("damping.mass", &malformed);
    assert!(err.contains("malformed.csv:4: expected 20 fields"), "{err}");

    // Missing files: the target, then the scene.
    let err = fit("damping.mass", &dir.join("absent.csv"));
    assert!(err.contains("absent.csv"), "{err}");
    let output = pd(&[
        "fit",
        arg(&dir.join("absent.toml")),
        "--target",
        arg(&target),
        "--fit",
        "damping.mass",
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).contains("absent.toml"),
        "{}",
        stderr(&output)
    );

    // Nothing was written for any of them.
    assert!(!dir.join("out").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The beam as a JSON scene whose damping is given as the ratio of its
/// lowest mode, over 50 steps.
fn ratio_scene(dir: &Path, name: &str, ratio: f64) -> PathBuf {
    let text = format!(
        r#"{{
  "simulation": {{ "dt": 0.01, "steps": 50, "gravity": [0.0, -9.81, 0.0],
                  "integrator": "implicit-midpoint", "accuracy": 1e-9, "threads": 1 }},
  "damping": {{ "model": "laplacian", "ratio": {ratio:e} }},
  "body": [ {{
    "mesh": {{ "generator": "box", "size": [0.4, 0.1, 0.1], "cells": [4, 1, 1] }},
    "density": 1000.0,
    "constraints": [ {{ "kind": "tet-strain", "stiffness": 1.0e5 }} ],
    "fixed": {{ "box": {{ "min": [-1.0, -1.0, -1.0], "max": [0.001, 1.0, 1.0] }} }},
    "initial_velocity": [0.0, 0.0, 0.5]
  }} ],
  "solver": {{ "method": "newton" }},
  "output": {{ "every": 0, "formats": [], "probes": [4, 19] }}
}}"#
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_damping_ratio_is_fitted_in_a_json_scene() {
    let dir = temp_dir("fit-ratio");
    let target = record(&ratio_scene(&dir, "truth.json", 0.05), &dir.join("truth"));
    let start = ratio_scene(&dir, "start.json", 0.2);
    let out = dir.join("fit");
    pd_ok(&[
        "fit",
        arg(&start),
        "--target",
        arg(&target),
        "--fit",
        "damping.ratio",
        "--out",
        arg(&out),
    ]);
    let report = json(&out.join("fit.json"));
    let fitted = report["parameters"]["damping.ratio"].as_f64().unwrap();
    // 1%, as for the three values; measured: 1.2e-11 relative in 9
    // iterations with adjoint gradients (an exact recording).
    assert!((fitted / 0.05 - 1.0).abs() < 0.01, "{report:#}");
    // The fitted scene is TOML and sets the ratio (the loader turns it into
    // coefficients when building).
    let rerun = record(&out.join("fitted.toml"), &dir.join("rerun"));
    let reproduced = loss(&rerun, &target);
    let reported = report["loss"].as_f64().unwrap();
    // As in the three-value fit: the same converged runs, rounding only.
    assert!(
        (reproduced - reported).abs() <= 1e-12 * reported + 1e-24,
        "fit.json {reported}, pd run of fitted.toml {reproduced}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A clamped beam of 28 vertices (0.6 x 0.1 x 0.06 m: its bending modes
/// in y and z have different frequencies) for 100 steps, with `damping`
/// as the `[damping]` table's lines. It starts bent and twisted at once (a
/// uniform velocity and a spin about its centre: the spin's velocity
/// changes sign along the beam, which excites the second bending mode
/// besides the first, and its twist the torsion), under gravity, and five
/// probes (the free end's four corners and a vertex near mid-span) record
/// it.
fn caughey_scene(dir: &Path, name: &str, damping: &str) -> PathBuf {
    let text = format!(
        r#"[simulation]
dt = 0.01
steps = 100
gravity = [0.0, -9.81, 0.0]
integrator = "implicit-midpoint"
accuracy = 1e-9
threads = 1

[damping]
model = "laplacian"
{damping}

[[body]]
mesh = {{ generator = "box", size = [0.6, 0.1, 0.06], cells = [6, 1, 1] }}
density = 1000.0
constraints = [ {{ kind = "tet-strain", stiffness = 4.0e5 }} ]
fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] }} }}
initial_velocity = [0.0, 0.2, 0.3]
angular_velocity = [4.0, 2.0, -3.0]

[solver]
method = "anderson"

[output]
every = 0
formats = []
probes = [6, 13, 20, 27, 10]
"#
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The damping ratios `pd modes` gives the scene's lowest six modes.
fn mode_ratios(scene: &Path, out: &Path) -> Vec<f64> {
    pd_ok(&["modes", arg(scene), "--count", "6", "--out", arg(out)]);
    json(&out.join("modes.json"))["damping_ratios"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_f64().unwrap())
        .collect()
}

/// A Caughey three-ratio damping (`ratios = [0.06, 0.05, 0.2]` on modes
/// 1, 3 and 4: `a1 M + a2 L_d + a3 L_d M^-1 L_d`) is recovered from a
/// recording by fitting its three coefficients through the adjoint method,
/// from 4x off.
#[test]
fn a_caughey_three_ratio_damping_is_recovered_from_four_times_off() {
    let dir = temp_dir("fit-caughey");
    let truth = caughey_scene(
        &dir,
        "truth.toml",
        "ratios = [0.06, 0.05, 0.2]\nmodes = [1, 3, 4]",
    );
    let target = record(&truth, &dir.join("truth"));
    // The coefficients the ratios give (the run's own fit, which the
    // recording was made with).
    let summary = json(&dir.join("truth/summary.json"));
    let coefficients = &summary["damping_coefficients"];
    let truth_values = [
        coefficients["mass_per_s"].as_f64().unwrap(),
        coefficients["laplacian_stiffness_s"].as_f64().unwrap(),
        coefficients["series"][0].as_f64().unwrap(),
    ];
    // pd fit fits positive values; these ratios were chosen for a series
    // of three positive terms (measured: 0.245 1/s, 4.04e-5 s, 1.23e-10
    // s^3).
    assert!(truth_values.iter().all(|v| *v > 0.0), "{coefficients:#}");
    // a1 and a3 4x too large, a2 4x too small.
    let start = caughey_scene(
        &dir,
        "start.toml",
        &format!(
            "mass = {:e}\nstiffness = {:e}\nseries = [{:e}]",
            4.0 * truth_values[0],
            truth_values[1] / 4.0,
            4.0 * truth_values[2]
        ),
    );
    let paths = ["damping.mass", "damping.stiffness", "damping.series[0]"];
    let out = dir.join("fit");
    pd_ok(&[
        "fit",
        arg(&start),
        "--target",
        arg(&target),
        "--fit",
        &paths.join(","),
        "--out",
        arg(&out),
    ]);
    let report = json(&out.join("fit.json"));
    assert_eq!(report["gradient_method"], "adjoint", "{report:#}");
    for (path, value) in paths.iter().zip(truth_values) {
        let fitted = report["parameters"][path].as_f64().unwrap();
        // 1%, as pd fit promises for coefficients; measured: within 1e-8
        // relative after 27 iterations (the recording is exact).
        assert!(
            (fitted / value - 1.0).abs() < 0.01,
            "{path}: fitted {fitted}, true {value}\n{report:#}"
        );
    }
    // The damping the fitted scene gives each mode is the recording's: the
    // modal ratios of the fitted coefficients against those of the ratio
    // scene (both by pd modes, which sums the series per mode). A 1%
    // change of one coefficient moves a ratio by at most 1%; the measured
    // agreement is 1e-8.
    let fitted_ratios = mode_ratios(&out.join("fitted.toml"), &dir.join("modes-fitted"));
    let truth_ratios = mode_ratios(&truth, &dir.join("modes-truth"));
    for (mode, (f, t)) in fitted_ratios.iter().zip(&truth_ratios).enumerate() {
        assert!(
            (f / t - 1.0).abs() < 0.01,
            "mode {}: fitted {f}, recorded {t}",
            mode + 1
        );
    }
    // The asked ratios, within 5%: pd modes gives the run's ratios (with
    // the integrator at dt = 0.01 s), which differ from the asked ones by
    // up to 3.8% (measured 0.0599, 0.0485, 0.1925 for both scenes).
    for (mode, asked) in [(1, 0.06), (3, 0.05), (4, 0.2)] {
        let got = fitted_ratios[mode - 1];
        assert!(
            (got / asked - 1.0).abs() < 0.05,
            "mode {mode}: ratio {got}, asked {asked}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_decay_per_cycle_is_matched() {
    let dir = temp_dir("fit-decay");
    // The example beam, swinging for 3 s (five cycles of its first mode).
    let (text, _) = beam();
    let scene = dir.join("beam.toml");
    std::fs::write(&scene, text.replacen("steps = 100", "steps = 300", 1)).unwrap();
    let target = dir.join("decay.toml");
    // The tip's sideways swing (z); along y the sag's own bounce also
    // shows. This corner probe's motion mixes modes (an independent
    // reading from its maxima alone gives 0.34 for the fitted scene):
    // the decay of a description is only meaningful for a probe that
    // swings in one mode (docs/reference/cli.md).
    std::fs::write(
        &target,
        "[decay]\nprobe = 2\nlost_per_cycle = 0.3\ndirection = [0.0, 0.0, 1.0]\n",
    )
    .unwrap();
    let out = dir.join("fit");
    pd_ok(&[
        "fit",
        arg(&scene),
        "--target",
        arg(&target),
        "--fit",
        "damping.stiffness",
        "--out",
        arg(&out),
    ]);
    let report = json(&out.join("fit.json"));
    assert_eq!(report["target_kind"], "decay");
    assert_eq!(report["gradient_method"], "finite-difference");
    // The fit reaches the asked decay by its own measure (the extrema's
    // swings, unit-tested against a damped cosine in `fit::decay`): the
    // loss is the squared difference, and the fit stops where no step
    // lowers it (measured: 0.29999999995).
    let simulated = report["decay"]["simulated_lost_per_cycle"]
        .as_f64()
        .unwrap();
    assert!((simulated - 0.3).abs() < 1e-6, "lost per cycle {simulated}");
    // And an impossible description is refused, naming the key.
    std::fs::write(&target, "[decay]\nlost_per_cycle = 1.5\n").unwrap();
    let output = pd(&[
        "fit",
        arg(&scene),
        "--target",
        arg(&target),
        "--fit",
        "damping.stiffness",
        "--out",
        arg(&dir.join("bad")),
    ]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(stderr(&output).contains("decay.lost_per_cycle: must be in (0, 1)"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_decay_per_cycle_gives_the_damping_of_a_single_oscillator() {
    // One mass on one spring (a chain of two points, the first fixed):
    // w = 10 N/m, m = 2 kg/m x 0.1 m / 2 = 0.1 kg, omega = 10 rad/s;
    // D = a1 M (Laplacian damping's `mass`; its `stiffness` a2 = 1e-12 s
    // adds 1e-11 to the damping rate, nothing). The free vertex swings
    // along the spring: one mode, amplitude lost per cycle
    // 1 - exp(-(a1/2) T_d), T_d = 2 pi / sqrt(omega^2 - a1^2/4). For 0.3 a
    // cycle: zeta / sqrt(1 - zeta^2) = -ln(0.7) / (2 pi), a1 = 2 zeta omega.
    let dir = temp_dir("fit-decay-oscillator");
    let scene = dir.join("oscillator.toml");
    std::fs::write(
        &scene,
        r#"[simulation]
dt = 0.004
steps = 480
gravity = [0.0, 0.0, 0.0]
integrator = "implicit-midpoint"
accuracy = 1e-9
threads = 1

[damping]
model = "laplacian"
stiffness = 1e-12
mass = 0.5

[[body]]
mesh = { generator = "chain", points = 2, length = 0.1 }
density = 2.0
constraints = [ { kind = "spring", stiffness = 10.0 } ]
fixed = { vertices = [0] }
initial_velocity = [0.5, 0.0, 0.0]

[solver]
method = "newton"

[output]
every = 0
formats = []
probes = [1]
"#,
    )
    .unwrap();
    let target = dir.join("decay.json");
    std::fs::write(&target, r#"{"decay": {"lost_per_cycle": 0.3}}"#).unwrap();
    let out = dir.join("fit");
    pd_ok(&[
        "fit",
        arg(&scene),
        "--target",
        arg(&target),
        "--fit",
        "damping.mass",
        "--out",
        arg(&out),
    ]);
    let report = json(&out.join("fit.json"));
    let a1 = report["parameters"]["damping.mass"].as_f64().unwrap();
    let delta = -(0.7_f64.ln()) / (2.0 * std::f64::consts::PI);
    let zeta = delta / (1.0 + delta * delta).sqrt();
    let expected = 2.0 * zeta * 10.0;
    // Implicit midpoint at h omega = 0.04 changes the discrete decay and
    // period by O((h omega)^2) = 1.6e-3 relative; the extrema's parabolas
    // (157 samples a cycle) err by about (2 pi / 157)^2 / 12 = 1.3e-4.
    // Bound 5e-3; measured 2.7e-4 (1.13381 against 1.13351).
    assert!(
        (a1 / expected - 1.0).abs() < 5e-3,
        "fitted a1 = {a1}, theory {expected}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The `[damping]` lines for given ratios, the fitted paths and the start.
type RatioCase<'a> = (&'a dyn Fn(&[f64]) -> String, &'a [&'a str], Vec<f64>);

/// The gradient with respect to one, two and three damping ratios, which
/// `pd fit` takes from the adjoint method through the ratios' fit to
/// coefficients, against central differences of `pd run` outputs, at a
/// start off the recorded three-ratio damping.
#[test]
fn ratio_gradients_by_the_adjoint_match_central_differences_of_pd_run() {
    let dir = temp_dir("fit-ratio-adjoint");
    let target = record(
        &caughey_scene(
            &dir,
            "truth.toml",
            "ratios = [0.06, 0.05, 0.2]\nmodes = [1, 3, 4]",
        ),
        &dir.join("truth"),
    );
    let one = |z: &[f64]| format!("ratio = {:e}", z[0]);
    let two = |z: &[f64]| format!("ratios = [{:e}, {:e}]\nmodes = [1, 3]", z[0], z[1]);
    let three = |z: &[f64]| {
        format!(
            "ratios = [{:e}, {:e}, {:e}]\nmodes = [1, 3, 4]",
            z[0], z[1], z[2]
        )
    };
    let cases: [RatioCase; 3] = [
        (&one, &["damping.ratio"], vec![0.08]),
        (
            &two,
            &["damping.ratios[0]", "damping.ratios[1]"],
            vec![0.08, 0.06],
        ),
        (
            &three,
            &[
                "damping.ratios[0]",
                "damping.ratios[1]",
                "damping.ratios[2]",
            ],
            // The recorded ratios, 1.25x: the same series scaled, so
            // positive too.
            vec![0.075, 0.0625, 0.25],
        ),
    ];
    for (case, (lines, paths, start)) in cases.iter().enumerate() {
        let scene = caughey_scene(&dir, &format!("start{case}.toml"), &lines(start));
        let out = dir.join(format!("fit{case}"));
        pd_ok(&[
            "fit",
            arg(&scene),
            "--target",
            arg(&target),
            "--fit",
            &paths.join(","),
            "--out",
            arg(&out),
            "--max-iterations",
            "0",
        ]);
        let report = json(&out.join("fit.json"));
        assert_eq!(report["gradient_method"], "adjoint", "{report:#}");
        // As in the three-value check above: a relative step 10x `pd
        // fit`'s, so that the two do not share their errors.
        let h = 1e-3;
        for (i, path) in paths.iter().enumerate() {
            let side = |sign: f64| {
                let mut z = start.clone();
                z[i] *= 1.0 + sign * h;
                let name = format!("c{case}p{i}{sign}");
                let scene = caughey_scene(&dir, &format!("{name}.toml"), &lines(&z));
                loss(&record(&scene, &dir.join(name)), &target)
            };
            let central = (side(1.0) - side(-1.0)) / (2.0 * h * start[i]);
            let reported = report["gradient"][path].as_f64().unwrap();
            // The same bound as the three-value check (truncation ~h^2/6
            // of the third log-derivative over the first, noise of
            // converged runs over 2h: ~1e-6), with the adjoint's own
            // residual (1e-10) below both. Measured: within 6e-7 for one
            // and two ratios, 1.2e-5 for three.
            assert!(
                (reported / central - 1.0).abs() < 1e-4,
                "{path} ({} ratios): pd fit {reported:e}, central difference of pd run {central:e}",
                paths.len()
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
