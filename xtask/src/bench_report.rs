//! `cargo xtask bench-report [--quick]`: measures the speed/accuracy trade
//! and writes `docs/reports/bench-report.md`, the raw numbers
//! (`docs/reports/bench-report/report.json`) and the figures
//! (`docs/reports/bench-report/*.png`).
//!
//! Every measurement runs in a fresh process of the release-built
//! `pd-probe` (benches/src/bin/pd-probe.rs), so that each one's peak memory
//! (`VmHWM`) is its own and a crash cannot take the report down with it.
//! The sizes, iteration counts and repetitions below are fixed, so the
//! command is deterministic to run; only the timings vary with the machine.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use pd_benches::schema::{Accuracy, AccuracyRow, AccuracyTarget, Contact, Overhead, Phases, Step};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::bench_methods::MethodsRun;
use crate::bench_plot::{self, Series};

/// The machine a report ran on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Machine {
    /// The CPU model (`unknown` if not found).
    pub cpu: String,
    /// Logical cores (0 if not known).
    pub logical_cores: usize,
    /// Memory in GiB, if known.
    pub memory_gib: Option<f64>,
    /// The first line of `/proc/pressure/cpu`, if there is one.
    pub cpu_pressure: Option<String>,
    /// The widest SIMD instructions pd's kernels dispatch to here
    /// (`AVX-512`, `AVX2` or `none`), if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simd: Option<String>,
    /// The 1-, 5- and 15-minute load averages of `/proc/loadavg`, if
    /// known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_average: Option<String>,
}

/// Where and when a section measured again on its own
/// (`bench-report --only SECTION`) was measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SectionRun {
    /// The commit (with `-dirty` for uncommitted changes).
    pub commit: String,
    /// The UTC date.
    pub date: String,
    /// The machine, read just before the section ran.
    pub machine: Machine,
}

/// The sections `bench-report --only` can measure again on their own,
/// keeping the rest of the stored report.
pub const SECTIONS_ALONE: &[&str] = &["python", "gradients", "accuracy-target", "contact"];

/// One pair of `pd-probe phases` runs, on 1 and on 2 threads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct LocalSpeedup {
    one: Phases,
    two: Phases,
    /// The local step's median on one thread over that on two.
    #[serde(
        default = "pd_benches::schema::nan",
        deserialize_with = "pd_benches::schema::number"
    )]
    speedup: f64,
}

/// Everything `docs/reports/bench-report/report.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Report {
    limits: Value,
    methods: Vec<MethodsRun>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    accuracy_target: Vec<AccuracyTarget>,
    contact: Vec<Contact>,
    mode: String,
    commit: String,
    date: String,
    machine: Machine,
    machine_after: Machine,
    #[serde(
        default = "pd_benches::schema::nan",
        deserialize_with = "pd_benches::schema::number"
    )]
    wall_seconds: f64,
    overhead: Vec<Overhead>,
    accuracy: Vec<Accuracy>,
    scaling: Vec<Step>,
    local_speedup: Vec<LocalSpeedup>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    python: Option<crate::bench_python::PythonSection>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    gradients: Vec<crate::bench_gradients::GradientCost>,
    /// Sections measured again on their own after the full run, by name
    /// ([`SECTIONS_ALONE`]), with their own commit and machine.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    remeasured: std::collections::BTreeMap<String, SectionRun>,
}

/// What one mode (full or quick) measures.
struct Plan {
    overhead_cells: [usize; 3],
    overhead_rounds: usize,
    accuracy_cells: [usize; 3],
    accuracy_time: f64,
    scaling_cells: Vec<[usize; 3]>,
    scaling_steps: usize,
    speedup_cells: [usize; 3],
    speedup_pairs: usize,
}

