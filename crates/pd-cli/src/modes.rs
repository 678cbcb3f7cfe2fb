//! `pd modes SCENE [--count K] [--out DIR]`: the scene's lowest elastic
//! modes at rest (`pd_modes`), their frequencies and the damping
//! ratio each gets under the scene's damping and integrator at its time
//! step (numerical damping included), in `DIR/modes.json`, and each mode
//! shape as an animated sequence: `DIR/mode_NN.pvd` over VTU frames and
//! `DIR/mode_NN/frames/frame_NNNN.obj` (so `pd render DIR/mode_NN` draws it).

use std::path::{Path, PathBuf};

use pd_damping::Point;
use pd_damping::registry::DampingSpec;
use pd_io::frames::{Cells, write_obj};
use pd_io::vtu::{PvdEntry, write_pvd, write_vtu};
use pd_modes::Mode;
use pd_solver::{Model, Simulation};
use tracing::info;

use crate::Failure;
use crate::run::{self, SceneOptions};

/// Frames per period of each animated mode.
const FRAMES: usize = 24;
/// The largest vertex displacement of an animated mode, as a fraction of the
/// scene's bounding-box diagonal.
const AMPLITUDE: f64 = 0.1;

/// `pd modes`.
pub(crate) fn modes(options: &SceneOptions, count: usize) -> Result<(), Failure> {
    if count == 0 {
        return Err(Failure::Input("--count must be at least 1".into()));
    }
    if options.steps.is_some() {
        return Err(Failure::Input(format!(
            "--steps: pd modes runs no steps (each mode is animated over one period, \
             {FRAMES} frames)"
        )));
    }
    let loaded = run::load_scene(options)?;
    let scene = &loaded.scene;
    let sim = run::build(scene)?;
    let analysis = pd_modes::elastic_modes(sim.model(), count)
        .map_err(|e| Failure::Input(format!("{}: modal analysis: {e}", scene.source.display())))?;
    info!(
        "{} elastic modes of {} dofs ({} rigid, {} mechanisms skipped) by {} in {:.1} ms \
         (factorisation {:.1} ms, {} iterations); the solver's own factorisation took {:.1} ms",
        analysis.modes.len(),
        analysis.dofs,
        analysis.rigid_modes,
        analysis.mechanisms,
        analysis.method,
        analysis.seconds * 1e3,
        analysis.factor_seconds * 1e3,
        analysis.iterations,
        sim.setup_stats().factor_seconds * 1e3
    );
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(format!("modes-{}", loaded.name)));
    std::fs::create_dir_all(&out)
        .map_err(|e| Failure::Output(format!("{}: {e}", out.display())))?;
    let dt = scene.settings.dt;
    let d = sim.damping_matrix();
    // Per-body damping gives each body its own coefficients, which the
    // one-coefficient modal estimate below does not split: no ratios then.
    let per_body = sim.damping_body_coefficients().is_some();
    let implicit_only = damping_is_implicit(&scene.damping) && !per_body;
    let make = || scene.integrator.create();
    let mut entries = Vec::new();
    for (i, mode) in analysis.modes.iter().enumerate() {
        let c = d.mass
            + d.damping_laplacian * mode.laplacian_quotient
            + d.lagged_stiffness * mode.omega * mode.omega;
        let discrete = pd_modes::discrete_mode(&make, dt, mode.omega, c);
        let name = format!("mode_{:02}", i + 1);
        write_animation(&out, &name, &sim, mode)?;
        entries.push(serde_json::json!({
            "mode": i + 1,
            "frequency_hz": mode.frequency_hz(),
            "omega_rad_s": mode.omega,
            "laplacian_quotient_per_s2": mode.laplacian_quotient,
            "modal_damping_per_s": c,
            "continuous_damping_ratio": c / (2.0 * mode.omega),
            "damping_ratio": implicit_only.then_some(discrete.damping_ratio),
            "discrete_frequency_hz": discrete.omega / std::f64::consts::TAU,
            "amplitude_factor_per_step": discrete.spectral_radius,
            "animation": format!("{name}.pvd"),
        }));
    }
    let column =
        |key: &str| -> Vec<serde_json::Value> { entries.iter().map(|e| e[key].clone()).collect() };
    let json = serde_json::json!({
        "scene": scene.source.display().to_string(),
        "integrator": scene.integrator.name(),
        "dt": dt,
        "damping": sim.damping_name(),
        "damping_coefficients": {
            "mass_per_s": d.mass,
            "laplacian_stiffness_s": d.damping_laplacian,
            "lagged_stiffness_s": d.lagged_stiffness,
        },
        "damping_ratios_note": if per_body {
            "null: per-body damping ([[body]] damping); each body's ratio is set for its own \
             lowest mode (docs/design/damping.md), which this estimate does not split by body"
        } else if implicit_only {
            "discrete damping ratio of each mode under the scene's integrator at dt: the model's \
             damping plus the integrator's numerical damping"
        } else {
            "null: this damping model acts by an explicit velocity filter, which the modal \
             estimate does not include"
        },
        "frequencies_hz": column("frequency_hz"),
        "damping_ratios": column("damping_ratio"),
        "dofs": analysis.dofs,
        "rigid_modes": analysis.rigid_modes,
        "mechanisms": analysis.mechanisms,
        "method": analysis.method,
        "iterations": analysis.iterations,
        "solved_columns": analysis.solved_columns,
        "analysis_ms": analysis.seconds * 1e3,
        "analysis_factor_ms": analysis.factor_seconds * 1e3,
        "solver_factor_ms": sim.setup_stats().factor_seconds * 1e3,
        "modes": entries,
    });
    let path = out.join("modes.json");
    let text = serde_json::to_string_pretty(&json).map_err(|e| Failure::Output(e.to_string()))?;
    std::fs::write(&path, text + "\n")
        .map_err(|e| Failure::Output(format!("{}: {e}", path.display())))?;
    info!(
        "wrote {} and {} animated modes",
        path.display(),
        analysis.modes.len()
    );
    Ok(())
}

