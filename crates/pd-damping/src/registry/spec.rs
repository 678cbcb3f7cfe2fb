//! [`DampingSpec`]: a model of the registry with validated parameters.

use super::models::NONE;
use super::{Arguments, Model, Numbers, Requirement, Value, model, parameter_names};
use crate::ratio::{self, FittedCoefficients, RatioTarget};
use crate::{Damping, DampingError, none};

/// A damping model and its validated parameters: what a scene's `[damping]`
/// table means. [`DampingSpec::create`] builds the model.
///
/// It holds every parameter of the model that was given or has a default,
/// in the model's parameter order, so two specs of the same model with the
/// same effective parameters compare equal.
#[derive(Debug, Clone, PartialEq)]
pub struct DampingSpec {
    model: &'static str,
    arguments: Vec<(&'static str, Value)>,
}

impl Default for DampingSpec {
    fn default() -> Self {
        Self::None
    }
}

impl DampingSpec {
    /// No damping: what a scene without a `[damping]` table means.
    #[allow(non_upper_case_globals)]
    pub const None: Self = Self {
        model: none::NAME,
        arguments: Vec::new(),
    };

    /// The model `model` with the parameters `arguments` (the rest take
    /// their defaults), validated: the model's constructor accepts them.
    ///
    /// # Errors
    /// [`DampingError::UnknownModel`]; [`DampingError::UnknownParameter`]
    /// for a key the model does not take (the first in
    /// [`parameter_names`] order); [`DampingError::WrongType`];
    /// [`DampingError::Conflict`] for a key given twice or a combination the
    /// model refuses; [`DampingError::MissingParameter`] for the first
    /// required one left out; [`DampingError::InvalidParameter`] from the
    /// constructor.
    pub fn new<'k>(
        model: &str,
        arguments: impl IntoIterator<Item = (&'k str, Value)>,
    ) -> Result<Self, DampingError> {
        let entry = self::model(model).ok_or_else(|| DampingError::UnknownModel {
            name: model.to_string(),
        })?;
        let given: Vec<(&str, Value)> = arguments.into_iter().collect();
        check_names(entry, &given)?;
        let mut values = Vec::with_capacity(entry.parameters.len());
        for parameter in entry.parameters {
            let mut matching = given.iter().filter(|(name, _)| *name == parameter.name);
            let value = match (matching.next(), parameter.requirement) {
                (Some(&(_, value)), _) => Some(value),
                (None, Requirement::Default(value)) => Some(value),
                (None, Requirement::Optional) => None,
                (None, Requirement::Required) => {
                    return Err(DampingError::MissingParameter {
                        model: entry.name,
                        parameter: parameter.name,
                    });
                }
            };
            if matching.next().is_some() {
                return Err(DampingError::Conflict {
                    parameter: parameter.name,
                    reason: "is given more than once".into(),
                });
            }
            if let Some(value) = value {
                if value.kind() != parameter.kind {
                    return Err(DampingError::WrongType {
                        model: entry.name,
                        parameter: parameter.name,
                        expected: parameter.kind.expected(),
                    });
                }
                values.push((parameter.name, value));
            }
        }
        let spec = Self {
            model: entry.name,
            arguments: values,
        };
        // A spec with a ratio is checked here and built once its
        // coefficients are known ([`DampingSpec::resolved`]).
        if spec.ratio_target()?.is_none() {
            spec.create()?;
        }
        Ok(spec)
    }

