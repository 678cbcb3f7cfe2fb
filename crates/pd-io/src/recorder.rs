//! The run recorder: what a run writes into its output folder.
//!
//! - `metrics.csv`: one row per step (row 0 is the initial state) with
//!   `step,time,kinetic,elastic,gravity,total,px,py,pz,jx,jy,jz,iterations,step_ms,local_ms,global_ms,residual,estimated_error,contacts,penetration`
//!   (energies in J, linear momentum in kg m/s, angular momentum about the
//!   origin in kg m^2/s, times in ms), the format of [`MetricsRow`], which
//!   also reads it back;
//! - `probes.csv`: `step,time` and `x_I,y_I,z_I,vx_I,vy_I,vz_I` per probed
//!   vertex `I`, every step;
//! - `frames/frame_NNNNN.vtk` / `.vtu` / `.obj` / `.ply` every `output.every`
//!   steps (frame 0 is the initial state), and with `.vtu` frames the series
//!   `frames.pvd` (rewritten atomically after each frame) that ParaView
//!   opens as an animation;
//! - `summary.json`: sizes, timings (medians), how the run ended, its
//!   `"accuracy"` (the steps' estimated errors, the energy created where
//!   the setting should only dissipate; `recorder/accuracy.rs`) and
//!   `"warnings"` (what to change when either is too large);
//! - `final_state.json`: the last state, an initial-state file another scene
//!   can start from (`initial_state = ".../final_state.json"`).
//!
//! Rows are flushed every step, so a run that stops early (divergence, a
//! signal) keeps every row written before it.
//!
//! A new run in a folder that holds an earlier one first removes that
//! run's `frames/frame_*`, `frames.pvd` and (if it writes none) `probes.csv`,
//! so no file of the earlier run passes for this one's; the other files are
//! rewritten. The scene is built before that, so a scene that fails to
//! build leaves the folder as it was.

mod accuracy;
mod metrics;
mod resume;

pub use accuracy::{AccuracyWatch, ENERGY_WARNING, EnergyCreated};
pub use metrics::MetricsRow;

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use pd_solver::{Simulation, StepStats};

use pd_mesh::Point;

use crate::frames::{Cells, write_obj, write_vtk};
use crate::ply::write_ply;
use crate::scene::{FrameFormat, OutputSpec, Scene};
use crate::stats::median;
use crate::strain::StrainMeasure;
use crate::vtu::{PvdEntry, write_pvd, write_vtu};
use crate::{Error, Result};

/// Merged output topology of every body, in the global vertex numbering.
#[derive(Debug, Clone, Default)]
struct Topology {
    tets: Vec<[usize; 4]>,
    /// Boundary triangles of tet bodies and the triangles of surface bodies.
    surface: Vec<[usize; 3]>,
    /// Triangles of bodies that are surfaces (cloth), for VTK cells.
    surface_cells: Vec<[usize; 3]>,
    /// Edges of bodies that have neither tets nor triangles (chains).
    lines: Vec<[usize; 2]>,
    /// Rest positions of every vertex (the meshes, translated), for strain.
    rest: Vec<Point>,
}

impl Topology {
    fn of(sim: &Simulation) -> Self {
        let mut t = Topology::default();
        for body in sim.model().bodies() {
            let o = body.offset;
            let mesh = &body.mesh;
            if t.rest.len() < o + mesh.num_vertices() {
                t.rest.resize(o + mesh.num_vertices(), Point::zeros());
            }
            t.rest[o..o + mesh.num_vertices()].copy_from_slice(mesh.vertices());
            t.tets.extend(mesh.tets().iter().map(|e| e.map(|v| v + o)));
            t.surface
                .extend(mesh.surface_triangles().iter().map(|e| e.map(|v| v + o)));
            if mesh.tets().is_empty() {
                t.surface_cells
                    .extend(mesh.triangles().iter().map(|e| e.map(|v| v + o)));
                if mesh.triangles().is_empty() {
                    t.lines
                        .extend(mesh.edges().iter().map(|e| e.map(|v| v + o)));
                }
            }
        }
        t
    }

