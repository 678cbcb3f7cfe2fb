//! The modal report `pd modes` writes as `modes.json` (and the Python
//! package's `projdyn.modes` returns): each elastic mode's frequency and
//! the damping ratio it gets under the scene's damping and integrator at
//! its time step, numerical damping included.

use pd_damping::registry::DampingSpec;
use pd_modes::ModalAnalysis;
use pd_solver::Simulation;

use crate::scene::Scene;

/// The file name of the report inside `pd modes`'s output folder.
pub const MODES_FILE: &str = "modes.json";

/// The report of `analysis`, the elastic modes of `sim` built from
/// `scene`. With `animations`, each mode names its animation
/// `mode_NN.pvd` (the files `pd modes` writes beside the report); without,
/// the key is absent.
pub fn modes_report(
    scene: &Scene,
    sim: &Simulation,
    analysis: &ModalAnalysis,
    animations: bool,
) -> serde_json::Value {
    let dt = scene.settings.dt;
    let d = sim.damping_matrix();
    // Per-body damping gives each body its own coefficients, which the
    // one-coefficient modal estimate below does not split: no ratios then.
    let per_body = sim.damping_body_coefficients().is_some();
    let implicit_only = damping_is_implicit(&scene.damping) && !per_body;
    let make = || scene.integrator.create();
    // A Caughey series sums its terms over each mode's series quotients
    // `phi^T L_d (M^-1 L_d)^(k-2) phi` (docs/design/damping.md).
    let series = d
        .has_series()
        .then(|| pd_modes::SeriesOperator::new(sim.model()));
    let terms = d.series_coefficients().len();
    let mut entries = Vec::new();
    for (i, mode) in analysis.modes.iter().enumerate() {
        let c = match &series {
            None => {
                d.mass
                    + d.damping_laplacian * mode.laplacian_quotient
                    + d.lagged_stiffness * mode.omega * mode.omega
            }
            Some(operator) => d.series_damping(&operator.quotients(&mode.shape, terms)),
        };
        let discrete = pd_modes::discrete_mode(&make, dt, mode.omega, c);
        let mut entry = serde_json::json!({
            "mode": i + 1,
            "frequency_hz": mode.frequency_hz(),
            "omega_rad_s": mode.omega,
            "laplacian_quotient_per_s2": mode.laplacian_quotient,
            "modal_damping_per_s": c,
            "continuous_damping_ratio": c / (2.0 * mode.omega),
            "damping_ratio": implicit_only.then_some(discrete.damping_ratio),
            "discrete_frequency_hz": discrete.omega / std::f64::consts::TAU,
            "amplitude_factor_per_step": discrete.spectral_radius,
        });
        if animations {
            entry["animation"] = format!("{}.pvd", animation_name(i)).into();
        }
        entries.push(entry);
    }
    let column =
        |key: &str| -> Vec<serde_json::Value> { entries.iter().map(|e| e[key].clone()).collect() };
    serde_json::json!({
        "scene": scene.source.display().to_string(),
        "integrator": scene.integrator.name(),
        "dt": dt,
        "damping": sim.damping_name(),
        "damping_coefficients": {
            "mass_per_s": d.mass,
            "laplacian_stiffness_s": d.damping_laplacian,
            "lagged_stiffness_s": d.lagged_stiffness,
            "series": d.series_coefficients()[2..].to_vec(),
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
    })
}

/// The name of mode `index`'s (from 0) animation: `mode_01` for the first.
pub fn animation_name(index: usize) -> String {
    format!("mode_{:02}", index + 1)
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
