//! The `[solver]` table: which iteration method a step uses
//! ([`pd_solver::SolverSpec`], docs/design/solver.md "Iteration methods"). Its raw
//! serde image and its validation, by field path (`solver.rho`).

use pd_solver::{Predictor, SolverError, SolverMethod, SolverSpec, SpectralRadius};
use serde::Deserialize;

use super::validate::Validator;
use crate::Result;

/// The raw `[solver]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Solver {
    pub(super) method: Option<String>,
    pub(super) window: Option<usize>,
    pub(super) rho: Option<Rho>,
    pub(super) start: Option<usize>,
    /// Where each step's iteration starts (`pd_solver::Predictor`).
    pub(super) predictor: Option<String>,
    /// `k` of `predictor = "fitted"` (docs/reference/scene-format.md).
    pub(super) predictor_order: Option<u8>,
    /// `m` of `predictor = "fitted"`: the past steps fitted.
    pub(super) predictor_window: Option<u8>,
}

/// `rho = 0.99` or `rho = "auto"`.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(super) enum Rho {
    Number(f64),
    Text(String),
}

impl Validator<'_> {
    /// The validated `solver.predictor`; `inertial` without one.
    pub(super) fn predictor(&self, raw: Option<&Solver>) -> Result<Predictor> {
        let Some(name) = raw.and_then(|raw| raw.predictor.as_deref()) else {
            return super::solver_fitted::fitted_keys(self, raw, Predictor::default());
        };
        let predictor = Predictor::parse(name).ok_or_else(|| {
            self.field(
                "solver.predictor",
                format!(
                    "unknown predictor \"{name}\"; expected one of: {}",
                    Predictor::ALL.map(Predictor::name).join(", ")
                ),
            )
        })?;
        super::solver_fitted::fitted_keys(self, raw, predictor)
    }

    /// The validated `[solver]` table; the default (local-global) without one.
    pub(super) fn solver(&self, raw: Option<Solver>) -> Result<SolverSpec> {
        let defaults = SolverSpec::default();
        let Some(raw) = raw else {
            return Ok(defaults);
        };
        let method = match raw.method.as_deref() {
            None => defaults.method,
            Some(name) => SolverMethod::parse(name).ok_or_else(|| {
                self.field(
                    "solver.method",
                    format!(
                        "unknown method \"{name}\"; expected one of: {}",
                        SolverMethod::ALL.map(SolverMethod::name).join(", ")
                    ),
                )
            })?,
        };
        let rho = match &raw.rho {
            None => defaults.rho,
            Some(Rho::Number(rho)) => SpectralRadius::Fixed(*rho),
            Some(Rho::Text(text)) if text == "auto" => SpectralRadius::Auto,
            Some(Rho::Text(text)) => {
                return Err(self.field(
                    "solver.rho",
                    format!("must be a number in (0, 1) or \"auto\", got \"{text}\""),
                ));
            }
        };
        let spec = SolverSpec {
            method,
            window: raw.window.unwrap_or(defaults.window),
            rho,
            start: raw.start.unwrap_or(defaults.start),
        };
        match spec.validate() {
            Ok(()) => {}
            Err(SolverError::InvalidSetting { field, reason }) => {
                return Err(self.field(format!("solver.{field}"), reason));
            }
            Err(other) => return Err(self.field("solver", other.to_string())),
        }
        self.keys_apply(&raw, method)?;
        Ok(spec)
    }

    /// A method's own keys given with another method are refused rather
    /// than ignored: `rho = 0.9` without `method = "chebyshev"` would
    /// otherwise run plain PD without a word.
    fn keys_apply(&self, raw: &Solver, method: SolverMethod) -> Result<()> {
        use SolverMethod::{Anderson, Chebyshev, Lbfgs};
        let keys: [(&str, bool, &[SolverMethod]); 3] = [
            ("window", raw.window.is_some(), &[Anderson, Lbfgs]),
            ("rho", raw.rho.is_some(), &[Chebyshev]),
            ("start", raw.start.is_some(), &[Chebyshev]),
        ];
        for (key, given, methods) in keys {
            if given && !methods.contains(&method) {
                let names: Vec<String> = methods
                    .iter()
                    .map(|m| format!("\"{}\"", m.name()))
                    .collect();
                return Err(self.field(
                    format!("solver.{key}"),
                    format!(
                        "applies only with method = {} (method is \"{}\")",
                        names.join(" or "),
                        method.name()
                    ),
                ));
            }
        }
        Ok(())
    }
}
