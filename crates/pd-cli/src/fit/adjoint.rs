//! Adjoint gradients for `pd fit` (`pd_adjoint`, docs/design/gradients.md):
//! one forward run and one backward pass per gradient, whatever the number
//! of fitted values, where the scene and the paths allow it.

use pd_adjoint::{AdjointError, AdjointOptions, Parameter, ParameterGradient, ProbeLoss};

use super::{Evaluation, GradientBackend, Problem};
use crate::Failure;

/// Gradients by the adjoint method.
pub(crate) struct Adjoint<'a> {
    problem: &'a Problem,
    /// What the adjoint differentiates: the fitted values themselves, or
    /// the damping coefficients the fitted ratios give.
    parameters: Vec<Parameter>,
    /// For fitted damping ratios, `d a_j / d zeta_i`: one row per entry of
    /// `parameters` (a damping coefficient), one column per fitted value.
    ratio_jacobian: Option<Vec<Vec<f64>>>,
    loss: ProbeLoss,
}

/// Whether `path` is the scene's damping ratio or one of its ratios.
fn is_ratio(path: &str) -> bool {
    path == "damping.ratio" || (path.starts_with("damping.ratios[") && path.ends_with(']'))
}

/// The damping coefficients `[a1, a2, a3, ...]` the scene at `values`
/// builds with (every series term, zero or not).
fn coefficients(problem: &Problem, values: &[f64]) -> Result<Vec<f64>, String> {
    let scene = problem.scene_at(values).map_err(|e| match e {
        Failure::Input(why)
        | Failure::Diverged(why)
        | Failure::Output(why)
        | Failure::Interrupted(why) => why,
    })?;
    let sim = scene
        .build()
        .map_err(|e| format!("at the parameters {}: {e}", problem.describe(values)))?;
    let d = sim.damping_model().implicit_matrix();
    let mut a = vec![d.mass, d.damping_laplacian];
    a.extend_from_slice(&d.series);
    Ok(a)
}

/// For a fit of damping ratios only: the adjoint's parameters (the damping
/// coefficients the ratios move) and `d a / d zeta`. With the modes fixed
/// (no fitted value changes a stiffness or a mass) the ratios map
/// linearly onto the coefficients (`a1 + a2 q_i + ... = 2 zeta_i omega_i`,
/// or `a2 = (2 zeta omega - a1) / q` for one ratio; pd-damping's
/// `RatioTarget`), so the map's Jacobian is constant, and one difference
/// per ratio gives it exactly but for rounding (the step is 1% of the
/// ratio: the coefficients' rounding, ~1e-16 of them, becomes ~1e-14 of
/// the Jacobian).
fn ratio_chain(problem: &Problem) -> Result<(Vec<Parameter>, Vec<Vec<f64>>), String> {
    let others: Vec<&str> = problem
        .paths
        .iter()
        .map(|p| p.text.as_str())
        .filter(|p| !is_ratio(p))
        .collect();
    if !others.is_empty() {
        return Err(format!(
            "damping ratios are fitted together with {}: a stiffness or a density moves the modes the ratios are fitted on, and another damping value enters the same fit (their derivatives through the modes are not implemented)",
            others.join(", ")
        ));
    }
    if problem
        .tree
        .get("damping")
        .and_then(|d| d.get("band"))
        .is_some()
    {
        return Err(
            "a band's ratio: which series terms the band fit keeps changes with the ratio, so the coefficients are not a smooth function of it"
                .into(),
        );
    }
    let start = &problem.start;
    let base = coefficients(problem, start)?;
    let mut columns = Vec::with_capacity(start.len());
    for i in 0..start.len() {
        let mut column = None;
        // Downwards if upwards the fit refuses the ratios (a negative
        // coefficient).
        for sign in [1.0, -1.0] {
            let mut values = start.clone();
            let step = sign * 0.01 * start[i];
            values[i] += step;
            if let Ok(moved) = coefficients(problem, &values) {
                let step = values[i] - start[i];
                column = Some(
                    moved
                        .iter()
                        .zip(&base)
                        .map(|(m, b)| (m - b) / step)
                        .collect::<Vec<f64>>(),
                );
                break;
            }
        }
        columns.push(column.ok_or_else(|| {
            format!(
                "{}: the ratios 1% either side of {} give no damping coefficients",
                problem.paths[i].text, start[i]
            )
        })?);
    }
    // The coefficients some ratio moves, each a parameter of the adjoint.
    let mut parameters = Vec::new();
    let mut jacobian = Vec::new();
    for j in 0..base.len() {
        let row: Vec<f64> = columns.iter().map(|c| c[j]).collect();
        if row.iter().all(|d| *d == 0.0) {
            continue;
        }
        parameters.push(match j {
            0 => Parameter::DampingMass,
            1 => Parameter::DampingStiffness,
            k => Parameter::DampingSeries(k - 2),
        });
        jacobian.push(row);
    }
    Ok((parameters, jacobian))
}