impl Plan {
    fn new(quick: bool) -> Self {
        if quick {
            Self {
                overhead_cells: [35, 7, 7],
                overhead_rounds: 5,
                accuracy_cells: [20, 4, 4],
                accuracy_time: 0.3,
                scaling_cells: vec![[20, 4, 4], [35, 7, 7], [50, 10, 10], [75, 15, 15]],
                scaling_steps: 2,
                speedup_cells: [75, 15, 15],
                speedup_pairs: 1,
            }
        } else {
            Self {
                overhead_cells: [35, 7, 7],
                overhead_rounds: 21,
                accuracy_cells: [35, 7, 7],
                accuracy_time: 0.5,
                scaling_cells: vec![
                    [20, 4, 4],
                    [35, 7, 7],
                    [50, 10, 10],
                    [75, 15, 15],
                    [100, 20, 20],
                    [130, 26, 26],
                ],
                scaling_steps: 3,
                speedup_cells: [75, 15, 15],
                speedup_pairs: 3,
            }
        }
    }
}

fn cells_arg(cells: [usize; 3]) -> String {
    format!("{},{},{}", cells[0], cells[1], cells[2])
}

/// Builds `pd-probe` in release mode and returns its path.
pub fn build_probe(root: &Path) -> Result<PathBuf, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("building pd-probe (release)...");
    let status = Command::new(&cargo)
        .current_dir(root)
        .args([
            "build",
            "--release",
            "--quiet",
            "-p",
            "pd-benches",
            "--bin",
            "pd-probe",
        ])
        .status()
        .map_err(|e| format!("cannot run {cargo}: {e}"))?;
    if !status.success() {
        return Err("building pd-probe failed".into());
    }
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    Ok(target.join("release").join("pd-probe"))
}

