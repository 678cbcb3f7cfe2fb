//! Damping by ratio: a `[damping]` table with `ratio` (and `mode`) or
//! `ratios` and `modes` instead of `stiffness` is turned into coefficients
//! from the model's elastic modes at rest ([`pd_modes`],
//! [`pd_damping::ratio`]) when the scene is built.

use pd_damping::ratio::{FittedCoefficients, ModalData};
use pd_solver::Model;

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
        self.resolve_spec(&self.damping, model, "damping")
    }

    /// [`Scene::resolve_damping`] for any `spec` against `model`, errors
    /// at `field.KEY` (`damping`, or `body[i].damping` for a body's own).
    pub(super) fn resolve_spec(
        &self,
        spec: &pd_damping::registry::DampingSpec,
        model: &Model,
        field: &str,
    ) -> Result<(
        pd_damping::registry::DampingSpec,
        Option<FittedCoefficients>,
    )> {
        let error =
            |e: &pd_damping::DampingError| super::per_body::damping_error(&self.source, field, e);
        let target = spec.ratio_target().map_err(|e| error(&e))?;
        let (Some(target), Some(quotient)) = (target, spec.model().ratio) else {
            return Ok((spec.clone(), None));
        };
        let analysis = pd_modes::elastic_modes(model, target.highest_mode()).map_err(|e| {
            super::field_error(
                &self.source,
                field,
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
        let coefficients = target.fit(quotient, &data).map_err(|e| error(&e))?;
        let resolved = spec.resolved(coefficients).map_err(|e| error(&e))?;
        Ok((resolved, Some(coefficients)))
    }
}