    /// The cells of a volume frame (VTK, VTU): tetrahedra, the triangles of
    /// cloth, the edges of chains.
    fn vtk_cells(&self) -> Cells<'_> {
        Cells {
            tets: &self.tets,
            triangles: &self.surface_cells,
            lines: &self.lines,
        }
    }
}

/// The end of a run, for `summary.json`.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Every step ran.
    Completed,
    /// The run stopped with this error message.
    Failed(String),
    /// The user stopped the run (Ctrl-C) after a whole step; the message
    /// says where.
    Interrupted(String),
}

/// Writes a run's outputs step by step.
#[derive(Debug)]
pub struct Recorder {
    dir: PathBuf,
    output: OutputSpec,
    topology: Topology,
    metrics: BufWriter<File>,
    metrics_path: PathBuf,
    probes: Option<(BufWriter<File>, PathBuf)>,
    step_ms: Vec<f64>,
    local_ms: Vec<f64>,
    global_ms: Vec<f64>,
    frames: usize,
    /// Strain of the VTU cells, prepared when `.vtu` frames are written.
    strain: Option<StrainMeasure>,
    /// Scratch for one frame's strain values.
    strain_values: Vec<f64>,
    /// The `.vtu` frames written so far, for `frames.pvd`.
    pvd: Vec<PvdEntry>,
    /// The `"accuracy"` of `summary.json`, row by row.
    accuracy: AccuracyWatch,
}

impl Recorder {
    /// Creates the output folder and files and records the initial state
    /// (metrics row 0, probes row 0, frame 0).
    ///
    /// # Errors
    /// A probe beyond the simulation's vertices ([`Error::Field`], before
    /// anything is written); the folder or a file cannot be created or
    /// written.
    pub fn create(dir: &Path, scene: &Scene, sim: &Simulation) -> Result<Self> {
        // `Scene::build` checks the probes; a scene edited or paired with
        // another simulation after it is checked again, before any file.
        scene.check_probes(sim.model().num_vertices())?;
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        // An earlier run's frames, series and probes in the same folder
        // would read as this run's (ParaView groups `frame_*`).
        let frames = dir.join("frames");
        crate::frames::remove_frames_from(&frames, 0)?;
        remove_if_present(&dir.join("frames.pvd"))?;
        if scene.output.probes.is_empty() {
            remove_if_present(&dir.join("probes.csv"))?;
        }
        if scene.output.frame_every() > 0 {
            std::fs::create_dir_all(&frames).map_err(|e| Error::io(&frames, e))?;
        }
        let metrics_path = dir.join(MetricsRow::FILE);
        let mut metrics = create(&metrics_path)?;
        MetricsRow::write_header(&mut metrics).map_err(|e| Error::io(&metrics_path, e))?;
        let probes = if scene.output.probes.is_empty() {
            None
        } else {
            let path = dir.join("probes.csv");
            let mut file = create(&path)?;
            let mut header = String::from("step,time");
            for p in &scene.output.probes {
                header.push_str(&format!(",x_{p},y_{p},z_{p},vx_{p},vy_{p},vz_{p}"));
            }
            writeln!(file, "{header}").map_err(|e| Error::io(&path, e))?;
            Some((file, path))
        };
        let topology = Topology::of(sim);
        let strain = scene
            .output
            .formats
            .contains(&FrameFormat::Vtu)
            .then(|| StrainMeasure::new(&topology.rest, &topology.vtk_cells()));
        let mut recorder = Self {
            dir: dir.to_path_buf(),
            output: scene.output.clone(),
            topology,
            metrics,
            metrics_path,
            probes,
            step_ms: Vec::new(),
            local_ms: Vec::new(),
            global_ms: Vec::new(),
            frames: 0,
            strain,
            strain_values: Vec::new(),
            pvd: Vec::new(),
            accuracy: AccuracyWatch::default(),
        };
        recorder.write_rows(sim, None)?;
        if recorder.output.frame_every() > 0 {
            recorder.write_frame(sim)?;
        }
        Ok(recorder)
    }

