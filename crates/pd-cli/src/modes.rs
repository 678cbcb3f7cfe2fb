//! `pd modes SCENE [--count K] [--out DIR]`: the scene's lowest elastic
//! modes at rest (`pd_modes`), their frequencies and the damping
//! ratio each gets under the scene's damping and integrator at its time
//! step (numerical damping included), in `DIR/modes.json`, and each mode
//! shape as an animated sequence: `DIR/mode_NN.pvd` over VTU frames and
//! `DIR/mode_NN/frames/frame_NNNN.obj` (so `pd render DIR/mode_NN` draws it).

use std::path::{Path, PathBuf};

use pd_damping::Point;
use pd_io::frames::{Cells, write_obj};
use pd_io::modes_report::{MODES_FILE, animation_name, modes_report};
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
    for (i, mode) in analysis.modes.iter().enumerate() {
        write_animation(&out, &animation_name(i), &sim, mode)?;
    }
    let json = modes_report(scene, &sim, &analysis, true);
    let path = out.join(MODES_FILE);
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
