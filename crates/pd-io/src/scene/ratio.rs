//! Damping by ratio: a `[damping]` table with `ratio` (and `mode`) or
//! `ratios` and `modes` instead of `stiffness` is turned into coefficients
//! from the model's elastic modes at rest ([`pd_solver::modes`],
//! [`pd_damping::ratio`]) when the scene is built.

use pd_damping::ratio::{FittedCoefficients, ModalData};
use pd_solver::{Model, modes};

use super::spec::Scene;
use crate::Result;

impl Scene {
    /// The damping to build for `model`: the scene's `[damping]` as written,
    /// or, when it gives a damping ratio, the same model with the fitted
    /// `stiffness` (`a2`, s) and `mass` (`a1`, 1/s), which are also
    /// returned.
    ///
    /// # Errors
    /// The modal analysis fails, or the fit asks for a mode the model does
    /// not have or needs a negative coefficient; each names the
    /// `damping.KEY`.
    pub fn resolve_damping(
        &self,
        model: &Model,
    ) -> Result<(
        pd_damping::registry::DampingSpec,
        Option<FittedCoefficients>,
    )> {
        let target = self
            .damping
            .ratio_target()
            .map_err(|e| self.damping_field_error(&e))?;
        let (Some(target), Some(quotient)) = (target, self.damping.model().ratio) else {
            return Ok((self.damping.clone(), None));
        };
        let analysis = modes::elastic_modes(model, target.highest_mode()).map_err(|e| {
            super::field_error(
                &self.source,
                "damping",
                format!("the modal analysis for the damping ratio failed: {e}"),
            )
        })?;
        let data: Vec<ModalData> = analysis
            .modes
            .iter()
            .map(|m| ModalData {
                omega: m.omega,
                laplacian_quotient: m.laplacian_quotient,
            })
            .collect();
        let coefficients = target
            .fit(quotient, &data)
            .map_err(|e| self.damping_field_error(&e))?;
        let spec = self
            .damping
            .resolved(coefficients)
            .map_err(|e| self.damping_field_error(&e))?;
        Ok((spec, Some(coefficients)))
    }

    fn damping_field_error(&self, error: &pd_damping::DampingError) -> crate::Error {
        match error.key_and_reason() {
            Some((key, reason)) => {
                super::field_error(&self.source, format!("damping.{key}"), reason)
            }
            None => super::field_error(&self.source, "damping", error.to_string()),
        }
    }
}
