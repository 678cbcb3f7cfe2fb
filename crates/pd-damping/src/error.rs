//! The error of this crate: a damping model built with an invalid parameter,
//! or a parameter map the [registry](crate::registry) cannot turn into one.

use std::fmt;

/// Why a damping model could not be built.
///
/// [`DampingError::InvalidParameter`] comes from the models' constructors;
/// the other variants from [`crate::registry`], which checks a parameter map
/// against a model's declared parameters before calling its constructor.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum DampingError {
    /// A parameter is NaN, infinite or outside its range.
    InvalidParameter {
        /// The parameter as the constructor names it (`factor`, `rate`,
        /// `mass`, `stiffness`).
        parameter: &'static str,
        /// The rejected value, in the parameter's own unit.
        value: f64,
        /// The range the value must lie in, e.g. `a finite number in [0, 1]`.
        requirement: &'static str,
    },
    /// No model of the registry has this name.
    UnknownModel {
        /// The name asked for.
        name: String,
    },
    /// The model does not take this parameter.
    UnknownParameter {
        /// The model's name.
        model: &'static str,
        /// The parameter given.
        parameter: String,
    },
    /// The model needs this parameter and it was not given.
    MissingParameter {
        /// The model's name.
        model: &'static str,
        /// The parameter missing.
        parameter: &'static str,
    },
    /// A parameter was given a number where the model takes a flag, or the
    /// other way round.
    WrongType {
        /// The model's name.
        model: &'static str,
        /// The parameter.
        parameter: &'static str,
        /// What it takes: `a number` or `true or false`.
        expected: &'static str,
    },
    /// Parameters that the model accepts one by one but not together (or a
    /// choice none was made of), e.g. ether drag's `factor` and `rate`.
    Conflict {
        /// The parameter the error is reported at.
        parameter: &'static str,
        /// What is wrong, a sentence.
        reason: String,
    },
}

impl DampingError {
    /// For errors about the shape of a parameter map: the key the error is
    /// about (`model` or a parameter name) and what is wrong with it, in a
    /// form a scene reports as `damping.KEY: REASON`. `None` for
    /// [`DampingError::InvalidParameter`], a value outside its domain, whose
    /// own message names the parameter and the value.
    pub fn key_and_reason(&self) -> Option<(&str, String)> {
        match self {
            Self::InvalidParameter { .. } => None,
            Self::UnknownModel { name } => Some((
                "model",
                format!(
                    "unknown damping model \"{name}\"; expected one of: {}",
                    crate::registry::model_names().join(", ")
                ),
            )),
            Self::UnknownParameter { model, parameter } => Some((
                parameter,
                format!("is not a parameter of model \"{model}\""),
            )),
            Self::MissingParameter { model, parameter } => {
                Some((parameter, format!("model \"{model}\" needs it")))
            }
            Self::WrongType {
                parameter,
                expected,
                ..
            } => Some((parameter, format!("must be {expected}"))),
            Self::Conflict { parameter, reason } => Some((parameter, reason.clone())),
        }
    }
}

impl fmt::Display for DampingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidParameter {
                parameter,
                value,
                requirement,
            } => write!(
                f,
                "invalid damping parameter `{parameter}` = {value}: must be {requirement}"
            ),
            Self::UnknownModel { .. } => {
                let (_, reason) = self.key_and_reason().unwrap_or_default();
                f.write_str(&reason)
            }
            _ => {
                let (key, reason) = self.key_and_reason().unwrap_or_default();
                write!(f, "damping parameter `{key}`: {reason}")
            }
        }
    }
}

impl std::error::Error for DampingError {}

/// Accepts a finite `value >= 0`; `!(value >= 0.0)` also rejects NaN.
pub(crate) fn non_negative(parameter: &'static str, value: f64) -> Result<f64, DampingError> {
    if !(value >= 0.0) || !value.is_finite() {
        return Err(DampingError::InvalidParameter {
            parameter,
            value,
            requirement: "a finite number >= 0",
        });
    }
    Ok(value)
}

/// Accepts `value` in `[0, 1]`; `contains` is false for NaN.
pub(crate) fn unit_interval(parameter: &'static str, value: f64) -> Result<f64, DampingError> {
    if !(0.0..=1.0).contains(&value) {
        return Err(DampingError::InvalidParameter {
            parameter,
            value,
            requirement: "a finite number in [0, 1]",
        });
    }
    Ok(value)
}
