//! Adjoint gradients for `pd fit` (`pd_adjoint`, docs/design/gradients.md):
//! one forward run and one backward pass per gradient, whatever the number
//! of fitted values, where the scene and the paths allow it.

use pd_adjoint::{AdjointError, AdjointOptions, Parameter, ParameterGradient, ProbeLoss};

use super::{Evaluation, GradientBackend, Problem};
use crate::Failure;

/// Gradients by the adjoint method.
pub(crate) struct Adjoint<'a> {
    problem: &'a Problem,
    parameters: Vec<Parameter>,
    loss: ProbeLoss,
}

impl<'a> Adjoint<'a> {
    /// The backend for `problem`, or why the adjoint method cannot give its
    /// gradient: a fitted path that is not one of its parameters (a ratio,
    /// a vertex mass, a Young's modulus, a body's own damping), or a scene
    /// it does not differentiate (contact, materials, velocity filters,
    /// lagged or per-body damping), found by one gradient at the start.
    pub(crate) fn new(problem: &'a Problem) -> Result<Self, String> {
        if problem.has_decay_target() {
            return Err("a decay target is not a loss on positions at each step".into());
        }
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
        let (probes, targets) = problem.loss_data();
        let backend = Self {
            problem,
            parameters,
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
        let gradient = result
            .gradients
            .iter()
            .map(|g| match g {
                ParameterGradient::Scalar(value) => *value,
                // Only scalar parameters are parsed from scene paths.
                ParameterGradient::Points(_) => f64::NAN,
            })
            .collect();
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
