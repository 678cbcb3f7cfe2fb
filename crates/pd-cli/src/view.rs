//! `pd view`: one self-contained HTML page of one or more runs' output
//! folders, drawn with WebGL2 in the browser (docs/reference/cli.md,
//! "pd view").
//!
//! The page holds everything: the viewer's script and style (`view/`,
//! inlined at build time) and the runs' data as JSON. Positions are
//! quantised to 16 bits a coordinate over the box that holds every frame of
//! every run, so a coordinate is off by at most half of `extent / 65535`
//! (stated on the page and in the log); triangles, lines, colliders,
//! energies and probes are stored as they are.

use std::path::{Path, PathBuf};

use pd_viz::obj::{Surface, read_obj};
use serde_json::{Value, json};
use tracing::info;

use crate::Failure;
use crate::pictures::{label_of, obj_frames, read_metrics};

/// The viewer's page around the data.
const PAGE: &str = include_str!("view/page.html");
/// The viewer's script, inlined into the page.
const SCRIPT: &str = include_str!("view/viewer.js");
/// Where the script and data go in [`PAGE`].
const SCRIPT_SLOT: &str = "/*PD_SCRIPT*/";
const DATA_SLOT: &str = "/*PD_DATA*/";

/// Most points of a curve on the page's plot: longer series are thinned
/// evenly (the plot is at most about 1,000 pixels wide).
const PLOT_POINTS: usize = 2000;

/// Options of `pd view`.
pub(crate) struct ViewOptions {
    /// Keep every K-th frame (and the last).
    pub every: usize,
    /// Refuse to write a page larger than this, MB (10^6 bytes).
    pub max_mb: f64,
}

/// One run as it goes on the page.
struct Run {
    label: String,
    /// Frame files kept, in time order.
    frames: Vec<Surface>,
    /// Time of each kept frame, s.
    times: Vec<f64>,
    colliders: Vec<Value>,
    metrics: Option<Value>,
    probes: Option<Value>,
}

