//! `pd compare`: one scene, several damping models, integrators, damping
//! ratios or accuracy targets (one of these axes at a time).
//!
//! Damping models are named by the presets of `pd_damping::registry`: each
//! model's main preset (named as the model) and variants such as
//! `laplacian-rot`, with the coefficients of the measured table in
//! `docs/reports/damping-table.md`. Integrators keep the scene's damping model.
//! `--ratio z1,z2,...` runs the scene's model (or Laplacian damping) with
//! each damping ratio of its lowest elastic mode. A damping or ratio
//! variant sets the model of every body, in place of a body's own
//! `damping`. `--accuracy e1,e2,...` runs the scene with each accuracy
//! target as its stopping rule ([`with_accuracy`]).

use pd_io::stats::median;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use pd_damping::registry;
use pd_integrators::registry as integrator_registry;
use pd_io::scene::{ACCURACY_ITERATIONS, DampingSpec, FrameFormat, Scene, check_accuracy};
use pd_viz::plot::Plot;
use serde_json::json;
use tracing::{info, warn};

use crate::Failure;
use crate::pictures::{self, RenderOptions, read_metrics, render, write_plot};
use crate::run::{LoadedScene, SceneOptions, load_scene, run_loaded};

/// The help of `--damping`: every preset with its coefficients.
pub(crate) fn damping_help() -> String {
    let presets: Vec<String> = registry::presets()
        .iter()
        .map(|p| match (p.description.is_empty(), p.is_main()) {
            (true, _) => p.name.to_string(),
            (false, true) => format!("{} ({})", p.name, p.description),
            (false, false) => format!("{} ({})", p.name, p.label()),
        })
        .collect();
    format!(
        "Damping models, comma separated, each for every body (in place of a body's own \
         damping), by preset: {}",
        presets.join("; ")
    )
}

/// The help of `--integrator`: every integrator of the registry.
pub(crate) fn integrator_help() -> String {
    format!(
        "Integrators, comma separated ({})",
        integrator_registry::names().join(", ")
    )
}

/// The help of `--accuracy`: what a variant runs, and its iteration cap.
pub(crate) fn accuracy_help() -> String {
    format!(
        "Accuracy targets, comma separated (0.1,0.01,0.001), each in (0, 1): each variant runs \
         the scene with `accuracy = E` in [simulation], so that every step iterates until its \
         estimated relative error is at most E, without the scene's tolerance. The iteration \
         cap is the scene's `iterations` if the scene sets `accuracy` itself, else \
         {ACCURACY_ITERATIONS}"
    )
}

/// An `--accuracy` value, checked as the scene's `accuracy` is (clap names
/// the option and the value in its error).
pub(crate) fn accuracy_of(text: &str) -> Result<f64, String> {
    let value = text
        .trim()
        .parse::<f64>()
        .map_err(|_| "not a number: give a relative error in (0, 1), e.g. 0.01".to_string())?;
    check_accuracy(value)
}

/// The damping model a preset name stands for.
fn damping_of(name: &str) -> Result<DampingSpec, Failure> {
    let preset = registry::preset(name).ok_or_else(|| {
        Failure::Input(format!(
            "--damping: unknown model {name:?}; expected one of: {}",
            registry::preset_names().join(", ")
        ))
    })?;
    preset
        .spec()
        .map_err(|e| Failure::Input(format!("--damping {name}: {e}")))
}

/// One row of the comparison table.
struct Row {
    name: String,
    status: String,
    median_step_ms: f64,
    steps: usize,
    initial_energy: f64,
    final_energy: f64,
    momentum_kept: Option<f64>,
    angular_momentum_kept: Option<f64>,
    final_momentum: f64,
    final_angular_momentum: f64,
    /// The `"accuracy"` object of the run's `summary.json`.
    accuracy: serde_json::Value,
}

/// `|final| / |initial|`, or `None` when the initial value is below 0.1%
/// of the largest during the run: then there was nothing to keep (a body
/// starting at rest), and the ratio would only measure round-off growth.
fn kept(initial: f64, last: f64, largest: f64) -> Option<f64> {
    (initial > 0.0 && initial >= 1e-3 * largest).then(|| last / initial)
}

