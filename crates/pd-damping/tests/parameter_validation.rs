//! Every constructor rejects NaN, infinite and out-of-range parameters and
//! names the parameter and the value in its error.

use pd_damping::{DampingError, EtherDrag, LaplacianDamping, PbdDamping, RayleighLagged};

/// Asserts that `result` is an invalid-parameter error for `parameter` with
/// `value`, and that its message names both.
fn assert_rejects<T: std::fmt::Debug>(
    result: Result<T, DampingError>,
    parameter: &str,
    value: f64,
) {
    let error = result.expect_err("accepted an invalid parameter");
    match error {
        DampingError::InvalidParameter {
            parameter: named,
            value: reported,
            ..
        } => {
            assert_eq!(named, parameter);
            assert!(
                reported.to_bits() == value.to_bits(),
                "reported {reported}, expected {value}"
            );
        }
        _ => panic!("unexpected error {error:?}"),
    }
    let message = error.to_string();
    assert!(message.contains(parameter), "{message}");
    assert!(message.contains(&value.to_string()), "{message}");
}

const NOT_FINITE: [f64; 3] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];

#[test]
fn factors_must_lie_in_the_unit_interval() {
    for value in NOT_FINITE
        .into_iter()
        .chain([-0.1, -1e-300, 1.0 + f64::EPSILON, 2.0])
    {
        assert_rejects(EtherDrag::factor(value), "factor", value);
        assert_rejects(PbdDamping::new(value), "factor", value);
    }
    for value in [0.0, 1e-300, 0.5, 1.0] {
        assert!(EtherDrag::factor(value).is_ok());
        assert!(PbdDamping::new(value).is_ok());
    }
}

#[test]
fn rates_must_be_finite_and_non_negative() {
    for value in NOT_FINITE.into_iter().chain([-1e-300, -1.0]) {
        assert_rejects(EtherDrag::rate(value), "rate", value);
        assert_rejects(EtherDrag::implicit(value), "rate", value);
    }
    for value in [0.0, 1e-300, 1.0, 1e300] {
        assert!(EtherDrag::rate(value).is_ok());
        assert!(EtherDrag::implicit(value).is_ok());
    }
}

#[test]
fn laplacian_coefficients_must_be_finite_and_non_negative() {
    for value in NOT_FINITE.into_iter().chain([-1e-300, -1.0]) {
        assert_rejects(LaplacianDamping::new(value, 0.0, false), "stiffness", value);
        assert_rejects(LaplacianDamping::new(0.0, value, true), "mass", value);
    }
    assert!(LaplacianDamping::new(0.0, 0.0, false).is_ok());
    assert!(LaplacianDamping::new(1e-2, 0.5, true).is_ok());
}

#[test]
fn rayleigh_coefficients_must_be_finite_and_non_negative() {
    for value in NOT_FINITE.into_iter().chain([-1e-300, -1.0]) {
        assert_rejects(RayleighLagged::new(0.0, value), "mass", value);
        assert_rejects(RayleighLagged::new(value, 0.0), "stiffness", value);
    }
    assert!(RayleighLagged::new(0.0, 0.0).is_ok());
    assert!(RayleighLagged::new(1e-2, 0.5).is_ok());
}

#[test]
fn the_error_is_a_std_error() {
    let error: Box<dyn std::error::Error> = Box::new(PbdDamping::new(1.5).unwrap_err());
    assert_eq!(
        error.to_string(),
        "invalid damping parameter `factor` = 1.5: must be a finite number in [0, 1]"
    );
}