/// `pd view DIR... -o OUT`.
pub(crate) fn view(dirs: &[PathBuf], out: &Path, options: &ViewOptions) -> Result<(), Failure> {
    if options.every == 0 {
        return Err(Failure::Input("--every must be at least 1".into()));
    }
    if options.max_mb.is_nan() || options.max_mb <= 0.0 {
        return Err(Failure::Input("--max-mb must be positive".into()));
    }
    let mut runs = Vec::with_capacity(dirs.len());
    for dir in dirs {
        runs.push(read_run(dir, options)?);
    }
    let estimate = estimated_bytes(&runs);
    let limit = options.max_mb * 1e6;
    if estimate > limit {
        let factor = (estimate / limit).ceil() as usize * options.every;
        return Err(Failure::Input(format!(
            "the page would hold about {:.1} MB of frames, above --max-mb {} ({}); \
             keep fewer frames with --every {factor} (or raise --max-mb)",
            estimate / 1e6,
            options.max_mb,
            runs.iter()
                .map(|r| format!(
                    "{}: {} frames of {} vertices",
                    r.label,
                    r.frames.len(),
                    r.frames[0].positions.len()
                ))
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let (page, quantum) = page(&runs);
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .map_err(|e| Failure::Output(format!("{}: {e}", parent.display())))?;
    }
    // Written next to its place and renamed, so that a page a browser has
    // open is never seen half written.
    let partial = out.with_extension("html.partial");
    std::fs::write(&partial, &page)
        .and_then(|()| std::fs::rename(&partial, out))
        .map_err(|e| Failure::Output(format!("{}: {e}", out.display())))?;
    info!(
        "{} ({:.2} MB, {} run{}, {} frames; positions quantised to {:.2e} m); open it in a browser",
        out.display(),
        page.len() as f64 / 1e6,
        runs.len(),
        if runs.len() == 1 { "" } else { "s" },
        runs.iter().map(|r| r.frames.len()).sum::<usize>(),
        quantum
    );
    Ok(())
}

/// Reads one run folder: its frames (every `options.every`-th and the
/// last), their times, its scene's colliders and its curves.
fn read_run(dir: &Path, options: &ViewOptions) -> Result<Run, Failure> {
    let paths = obj_frames(dir)?;
    let last = paths.len() - 1;
    let kept: Vec<usize> = (0..paths.len())
        .filter(|&i| i % options.every == 0 || i == last)
        .collect();
    let mut frames = Vec::with_capacity(kept.len());
    for &i in &kept {
        let surface = read_obj(&paths[i]).map_err(|e| Failure::Input(e.to_string()))?;
        if let Some(first) = frames.first() {
            check_same_topology(first, &surface, &paths[kept[0]], &paths[i])?;
        }
        frames.push(surface);
    }
    if frames[0].positions.is_empty() {
        return Err(Failure::Input(format!(
            "{}: a frame without vertices",
            paths[0].display()
        )));
    }
    let scene = crate::scenery::run_scene(dir);
    let frame_dt = frame_interval(dir, scene.as_ref(), paths.len());
    let colliders = colliders_json(scene.as_ref(), &frames[0].positions);
    let times = kept.iter().map(|&i| i as f64 * frame_dt).collect();
    let metrics = if dir.join(pd_io::recorder::MetricsRow::FILE).exists() {
        Some(metrics_json(dir)?)
    } else {
        None
    };
    let probes = probes_json(&dir.join("probes.csv"))?;
    Ok(Run {
        label: label_of(dir),
        frames,
        times,
        colliders,
        metrics,
        probes,
    })
}

/// Frames of one run must share their vertices and faces: the page draws
/// one mesh moving.
fn check_same_topology(a: &Surface, b: &Surface, pa: &Path, pb: &Path) -> Result<(), Failure> {
    if a.positions.len() != b.positions.len() {
        return Err(Failure::Input(format!(
            "{}: {} vertices, but {} has {}: the frames of one run must have the same vertices",
            pb.display(),
            b.positions.len(),
            pa.display(),
            a.positions.len()
        )));
    }
    if a.triangles != b.triangles || a.lines != b.lines {
        return Err(Failure::Input(format!(
            "{}: its faces differ from those of {}: the frames of one run must have the same faces",
            pb.display(),
            pa.display()
        )));
    }
    Ok(())
}

/// Seconds between consecutive frame files: `dt` from `summary.json` and
/// `output.every` from the run's scene; failing those, the run's time
/// spread evenly over its frames.
fn frame_interval(dir: &Path, scene: Option<&pd_io::scene::Scene>, frames: usize) -> f64 {
    let summary = std::fs::read_to_string(dir.join("summary.json"))
        .ok()
        .and_then(|text| serde_json::from_str::<Value>(&text).ok());
    let Some(summary) = summary else {
        return 1.0;
    };
    let dt = summary.get("dt").and_then(Value::as_f64);
    let every = scene.map(|scene| scene.output.every);
    match (dt, every) {
        (Some(dt), Some(every)) if every > 0 => dt * every as f64,
        _ => {
            let time = summary.get("time").and_then(Value::as_f64).unwrap_or(0.0);
            if frames > 1 && time > 0.0 {
                time / (frames - 1) as f64
            } else {
                1.0
            }
        }
    }
}

/// The run's colliders as surfaces (`pd render`'s scenery); the ground is
/// a square under the body, sized to its first frame.
fn colliders_json(scene: Option<&pd_io::scene::Scene>, first_frame: &[[f64; 3]]) -> Vec<Value> {
    let scenery = crate::scenery::of_scene(scene);
    let mut colliders: Vec<Value> = scenery
        .solids
        .iter()
        .map(|s| json!({"positions": flat(&s.positions), "triangles": flat_indices(&s.triangles)}))
        .collect();
    if let Some(y) = scenery.ground {
        let (lo, hi) = bounds(first_frame);
        let centre = [(lo[0] + hi[0]) / 2.0, (lo[2] + hi[2]) / 2.0];
        let half = 1.5 * (hi[0] - lo[0]).max(hi[2] - lo[2]).max(0.5);
        let corners = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
            .map(|[a, b]| [centre[0] + a * half, y, centre[1] + b * half]);
        colliders.push(json!({
            "positions": flat(&corners),
            "triangles": [0, 2, 1, 0, 3, 2],
        }));
    }
    colliders
}

fn flat(points: &[[f64; 3]]) -> Vec<f64> {
    points.iter().flatten().copied().collect()
}

fn flat_indices<const N: usize>(items: &[[usize; N]]) -> Vec<usize> {
    items.iter().flatten().copied().collect()
}

/// The smallest box holding `points` (a unit box at the origin if none).
fn bounds<'a>(points: impl IntoIterator<Item = &'a [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut any = false;
    for p in points {
        any = true;
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if any { (lo, hi) } else { ([0.0; 3], [1.0; 3]) }
}

/// Evenly thinned indices `0..n`, at most [`PLOT_POINTS`], the last kept.
fn thinned(n: usize) -> Vec<usize> {
    let stride = n.div_ceil(PLOT_POINTS).max(1);
    let mut idx: Vec<usize> = (0..n).step_by(stride).collect();
    if n > 0 && idx.last() != Some(&(n - 1)) {
        idx.push(n - 1);
    }
    idx
}

/// Energies of `metrics.csv`, J, against time.
fn metrics_json(dir: &Path) -> Result<Value, Failure> {
    let rows = read_metrics(dir)?;
    let idx = thinned(rows.len());
    let column = |f: fn(&pd_io::recorder::MetricsRow) -> f64| -> Vec<f64> {
        idx.iter().map(|&i| f(&rows[i])).collect()
    };
    Ok(json!({
        "time": column(|r| r.time),
        "kinetic": column(|r| r.kinetic),
        "elastic": column(|r| r.elastic),
        "gravity": column(|r| r.gravity),
        "total": column(|r| r.total),
    }))
}

/// Each probe's distance from where it started, m, against time, from
/// `probes.csv` (`step,time,x_V,y_V,z_V,vx_V,...`); `None` without the
/// file or without probes.
fn probes_json(path: &Path) -> Result<Option<Value>, Failure> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(None);
    };
    let mut lines = text.lines();
    let Some(header) = lines.next() else {
        return Ok(None);
    };
    let names: Vec<&str> = header.split(',').collect();
    // Columns of each probe's position: x_V, y_V, z_V side by side.
    let probes: Vec<(String, usize)> = names
        .iter()
        .enumerate()
        .filter_map(|(i, n)| {
            let v = n.strip_prefix("x_")?;
            (names.get(i + 1) == Some(&format!("y_{v}").as_str())
                && names.get(i + 2) == Some(&format!("z_{v}").as_str()))
            .then(|| (format!("vertex {v}"), i))
        })
        .collect();
    if probes.is_empty() || names.get(1) != Some(&"time") {
        return Ok(None);
    }
    let mut rows: Vec<Vec<f64>> = Vec::new();
    for (n, line) in lines.enumerate() {
        let row = line
            .split(',')
            .map(str::parse::<f64>)
            .collect::<Result<Vec<_>, _>>()
            .ok()
            .filter(|r| r.len() == names.len())
            .ok_or_else(|| {
                Failure::Input(format!(
                    "{}:{}: expected {} numbers",
                    path.display(),
                    n + 2,
                    names.len()
                ))
            })?;
        rows.push(row);
    }
    if rows.is_empty() {
        return Ok(None);
    }
    let idx = thinned(rows.len());
    let series: Vec<Value> = probes
        .iter()
        .map(|(label, c)| {
            let start = [rows[0][*c], rows[0][c + 1], rows[0][c + 2]];
            let distance: Vec<f64> = idx
                .iter()
                .map(|&i| {
                    let r = &rows[i];
                    ((r[*c] - start[0]).powi(2)
                        + (r[c + 1] - start[1]).powi(2)
                        + (r[c + 2] - start[2]).powi(2))
                    .sqrt()
                })
                .collect();
            json!({"label": label, "distance": distance})
        })
        .collect();
    Ok(Some(json!({
        "time": idx.iter().map(|&i| rows[i][1]).collect::<Vec<_>>(),
        "series": series,
    })))
}

/// Bytes the runs' frames take on the page: 2 bytes a coordinate, base64
/// (4/3).
fn estimated_bytes(runs: &[Run]) -> f64 {
    runs.iter()
        .map(|r| (r.frames.len() * r.frames[0].positions.len() * 3 * 2) as f64 * 4.0 / 3.0)
        .sum()
}

/// The page, and the quantisation step of its positions, m.
fn page(runs: &[Run]) -> (String, f64) {
    let (lo, hi) = bounds(
        runs.iter()
            .flat_map(|r| &r.frames)
            .flat_map(|f| &f.positions),
    );
    let extent: [f64; 3] = std::array::from_fn(|k| (hi[k] - lo[k]).max(1e-12));
    let quantum = extent.iter().fold(0.0_f64, |a, &e| a.max(e)) / 65535.0;
    let runs_json: Vec<Value> = runs
        .iter()
        .map(|run| {
            let mut bytes =
                Vec::with_capacity(run.frames.len() * run.frames[0].positions.len() * 6);
            for frame in &run.frames {
                for p in &frame.positions {
                    for k in 0..3 {
                        let q = ((p[k] - lo[k]) / extent[k] * 65535.0)
                            .round()
                            .clamp(0.0, 65535.0);
                        bytes.extend_from_slice(&(q as u16).to_le_bytes());
                    }
                }
            }
            let first = &run.frames[0];
            json!({
                "label": run.label,
                "vertices": first.positions.len(),
                "triangles": flat_indices(&first.triangles),
                "lines": flat_indices(&first.lines),
                "times": run.times,
                "positions": base64(&bytes),
                "colliders": run.colliders,
                "metrics": run.metrics,
                "probes": run.probes,
            })
        })
        .collect();
    let data = json!({
        "lo": lo,
        "extent": extent,
        "quantum": quantum,
        "runs": runs_json,
    });
    // `</` cannot close the data's script element: JSON strings never hold
    // it here (labels are folder names), but a folder may be named anyhow.
    let data = data.to_string().replace("</", "<\\/");
    let page = PAGE
        .replacen(SCRIPT_SLOT, SCRIPT, 1)
        .replacen(DATA_SLOT, &data, 1);
    (page, quantum)
}

/// Standard base64 (RFC 4648) with padding.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> shift & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_4648_test_vectors() {
        // RFC 4648, section 10.
        let cases = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in cases {
            assert_eq!(base64(plain.as_bytes()), encoded, "{plain:?}");
        }
    }

    #[test]
    fn thinned_keeps_the_ends_and_at_most_the_plot_points() {
        assert!(thinned(0).is_empty());
        assert_eq!(thinned(3), vec![0, 1, 2]);
        let many = thinned(10 * PLOT_POINTS + 7);
        assert!(many.len() <= PLOT_POINTS + 1);
        assert_eq!(many[0], 0);
        assert_eq!(*many.last().unwrap(), 10 * PLOT_POINTS + 6);
    }
}
