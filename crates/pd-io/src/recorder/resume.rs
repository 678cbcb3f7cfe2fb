//! Reopening a run's output folder to continue it from a checkpoint.

use std::fs::{File, OpenOptions};
use std::io::BufWriter;
use std::path::Path;

use pd_solver::Simulation;

use super::{AccuracyWatch, MetricsRow, Recorder, Topology};
use crate::atomic::write_atomically;
use crate::frames::remove_frames_from;
use crate::scene::{FrameFormat, Scene};
use crate::vtu::{PvdEntry, write_pvd};
use crate::{Error, Result};

impl Recorder {
    /// Reopens the output folder `dir` of a run of `scene` to continue it
    /// from `sim`, restored from a checkpoint taken after step
    /// `sim.steps()`: drops the rows of `metrics.csv` and `probes.csv` and
    /// the frames written after that step (a run may have gone on past its
    /// last checkpoint before it stopped), and appends from there. The
    /// medians in `summary.json` then cover the earlier steps' timings too,
    /// and its `"accuracy"` the earlier steps' rows.
    ///
    /// # Errors
    /// [`Error::Content`] naming the file if it has fewer rows than the
    /// checkpoint's step or rows out of order; [`Error::Io`].
    pub fn resume(dir: &Path, scene: &Scene, sim: &Simulation) -> Result<Self> {
        let steps = sim.steps();
        let metrics_path = dir.join(MetricsRow::FILE);
        let kept = truncate_rows(&metrics_path, steps)?;
        let rows = MetricsRow::parse_all(&kept, &metrics_path)?;
        // Simulated time of every kept step (written with `{}` so it parses
        // back exactly), for rebuilding `frames.pvd`.
        let times: Vec<f64> = rows.iter().map(|r| r.time).collect();
        // Rows after row 0 carry the timings of their step.
        let timings = &rows[1.min(rows.len())..];
        let step_ms = timings.iter().map(|r| r.step_ms).collect();
        let local_ms = timings.iter().map(|r| r.local_ms).collect();
        let global_ms = timings.iter().map(|r| r.global_ms).collect();
        let metrics = append(&metrics_path)?;
        let probes = if scene.output.probes.is_empty() {
            None
        } else {
            let path = dir.join("probes.csv");
            truncate_rows(&path, steps)?;
            Some((append(&path)?, path))
        };
        // Frames 0..=steps/every exist at the checkpoint; none without frames.
        let every = scene.output.frame_every();
        let frames = match steps.checked_div(every) {
            Some(last) => {
                let frames = dir.join("frames");
                remove_frames_from(&frames, last + 1)?;
                std::fs::create_dir_all(&frames).map_err(|e| Error::io(&frames, e))?;
                last + 1
            }
            None => 0,
        };
        // The `.vtu` series so far: frame i is step i * every.
        let pvd: Vec<PvdEntry> = if scene.output.formats.contains(&FrameFormat::Vtu) {
            (0..frames)
                .map(|i| PvdEntry {
                    time: times[i * every],
                    file: format!("frames/frame_{i:05}.vtu"),
                })
                .collect()
        } else {
            Vec::new()
        };
        if !pvd.is_empty() {
            write_pvd(&dir.join("frames.pvd"), &pvd)?;
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            output: scene.output.clone(),
            topology: Topology::of(sim),
            strain: None,
            strain_values: Vec::new(),
            pvd,
            metrics,
            metrics_path,
            probes,
            step_ms,
            local_ms,
            global_ms,
            frames,
            accuracy: AccuracyWatch::of_rows(&rows),
        })
    }
}

/// Keeps the header and the rows of steps `0..=steps` (rewriting the file
/// atomically if anything goes); returns the kept text.
fn truncate_rows(path: &Path, steps: usize) -> Result<String> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let content = |message: String| Error::Content {
        path: path.to_path_buf(),
        message,
    };
    let mut end = None;
    let mut offset = 0;
    for (index, line) in text.split_inclusive('\n').enumerate() {
        offset += line.len();
        if index == 0 {
            continue;
        }
        let step: usize = line
            .split(',')
            .next()
            .and_then(|s| s.trim().parse().ok())
            .ok_or_else(|| content(format!("line {}: no step number", index + 1)))?;
        if step != index - 1 || !line.ends_with('\n') {
            return Err(content(format!(
                "line {}: expected the complete row of step {}",
                index + 1,
                index - 1
            )));
        }
        if step == steps {
            end = Some(offset);
            break;
        }
    }
    let Some(end) = end else {
        return Err(content(format!(
            "has no row for step {steps}, where the checkpoint is; it does not belong to this checkpoint"
        )));
    };
    let kept = &text[..end];
    if end < text.len() {
        write_atomically(path, |w| std::io::Write::write_all(w, kept.as_bytes()))?;
    }
    Ok(kept.to_string())
}

fn append(path: &Path) -> Result<BufWriter<File>> {
    OpenOptions::new()
        .append(true)
        .open(path)
        .map(BufWriter::new)
        .map_err(|e| Error::io(path, e))
}
