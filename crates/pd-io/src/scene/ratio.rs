//! Damping by ratio: a `[damping]` table with `ratio` (and `mode`) or
//! `ratios` and `modes` instead of `stiffness` is turned into coefficients
//! from the model's elastic modes at rest ([`pd_modes`],
//! [`pd_damping::ratio`]) when the scene is built.

use pd_damping::ratio::{AchievedRatio, FittedCoefficients, ModalData, RatioTarget, SeriesData};
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
        let (spec, fitted, _) = self.resolve_spec_with_ratios(spec, model, field)?;
        Ok((spec, fitted))
    }

    /// [`Scene::resolve_spec`], with the ratios a Caughey series fit
    /// achieves at its modes (empty for one or two ratios).
    pub(super) fn resolve_spec_with_ratios(
        &self,
        spec: &pd_damping::registry::DampingSpec,
        model: &Model,
        field: &str,
    ) -> Result<(
        pd_damping::registry::DampingSpec,
        Option<FittedCoefficients>,
        Vec<AchievedRatio>,
    )> {
        let error =
            |e: &pd_damping::DampingError| super::per_body::damping_error(&self.source, field, e);
        let target = spec.ratio_target().map_err(|e| error(&e))?;
        let (Some(target), Some(quotient)) = (target, spec.model().ratio) else {
            return Ok((spec.clone(), None, Vec::new()));
        };
        let analysis_error = |e: pd_solver::SolverError| {
            super::field_error(
                &self.source,
                field,
                format!("the modal analysis for the damping ratio failed: {e}"),
            )
        };
        let analysis = match target.band() {
            None => {
                pd_modes::elastic_modes(model, target.highest_mode()).map_err(analysis_error)?
            }
            Some([_, f_hi]) => band_modes(model, f_hi).map_err(analysis_error)?,
        };
        let data: Vec<ModalData> = analysis
            .modes
            .iter()
            .map(|m| ModalData {
                omega: m.omega,
                laplacian_quotient: m.laplacian_quotient,
            })
            .collect();
        if !target.is_series() {
            let coefficients = target.fit(quotient, &data).map_err(|e| error(&e))?;
            let resolved = spec.resolved(coefficients).map_err(|e| error(&e))?;
            return Ok((resolved, Some(coefficients), Vec::new()));
        }
        let operator = pd_modes::SeriesOperator::new(model);
        let terms = match &target {
            RatioTarget::Series { modes, .. } => modes.len(),
            _ => pd_damping::ratio::BAND_TERMS,
        };
        let series = SeriesData {
            quotients: analysis
                .modes
                .iter()
                .map(|m| operator.quotients(&m.shape, terms))
                .collect(),
            spectrum_bound: operator.spectrum_bound(),
        };
        let fit = target.fit_series(&data, &series).map_err(|e| error(&e))?;
        let resolved = spec.resolved(fit.coefficients).map_err(|e| error(&e))?;
        Ok((resolved, Some(fit.coefficients), fit.achieved))
    }
}

/// The elastic modes of `model` up to `f_hi` Hz and one above it (or all
/// of them): the analysis asks for 12 modes, then twice as many until the
/// highest one found lies above the band or the model has no more.
fn band_modes(
    model: &Model,
    f_hi: f64,
) -> std::result::Result<pd_modes::ModalAnalysis, pd_solver::SolverError> {
    let mut count = 12;
    loop {
        let analysis = pd_modes::elastic_modes(model, count)?;
        let above = analysis
            .modes
            .last()
            .is_none_or(|m| m.frequency_hz() > f_hi);
        if above || analysis.modes.len() < count {
            return Ok(analysis);
        }
        count *= 2;
    }
}