impl<'a> Adjoint<'a> {
    /// The backend for `problem`, or why the adjoint method cannot give its
    /// gradient: a fitted path that is not one of its parameters (a vertex
    /// mass, a Young's modulus, a body's own damping, a band's ratio, a
    /// ratio fitted with a value that moves the modes), or a scene
    /// it does not differentiate (contact, materials, velocity filters,
    /// lagged or per-body damping), found by one gradient at the start.
    pub(crate) fn new(problem: &'a Problem) -> Result<Self, String> {
        if problem.has_decay_target() {
            return Err("a decay target is not a loss on positions at each step".into());
        }
        let (parameters, ratio_jacobian) = if problem.paths.iter().any(|p| is_ratio(&p.text)) {
            let (parameters, jacobian) = ratio_chain(problem)?;
            (parameters, Some(jacobian))
        } else {
            let parameters = problem
                .paths
                .iter()
                .map(|p| {
                    p.text.parse::<Parameter>().map_err(|_| {
                        format!(
                            "{} is not a parameter the adjoint method differentiates",
                            p.text
                        )
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            (parameters, None)
        };
        let (probes, targets) = problem.loss_data();
        let backend = Self {
            problem,
            parameters,
            ratio_jacobian,
            loss: ProbeLoss {
                vertices: probes.to_vec(),
                targets: targets.to_vec(),
            },
        };
        match backend.run(&problem.start) {
            Err(Failure::Input(why)) => Err(why),
            _ => Ok(backend),
        }
    }

    fn run(&self, values: &[f64]) -> Result<Evaluation, Failure> {
        let scene = self.problem.scene_at(values)?;
        let sim = scene.build().map_err(|e| {
            Failure::Input(format!(
                "at the parameters {}: {e}",
                self.problem.describe(values)
            ))
        })?;
        let options = AdjointOptions::default();
        let steps = self.loss.targets.len();
        let result =
            pd_adjoint::loss_and_gradient(sim, steps, &self.loss, &self.parameters, &options)
                .map_err(|e| match e {
                    AdjointError::Unsupported { .. } | AdjointError::InvalidArgument { .. } => {
                        Failure::Input(e.to_string())
                    }
                    _ => Failure::Diverged(format!(
                        "at the parameters {}: {e}",
                        self.problem.describe(values)
                    )),
                })?;
        let gradient: Vec<f64> = result
            .gradients
            .iter()
            .map(|g| match g {
                ParameterGradient::Scalar(value) => *value,
                // Only scalar parameters are parsed from scene paths.
                ParameterGradient::Points(_) => f64::NAN,
            })
            .collect();
        // Through the ratios: dL/dzeta_i = sum_j (d a_j / d zeta_i) dL/da_j.
        let gradient = match &self.ratio_jacobian {
            Some(jacobian) => (0..values.len())
                .map(|i| {
                    jacobian
                        .iter()
                        .zip(&gradient)
                        .map(|(row, g)| row[i] * g)
                        .sum()
                })
                .collect(),
            None => gradient,
        };
        Ok(Evaluation {
            loss: result.loss,
            gradient,
            forward_s: result.forward_s,
            backward_s: result.backward_s,
        })
    }
}

impl GradientBackend for Adjoint<'_> {
    fn name(&self) -> &'static str {
        "adjoint"
    }

    fn loss(&mut self, values: &[f64]) -> Result<f64, Failure> {
        Ok(self.problem.forward(values)?.unwrap_or(f64::INFINITY))
    }

    /// The loss of the same forward run as [`GradientBackend::loss`] (so
    /// that the line search compares like with like), and the gradient of
    /// the adjoint method's own converged run (its forward and backward
    /// time are the gradient's cost).
    fn evaluate(&mut self, values: &[f64]) -> Result<Evaluation, Failure> {
        let start = std::time::Instant::now();
        let loss = self.problem.forward(values)?.ok_or_else(|| {
            Failure::Diverged(format!(
                "the run diverged at the parameters {}",
                self.problem.describe(values)
            ))
        })?;
        let forward_s = start.elapsed().as_secs_f64();
        let adjoint = self.run(values)?;
        Ok(Evaluation {
            loss,
            gradient: adjoint.gradient,
            forward_s,
            backward_s: adjoint.forward_s + adjoint.backward_s,
        })
    }
}