fn row_of(name: &str, status: String, dir: &Path) -> Result<Row, Failure> {
    let rows = read_metrics(dir)?;
    let path = dir.join("summary.json");
    let unreadable = |e: &dyn std::fmt::Display| Failure::Input(format!("{}: {e}", path.display()));
    let summary: serde_json::Value = std::fs::read_to_string(&path)
        .map_err(|e| unreadable(&e))
        .and_then(|text| serde_json::from_str(&text).map_err(|e| unreadable(&e)))?;
    let last = rows.len() - 1;
    let p = |i: usize| rows[i].linear_momentum().norm();
    let j = |i: usize| rows[i].angular_momentum().norm();
    // Row 0 is the initial state and has no step time.
    let step_ms: Vec<f64> = rows[1..].iter().map(|r| r.step_ms).collect();
    Ok(Row {
        name: name.to_string(),
        status,
        median_step_ms: median(&step_ms),
        steps: last,
        initial_energy: rows[0].total,
        final_energy: rows[last].total,
        momentum_kept: kept(p(0), p(last), (0..=last).map(p).fold(0.0, f64::max)),
        angular_momentum_kept: kept(j(0), j(last), (0..=last).map(j).fold(0.0, f64::max)),
        final_momentum: p(last),
        final_angular_momentum: j(last),
        accuracy: summary["accuracy"].clone(),
    })
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), |v| format!("{v:.4}"))
}

/// The accuracy cells of a row of `comparison.md`, from the run's
/// `summary.json` `"accuracy"`: target, method, median iterations, median
/// and largest estimated error, energy created.
fn accuracy_cells(accuracy: &serde_json::Value) -> String {
    let cell = |key: &str, absent: &str, show: fn(f64) -> String| {
        accuracy[key]
            .as_f64()
            .map_or_else(|| absent.to_string(), show)
    };
    format!(
        "{} | {} | {} | {} | {} | {}",
        cell("target", "none", |v| v.to_string()),
        accuracy["method"].as_str().unwrap_or("n/a"),
        cell("iterations_median", "n/a", |v| v.to_string()),
        cell("estimated_error_median", "n/a", |v| format!("{v:.3e}")),
        cell("estimated_error_max", "n/a", |v| format!("{v:.3e}")),
        cell("energy_created_j", "n/a", |v| format!("{v:.3e}")),
    )
}

/// What `pd compare` varies: damping presets, integrators, damping ratios
/// or accuracy targets.
pub(crate) struct Variants {
    /// Damping presets (`--damping`).
    pub damping: Vec<String>,
    /// Integrators (`--integrator`).
    pub integrator: Vec<String>,
    /// Damping ratios of the lowest elastic mode (`--ratio`).
    pub ratio: Vec<f64>,
    /// Accuracy targets (`--accuracy`).
    pub accuracy: Vec<f64>,
}

/// `pd compare`.
pub(crate) fn compare(
    options: &SceneOptions,
    asked: &Variants,
    quiet: bool,
) -> Result<(), Failure> {
    let loaded = load_scene(options)?;
    let mut variants = variants(&loaded, &asked.damping, &asked.integrator)?;
    variants.extend(ratio_variants(&loaded, &asked.ratio)?);
    variants.extend(
        asked
            .accuracy
            .iter()
            .map(|&e| (format!("accuracy-{e}"), with_accuracy(&loaded.scene, e))),
    );
    check_variants(&variants)?;
    if !asked.accuracy.is_empty() && loaded.scene.settings.tolerance > 0.0 {
        info!(
            "each variant's accuracy is its stopping rule, in place of the scene's tolerance ({})",
            loaded.scene.settings.tolerance
        );
    }
    let per_body = loaded.scene.bodies.iter().any(|b| b.damping.is_some());
    if per_body && (!asked.damping.is_empty() || !asked.ratio.is_empty()) {
        info!("each variant's damping replaces the scene's per-body damping for every body");
    }
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(format!("compare-{}", loaded.name)));

    let mut rows = Vec::new();
    let mut diverged = Vec::new();
    for (name, scene) in variants {
        let dir = out.join(&name);
        let status = run_variant(&loaded, &name, scene, &dir, quiet)?;
        if status == "diverged" {
            diverged.push(name.clone());
        }
        rows.push((row_of(&name, status.to_string(), &dir)?, dir));
    }
    write_pictures(&rows, &out)?;
    write_table(&rows, &loaded, &out)?;
    info!(
        "comparison.md, comparison.json, energy.png/svg and render/ in {}",
        out.display()
    );
    if diverged.is_empty() {
        Ok(())
    } else {
        Err(Failure::Diverged(format!(
            "variants diverged: {} (the comparison is written to {})",
            diverged.join(", "),
            out.display()
        )))
    }
}