/// Runs `pd-probe ARGS` and parses its JSON line.
pub fn probe(binary: &Path, args: &[String]) -> Result<Value, String> {
    eprintln!("  pd-probe {}", args.join(" "));
    let output = Command::new(binary)
        .args(args)
        .output()
        .map_err(|e| format!("cannot run {}: {e}", binary.display()))?;
    if !output.status.success() {
        return Err(format!(
            "pd-probe {} failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    let text = String::from_utf8_lossy(&output.stdout);
    serde_json::from_str(text.trim())
        .map_err(|e| format!("pd-probe printed bad JSON ({e}): {text}"))
}

/// A probe's output as its typed schema (`pd_benches::schema`).
pub fn typed<T: DeserializeOwned>(value: Value) -> Result<T, String> {
    serde_json::from_value(value).map_err(|e| format!("pd-probe output: {e}"))
}

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// The machine: CPU model, logical cores, memory.
pub fn machine() -> Machine {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|| "unknown".into());
    let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
    let memory_gib = meminfo
        .lines()
        .find(|l| l.starts_with("MemTotal:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<f64>().ok())
        .map(|kb| kb / (1024.0 * 1024.0));
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let pressure = std::fs::read_to_string("/proc/pressure/cpu")
        .ok()
        .and_then(|t| t.lines().next().map(str::to_string));
    let load_average = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|t| t.split_whitespace().take(3).collect::<Vec<_>>().join(" "));
    Machine {
        cpu,
        logical_cores: cores,
        memory_gib,
        cpu_pressure: pressure,
        simd: Some(simd().into()),
        load_average,
    }
}

/// The widest instructions `pd_linalg::simd::dispatch` runs here: AVX-512
/// (F, DQ and VL: 8 f64 lanes), else AVX2 (with FMA: 4 lanes), else none.
fn simd() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        if has!("avx512f") && has!("avx512dq") && has!("avx512vl") {
            return "AVX-512 (8 f64 lanes)";
        }
        if has!("avx2") && has!("fma") {
            return "AVX2 (4 f64 lanes)";
        }
    }
    "none (plain path)"
}

fn command_output(program: &str, arguments: &[&str], root: &Path) -> Option<String> {
    let out = Command::new(program)
        .current_dir(root)
        .args(arguments)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// The commit (with `-dirty` for uncommitted changes) and the UTC date.
pub fn provenance(root: &Path) -> (String, String) {
    let commit = command_output("git", &["rev-parse", "--short=12", "HEAD"], root)
        .unwrap_or_else(|| "unknown".into());
    let dirty = command_output(
        "git",
        &["status", "--porcelain", "--untracked-files=no"],
        root,
    )
    .is_some_and(|s| !s.is_empty());
    let date = command_output("date", &["-u", "+%Y-%m-%d %H:%M UTC"], root)
        .unwrap_or_else(|| "unknown".into());
    (
        if dirty {
            format!("{commit}-dirty")
        } else {
            commit
        },
        date,
    )
}

/// Least-squares slope of `ln y` against `ln x`: the exponent `p` of
/// `y ~ x^p`. `None` with fewer than two usable points.
pub fn fitted_exponent(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let (mx, my) = (
        logs.iter().map(|p| p.0).sum::<f64>() / n,
        logs.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// A byte count as a number, NaN if it is not known.
fn bytes(value: Option<u64>) -> f64 {
    value.map_or(f64::NAN, |b| b as f64)
}

/// A number as JSON writes it (`0.01`, `1.0`; `null` if not finite).
pub fn json_text(value: f64) -> String {
    Value::from(value).to_string()
}

/// Runs every measurement and writes the report; returns the Markdown path.
/// Runs every measurement; `meshes` are TetGen bases (`.node`/`.ele`)
/// measured in the "Real meshes" section (the armadillo by default).
pub fn run(root: &Path, quick: bool, meshes: &[PathBuf]) -> Result<PathBuf, String> {
    let started = Instant::now();
    let plan = Plan::new(quick);
    let probe_path = build_probe(root)?;
    let p = |a: Vec<String>| probe(&probe_path, &a);
    let (commit, date) = provenance(root);
    let machine_before = machine();

    eprintln!("damping overhead...");
    let mut overhead: Vec<Overhead> = Vec::new();
    for integrator in ["be", "im"] {
        overhead.push(typed(p(args(&[
            "overhead",
            "--cells",
            &cells_arg(plan.overhead_cells),
            "--integrator",
            integrator,
            "--rounds",
            &plan.overhead_rounds.to_string(),
            "--warmup",
            "5",
            "--threads",
            "1",
        ]))?)?);
    }

    eprintln!("speed against accuracy...");
    let mut accuracy: Vec<Accuracy> = Vec::new();
    for integrator in pd_integrators::registry::short_names() {
        accuracy.push(typed(p(args(&[
            "accuracy",
            "--cells",
            &cells_arg(plan.accuracy_cells),
            "--integrator",
            integrator,
            "--time",
            &plan.accuracy_time.to_string(),
            "--threads",
            "1",
        ]))?)?);
    }

    eprintln!("scaling...");
    let mut scaling: Vec<Step> = Vec::new();
    for &cells in &plan.scaling_cells {
        scaling.push(typed(p(args(&[
            "step",
            "--cells",
            &cells_arg(cells),
            "--steps",
            &plan.scaling_steps.to_string(),
            "--threads",
            "1",
        ]))?)?);
    }

    eprintln!("local-step speed-up...");
    let mut speedup = Vec::new();
    for _ in 0..plan.speedup_pairs {
        let mut pair: Vec<Phases> = Vec::new();
        for threads in ["1", "2"] {
            pair.push(typed(p(args(&[
                "phases",
                "--cells",
                &cells_arg(plan.speedup_cells),
                "--threads",
                threads,
                "--reps",
                "20",
                "--factor-reps",
                "1",
            ]))?)?);
        }
        let [one, two]: [Phases; 2] = pair
            .try_into()
            .map_err(|_| "a speed-up pair is two runs".to_string())?;
        speedup.push(LocalSpeedup {
            speedup: one.local_ms_median / two.local_ms_median,
            one,
            two,
        });
    }

    eprintln!("limits and real meshes...");
    let mut limits = crate::bench_limits::measure(&p, quick, meshes)?;
    let pair_speedups: Vec<f64> = speedup.iter().map(|pair| pair.speedup).collect();
    crate::bench_limits::flag_speedups(&mut limits, "local step", &pair_speedups);
    eprintln!("iteration methods...");
    let methods = crate::bench_methods::measure(&p, quick)?;
    eprintln!("speed against an accuracy target...");
    let accuracy_target = crate::bench_accuracy_target::measure(&p, quick, meshes)?;
    eprintln!("contact...");
    let contact = crate::bench_contact::measure(&p, quick)?;
    eprintln!("gradients...");
    let gradients = crate::bench_gradients::measure(root, quick)?;
    eprintln!("python call overhead...");
    let python = crate::bench_python::measure(root, if quick { 3 } else { 9 });

    let report = Report {
        limits,
        methods,
        accuracy_target,
        contact,
        mode: if quick { "quick" } else { "full" }.into(),
        commit,
        date,
        machine: machine_before,
        machine_after: machine(),
        wall_seconds: started.elapsed().as_secs_f64(),
        overhead,
        accuracy,
        scaling,
        local_speedup: speedup,
        python: Some(python),
        gradients,
        remeasured: Default::default(),
    };
    write_report(root, &report)
}

/// `bench-report --only NAMES`: measures the sections `names` (of
/// [`SECTIONS_ALONE`]) again and writes them into the stored report, each
/// stamped with its own commit, date and machine; every other section stays
/// as the last full run measured it.
///
/// # Errors
/// An unknown section, no stored report, or a failed measurement.
pub fn run_only(root: &Path, names: &[String], meshes: &[PathBuf]) -> Result<PathBuf, String> {
    if let Some(unknown) = names.iter().find(|n| !SECTIONS_ALONE.contains(&n.as_str())) {
        return Err(format!(
            "--only: unknown section {unknown:?}; sections measured alone: {}",
            SECTIONS_ALONE.join(", ")
        ));
    }
    let json_path = root.join("docs/reports/bench-report/report.json");
    let text = std::fs::read_to_string(&json_path).map_err(|e| {
        format!(
            "{}: {e} (--only updates a stored report; run the full report first)",
            json_path.display()
        )
    })?;
    let mut report: Report =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", json_path.display()))?;
    for name in names {
        let (commit, date) = provenance(root);
        let run = SectionRun {
            commit,
            date,
            machine: machine(),
        };
        eprintln!("{name}...");
        match name.as_str() {
            "python" => report.python = Some(crate::bench_python::measure(root, 9)),
            "gradients" => report.gradients = crate::bench_gradients::measure(root, false)?,
            "accuracy-target" | "contact" => {
                let probe_path = build_probe(root)?;
                let p = |a: Vec<String>| probe(&probe_path, &a);
                if name == "contact" {
                    report.contact = crate::bench_contact::measure(&p, false)?;
                } else {
                    report.accuracy_target =
                        crate::bench_accuracy_target::measure(&p, false, meshes)?;
                }
            }
            _ => {}
        }
        report.remeasured.insert(name.clone(), run);
    }
    write_report(root, &report)
}

/// The line under a section's heading saying where it was measured, when
/// that was after the full run.
fn remeasured_note(r: &Report, name: &str) -> String {
    r.remeasured.get(name).map_or_else(String::new, |run| {
        format!(
            "Measured on its own (`cargo xtask bench-report --only {name}`) at commit `{}`, {}, \
             {} ({}), load average {}.\n\n",
            run.commit,
            run.date,
            run.machine.cpu,
            run.machine.simd.as_deref().unwrap_or("SIMD unknown"),
            run.machine.load_average.as_deref().unwrap_or("unknown"),
        )
    })
}

fn write_report(root: &Path, report: &Report) -> Result<PathBuf, String> {
    let dir = root.join("docs/reports").join("bench-report");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let json_path = dir.join("report.json");
    // Through `Value`, whose objects keep their keys sorted.
    let value = serde_json::to_value(report).map_err(|e| e.to_string())?;
    let text = serde_json::to_string_pretty(&value).map_err(|e| e.to_string())?;
    std::fs::write(&json_path, text + "\n").map_err(|e| format!("{}: {e}", json_path.display()))?;

    // Figures.
    crate::bench_methods::figure(&dir, &report.methods)?;
    let mut position = Vec::new();
    let mut energy = Vec::new();
    for run in &report.accuracy {
        let name = run.integrator.to_uppercase();
        let pick = |error: fn(&AccuracyRow) -> f64| -> Vec<(f64, f64)> {
            run.rows
                .iter()
                .map(|r| (r.step_ms_median, error(r)))
                .collect()
        };
        position.push(Series {
            name: name.clone(),
            points: pick(|r| r.position_error_rel),
        });
        energy.push(Series {
            name,
            points: pick(|r| r.energy_error_rel),
        });
    }
    bench_plot::log_log(
        &dir.join("accuracy.png"),
        "Error after a fixed simulated time vs time per step (iterations 1..50)",
        "time per step [ms]",
        &[
            ("position error / body diagonal", &position),
            ("energy error / (m g L)", &energy),
        ],
    )?;
    let scaling = &report.scaling;
    let by_size = |time: fn(&Step) -> f64| -> Vec<(f64, f64)> {
        scaling
            .iter()
            .map(|r| (r.n_verts as f64, time(r)))
            .collect()
    };
    let memory: Vec<(f64, f64)> = scaling
        .iter()
        .map(|r| (r.n_verts as f64, bytes(r.peak_bytes) / 1e6))
        .collect();
    bench_plot::log_log(
        &dir.join("scaling.png"),
        "Scaling with the vertex count (1 thread, 10 iterations, BE)",
        "vertices",
        &[
            (
                "time [ms]",
                &[
                    Series {
                        name: "numeric factorisation".into(),
                        points: by_size(|r| r.numeric_factor_ms),
                    },
                    Series {
                        name: "step".into(),
                        points: by_size(|r| r.step_ms_median),
                    },
                ],
            ),
            (
                "peak memory [MB]",
                &[Series {
                    name: "VmHWM".into(),
                    points: memory,
                }],
            ),
        ],
    )?;

    let md = markdown(report);
    let md_path = root.join("docs/reports").join("bench-report.md");
    std::fs::write(&md_path, md).map_err(|e| format!("{}: {e}", md_path.display()))?;
    Ok(md_path)
}

fn markdown(r: &Report) -> String {
    let mut md = String::new();
    let m = &r.machine;
    let _ = writeln!(md, "# Benchmark report\n");
    let _ = writeln!(
        md,
        "Generated by `cargo xtask bench-report{}` ({} mode); do not edit by hand. \
         Raw numbers: [`bench-report/report.json`](bench-report/report.json). \
         How to read it and what was found: [performance.md](../design/performance.md).\n",
        if r.mode == "quick" { " --quick" } else { "" },
        r.mode
    );
    let _ = writeln!(md, "| | |\n| --- | --- |");
    let _ = writeln!(md, "| CPU | {} |", m.cpu);
    if let Some(simd) = &m.simd {
        let _ = writeln!(md, "| SIMD | {simd} |");
    }
    let _ = writeln!(md, "| logical cores | {} |", m.logical_cores);
    let _ = writeln!(
        md,
        "| memory | {:.1} GiB |",
        m.memory_gib.unwrap_or(f64::NAN)
    );
    let _ = writeln!(md, "| commit | `{}` |", r.commit);
    let _ = writeln!(md, "| date | {} |", r.date);
    let _ = writeln!(
        md,
        "| CPU pressure before / after | `{}` / `{}` |",
        m.cpu_pressure.as_deref().unwrap_or("n/a"),
        r.machine_after.cpu_pressure.as_deref().unwrap_or("n/a")
    );
    if let (Some(before), Some(after)) = (&m.load_average, &r.machine_after.load_average) {
        let _ = writeln!(
            md,
            "| load average (1, 5, 15 min) before / after | {before} / {after} |"
        );
    }
    let _ = writeln!(
        md,
        "| wall time of the report | {:.0} s |\n",
        r.wall_seconds
    );
    let _ = writeln!(
        md,
        "Scene: box cantilever 1 x 0.2 x 0.2 m clamped at x = 0, corotational strain \
         1e5 Pa, 1000 kg/m^3, gravity, h = 0.01 s, fixed iteration count (no tolerance), \
         release build, timings with `std::time::Instant`. Damping coefficients: ether drag \
         1/s (explicit), PBD 0.05, lagged Rayleigh 0.003 s, Laplacian 0.003 s.\n"
    );

    let _ = writeln!(md, "## Overhead of each damping model\n");
    let overhead = &r.overhead;
    if let Some(first) = overhead.first() {
        let _ = writeln!(
            md,
            "{} vertices, {} iterations, 1 thread. Every model steps from the same state (the \
             undamped beam after 5 steps); the models' steps are interleaved, {} rounds, so drift \
             in the machine's speed hits all alike. Median time per step and its ratio to `none` \
             of the same integrator, same run.\n",
            first.n_verts, first.iters, first.rounds
        );
    }
    let _ = writeln!(
        md,
        "| integrator | model | median step [ms] | fastest [ms] | ratio to none |"
    );
    let _ = writeln!(md, "| --- | --- | --- | --- | --- |");
    for run in overhead {
        for model in &run.models {
            let _ = writeln!(
                md,
                "| {} | {} | {:.2} | {:.2} | {:.3} |",
                run.integrator, model.model, model.median_ms, model.min_ms, model.ratio_to_none
            );
        }
    }

    let _ = writeln!(md, "\n## Speed against accuracy\n");
    let accuracy = &r.accuracy;
    if let Some(first) = accuracy.first() {
        let _ = writeln!(
            md,
            "{} vertices, no damping, {} steps of {} s ({} s simulated), 1 thread. Reference: the \
             same integrator and step solved to a relative tolerance of {:e} (at most 2000 \
             iterations). Position error: the largest vertex distance to the reference divided by \
             the body's diagonal (1.04 m). Energy error: |E - E_ref| (kinetic + elastic + \
             gravitational) divided by m g L, the total weight times the diagonal ({:.1} J).\n",
            first.n_verts,
            first.steps,
            json_text(first.dt),
            json_text(first.time),
            first.reference_tolerance,
            first.energy_scale_joule
        );
    }
    let _ = writeln!(
        md,
        "| integrator | iterations | position error | energy error | step [ms] |"
    );
    let _ = writeln!(md, "| --- | --- | --- | --- | --- |");
    for run in accuracy {
        for row in &run.rows {
            let _ = writeln!(
                md,
                "| {} | {} | {:.2e} | {:.2e} | {:.2} |{}",
                run.integrator,
                row.iters,
                row.position_error_rel,
                row.energy_error_rel,
                row.step_ms_median,
                if row.diverged { " diverged" } else { "" }
            );
        }
    }
    for run in accuracy {
        let _ = writeln!(
            md,
            "\nReference ({}): {:.1} iterations per step on average, {} steps not converged.",
            run.integrator, run.reference_mean_iterations, run.reference_unconverged_steps
        );
    }
    let _ = writeln!(
        md,
        "\n![error against time per step](bench-report/accuracy.png)\n\n\
         Left: position error, right: energy error, both against the median time per step; \
         each curve's points are the iteration counts 1, 2, 3, 5, 10, 20, 50 from left to right.\n"
    );

    md.push_str(&crate::bench_methods::markdown(&r.methods));
    if !r.accuracy_target.is_empty() {
        md.push_str(&crate::bench_accuracy_target::markdown(
            &r.accuracy_target,
            &remeasured_note(r, "accuracy-target"),
        ));
    }
    md.push_str(&crate::bench_contact::markdown(
        &r.contact,
        &remeasured_note(r, "contact"),
    ));
    if !r.gradients.is_empty() {
        md.push('\n');
        md.push_str(&crate::bench_gradients::markdown(
            &r.gradients,
            &remeasured_note(r, "gradients"),
        ));
    }
    if let Some(python) = &r.python {
        md.push('\n');
        md.push_str(&crate::bench_python::markdown(
            python,
            &remeasured_note(r, "python"),
        ));
    }
    let _ = writeln!(md, "## Scaling\n");
    let scaling = &r.scaling;
    let _ = writeln!(
        md,
        "Backward Euler, no damping, 10 iterations, 1 thread; each size in its own process. \
         Factorisation: the numeric Cholesky factorisation (faer; AMD or nested-dissection ordering, whichever a cost model of the solve prefers); analysis: \
         assembly, ordering and symbolic factorisation. Peak memory: the process's `VmHWM`.\n"
    );
    let _ = writeln!(
        md,
        "| vertices | tets | nnz(L) [M] | analysis [ms] | numeric factorisation [ms] | step [ms] | local / global per step [ms] | peak memory [MB] |"
    );
    let _ = writeln!(md, "| --- | --- | --- | --- | --- | --- | --- | --- |");
    for row in scaling {
        let _ = writeln!(
            md,
            "| {} | {} | {:.2} | {:.0} | {:.1} | {:.1} | {:.1} / {:.1} | {:.0} |",
            row.n_verts,
            row.n_tets,
            row.nnz_l_factor as f64 / 1e6,
            row.symbolic_ms,
            row.numeric_factor_ms,
            row.step_ms_median,
            row.local_ms_median,
            row.global_ms_median,
            bytes(row.peak_bytes) / 1e6
        );
    }
    let fit = |y: fn(&Step) -> f64, scale: f64| {
        fitted_exponent(
            &scaling
                .iter()
                .map(|r| (r.n_verts as f64, y(r) * scale))
                .collect::<Vec<_>>(),
        )
    };
    let show = |e: Option<f64>| e.map_or("n/a".into(), |e| format!("{e:.2}"));
    let _ = writeln!(
        md,
        "\nFitted exponents p of `y ~ n^p` (least squares in log-log over all sizes): \
         numeric factorisation {}, step {}, nnz(L) {}, peak memory {}.\n",
        show(fit(|r| r.numeric_factor_ms, 1.0)),
        show(fit(|r| r.step_ms_median, 1.0)),
        show(fit(|r| r.nnz_l_factor as f64, 1.0)),
        show(fit(|r| bytes(r.peak_bytes), 1.0))
    );
    let _ = writeln!(md, "![scaling](bench-report/scaling.png)\n");

    let _ = writeln!(md, "## Parallel speed-up of the local step\n");
    let speedup = &r.local_speedup;
    if let Some(first) = speedup.first() {
        let _ = writeln!(
            md,
            "{} tets, median of 20 local steps (every constraint projected once, caches warm) \
             per run; 1 and 2 threads run alternately in separate processes. A speed-up above \
             2.05 flags the report as noisy (limits section below).\n",
            first.one.n_tets
        );
    }
    let _ = writeln!(md, "| pair | 1 thread [ms] | 2 threads [ms] | speed-up |");
    let _ = writeln!(md, "| --- | --- | --- | --- |");
    for (i, pair) in speedup.iter().enumerate() {
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} | {:.2} |",
            i + 1,
            pair.one.local_ms_median,
            pair.two.local_ms_median,
            pair.speedup
        );
    }
    if !r.limits.is_null() {
        let _ = writeln!(md);
        md.push_str(&crate::bench_limits::markdown(&r.limits));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponent_of_a_power_law_is_recovered() {
        let points: Vec<(f64, f64)> = [1.0, 10.0, 100.0]
            .iter()
            .map(|&x: &f64| (x, 3.0 * x.powf(1.5)))
            .collect();
        assert!((fitted_exponent(&points).unwrap() - 1.5).abs() < 1e-12);
        assert_eq!(fitted_exponent(&points[..1]), None);
    }

    /// The stored report reads into the typed schema and writes back
    /// byte for byte (the file is written through `Value`, keys sorted),
    /// and renders.
    #[test]
    fn the_stored_report_round_trips_through_the_schema() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .expect("xtask lives inside the workspace");
        let path = root.join("docs/reports/bench-report/report.json");
        let text = std::fs::read_to_string(&path).expect("the stored report");
        let report: Report = serde_json::from_str(&text).expect("a report");
        let value = serde_json::to_value(&report).expect("a value");
        assert_eq!(
            serde_json::to_string_pretty(&value).expect("JSON") + "\n",
            text
        );
        assert!(markdown(&report).starts_with("# Benchmark report"));
    }
}
