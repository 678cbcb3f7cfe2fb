//! The "limits" and "meshes" sections of `cargo xtask bench-report`: how
//! far the step is from what the machine allows, whether the run was quiet
//! enough for any verdict, and the step on real (TetGen) meshes.
//!
//! - Streaming bandwidth: `pd-probe bandwidth` (best single-thread read of
//!   a 512 MiB array), and with `--threads 2` the bandwidth both cores get
//!   together, the bound of the 2-thread rows (the same bytes).
//! - The solve bound: a forward and a backward substitution each read the
//!   whole factor once (all three right-hand-side columns at a time), so a
//!   solve cannot take less than `2 x 8 bytes x stored values / bandwidth`.
//!   The report divides by it both the solve alone (`solve_ms_median` of
//!   `pd-probe step`: the solves timed after the steps, which is what the
//!   bound describes) and the global step's time per iteration (the solve
//!   plus the right-hand side's assembly `B^T p` and the update of the
//!   displacement, which the bound does not count). The bandwidth is the
//!   best of its repetitions, so the fastest solve (`solve_ms_min`, the
//!   fastest over the runs) is divided by it too: best against best, beside
//!   the median against best.
//! - The solve in the caches: the same solve on a beam whose factor stays
//!   in the caches (32 x 8 x 8 cells, 1.7 MB), in ns per stored value per
//!   pass against the bound's `8 bytes / bandwidth`: above 1, the kernels,
//!   not the memory, set the solve's floor on this machine.
//! - Local step: ns per tet per iteration, at 1 and 2 threads.
//! - Noise: CPU pressure (`/proc/pressure/cpu`, `some avg10`) above
//!   [`PRESSURE_NOISY`] % before or after, a 2-thread speed-up above
//!   [`SPEEDUP_NOISY`] (impossible on 2 cores without interference) or a
//!   spread of repeated runs above [`SPREAD_NOISY`] flags the report as
//!   noisy, with the reasons. Beside it, a control: `pd-probe
//!   cache-scaling` reads the local step's working set again and again on
//!   1 and 2 threads, sharing nothing; above the same threshold there, the
//!   machine's caches alone make a 2-thread speed-up above 2 (the report
//!   says so; the flag stands).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use pd_benches::schema::{Bandwidth, Step};
use pd_io::stats::upper_median;
use serde_json::{Value, json};

use crate::bench_report::typed;

/// `some avg10` CPU pressure (%) above which a run is flagged.
const PRESSURE_NOISY: f64 = 5.0;
/// A 2-thread speed-up above this is interference, not parallelism.
const SPEEDUP_NOISY: f64 = 2.05;
/// Spread `(max - min) / min` of repeated step times above this is noise.
const SPREAD_NOISY: f64 = 0.05;

/// The limits beam (1 x 0.2 x 0.2 m; 80 x 14 x 14 cells,
/// 94,080 tets) or a smaller one for `--quick`.
fn cells(quick: bool) -> [usize; 3] {
    if quick { [35, 7, 7] } else { [80, 14, 14] }
}

/// A beam whose factor (about 1.7 MB stored, 0.4 MB for `--quick`) stays
/// in the caches between solves.
fn cells_in_cache(quick: bool) -> [usize; 3] {
    if quick { [20, 6, 6] } else { [32, 8, 8] }
}

/// The standard real mesh, if the shared meshes sit beside the repository.
pub fn default_meshes(root: &Path) -> Vec<PathBuf> {
    let armadillo = root.join("../shared/meshes/armadillo/armadillo");
    if armadillo.with_extension("node").exists() {
        vec![armadillo]
    } else {
        Vec::new()
    }
}

/// `some avg10` of `/proc/pressure/cpu`, if the kernel reports it.
fn cpu_pressure() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/pressure/cpu").ok()?;
    let some = text.lines().find(|l| l.starts_with("some"))?;
    some.split_whitespace()
        .find_map(|field| field.strip_prefix("avg10="))?
        .parse()
        .ok()
}

fn f(value: &Value) -> f64 {
    value.as_f64().unwrap_or(f64::NAN)
}