/// Whether the model's damping is all in its implicit matrix (what the
/// modal estimate sees): not explicit ether drag or PBD.
fn damping_is_implicit(spec: &DampingSpec) -> bool {
    match spec.name() {
        "pbd" => false,
        "ether-drag" => spec.flag("implicit").unwrap_or(false),
        _ => true,
    }
}

/// One period of `mode` as `DIR/NAME.pvd` (VTU frames in `DIR/NAME/`) and
/// OBJ surface frames in `DIR/NAME/frames/`.
fn write_animation(dir: &Path, name: &str, sim: &Simulation, mode: &Mode) -> Result<(), Failure> {
    let model = sim.model();
    let (tets, surface, lines) = cells(model);
    let rest = model.rest_positions();
    let largest = mode.shape.iter().map(|p| p.norm()).fold(0.0, f64::max);
    let (lo, hi) = rest.iter().fold(
        (
            Point::repeat(f64::INFINITY),
            Point::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let scale = if largest > 0.0 {
        AMPLITUDE * (hi - lo).norm() / largest
    } else {
        0.0
    };
    let frames = dir.join(name).join("frames");
    std::fs::create_dir_all(&frames)
        .map_err(|e| Failure::Output(format!("{}: {e}", frames.display())))?;
    let output = |e: pd_io::Error| Failure::Output(e.to_string());
    let mut entries = Vec::new();
    let period = std::f64::consts::TAU / mode.omega;
    for k in 0..FRAMES {
        let phase = std::f64::consts::TAU * k as f64 / FRAMES as f64;
        let positions: Vec<Point> = rest
            .iter()
            .zip(&mode.shape)
            .map(|(x, phi)| x + phi * (scale * phase.sin()))
            .collect();
        let vtu = format!("{name}/frame_{k:04}.vtu");
        let cells = Cells {
            tets: &tets,
            triangles: if tets.is_empty() { &surface } else { &[] },
            lines: &lines,
        };
        write_vtu(&dir.join(&vtu), &positions, &cells, None, None).map_err(output)?;
        write_obj(
            &frames.join(format!("frame_{k:04}.obj")),
            &positions,
            &surface,
            &lines,
        )
        .map_err(output)?;
        entries.push(PvdEntry {
            time: period * k as f64 / FRAMES as f64,
            file: vtu,
        });
    }
    write_pvd(&dir.join(format!("{name}.pvd")), &entries).map_err(output)
}

/// Tetrahedra, surface triangles and chain edges of every body, in the
/// global numbering.
type AllCells = (Vec<[usize; 4]>, Vec<[usize; 3]>, Vec<[usize; 2]>);

fn cells(model: &Model) -> AllCells {
    let (mut tets, mut surface, mut lines) = (Vec::new(), Vec::new(), Vec::new());
    for body in model.bodies() {
        let (o, mesh) = (body.offset, &body.mesh);
        tets.extend(mesh.tets().iter().map(|e| e.map(|v| v + o)));
        surface.extend(mesh.surface_triangles().iter().map(|e| e.map(|v| v + o)));
        if mesh.tets().is_empty() && mesh.triangles().is_empty() {
            lines.extend(mesh.edges().iter().map(|e| e.map(|v| v + o)));
        }
    }
    (tets, surface, lines)
}