    /// The damping ratio(s) this spec asks for instead of `stiffness`, for
    /// a model that takes them; `None` when the coefficients are given.
    ///
    /// # Errors
    /// As [`crate::ratio`]'s checks: conflicting or invalid ratio keys.
    pub fn ratio_target(&self) -> Result<Option<RatioTarget>, DampingError> {
        if self.model().ratio.is_none() {
            return Ok(None);
        }
        let view = self.view();
        let target = ratio::target(|n| view.number(n), |n| view.list(n))?;
        if target.as_ref().is_some_and(RatioTarget::is_series)
            && self.model().ratio != Some(ratio::Quotient::Laplacian)
        {
            let parameter = if view.list("band").is_some() {
                "band"
            } else {
                "ratios"
            };
            return Err(DampingError::Conflict {
                parameter,
                reason: format!(
                    "a Caughey series (three or more ratios, or a band) is available for the \
                     laplacian model only, not {}",
                    self.model
                ),
            });
        }
        Ok(target)
    }

    /// The same model with the fitted coefficients as `stiffness`, `mass`
    /// (and `series` for a Caughey series) in place of the ratio keys,
    /// validated and buildable.
    ///
    /// # Errors
    /// As [`DampingSpec::new`] (a coefficient out of its domain).
    pub fn resolved(&self, coefficients: FittedCoefficients) -> Result<Self, DampingError> {
        const RATIO_KEYS: [&str; 8] = [
            "ratio",
            "mode",
            "ratios",
            "modes",
            "band",
            "series",
            "stiffness",
            "mass",
        ];
        let kept = self
            .arguments
            .iter()
            .filter(|(n, _)| !RATIO_KEYS.contains(n))
            .copied();
        let higher = coefficients.higher_terms();
        let series = (!higher.is_empty())
            .then(|| Numbers::new(higher).map(|list| ("series", Value::List(list))))
            .flatten();
        Self::new(
            self.model,
            kept.chain([
                ("stiffness", Value::Number(coefficients.stiffness)),
                ("mass", Value::Number(coefficients.mass)),
            ])
            .chain(series),
        )
    }

    /// The model's name.
    pub fn name(&self) -> &'static str {
        self.model
    }

    /// The model's registry entry.
    pub fn model(&self) -> &'static Model {
        // Only `new` and `None` make specs, both from a registry name.
        model(self.model).unwrap_or(&NONE)
    }

    /// The parameters given or defaulted, in the model's order.
    pub fn arguments(&self) -> &[(&'static str, Value)] {
        &self.arguments
    }

    /// The number parameter `name`, if the spec has it.
    pub fn number(&self, name: &str) -> Option<f64> {
        self.view().number(name)
    }

    /// The flag parameter `name`, if the spec has it.
    pub fn flag(&self, name: &str) -> Option<bool> {
        self.view().flag(name)
    }

    /// The same model with parameter `name` set to `value`, validated again.
    ///
    /// # Errors
    /// As [`DampingSpec::new`].
    pub fn with(&self, name: &str, value: Value) -> Result<Self, DampingError> {
        let others = self.arguments.iter().filter(|(n, _)| *n != name).copied();
        Self::new(self.model, others.chain([(name, value)]))
    }

    /// Builds the model.
    ///
    /// # Errors
    /// A parameter outside its domain, named ([`DampingError::InvalidParameter`]).
    pub fn create(&self) -> Result<Box<dyn Damping>, DampingError> {
        (self.model().build)(&self.view())
    }

    fn view(&self) -> Arguments<'_> {
        Arguments {
            model: self.model,
            values: &self.arguments,
        }
    }
}

/// Rejects a key `model` does not take: the first in [`parameter_names`]
/// order, then any key no model takes, in the order given.
fn check_names(model: &Model, given: &[(&str, Value)]) -> Result<(), DampingError> {
    let is_given = |name: &str| given.iter().any(|(n, _)| *n == name);
    let known = parameter_names().iter().copied().filter(|n| is_given(n));
    let unknown_to_all = given
        .iter()
        .map(|(n, _)| *n)
        .filter(|n| !parameter_names().contains(n));
    match known
        .chain(unknown_to_all)
        .find(|n| model.parameter(n).is_none())
    {
        Some(name) => Err(DampingError::UnknownParameter {
            model: model.name,
            parameter: name.to_string(),
        }),
        None => Ok(()),
    }
}
