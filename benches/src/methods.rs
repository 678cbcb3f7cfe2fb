//! `pd-probe methods`: error against cost per step for each iteration
//! method of the `[solver]` table (docs/design/solver.md "Iteration methods").
//!
//! The reference is Newton's method run to a relative residual of
//! `reference_tolerance` (1e-10) with the same integrator, damping and step.
//! For each method and iteration budget, the beam runs `steps` steps; the
//! error is the largest vertex distance to the reference's final positions
//! over the body's diagonal. Cost is reported three ways: the median wall
//! time per step (noisy on a loaded machine), and the deterministic counts
//! per step of local-global iterations (one projection pass and one
//! prefactored solve each) and of objective evaluations (one projection
//! pass each), from which `work` (in plain-iteration equivalents) is
//! `iterations + evaluations * local_fraction`, the local step's share of a
//! plain iteration measured in the same run.

use pd_io::stats::median;
use pd_mesh::Mesh;
use pd_solver::{Predictor, Settings, Simulation, SolverMethod, SolverSpec, StepStats};
use serde_json::Value;

use crate::Beam;
use crate::schema::{Methods, MethodsRow};

/// What one `methods` measurement runs.
#[derive(Debug, Clone)]
pub struct MethodsPlan {
    /// `be`, `im` or `bdf2`.
    pub integrator: String,
    /// A damping preset name (`pd_benches::damping`).
    pub damping: String,
    /// Steps of the run.
    pub steps: usize,
    /// Iteration budgets of the accelerated and plain methods.
    pub budgets: Vec<usize>,
    /// Iteration budgets of Newton.
    pub newton_budgets: Vec<usize>,
    /// Newton's relative residual for the reference.
    pub reference_tolerance: f64,
    /// The methods measured (plain local-global with a budget of 20 must be
    /// among them for `local_fraction`).
    pub methods: Vec<SolverMethod>,
    /// The `[solver]` parameters (window, rho, start) of every method.
    pub parameters: SolverSpec,
    /// Methods measured again with a `[solver] predictor` other than the
    /// inertial one (rows named `anderson+extrapolated`); the reference and
    /// `methods` start at the inertial target.
    pub predicted: Vec<(SolverMethod, Predictor)>,
}

impl MethodsPlan {
    /// Every method of the `[solver]` table, with its default parameters.
    pub const ALL_METHODS: [SolverMethod; 5] = [
        SolverMethod::LocalGlobal,
        SolverMethod::Anderson,
        SolverMethod::Chebyshev,
        SolverMethod::Lbfgs,
        SolverMethod::Newton,
    ];
}

fn simulation(
    beam: &Beam,
    mesh: &Mesh,
    plan: &MethodsPlan,
    (method, predictor): (SolverMethod, Predictor),
    settings: Settings,
) -> Result<Simulation, String> {
    let mut sim = Simulation::new(
        beam.model_on(mesh.clone())?,
        crate::integrator(&plan.integrator)?,
        crate::damping(&plan.damping)?,
        settings,
    )
    .map_err(|e| e.to_string())?;
    let spec = SolverSpec {
        method,
        ..plan.parameters
    };
    sim.set_position_solver(spec.create().map_err(|e| e.to_string())?);
    sim.set_predictor(predictor);
    Ok(sim)
}

fn per_step(stats: &[StepStats], f: impl Fn(&StepStats) -> f64) -> f64 {
    stats.iter().map(f).sum::<f64>() / stats.len().max(1) as f64
}

/// Runs the plan on `mesh` (the beam's, or one read from a file).
///
/// # Errors
/// A model or damping the solver rejects; a reference that fails.
pub fn measure(beam: &Beam, mesh: &Mesh, plan: &MethodsPlan) -> Result<Value, String> {
    let diagonal = {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in mesh.vertices() {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt()
    };
    let reference_settings = Settings {
        iterations: 100,
        tolerance: plan.reference_tolerance,
        ..beam.settings()
    };
    let inertial = (SolverMethod::Newton, Predictor::Inertial);
    let mut reference = simulation(beam, mesh, plan, inertial, reference_settings)?;
    let stats = reference.run(plan.steps).map_err(|e| e.to_string())?;
    let unconverged = stats.iter().filter(|s| !s.converged).count();
    let reference_iterations = per_step(&stats, |s| s.iterations as f64);
    let mut rows = Vec::new();
    let mut local_fraction = f64::NAN;
    let variants = (plan.methods.iter().map(|&m| (m, Predictor::Inertial)))
        .chain(plan.predicted.iter().copied());
    for (method, predictor) in variants {
        let name = match predictor {
            Predictor::Inertial => method.name().to_string(),
            Predictor::Fitted { order, equations } if predictor != Predictor::FITTED => {
                format!("{}+fitted{order}/{equations}", method.name())
            }
            other => format!("{}+{}", method.name(), other.name()),
        };
        let budgets = if method == SolverMethod::Newton {
            &plan.newton_budgets
        } else {
            &plan.budgets
        };
        for &iterations in budgets {
            let settings = Settings {
                iterations,
                ..beam.settings()
            };
            let mut sim = simulation(beam, mesh, plan, (method, predictor), settings)?;
            let row = match sim.run(plan.steps) {
                Ok(stats) => {
                    let error = sim
                        .state()
                        .positions
                        .iter()
                        .zip(&reference.state().positions)
                        .map(|(a, b)| (a - b).norm())
                        .fold(0.0, f64::max);
                    if (method, predictor) == (SolverMethod::LocalGlobal, Predictor::Inertial)
                        && iterations == 20
                    {
                        let local = per_step(&stats, |s| s.local_seconds);
                        let global = per_step(&stats, |s| s.global_seconds);
                        local_fraction = local / (local + global);
                    }
                    MethodsRow {
                        method: name.clone(),
                        budget: iterations,
                        position_error_rel: Some(error / diagonal),
                        iterations_per_step: Some(per_step(&stats, |s| s.iterations as f64)),
                        evaluations_per_step: Some(per_step(&stats, |s| {
                            s.objective_evaluations as f64
                        })),
                        step_ms_median: Some(
                            1e3 * median(
                                &stats.iter().map(|s| s.total_seconds).collect::<Vec<_>>(),
                            ),
                        ),
                        diverged: false,
                        error: None,
                    }
                }
                Err(e) => MethodsRow {
                    method: name.clone(),
                    budget: iterations,
                    position_error_rel: None,
                    iterations_per_step: None,
                    evaluations_per_step: None,
                    step_ms_median: None,
                    diverged: true,
                    error: Some(e.to_string()),
                },
            };
            rows.push(row);
        }
    }
    serde_json::to_value(Methods {
        integrator: plan.integrator.clone(),
        damping: plan.damping.clone(),
        n_verts: mesh.num_vertices(),
        steps: plan.steps,
        dt: beam.dt,
        reference_tolerance: plan.reference_tolerance,
        reference_unconverged_steps: unconverged,
        reference_iterations_per_step: reference_iterations,
        local_fraction,
        rows,
    })
    .map_err(|e| e.to_string())
}