/// Runs the measurements with `probe` (one `pd-probe` invocation per call).
pub fn measure(
    probe: &dyn Fn(Vec<String>) -> Result<Value, String>,
    quick: bool,
    meshes: &[PathBuf],
) -> Result<Value, String> {
    let strings = |list: &[&str]| list.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let pressure_before = cpu_pressure();
    let bandwidth: Bandwidth = typed(probe(strings(&[
        "bandwidth",
        "--mib",
        if quick { "256" } else { "512" },
    ]))?)?;
    let bandwidth_2: Bandwidth = typed(probe(strings(&[
        "bandwidth",
        "--mib",
        if quick { "256" } else { "512" },
        "--threads",
        "2",
    ]))?)?;
    let cells = cells(quick);
    let cells_arg = format!("{},{},{}", cells[0], cells[1], cells[2]);
    let repeats = if quick { 2 } else { 3 };
    let mut per_threads = Vec::new();
    for threads in ["1", "2"] {
        let measured = if threads == "1" {
            &bandwidth
        } else {
            &bandwidth_2
        };
        let bytes_per_second = measured.bytes_per_second;
        let mut runs: Vec<Step> = Vec::new();
        for _ in 0..repeats {
            runs.push(typed(probe(strings(&[
                "step",
                "--cells",
                &cells_arg,
                "--steps",
                "5",
                "--threads",
                threads,
            ]))?)?);
        }
        let first = runs.first().ok_or("no step runs")?;
        let pick =
            |time: fn(&Step) -> f64| upper_median(&runs.iter().map(time).collect::<Vec<_>>());
        let steps: Vec<f64> = runs.iter().map(|r| r.step_ms_median).collect();
        let low = steps.iter().copied().fold(f64::INFINITY, f64::min);
        let high = steps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (iters, tets) = (first.iters as f64, first.n_tets as f64);
        let factor_bytes = 8.0 * first.nnz_l_factor as f64;
        let bound_ms = 2.0 * factor_bytes / bytes_per_second * 1e3;
        let global_per_iteration = pick(|r| r.global_ms_median) / iters;
        let solve = pick(|r| r.solve_ms_median);
        let fastest = runs
            .iter()
            .map(|r| r.solve_ms_min)
            .fold(f64::INFINITY, f64::min);
        per_threads.push(json!({
            "threads": threads,
            "local_bytes": first.local_bytes as f64,
            "step_ms": pick(|r| r.step_ms_median),
            "local_ns_per_tet_iteration": pick(|r| r.local_ms_median) * 1e6 / (iters * tets),
            "global_ms_per_iteration": global_per_iteration,
            "factor_bytes": factor_bytes,
            "bandwidth_bytes_per_second": bytes_per_second,
            "solve_bound_ms": bound_ms,
            "ratio_to_bound": global_per_iteration / bound_ms,
            "solve_ms": solve,
            "solve_ratio_to_bound": solve / bound_ms,
            "solve_ms_fastest": fastest,
            "fastest_solve_ratio_to_bound": fastest / bound_ms,
            "spread": (high - low) / low,
            "n_tets": tets,
            "iters": iters,
        }));
    }
    // The same solve on a beam whose factor stays in the caches: its time
    // per stored value, against the streaming bound's, says whether the
    // kernels or the memory set the solve's floor.
    let small = cells_in_cache(quick);
    let in_cache: Step = typed(probe(strings(&[
        "step",
        "--cells",
        &format!("{},{},{}", small[0], small[1], small[2]),
        "--steps",
        "2",
        "--threads",
        "1",
    ]))?)?;
    let cached_values = in_cache.nnz_l_factor as f64;
    let cached_ns = in_cache.solve_ms_median * 1e6 / (2.0 * cached_values);
    let cached_fastest_ns = in_cache.solve_ms_min * 1e6 / (2.0 * cached_values);
    let bound_ns = 8.0 / bandwidth.bytes_per_second * 1e9;
    let in_cache = json!({
        "cells": small,
        "factor_bytes": 8.0 * cached_values,
        "solve_ms": in_cache.solve_ms_median,
        "ns_per_value_pass": cached_ns,
        "bound_ns_per_value": bound_ns,
        "ratio_to_bound": cached_ns / bound_ns,
        "fastest_ns_per_value_pass": cached_fastest_ns,
        "fastest_ratio_to_bound": cached_fastest_ns / bound_ns,
    });
    // The control of the 2-thread rule: a plain read loop over as many
    // bytes as one local pass touches, read again and again, on 1 and 2
    // threads. It shares nothing, so a speed-up above 2 there is the
    // caches (two cores hold more of the set than one), not load.
    let local_mib = (f(&per_threads[0]["local_bytes"]) / f64::from(1 << 20)).ceil();
    let cache_control = if local_mib.is_finite() && local_mib >= 1.0 {
        probe(strings(&[
            "cache-scaling",
            "--mib",
            &format!("{local_mib:.0}"),
        ]))?
    } else {
        Value::Null
    };
    let step_speedup = f(&per_threads[0]["step_ms"]) / f(&per_threads[1]["step_ms"]);
    let local_speedup = f(&per_threads[0]["local_ns_per_tet_iteration"])
        / f(&per_threads[1]["local_ns_per_tet_iteration"]);

    let mut mesh_rows = Vec::new();
    for base in meshes {
        for threads in ["1", "2"] {
            let base_text = base.to_string_lossy();
            let mut run = probe(strings(&[
                "step",
                "--mesh",
                &base_text,
                "--steps",
                "5",
                "--threads",
                threads,
            ]))?;
            run["mesh"] = json!(base_text);
            mesh_rows.push(run);
        }
    }

    let pressure_after = cpu_pressure();
    let mut reasons = Vec::new();
    for (when, pressure) in [("before", pressure_before), ("after", pressure_after)] {
        if let Some(p) = pressure.filter(|&p| p > PRESSURE_NOISY) {
            reasons.push(format!(
                "CPU pressure {p:.1} % {when} (> {PRESSURE_NOISY} %)"
            ));
        }
    }
    for (name, speedup) in [("step", step_speedup), ("local step", local_speedup)] {
        if speedup > SPEEDUP_NOISY {
            reasons.push(format!(
                "2-thread {name} speed-up {speedup:.2} (> {SPEEDUP_NOISY})"
            ));
        }
    }
    for run in &per_threads {
        let spread = f(&run["spread"]);
        if spread > SPREAD_NOISY {
            reasons.push(format!(
                "spread of repeated runs {:.1} % at {} thread(s) (> {:.0} %)",
                100.0 * spread,
                run["threads"].as_str().unwrap_or("?"),
                100.0 * SPREAD_NOISY
            ));
        }
    }
    Ok(json!({
        "bandwidth": bandwidth,
        "bandwidth_2_threads": bandwidth_2,
        "cells": cells,
        "by_threads": per_threads,
        "in_cache": in_cache,
        "step_speedup": step_speedup,
        "local_speedup": local_speedup,
        "cache_control": cache_control,
        "pressure_before": pressure_before,
        "pressure_after": pressure_after,
        "noisy": !reasons.is_empty(),
        "noise_reasons": reasons,
        "meshes": mesh_rows,
    }))
}

