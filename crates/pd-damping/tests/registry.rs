//! The registry of damping models: names and presets are unique and build,
//! parameter maps are checked key by key (each error naming the key), and
//! values by the models' constructors.

use pd_damping::DampingError;
use pd_damping::registry::{
    DampingSpec, Preset, Requirement, Value, models, parameter_kind, preset, presets,
};

#[test]
fn names_are_unique_and_presets_build() {
    for (i, model) in models().iter().enumerate() {
        assert!(models()[..i].iter().all(|m| m.name != model.name));
        if let Some(strength) = model.strength {
            assert!(model.parameter(strength).is_some(), "{}", model.name);
        }
    }
    for (i, preset) in presets().iter().enumerate() {
        assert!(presets()[..i].iter().all(|p| p.name != preset.name));
        let spec = preset.spec().unwrap();
        assert_eq!(spec.create().unwrap().name(), preset.model);
    }
    // Every model has a main preset, so `pd compare` can run each.
    for model in models() {
        assert!(preset(model.name).is_some_and(Preset::is_main));
    }
}

#[test]
fn a_parameter_name_has_one_kind_in_every_model() {
    for parameter in models().iter().flat_map(|m| m.parameters) {
        assert_eq!(parameter_kind(parameter.name), Some(parameter.kind));
        if let Requirement::Default(value) = parameter.requirement {
            assert_eq!(value.kind(), parameter.kind, "{}", parameter.name);
        }
    }
}

#[test]
fn shape_errors_name_the_key() {
    let number = Value::Number(0.1);
    let err = DampingSpec::new("viscous", []).unwrap_err();
    assert_eq!(
        err,
        DampingError::UnknownModel {
            name: "viscous".into()
        }
    );
    let (key, reason) = err.key_and_reason().unwrap();
    assert_eq!(key, "model");
    assert!(reason.contains("viscous") && reason.contains("laplacian"));

    // The first unknown key in registry order, whatever the given order.
    let err = DampingSpec::new("pbd", [("stiffness", number), ("rate", number)]);
    assert_eq!(
        err.unwrap_err().key_and_reason().unwrap(),
        ("rate", format!("is not a parameter of model \"{}\"", "pbd"))
    );
    let err = DampingSpec::new("pbd", [("factor", number), ("zz", number)]);
    assert_eq!(err.unwrap_err().key_and_reason().unwrap().0, "zz");

    let err = DampingSpec::new("laplacian", [("mass", number)]).unwrap_err();
    assert_eq!(
        err,
        DampingError::MissingParameter {
            model: "laplacian",
            parameter: "stiffness"
        }
    );
    let err = DampingSpec::new("laplacian", [("stiffness", Value::Flag(true))]);
    assert!(matches!(
        err,
        Err(DampingError::WrongType {
            parameter: "stiffness",
            ..
        })
    ));
    let err = DampingSpec::new("pbd", [("factor", number), ("factor", number)]);
    assert!(matches!(
        err,
        Err(DampingError::Conflict {
            parameter: "factor",
            ..
        })
    ));
}

#[test]
fn ether_drag_takes_a_factor_or_a_rate() {
    let factor = ("factor", Value::Number(0.1));
    let rate = ("rate", Value::Number(1.0));
    let implicit = ("implicit", Value::Flag(true));
    let conflict = |arguments: &[(&str, Value)]| match DampingSpec::new(
        "ether-drag",
        arguments.iter().copied(),
    ) {
        Err(DampingError::Conflict { parameter, .. }) => parameter,
        other => panic!("{other:?}"),
    };
    assert_eq!(conflict(&[]), "factor");
    assert_eq!(conflict(&[factor, rate]), "factor");
    assert_eq!(conflict(&[implicit]), "factor");
    assert_eq!(conflict(&[factor, implicit]), "implicit");
    let matrix = |arguments: &[(&str, Value)]| {
        let spec = DampingSpec::new("ether-drag", arguments.iter().copied()).unwrap();
        spec.create().unwrap().implicit_matrix().mass
    };
    assert_eq!(matrix(&[rate, implicit]), 1.0);
    assert_eq!(matrix(&[rate]), 0.0);
    assert_eq!(matrix(&[factor, ("implicit", Value::Flag(false))]), 0.0);
}

#[test]
fn domain_errors_come_from_the_constructor() {
    let err = DampingSpec::new("pbd", [("factor", Value::Number(2.0))]).unwrap_err();
    assert!(matches!(
        err,
        DampingError::InvalidParameter {
            parameter: "factor",
            ..
        }
    ));
    assert_eq!(err.key_and_reason(), None);
}

#[test]
fn defaults_fill_in_and_equal_specs_compare_equal() {
    let given = DampingSpec::new(
        "laplacian",
        [
            ("stiffness", Value::Number(0.003)),
            ("mass", Value::Number(0.0)),
        ],
    )
    .unwrap();
    assert_eq!(given, preset("laplacian").unwrap().spec().unwrap());
    assert_eq!(DampingSpec::new("none", []).unwrap(), DampingSpec::None);
    let stronger = given.with("stiffness", Value::Number(1.0)).unwrap();
    assert_eq!(stronger.number("stiffness"), Some(1.0));
    assert_eq!(stronger.flag("preserve_rotation"), Some(false));
}