/// The scene once per damping preset or integrator, each with its name.
/// One variant per damping ratio: the scene's model with `ratio` (mode 1)
/// if it takes one, else Laplacian damping.
fn ratio_variants(loaded: &LoadedScene, ratios: &[f64]) -> Result<Vec<(String, Scene)>, Failure> {
    let model = match loaded.scene.damping.model().ratio {
        Some(_) => loaded.scene.damping.name(),
        None => "laplacian",
    };
    ratios
        .iter()
        .map(|&ratio| {
            let spec = DampingSpec::new(model, [("ratio", registry::Value::Number(ratio))])
                .map_err(|e| Failure::Input(format!("--ratio {ratio}: {e}")))?;
            Ok((
                format!("{model}-ratio-{ratio}"),
                with_damping(&loaded.scene, spec),
            ))
        })
        .collect()
}

/// `scene` with `damping` for every body: a body's own `damping` would
/// otherwise keep its model in every variant.
fn with_damping(scene: &Scene, damping: DampingSpec) -> Scene {
    let mut scene = scene.clone();
    scene.damping = damping;
    for body in &mut scene.bodies {
        body.damping = None;
    }
    scene
}

/// `scene` with the accuracy target `accuracy` as its stopping rule: no
/// tolerance, and the scene's `iterations` as the cap if the scene sets an
/// accuracy itself (there it is explicitly a cap), else the cap of a scene
/// with `accuracy` and no `iterations`.
fn with_accuracy(scene: &Scene, accuracy: f64) -> Scene {
    let mut scene = scene.clone();
    if scene.settings.accuracy == 0.0 {
        scene.settings.iterations = ACCURACY_ITERATIONS;
    }
    scene.settings.accuracy = accuracy;
    scene.settings.tolerance = 0.0;
    scene
}

fn variants(
    loaded: &LoadedScene,
    damping: &[String],
    integrators: &[String],
) -> Result<Vec<(String, Scene)>, Failure> {
    let mut variants = Vec::new();
    for name in damping {
        let spec = damping_of(name)?;
        variants.push((name.clone(), with_damping(&loaded.scene, spec)));
    }
    for name in integrators {
        let entry = integrator_registry::by_name(name).ok_or_else(|| {
            Failure::Input(format!(
                "--integrator: unknown integrator {name:?}; expected one of: {}",
                integrator_registry::names().join(", ")
            ))
        })?;
        let mut scene = loaded.scene.clone();
        scene.integrator = entry.kind;
        variants.push((name.clone(), scene));
    }
    Ok(variants)
}

/// Refuses a comparison of nothing, and a variant named twice.
fn check_variants(variants: &[(String, Scene)]) -> Result<(), Failure> {
    if variants.is_empty() {
        return Err(Failure::Input(
            "give the variants to compare, along one axis: --damping a,b,... or --integrator \
             a,b,... or --ratio z1,z2,... or --accuracy e1,e2,..."
                .into(),
        ));
    }
    if let Some(name) = variants
        .iter()
        .enumerate()
        .find(|(i, (n, _))| variants[..*i].iter().any(|(m, _)| m == n))
        .map(|(_, (n, _))| n.clone())
    {
        return Err(Failure::Input(format!("variant {name:?} is given twice")));
    }
    Ok(())
}

/// Runs one variant into `dir`, with OBJ frames for the animation;
/// `completed` or `diverged` (any other failure ends the comparison).
fn run_variant(
    loaded: &LoadedScene,
    name: &str,
    mut scene: Scene,
    dir: &Path,
    quiet: bool,
) -> Result<&'static str, Failure> {
    if scene.output.every == 0 {
        scene.output.every = (scene.steps / 40).max(1);
    }
    if !scene.output.formats.contains(&FrameFormat::Obj) {
        scene.output.formats.push(FrameFormat::Obj);
    }
    info!("variant {name}: running into {}", dir.display());
    let variant = LoadedScene {
        scene,
        text: loaded.text.clone(),
        name: name.to_string(),
    };
    match run_loaded(&variant, dir, 0, quiet) {
        Ok(_) => Ok("completed"),
        Err(Failure::Diverged(message)) => {
            warn!("variant {name} diverged: {message}");
            Ok("diverged")
        }
        Err(other) => Err(other),
    }
}