    /// Records the step just taken.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn record(&mut self, sim: &Simulation, stats: &StepStats) -> Result<()> {
        self.step_ms.push(stats.total_seconds * 1e3);
        self.local_ms.push(stats.local_seconds * 1e3);
        self.global_ms.push(stats.global_seconds * 1e3);
        self.write_rows(sim, Some(stats))?;
        let every = self.output.frame_every();
        if every > 0 && sim.steps().is_multiple_of(every) {
            self.write_frame(sim)?;
        }
        Ok(())
    }

    /// Median wall time of a step so far, ms (NaN before the first step).
    pub fn median_step_ms(&self) -> f64 {
        median(&self.step_ms)
    }

    /// The run's accuracy warnings so far (`summary.json`'s `"warnings"`):
    /// each names the measured figure and what to change.
    pub fn warnings(&self, sim: &Simulation) -> Vec<String> {
        self.accuracy.warnings(sim)
    }

    /// Number of frames written.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The output folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes `summary.json` and flushes everything.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn finish(mut self, scene: &Scene, sim: &Simulation, outcome: &Outcome) -> Result<PathBuf> {
        self.metrics
            .flush()
            .map_err(|e| Error::io(&self.metrics_path, e))?;
        if let Some((file, path)) = &mut self.probes {
            file.flush().map_err(|e| Error::io(&*path, e))?;
        }
        let setup = sim.setup_stats();
        let (status, error) = match outcome {
            Outcome::Completed => ("completed", None),
            Outcome::Failed(message) => ("failed", Some(message.clone())),
            Outcome::Interrupted(message) => ("interrupted", Some(message.clone())),
        };
        let summary = serde_json::json!({
            "scene": scene.source.display().to_string(),
            "status": status,
            "error": error,
            "steps": sim.steps(),
            "steps_requested": scene.steps,
            "time": sim.time(),
            "dt": sim.settings().dt,
            "iterations": sim.settings().iterations,
            "integrator": sim.integrator_name(),
            "damping": sim.damping_name(),
            "damping_coefficients": damping_coefficients(sim),
            "bodies": sim.model().bodies().len(),
            "vertices": sim.model().num_vertices(),
            "free_vertices": sim.num_free_vertices(),
            "elements": sim.model().bodies().iter().map(|b| b.mesh.num_elements()).sum::<usize>(),
            "constraints": sim.model().num_constraints(),
            "factor_values": sim.factor_len(),
            "analysis_ms": setup.analysis_seconds * 1e3,
            "factor_ms": setup.factor_seconds * 1e3,
            "factorisations": setup.factorisations,
            "median_step_ms": json_number(median(&self.step_ms)),
            "median_local_ms": json_number(median(&self.local_ms)),
            "median_global_ms": json_number(median(&self.global_ms)),
            "frames": self.frames,
            "accuracy": self.accuracy.summary(sim),
            "warnings": self.accuracy.warnings(sim),
        });
        let state = sim.state();
        crate::state::write_state(
            &self.dir.join("final_state.json"),
            &state.positions,
            &state.velocities,
        )?;
        let path = self.dir.join("summary.json");
        let text = serde_json::to_string_pretty(&summary).expect("a JSON value always serialises");
        crate::atomic::write_atomically(&path, |w| writeln!(w, "{text}"))?;
        Ok(path)
    }

    fn write_rows(&mut self, sim: &Simulation, stats: Option<&StepStats>) -> Result<()> {
        let row = MetricsRow::of(sim, stats);
        self.accuracy.observe(&row);
        row.write(&mut self.metrics)
            .and_then(|()| self.metrics.flush())
            .map_err(|err| Error::io(&self.metrics_path, err))?;
        if let Some((file, path)) = &mut self.probes {
            let state = sim.state();
            let mut row = format!("{},{}", sim.steps(), sim.time());
            for &v in &self.output.probes {
                let (x, u) = (state.positions[v], state.velocities[v]);
                row.push_str(&format!(",{},{},{},{},{},{}", x.x, x.y, x.z, u.x, u.y, u.z));
            }
            writeln!(file, "{row}")
                .and_then(|()| file.flush())
                .map_err(|err| Error::io(&*path, err))?;
        }
        Ok(())
    }

    fn write_frame(&mut self, sim: &Simulation) -> Result<()> {
        let state = sim.state();
        let t = &self.topology;
        for format in &self.output.formats {
            match format {
                FrameFormat::Vtk => {
                    let path = self.frame_path("vtk");
                    write_vtk(
                        &path,
                        &state.positions,
                        &t.vtk_cells(),
                        Some(&state.velocities),
                    )?;
                }
                FrameFormat::Obj => {
                    let path = self.frame_path("obj");
                    write_obj(&path, &state.positions, &t.surface, &t.lines)?;
                }
                FrameFormat::Vtu => {
                    let path = self.frame_path("vtu");
                    let strain = self
                        .strain
                        .get_or_insert_with(|| StrainMeasure::new(&t.rest, &t.vtk_cells()));
                    strain.measure_into(&state.positions, &mut self.strain_values);
                    write_vtu(
                        &path,
                        &state.positions,
                        &t.vtk_cells(),
                        Some(&state.velocities),
                        Some(&self.strain_values),
                    )?;
                    self.pvd.push(PvdEntry {
                        time: sim.time(),
                        file: format!("frames/frame_{:05}.vtu", self.frames),
                    });
                    write_pvd(&self.dir.join("frames.pvd"), &self.pvd)?;
                }
                FrameFormat::Ply => {
                    let path = self.frame_path("ply");
                    write_ply(&path, &state.positions, &t.surface, &t.lines)?;
                }
            }
        }
        self.frames += 1;
        Ok(())
    }

    fn frame_path(&self, extension: &str) -> PathBuf {
        self.dir
            .join("frames")
            .join(format!("frame_{:05}.{extension}", self.frames))
    }
}