/// Adds the 2-thread speed-ups measured outside [`measure`] (the report's
/// alternating local-step pairs) to the noise check of `limits`: any above
/// [`SPEEDUP_NOISY`] flags the whole report, so that no section's verdict
/// rests on a run the limits section alone would have passed.
pub fn flag_speedups(limits: &mut Value, what: &str, speedups: &[f64]) {
    let mut reasons: Vec<Value> = limits["noise_reasons"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    for (i, &speedup) in speedups.iter().enumerate() {
        if speedup > SPEEDUP_NOISY {
            reasons.push(json!(format!(
                "2-thread {what} speed-up {speedup:.2} in pair {} (> {SPEEDUP_NOISY})",
                i + 1
            )));
        }
    }
    limits["noisy"] = json!(!reasons.is_empty());
    limits["noise_reasons"] = Value::Array(reasons);
}

/// What the cache control (`pd-probe cache-scaling` over the local step's
/// working set) says about the 2-thread rule, as a paragraph; empty
/// without one.
fn cache_control_line(limits: &Value) -> String {
    let control = &limits["cache_control"];
    let speedup = f(&control["speedup"]);
    if !speedup.is_finite() {
        return String::new();
    }
    let verdict = if speedup > SPEEDUP_NOISY {
        format!(
            "above {SPEEDUP_NOISY} with nothing shared and nothing else running in it, so on this \
             machine two cores cache more of such a set than one: 2-thread speed-ups above \
             {SPEEDUP_NOISY} of the local step can come from the caches rather than from load \
             (the flag stands; the other checks tell load apart)"
        )
    } else {
        format!(
            "at most {SPEEDUP_NOISY}, so here a 2-thread speed-up above {SPEEDUP_NOISY} of the \
             local step is not explained by the caches"
        )
    };
    format!(
        "Cache control: a plain read loop over the local step's working set ({:.0} MiB: the \
         elements, their projections and the positions), read again and again, ran {:.2} times \
         faster on 2 threads than on 1 ({:.0} against {:.0} GB/s), {verdict} \
         (docs/design/performance.md, \"Two cores cache more than one\").\n\n",
        f(&control["mib"]),
        speedup,
        f(&control["bytes_per_second_2_threads"]) / 1e9,
        f(&control["bytes_per_second_1_thread"]) / 1e9,
    )
}

/// The Markdown of the two sections.
pub fn markdown(limits: &Value) -> String {
    let mut md = String::new();
    let empty = Vec::new();
    let _ = writeln!(md, "## Limits: the step against the machine\n");
    if limits["noisy"].as_bool() == Some(true) {
        let reasons: Vec<&str> = limits["noise_reasons"]
            .as_array()
            .unwrap_or(&empty)
            .iter()
            .filter_map(Value::as_str)
            .collect();
        let _ = writeln!(
            md,
            "**NOISY RUN: no verdict rests on these numbers** ({}).\n",
            reasons.join("; ")
        );
    } else {
        let _ = writeln!(
            md,
            "Noise check passed (CPU pressure at most {PRESSURE_NOISY} %, 2-thread speed-ups at \
             most {SPEEDUP_NOISY} here and in the local step's alternating pairs, spread of repeated runs at most {:.0} %).\n",
            100.0 * SPREAD_NOISY
        );
    }
    md.push_str(&cache_control_line(limits));
    let bandwidth = f(&limits["bandwidth"]["bytes_per_second"]);
    let bandwidth_2 = f(&limits["bandwidth_2_threads"]["bytes_per_second"]);
    let cells = &limits["cells"];
    let _ = writeln!(
        md,
        "Streaming read bandwidth (measured now): {:.1} GB/s on 1 thread, {:.1} GB/s on 2 \
         threads together. Beam of {} x {} x {} \
         cells; a solve reads the factor twice (forward and backward), so its bound is \
         2 x factor bytes / bandwidth, with the bandwidth of the row's thread count. \
         \"solve\" is the solve alone (what the bound \
         describes), the median of its runs; \"fastest solve\" the fastest of them, \
         like with like against the bandwidth, which is the best of its repetitions; \
         \"global per iteration\" also assembles the right-hand side and \
         updates the displacement.\n",
        bandwidth / 1e9,
        bandwidth_2 / 1e9,
        cells[0],
        cells[1],
        cells[2]
    );
    let _ = writeln!(
        md,
        "| threads | tets | step [ms] | local [ns / tet / iteration] | factor [MB] | solve bound [ms] | solve [ms] | solve / bound | fastest solve [ms] | fastest / bound | global per iteration [ms] | ratio to bound | spread of runs |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for run in limits["by_threads"].as_array().unwrap_or(&empty) {
        let _ = writeln!(
            md,
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} % |",
            run["threads"].as_str().unwrap_or("?"),
            f(&run["n_tets"]),
            f(&run["step_ms"]),
            f(&run["local_ns_per_tet_iteration"]),
            f(&run["factor_bytes"]) / 1e6,
            f(&run["solve_bound_ms"]),
            f(&run["solve_ms"]),
            f(&run["solve_ratio_to_bound"]),
            f(&run["solve_ms_fastest"]),
            f(&run["fastest_solve_ratio_to_bound"]),
            f(&run["global_ms_per_iteration"]),
            f(&run["ratio_to_bound"]),
            100.0 * f(&run["spread"]),
        );
    }
    let cached = &limits["in_cache"];
    if cached.is_object() {
        let ratio = f(&cached["ratio_to_bound"]);
        let _ = writeln!(
            md,
            "\nThe solve with its factor in the caches (beam {} x {} x {}, {:.1} MB, 1 thread): \
             {:.2} ms (median), {:.3} ns per stored value per pass against the streaming \
             bound's {:.3} ns ({:.2}x; the fastest solve {:.3} ns, {:.2}x): {}",
            cached["cells"][0],
            cached["cells"][1],
            cached["cells"][2],
            f(&cached["factor_bytes"]) / 1e6,
            f(&cached["solve_ms"]),
            f(&cached["ns_per_value_pass"]),
            f(&cached["bound_ns_per_value"]),
            ratio,
            f(&cached["fastest_ns_per_value_pass"]),
            f(&cached["fastest_ratio_to_bound"]),
            if ratio > 1.0 {
                "with no DRAM traffic the solve is already slower than the bound, so on this \
                 machine its kernels, not the memory, set its floor."
            } else {
                "from the caches the solve beats the bound, so the memory, not the kernels, \
                 sets its floor on the large beam."
            }
        );
    }
    let _ = writeln!(
        md,
        "\n2-thread speed-up: step {:.2}, local step {:.2}.\n",
        f(&limits["step_speedup"]),
        f(&limits["local_speedup"])
    );
    let meshes = limits["meshes"].as_array().unwrap_or(&empty);
    if !meshes.is_empty() {
        let _ = writeln!(md, "## Real meshes (TetGen, `--mesh`)\n");
        let _ = writeln!(
            md,
            "Smallest-x vertex pinned as in the C++ reference's runs; 10 iterations, backward \
             Euler. nnz(L) counts structural non-zeros (CHOLMOD's `lnz`); stored values add \
             faer's supernode padding.\n"
        );
        let _ = writeln!(
            md,
            "| mesh | vertices | tets | threads | step [ms] | local [ms] | global [ms] | nnz(L) [M] | stored values [M] | peak memory [MB] |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
        );
        for run in meshes {
            let name = run["mesh"].as_str().unwrap_or("?");
            let short = Path::new(name)
                .file_name()
                .map_or(name.into(), |n| n.to_string_lossy());
            let _ = writeln!(
                md,
                "| {short} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.3} | {:.3} | {:.0} |",
                run["n_verts"],
                run["n_tets"],
                run["threads"],
                f(&run["step_ms_median"]),
                f(&run["local_ms_median"]),
                f(&run["global_ms_median"]),
                f(&run["nnz_L_exact"]) / 1e6,
                f(&run["nnz_L_factor"]) / 1e6,
                f(&run["peak_bytes"]) / 1e6,
            );
        }
        let _ = writeln!(md);
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The output of `pd-probe bandwidth` measuring `bytes_per_second`.
    fn bandwidth(bytes_per_second: f64) -> Value {
        serde_json::to_value(Bandwidth {
            bytes: 1 << 29,
            reps: 7,
            threads: 1,
            best_seconds: f64::from(1 << 29) / bytes_per_second,
            bytes_per_second,
            checksum: 0.0,
        })
        .unwrap()
    }

    /// A fake probe: bandwidth 10 GB/s, 100 tets, 10 iterations, a factor
    /// of 1e6 values (8 MB: bound 1.6 ms per solve).
    fn fake(speedup: f64) -> impl Fn(Vec<String>) -> Result<Value, String> {
        move |a: Vec<String>| {
            if a[0] == "bandwidth" {
                return Ok(bandwidth(1e10));
            }
            let two = a.iter().any(|x| x == "2");
            let s = if two { speedup } else { 1.0 };
            Ok(serde_json::to_value(Step {
                n_verts: 40,
                n_tets: 100,
                n_triangles: None,
                local_bytes: 0,
                n_free: 40,
                nnz_l_factor: 1_000_000,
                nnz_l_exact: 800_000,
                symbolic_ms: 0.0,
                factor_ms: 0.0,
                numeric_factor_ms: 0.0,
                step_ms_median: 40.0 / s,
                local_ms_median: 20.0 / s,
                global_ms_median: 20.0,
                solve_ms_median: 1.8,
                solve_ms_min: 1.7,
                rhs_and_solve_ms_median: 2.0,
                steps: 5,
                iters: 10,
                threads: if two { 2 } else { 1 },
                model: "none".into(),
                integrator: "be".into(),
                centroid: [0.0; 3],
                min_y: 0.0,
                kinetic_energy: 0.0,
                peak_bytes: Some(10_000_000),
                setup_peak_bytes: Some(10_000_000),
                state_hash: "0".into(),
            })
            .unwrap())
        }
    }

    #[test]
    fn bound_ratio_and_local_cost_follow_from_the_probe() {
        let limits = measure(&fake(1.5), true, &[]).unwrap();
        let one = &limits["by_threads"][0];
        assert!((f(&one["solve_bound_ms"]) - 1.6).abs() < 1e-12);
        assert!((f(&one["ratio_to_bound"]) - 2.0 / 1.6).abs() < 1e-12);
        // The solve alone: 1.8 ms against the same bound.
        assert!((f(&one["solve_ratio_to_bound"]) - 1.8 / 1.6).abs() < 1e-12);
        // The fastest solve, 1.7 ms, against it too.
        assert!((f(&one["fastest_solve_ratio_to_bound"]) - 1.7 / 1.6).abs() < 1e-12);
        // In the caches: 1.8 ms / (2 passes x 1e6 values) = 0.9 ns per value
        // against 8 bytes / 10 GB/s = 0.8 ns.
        let cached = &limits["in_cache"];
        assert!((f(&cached["ns_per_value_pass"]) - 0.9).abs() < 1e-12);
        assert!((f(&cached["ratio_to_bound"]) - 1.125).abs() < 1e-12);
        assert!((f(&cached["fastest_ratio_to_bound"]) - 0.85 / 0.8).abs() < 1e-12);
        assert!(
            markdown(&limits)
                .contains("(1.12x; the fastest solve 0.850 ns, 1.06x): with no DRAM traffic")
        );
        // 20 ms / (10 iterations x 100 tets) = 20,000 ns.
        assert!((f(&one["local_ns_per_tet_iteration"]) - 20_000.0).abs() < 1e-6);
        assert!((f(&limits["local_speedup"]) - 1.5).abs() < 1e-12);
        assert!(markdown(&limits).contains("| 1 | 100 |"));
    }

    #[test]
    fn the_two_thread_rows_use_the_two_thread_bandwidth() {
        // Bandwidth 10 GB/s on 1 thread and 16 GB/s on 2: the 2-thread bound
        // is 2 x 8 MB / 16 GB/s = 1 ms, the 1-thread one 1.6 ms.
        let probe = |a: Vec<String>| {
            if a[0] == "bandwidth" && a.iter().any(|x| x == "--threads") {
                return Ok(bandwidth(1.6e10));
            }
            fake(1.5)(a)
        };
        let limits = measure(&probe, true, &[]).unwrap();
        let [one, two] = [0, 1].map(|i| &limits["by_threads"][i]);
        assert!((f(&one["solve_bound_ms"]) - 1.6).abs() < 1e-12);
        assert!((f(&two["solve_bound_ms"]) - 1.0).abs() < 1e-12);
        assert!((f(&two["solve_ratio_to_bound"]) - 1.8).abs() < 1e-12);
        assert!(markdown(&limits).contains("16.0 GB/s on 2"));
    }

    #[test]
    fn a_superlinear_pair_elsewhere_flags_the_report() {
        let mut limits = measure(&fake(1.5), true, &[]).unwrap();
        // `measure` reads the machine's real CPU pressure, which a busy
        // machine (CI compiling) pushes over the threshold: start from a
        // quiet verdict so that only the pairs decide.
        limits["noisy"] = json!(false);
        limits["noise_reasons"] = json!([]);
        flag_speedups(&mut limits, "local step", &[1.9, 2.0]);
        assert_eq!(limits["noisy"], false);
        flag_speedups(&mut limits, "local step", &[1.9, 2.1]);
        assert_eq!(limits["noisy"], true);
        let md = markdown(&limits);
        assert!(
            md.contains("NOISY RUN") && md.contains("2.10 in pair 2"),
            "{md}"
        );
    }

    #[test]
    fn the_cache_control_reads_the_local_working_set_and_keeps_the_flag() {
        for (control, says) in [
            (2.3, "can come from the caches"),
            (1.9, "not explained by the caches"),
        ] {
            let asked = std::cell::RefCell::new(Vec::new());
            let probe = |a: Vec<String>| {
                if a[0] == "cache-scaling" {
                    asked.borrow_mut().push(a.clone());
                    return Ok(json!({
                        "mib": 17, "speedup": control,
                        "bytes_per_second_1_thread": 5e10,
                        "bytes_per_second_2_threads": 5e10 * control,
                    }));
                }
                let mut v = fake(2.2)(a)?;
                if v.get("step_ms_median").is_some() {
                    // 16.1 MiB (in whole bytes): the control runs at 17 MiB.
                    v["local_bytes"] = json!((16.1 * f64::from(1 << 20)) as u64);
                }
                Ok(v)
            };
            let limits = measure(&probe, true, &[]).unwrap();
            assert_eq!(
                asked.borrow().as_slice(),
                [vec!["cache-scaling", "--mib", "17"]]
            );
            // The flag stands either way.
            assert_eq!(limits["noisy"], true);
            let md = markdown(&limits);
            assert!(
                md.contains(&format!("ran {control:.2} times faster")),
                "{md}"
            );
            assert!(md.contains(says), "{md}");
        }
    }

    #[test]
    fn a_superlinear_speedup_flags_the_report() {
        let limits = measure(&fake(2.5), true, &[]).unwrap();
        assert_eq!(limits["noisy"], true);
        assert!(markdown(&limits).contains("NOISY RUN"));
    }
}
