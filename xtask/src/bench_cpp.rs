//! `cargo xtask cpp-compare --reference PATH [--quick] [--repeat N] [--mesh BASE]...`: runs pd
//! (`pd-probe step`, release build) and the C++ reference `pdref` (Eigen
//! SimplicialLLT and CHOLMOD supernodal back ends; built outside this
//! repository, see docs/design/performance.md) on the same TetGen meshes with the
//! same settings, 1 and 2 threads (generated beams, then each `--mesh`
//! TetGen base, the shared armadillo by default), and writes `docs/reports/cpp-comparison.md` plus
//! the raw numbers in `docs/reports/bench-report/cpp-comparison.json`.
//!
//! Same settings means the reference's formulation: every vertex is an
//! unknown and the clamped end is held by stiff attachments
//! (`--soft-clamp`), strain weight `1e5 x volume`, density 1000, gravity,
//! h = 0.01 s, 10 iterations, backward Euler, no damping, `steps` steps
//! from rest and the median step time. Peak memory of each process is its
//! `VmHWM`, polled from `/proc/PID/status` while it runs. With `--repeat N`
//! every program runs N times per configuration, alternating, and the run
//! with the lowest median step counts (what the reference's RESULTS.md
//! does), so a passing load spike on a shared machine does not decide a
//! ratio. The BLAS that CHOLMOD loads (reference or OpenBLAS) is recorded:
//! it changes CHOLMOD's solve and factorisation times severalfold.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use pd_benches::schema::Step;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::bench_report::{Machine, build_probe, machine, provenance, typed};

/// A `pd-probe step` run with the peak memory polled while it ran.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct PdRun {
    #[serde(flatten)]
    step: Step,
    /// `VmHWM` polled from `/proc/PID/status` (bytes), if it was read.
    peak_bytes_polled: Option<u64>,
}

/// One mesh and thread count: pd and the reference's two back ends (the
/// reference's own output, untyped).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Row {
    mesh: String,
    threads: usize,
    steps: usize,
    eigen: Value,
    cholmod: Value,
    pd: Option<PdRun>,
}

/// Everything `docs/reports/bench-report/cpp-comparison.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Report {
    commit: String,
    date: String,
    machine: Machine,
    machine_after: Machine,
    reference: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    reference_source: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    reference_blas: Option<String>,
    #[serde(default = "one")]
    repeat: u64,
    rows: Vec<Row>,
}

/// The repetitions of a report that does not say.
fn one() -> u64 {
    1
}

/// The meshes: label, cells, steps timed.
fn meshes(quick: bool) -> Vec<(&'static str, [usize; 3], usize)> {
    let mut list = vec![("small", [35, 7, 7], 20), ("medium", [75, 15, 15], 5)];
    if !quick {
        list.push(("large", [130, 26, 26], 3));
    }
    list
}

