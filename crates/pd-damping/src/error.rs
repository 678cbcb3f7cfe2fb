//! The error of this crate: a damping model built with an invalid parameter.

use std::fmt;

/// Why a damping model could not be built.
#[derive(Debug, Clone, Copy, PartialEq)]
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