/// The side-by-side animation (`render/`) and the energy plot.
fn write_pictures(rows: &[(Row, PathBuf)], out: &Path) -> Result<(), Failure> {
    let panels: Vec<(String, PathBuf)> = rows
        .iter()
        .map(|(row, dir)| (row.name.clone(), dir.clone()))
        .collect();
    let width = if panels.len() > 3 { 240 } else { 320 };
    render(
        &panels,
        &out.join("render"),
        &RenderOptions {
            width,
            height: width * 3 / 4,
            gif_frames: 40,
            gif_downscale: 1,
        },
    )?;
    let mut series = Vec::new();
    for (row, dir) in rows {
        series.push(pictures::series(&read_metrics(dir)?, &row.name, |r| {
            r.total
        }));
    }
    write_plot(
        &Plot {
            title: "Total energy".into(),
            x_label: "time (s)".into(),
            y_label: "kinetic + elastic + gravity (J)".into(),
            series,
        },
        out,
        "energy",
    )
}

/// `comparison.md` and `comparison.json`.
fn write_table(rows: &[(Row, PathBuf)], loaded: &LoadedScene, out: &Path) -> Result<(), Failure> {
    let base = rows[0].0.median_step_ms;
    let mut md = String::new();
    let _ = writeln!(
        md,
        "| variant | status | steps | median step ms | overhead vs {} | initial energy J | final energy J | momentum kept | angular momentum kept | accuracy target | method | median iterations | median estimated error | largest estimated error | energy created J |",
        rows[0].0.name
    );
    let _ = writeln!(
        md,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let mut json_rows = Vec::new();
    for (row, _) in rows {
        let overhead = row.median_step_ms / base - 1.0;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3} | {:+.1}% | {:.6e} | {:.6e} | {} | {} | {} |",
            row.name,
            row.status,
            row.steps,
            row.median_step_ms,
            100.0 * overhead,
            row.initial_energy,
            row.final_energy,
            fmt_opt(row.momentum_kept),
            fmt_opt(row.angular_momentum_kept),
            accuracy_cells(&row.accuracy),
        );
        json_rows.push(json!({
            "variant": row.name,
            "status": row.status,
            "steps": row.steps,
            "median_step_ms": finite(row.median_step_ms),
            "overhead": finite(overhead),
            "initial_energy": finite(row.initial_energy),
            "final_energy": finite(row.final_energy),
            "momentum_kept": row.momentum_kept.and_then(finite),
            "angular_momentum_kept": row.angular_momentum_kept.and_then(finite),
            "final_momentum": finite(row.final_momentum),
            "final_angular_momentum": finite(row.final_angular_momentum),
            "accuracy": row.accuracy,
        }));
    }
    md.push_str(
        "\nMedian wall time of a step; overhead against the first variant, measured in the same \
         command. Energy is kinetic + elastic + gravitational. *Kept* is |final| / |initial| of \
         the linear momentum and of the angular momentum about the origin (n/a when the \
         initial value is below 0.1% of the largest in the run: nothing to keep). The accuracy \
         columns are each run's `summary.json` `accuracy`: the target (none: a fixed budget or a \
         tolerance), the position method that ran, the median iterations of a step, the median \
         and largest estimated relative error of a step (the fraction of its correction left \
         undone), and the energy created where the integrator and damping should only \
         dissipate (n/a where they need not: undamped implicit midpoint).\n",
    );
    let write = |name: &str, text: &str| {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| Failure::Output(format!("{}: {e}", path.display())))
    };
    write("comparison.md", &md)?;
    let table =
        json!({ "scene": loaded.scene.source.display().to_string(), "variants": json_rows });
    write(
        "comparison.json",
        &(serde_json::to_string_pretty(&table).expect("a JSON value serialises") + "\n"),
    )
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}