/// Runs a command to completion, polling its `VmHWM`; returns stdout and
/// the peak resident memory in bytes.
fn run_measured(program: &Path, args: &[String]) -> Result<(String, Option<u64>), String> {
    eprintln!("  {} {}", program.display(), args.join(" "));
    let mut child = Command::new(program)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot run {}: {e}", program.display()))?;
    let status_path = format!("/proc/{}/status", child.id());
    let mut peak: Option<u64> = None;
    let read_hwm = || -> Option<u64> {
        let status = std::fs::read_to_string(&status_path).ok()?;
        let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
        Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
    };
    // The pipes are drained after exit; the outputs are one short line.
    loop {
        if let Some(hwm) = read_hwm() {
            peak = Some(peak.map_or(hwm, |p| p.max(hwm)));
        }
        match child.try_wait().map_err(|e| e.to_string())? {
            Some(_) => break,
            None => std::thread::sleep(Duration::from_millis(5)),
        }
    }
    let output = child.wait_with_output().map_err(|e| e.to_string())?;
    if !output.status.success() {
        return Err(format!(
            "{} {} failed: {}",
            program.display(),
            args.join(" "),
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    Ok((
        String::from_utf8_lossy(&output.stdout).trim().to_string(),
        peak,
    ))
}

fn parse(line: &str) -> Result<Value, String> {
    let last = line.lines().last().unwrap_or("");
    serde_json::from_str(last).map_err(|e| format!("bad JSON ({e}): {last}"))
}

/// The BLAS library the reference loads (`ldd`, then the symlinks resolved),
/// e.g. `/usr/lib/x86_64-linux-gnu/openblas-pthread/libblas.so.3`.
fn blas_of(program: &Path) -> String {
    let Ok(output) = Command::new("ldd").arg(program).output() else {
        return "unknown (ldd failed)".to_string();
    };
    let text = String::from_utf8_lossy(&output.stdout);
    let Some(path) = text
        .lines()
        .find(|l| l.contains("libblas"))
        .and_then(|l| l.split("=>").nth(1))
        .and_then(|rest| rest.split_whitespace().next())
    else {
        return "none linked".to_string();
    };
    std::fs::canonicalize(path).map_or_else(|_| path.to_string(), |p| p.display().to_string())
}

/// The reference's source, identified by the SHA-256 of `pdref.cpp` beside
/// the binary (or of the binary itself when the source is not there).
fn reference_source(program: &Path) -> String {
    let source = program.with_file_name("pdref.cpp");
    let file = if source.is_file() {
        source
    } else {
        program.to_path_buf()
    };
    let hash = Command::new("sha256sum")
        .arg(&file)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| {
            String::from_utf8_lossy(&o.stdout)
                .split_whitespace()
                .next()
                .map(str::to_string)
        });
    match hash {
        Some(hash) => format!("{} (sha256 {hash})", file.display()),
        None => format!("{} (not hashed)", file.display()),
    }
}

/// Keeps the reference run with the lower median step time.
fn keep_faster(best: Option<Value>, candidate: Value) -> Value {
    match best {
        Some(best) if f(&best["step_ms_median"]) <= f(&candidate["step_ms_median"]) => best,
        _ => candidate,
    }
}

/// Keeps the pd run with the lower median step time.
fn keep_faster_pd(best: Option<PdRun>, candidate: PdRun) -> PdRun {
    match best {
        Some(best) if best.step.step_ms_median <= candidate.step.step_ms_median => best,
        _ => candidate,
    }
}

/// A byte count as a number, NaN if it is not known.
fn bytes(value: Option<u64>) -> f64 {
    value.map_or(f64::NAN, |b| b as f64)
}

fn f(value: &Value) -> f64 {
    value.as_f64().unwrap_or(f64::NAN)
}

/// Runs the comparison and writes the table; returns the Markdown path.
pub fn run(root: &Path, args: &[String]) -> Result<PathBuf, String> {
    let quick = args.iter().any(|a| a == "--quick");
    let reference = args
        .iter()
        .position(|a| a == "--reference")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from)
        .ok_or(
            "usage: cargo xtask cpp-compare --reference PATH_TO_PDREF [--quick] [--repeat N] \
             [--mesh BASE]...",
        )?;
    let repeat = match args.iter().position(|a| a == "--repeat") {
        None => 1,
        Some(i) => args
            .get(i + 1)
            .and_then(|n| n.parse::<usize>().ok())
            .filter(|&n| n >= 1)
            .ok_or("--repeat needs a whole number >= 1")?,
    };
    if !reference.is_file() {
        return Err(format!(
            "--reference {}: no such file (build it with the reference's build.sh)",
            reference.display()
        ));
    }
    let probe = build_probe(root)?;
    let work = root.join("target").join("cpp-compare");
    std::fs::create_dir_all(&work).map_err(|e| format!("{}: {e}", work.display()))?;
    let (commit, date) = provenance(root);
    let machine_before = machine();

    // The generated beams, then the TetGen meshes of `--mesh BASE`
    // (repeatable; the shared armadillo by default).
    let mut inputs: Vec<(String, Option<[usize; 3]>, PathBuf, usize)> = meshes(quick)
        .into_iter()
        .map(|(label, cells, steps)| (label.to_string(), Some(cells), work.join(label), steps))
        .collect();
    let mut files: Vec<PathBuf> = args
        .windows(2)
        .filter(|w| w[0] == "--mesh")
        .map(|w| PathBuf::from(&w[1]))
        .collect();
    if files.is_empty() {
        files = crate::bench_limits::default_meshes(root);
    }
    for base in files {
        let label = base.file_name().map_or_else(
            || base.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        inputs.push((label, None, base, if quick { 3 } else { 5 }));
    }
    let mut rows = Vec::new();
    for (label, cells, base, steps) in inputs {
        if let Some(cells) = cells {
            let mesh =
                pd_mesh::generators::box_tets([1.0, 0.2, 0.2], cells).map_err(|e| e.to_string())?;
            pd_io::tetgen::write_tetgen(&base, &mesh).map_err(|e| e.to_string())?;
        }
        let base_arg = base.display().to_string();
        for threads in [1, 2] {
            let common = |extra: &[&str]| -> Vec<String> {
                let mut v: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
                v.extend(
                    [
                        "--mesh",
                        &base_arg,
                        "--steps",
                        &steps.to_string(),
                        "--iters",
                        "10",
                        "--threads",
                        &threads.to_string(),
                    ]
                    .iter()
                    .map(|s| s.to_string()),
                );
                v
            };
            let mut best: [Option<Value>; 2] = [None, None];
            let mut best_pd: Option<PdRun> = None;
            for _ in 0..repeat {
                for (slot, solver) in ["eigen", "cholmod"].into_iter().enumerate() {
                    let (out, peak) = run_measured(
                        &reference,
                        &common(&[
                            "run",
                            "--h",
                            "0.01",
                            "--stiffness",
                            "1e5",
                            "--rho",
                            "1000",
                            "--integrator",
                            "be",
                            "--damp",
                            "0",
                            "--solver",
                            solver,
                        ]),
                    )?;
                    let mut value = parse(&out)?;
                    value["peak_bytes"] = json!(peak);
                    best[slot] = Some(keep_faster(best[slot].take(), value));
                }
                let (out, peak) = run_measured(
                    &probe,
                    &common(&[
                        "step",
                        "--dt",
                        "0.01",
                        "--soft-clamp",
                        "--model",
                        pd_damping::registry::UNDAMPED,
                        "--integrator",
                        "be",
                    ]),
                )?;
                let run = PdRun {
                    step: typed(parse(&out)?)?,
                    peak_bytes_polled: peak,
                };
                best_pd = Some(keep_faster_pd(best_pd.take(), run));
            }
            let [eigen, cholmod] = best.map(|b| b.unwrap_or(Value::Null));
            rows.push(Row {
                mesh: label.clone(),
                threads,
                steps,
                eigen,
                cholmod,
                pd: best_pd,
            });
        }
    }

    let report = Report {
        commit,
        date,
        machine: machine_before,
        machine_after: machine(),
        reference: reference.display().to_string(),
        reference_source: Some(reference_source(&reference)),
        reference_blas: Some(blas_of(&reference)),
        repeat: repeat as u64,
        rows,
    };
    let dir = root.join("docs/reports").join("bench-report");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let json_path = dir.join("cpp-comparison.json");
    // Through `Value`, whose objects keep their keys sorted.
    let value = serde_json::to_value(&report).map_err(|e| e.to_string())?;
    let text = serde_json::to_string_pretty(&value).map_err(|e| e.to_string())?;
    std::fs::write(&json_path, text + "\n").map_err(|e| format!("{}: {e}", json_path.display()))?;
    let md_path = root.join("docs/reports").join("cpp-comparison.md");
    std::fs::write(&md_path, markdown(&report))
        .map_err(|e| format!("{}: {e}", md_path.display()))?;
    Ok(md_path)
}

fn markdown(r: &Report) -> String {
    let m = &r.machine;
    let mut md = String::new();
    let _ = writeln!(md, "# pd against the C++ reference (Eigen, CHOLMOD)\n");
    let _ = writeln!(
        md,
        "Generated by `cargo xtask cpp-compare --reference PATH`; do not edit by hand. Raw \
         numbers: [`bench-report/cpp-comparison.json`](bench-report/cpp-comparison.json). \
         Discussion: [performance.md](../design/performance.md).\n"
    );
    let _ = writeln!(
        md,
        "Machine: {}, {} logical cores, {:.1} GiB. Commit `{}`, {}. CPU pressure before / after: \
         `{}` / `{}`.\n",
        m.cpu,
        m.logical_cores,
        m.memory_gib.unwrap_or(f64::NAN),
        r.commit,
        r.date,
        m.cpu_pressure.as_deref().unwrap_or("n/a"),
        r.machine_after.cpu_pressure.as_deref().unwrap_or("n/a"),
    );
    let _ = writeln!(
        md,
        "Same TetGen mesh (the beams written by pd-io, `--mesh` files as given), same formulation (every vertex free, the clamped \
         end attached with weight 1e6 mean(m)/h^2), stiffness 1e5, rho 1000, h = 0.01 s, 10 \
         iterations, backward Euler, no damping; median step time over the steps run from \
         rest (local + global: the two phases summed over the 10 iterations). Factor: symbolic \
         + numeric factorisation. Ratio: pd / reference (below 1: pd is faster). Memory: peak \
         resident set (`VmHWM`) of each process. Each program ran {} time(s) per row, \
         alternating, and the run with the lowest median step is shown. CHOLMOD's BLAS: `{}`. \
         Reference source: `{}`.\n",
        r.repeat,
        r.reference_blas.as_deref().unwrap_or("not recorded"),
        r.reference_source.as_deref().unwrap_or("not recorded"),
    );
    let _ = writeln!(
        md,
        "| mesh | vertices | threads | steps | pd step [ms] (local + global) | Eigen step [ms] (local + global) | CHOLMOD step [ms] (local + global) | pd/Eigen | pd/CHOLMOD | factor pd / Eigen / CHOLMOD [ms] | nnz(L) pd (stored values) / Eigen / CHOLMOD [M] | peak memory pd / Eigen / CHOLMOD [MB] | pd/CHOLMOD memory | max centroid difference pd - Eigen [m] |"
    );
    let _ = writeln!(
        md,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for row in &r.rows {
        let Some(pd) = row.pd.as_ref().map(|run| &run.step) else {
            continue;
        };
        let (eigen, cholmod) = (&row.eigen, &row.cholmod);
        let centroid_difference = (0..3)
            .map(|k| {
                let key = ["centroid_x", "centroid_y", "centroid_z"][k];
                (pd.centroid[k] - f(&eigen[key])).abs()
            })
            .fold(0.0, f64::max);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.1} ({:.1} + {:.1}) | {:.1} ({:.1} + {:.1}) | {:.1} ({:.1} + {:.1}) | {:.2} | {:.2} | {:.0} / {:.0} / {:.0} | {:.2} ({:.2}) / {:.2} / {:.2} | {:.0} / {:.0} / {:.0} | {:.2} | {:.1e} |",
            row.mesh,
            pd.n_verts,
            row.threads,
            row.steps,
            pd.step_ms_median,
            pd.local_ms_median,
            pd.global_ms_median,
            f(&eigen["step_ms_median"]),
            f(&eigen["local_ms_median"]),
            f(&eigen["global_ms_median"]),
            f(&cholmod["step_ms_median"]),
            f(&cholmod["local_ms_median"]),
            f(&cholmod["global_ms_median"]),
            pd.step_ms_median / f(&eigen["step_ms_median"]),
            pd.step_ms_median / f(&cholmod["step_ms_median"]),
            pd.factor_ms,
            f(&eigen["factor_ms"]),
            f(&cholmod["factor_ms"]),
            // Structural non-zeros, as Eigen and CHOLMOD (`lnz`) count them;
            // the stored values add faer's supernode padding.
            pd.nnz_l_exact as f64 / 1e6,
            pd.nnz_l_factor as f64 / 1e6,
            f(&eigen["nnz_L_factor"]) / 1e6,
            f(&cholmod["nnz_L_factor"]) / 1e6,
            bytes(pd.peak_bytes) / 1e6,
            f(&eigen["peak_bytes"]) / 1e6,
            f(&cholmod["peak_bytes"]) / 1e6,
            bytes(pd.peak_bytes) / f(&cholmod["peak_bytes"]),
            centroid_difference,
        );
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stored comparison reads into the typed report and writes back
    /// byte for byte (through `Value`, keys sorted), and renders.
    #[test]
    fn the_stored_comparison_round_trips_through_the_schema() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .expect("xtask lives inside the workspace");
        let path = root.join("docs/reports/bench-report/cpp-comparison.json");
        let text = std::fs::read_to_string(&path).expect("the stored comparison");
        let report: Report = serde_json::from_str(&text).expect("a comparison");
        let value = serde_json::to_value(&report).expect("a value");
        assert_eq!(
            serde_json::to_string_pretty(&value).expect("JSON") + "\n",
            text
        );
        assert!(markdown(&report).starts_with("# pd against the C++ reference"));
    }
}