/// Writes the current state of `sim` as one frame file, in the format its
/// extension names (`.vtk`, `.vtu`, `.obj` or `.ply`), with the cells and
/// fields a run's frames of that format have.
///
/// # Errors
/// [`Error::Content`] for another extension; [`Error::Io`] if the file
/// cannot be written.
pub fn write_frame_file(path: &Path, sim: &Simulation) -> Result<()> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let format = FrameFormat::parse(&extension.to_ascii_lowercase()).ok_or_else(|| {
        let names: Vec<&str> = FrameFormat::ALL.iter().map(|f| f.name()).collect();
        Error::Content {
            path: path.to_path_buf(),
            message: format!(
                "unknown frame format {extension:?}: the extension must be one of {}",
                names.join(", ")
            ),
        }
    })?;
    let state = sim.state();
    let t = Topology::of(sim);
    match format {
        FrameFormat::Vtk => write_vtk(
            path,
            &state.positions,
            &t.vtk_cells(),
            Some(&state.velocities),
        ),
        FrameFormat::Obj => write_obj(path, &state.positions, &t.surface, &t.lines),
        FrameFormat::Ply => write_ply(path, &state.positions, &t.surface, &t.lines),
        FrameFormat::Vtu => {
            let mut strain = Vec::new();
            StrainMeasure::new(&t.rest, &t.vtk_cells()).measure_into(&state.positions, &mut strain);
            write_vtu(
                path,
                &state.positions,
                &t.vtk_cells(),
                Some(&state.velocities),
                Some(&strain),
            )
        }
    }
}

/// Removes the file at `path` if there is one.
fn remove_if_present(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(path, e)),
        _ => Ok(()),
    }
}

fn create(path: &Path) -> Result<BufWriter<File>> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|e| Error::io(path, e))
}

fn json_number(value: f64) -> serde_json::Value {
    serde_json::Number::from_f64(value).map_or(serde_json::Value::Null, serde_json::Value::Number)
}

/// The damping matrix coefficients of `sim` for the summary (what a
/// scene's `ratio` was turned into).
fn damping_coefficients(sim: &Simulation) -> serde_json::Value {
    let d = sim.damping_matrix();
    let mut json = serde_json::json!({
        "mass_per_s": d.mass,
        "laplacian_stiffness_s": d.damping_laplacian,
        "lagged_stiffness_s": d.lagged_stiffness,
    });
    // A Caughey series: a3, a4, ... (s^3, s^5, ...).
    if d.has_series() {
        json["series"] = d.series_coefficients()[2..].to_vec().into();
    }
    // Per-body damping: the above are the largest; each body's own follow.
    if let Some(per_body) = sim.damping_body_coefficients() {
        json["per_body"] = per_body
            .iter()
            .map(|d| serde_json::json!({"mass_per_s": d.mass, "laplacian_stiffness_s": d.damping_laplacian}))
            .collect();
    }
    json
}
