//! Per-body damping: `[[body]] damping = { model = "laplacian", ratio = 0.1 }`
//! overrides `[damping]` for that body (docs/design/damping.md, "Per-body
//! damping").
//!
//! When a body carries its own table, every body's damping is resolved on
//! its own: a `ratio` (its own, or one it inherits from `[damping]`) is
//! turned into coefficients from that body's own elastic modes, computed on
//! the body alone (its mesh, constraints and fixed vertices; scenes have no
//! constraint between bodies, so the scene's modes are the union of the
//! bodies'). If every body then has the same model and coefficients, the
//! scene runs that one model, bit for bit as a `[damping]` table would;
//! otherwise [`pd_damping::PerBodyDamping`] runs each body's model on its
//! own vertices, with the implicit terms in one constant global matrix.

use pd_damping::ratio::FittedCoefficients;
use pd_damping::registry::DampingSpec;
use pd_damping::{Damping, DampingError, PerBodyDamping};
use pd_solver::Model;

use super::spec::Scene;
use crate::{Error, Result};

/// A damping error at `field.KEY`, or at `field` for a value out of its
/// domain (whose message names the parameter).
pub(super) fn damping_error(source: &std::path::Path, field: &str, error: &DampingError) -> Error {
    match error.key_and_reason() {
        Some((key, reason)) => super::field_error(source, format!("{field}.{key}"), reason),
        None => super::field_error(source, field, error.to_string()),
    }
}

impl Scene {
    /// Whether any body carries its own `damping` table.
    pub fn has_per_body_damping(&self) -> bool {
        self.bodies.iter().any(|b| b.damping.is_some())
    }

    /// Each body's damping as it will run, in scene order: its own table or
    /// `[damping]`, with a ratio resolved against the body's own modes
    /// (and the fitted coefficients). Only meaningful when
    /// [`Scene::has_per_body_damping`].
    ///
    /// # Errors
    /// A body that cannot be built alone, or a ratio that cannot be fitted,
    /// named by `body[i].damping.KEY` (or `damping.KEY` for an inherited
    /// table).
    pub fn resolve_body_damping(&self) -> Result<Vec<(DampingSpec, Option<FittedCoefficients>)>> {
        self.bodies
            .iter()
            .enumerate()
            .map(|(b, body)| {
                let (spec, field) = match &body.damping {
                    Some(own) => (own, format!("body[{b}].damping")),
                    None => (&self.damping, "damping".to_string()),
                };
                if spec.ratio_target().ok().flatten().is_none() {
                    // No modes needed (errors are reported by resolve_spec).
                    return self.resolve_spec(spec, &Model::new(), &field);
                }
                let mut alone = Model::new();
                self.add_body(&mut alone, b, body)?;
                self.resolve_spec(spec, &alone, &field)
            })
            .collect()
    }

    /// The damping model to simulate `model` with: `[damping]` resolved
    /// against the whole model, or the per-body composite.
    ///
    /// # Errors
    /// As [`Scene::resolve_damping`] and [`Scene::resolve_body_damping`];
    /// a body's lagged model (`rayleigh-lagged`) next to a different model
    /// on another body, at `body[i].damping` (or `damping`). A Caughey
    /// series fit of `[damping]` puts the ratios it achieves in `achieved`.
    pub(super) fn damping_model(
        &self,
        model: &Model,
        achieved: &mut Vec<pd_damping::ratio::AchievedRatio>,
    ) -> Result<Box<dyn Damping>> {
        if !self.has_per_body_damping() {
            let (spec, _, ratios) =
                self.resolve_spec_with_ratios(&self.damping, model, "damping")?;
            *achieved = ratios;
            return spec
                .create()
                .map_err(|e| super::field_error(&self.source, "damping", e));
        }
        let specs = self.resolve_body_damping()?;
        let field = |b: usize| match self.bodies[b].damping {
            Some(_) => format!("body[{b}].damping"),
            None => "damping".to_string(),
        };
        if specs.iter().all(|(s, _)| *s == specs[0].0) {
            // One model for every body: exactly what `[damping]` would run.
            return specs[0]
                .0
                .create()
                .map_err(|e| damping_error(&self.source, &field(0), &e));
        }
        let mut models = Vec::with_capacity(specs.len());
        for (b, (spec, _)) in specs.iter().enumerate() {
            let damping = spec
                .create()
                .map_err(|e| damping_error(&self.source, &field(b), &e))?;
            if damping.implicit_matrix().is_lagged() {
                return Err(super::field_error(
                    &self.source,
                    field(b),
                    format!(
                        "model \"{}\" refactorises the lagged stiffness every step and cannot \
                         be mixed with other models per body; give every body the same \
                         rayleigh-lagged damping (or use it in [damping] alone)",
                        spec.name()
                    ),
                ));
            }
            if damping.implicit_matrix().has_series() {
                return Err(super::field_error(
                    &self.source,
                    field(b),
                    "a Caughey series (three or more ratios, a band, or series) cannot be \
                     mixed with other damping per body (the per-body weights scale a2 L_d \
                     only); give every body the same damping, or use it in [damping] alone",
                ));
            }
            models.push(damping);
        }
        let per_body =
            PerBodyDamping::new(models).map_err(|e| damping_error(&self.source, "body", &e))?;
        Ok(Box::new(per_body))
    }
}
