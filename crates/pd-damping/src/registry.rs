//! The registry of damping models: the one list of every model by name, with
//! a one-line summary, its parameters (name, unit, default or required, doc),
//! the constructor from a parameter map, and named presets (the coefficient
//! sets the benches, `pd compare`, `cargo xtask damping-table` and
//! `cargo xtask stability` measure).
//!
//! Scene files, the command line, the benches and xtask all reach the models
//! through this list; none of them names a model or its parameters itself.
//! Each model's name is the `NAME` constant in the model's own file.
//!
//! Validation is split between two places: [`DampingSpec::new`] checks the
//! shape of a parameter map against the model's declared parameters (an
//! unknown model or parameter, a missing required one, a number where a flag
//! belongs), each error naming the key; the model's constructor checks each
//! value's domain, and its error names the parameter and the value.
//!
//! Adding a model: write its file with its type, its [`Damping`]
//! implementation and its `NAME`; add one [`Model`] entry to `MODELS` below
//! (parameters and a `build` function that calls the constructor), and a
//! preset to `PRESETS` if it should appear in the comparisons. Adding a
//! parameter to a model is one more [`Parameter`] in its entry and one more
//! argument read in its `build`. Scene files then accept the new key
//! (`docs/ARCHITECTURE.md`, "Adding a damping model").
//!
//! ```
//! use pd_damping::registry::{self, DampingSpec, Value};
//!
//! // The preset of `pd compare --damping laplacian-rot`, and its model.
//! let preset = registry::preset("laplacian-rot").expect("a preset");
//! assert_eq!(preset.spec()?.flag("preserve_rotation"), Some(true));
//! let model = registry::model(preset.model).expect("a model");
//! assert_eq!(model.parameter("stiffness").map(|p| p.unit), Some("s"));
//!
//! let spec = DampingSpec::new(model.name, [("stiffness", Value::Number(0.01))])?;
//! assert_eq!(spec.number("mass"), Some(0.0)); // the default
//! assert_eq!(spec.create()?.implicit_matrix().damping_laplacian, 0.01);
//!
//! let err = DampingSpec::new(model.name, [("rate", Value::Number(1.0))]).unwrap_err();
//! assert_eq!(err.key_and_reason().map(|(key, _)| key), Some("rate"));
//! assert!(err.to_string().contains("is not a parameter of model"));
//! # Ok::<(), pd_damping::DampingError>(())
//! ```

use std::sync::LazyLock;

use crate::{
    Damping, DampingError, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged,
    ether_drag, laplacian, none, pbd, rayleigh_lagged,
};

/// A parameter's value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// A number, in the parameter's unit.
    Number(f64),
    /// A flag.
    Flag(bool),
}

impl Value {
    /// The kind of value this is.
    pub fn kind(self) -> Kind {
        match self {
            Self::Number(_) => Kind::Number,
            Self::Flag(_) => Kind::Flag,
        }
    }
}

/// What a parameter takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// An `f64`.
    Number,
    /// A `bool`.
    Flag,
}

impl Kind {
    /// How messages spell what this kind takes.
    pub fn expected(self) -> &'static str {
        match self {
            Self::Number => "a number",
            Self::Flag => "true or false",
        }
    }
}

/// Whether a parameter must be given, and its value when it is not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Requirement {
    /// It must be given.
    Required,
    /// It may be left out, and then it is absent: the model decides (ether
    /// drag's `factor` and `rate`, of which exactly one is given).
    Optional,
    /// It may be left out, and then it has this value.
    Default(Value),
}

/// One parameter of a model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parameter {
    /// The key, as scenes spell it (`stiffness`).
    pub name: &'static str,
    /// The SI unit of a number (`s`, `1/s`; `1` for a dimensionless
    /// factor), empty for a flag.
    pub unit: &'static str,
    /// What it takes.
    pub kind: Kind,
    /// Required, optional, or its default.
    pub requirement: Requirement,
    /// The largest value the model accepts where that is finite (1 for a
    /// factor), for sweeps over a coefficient. The constructor enforces it.
    pub maximum: Option<f64>,
    /// What it does, one line.
    pub doc: &'static str,
}

/// One damping model of the registry.
#[derive(Debug, Clone, Copy)]
pub struct Model {
    /// The name, the model file's `NAME`.
    pub name: &'static str,
    /// What the model does, one line.
    pub summary: &'static str,
    /// Its parameters, in the order messages and documentation list them.
    pub parameters: &'static [Parameter],
    /// The parameter that sets how strongly it damps (`rate`, `factor`,
    /// `stiffness`), which sweeps over a damping coefficient vary; `None` for
    /// a model without one.
    pub strength: Option<&'static str>,
    build: fn(&Arguments<'_>) -> Result<Box<dyn Damping>, DampingError>,
}

impl Model {
    /// The parameter called `name`.
    pub fn parameter(&self, name: &str) -> Option<&'static Parameter> {
        self.parameters.iter().find(|p| p.name == name)
    }
}

/// A named coefficient set of a model, for comparisons.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Preset {
    /// The name `pd compare --damping` takes (the model's name for its
    /// main preset).
    pub name: &'static str,
    /// The model.
    pub model: &'static str,
    /// The parameters given; the rest take their defaults.
    pub arguments: &'static [(&'static str, Value)],
    /// The coefficients in words (`rate 1/s`), empty for none.
    pub description: &'static str,
}

impl Preset {
    /// The validated parameter set.
    ///
    /// # Errors
    /// None for the presets of this registry (a unit test builds each).
    pub fn spec(&self) -> Result<DampingSpec, DampingError> {
        DampingSpec::new(self.model, self.arguments.iter().copied())
    }

    /// The model's name and the coefficients in words:
    /// `laplacian, 0.003 s`, or `none`.
    pub fn label(&self) -> String {
        if self.description.is_empty() {
            self.model.to_string()
        } else {
            format!("{}, {}", self.model, self.description)
        }
    }

    /// Whether this is a model's main preset (named as the model).
    pub fn is_main(&self) -> bool {
        self.name == self.model
    }
}

/// The parameters of one model, validated and with their defaults, as its
/// `build` function reads them.
struct Arguments<'a> {
    model: &'static str,
    values: &'a [(&'static str, Value)],
}

impl Arguments<'_> {
    fn get(&self, name: &str) -> Option<Value> {
        self.values
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| *v)
    }

    fn number(&self, name: &str) -> Option<f64> {
        match self.get(name)? {
            Value::Number(x) => Some(x),
            Value::Flag(_) => None,
        }
    }

    fn flag(&self, name: &str) -> Option<bool> {
        match self.get(name)? {
            Value::Flag(b) => Some(b),
            Value::Number(_) => None,
        }
    }

    /// A required number (validation has made sure it is there).
    fn required(&self, name: &'static str) -> Result<f64, DampingError> {
        self.number(name).ok_or(DampingError::MissingParameter {
            model: self.model,
            parameter: name,
        })
    }
}

const NONE: Model = Model {
    name: none::NAME,
    summary: "no damping (backward Euler's own numerical damping remains)",
    parameters: &[],
    strength: None,
    build: |_| Ok(Box::new(NoDamping)),
};

const ETHER_DRAG: Model = Model {
    name: ether_drag::NAME,
    summary: "every velocity decays towards zero, as in a viscous medium at rest \
              (rigid motion too)",
    parameters: &[
        Parameter {
            name: "factor",
            unit: "1",
            kind: Kind::Number,
            requirement: Requirement::Optional,
            maximum: Some(1.0),
            doc: "in [0, 1]: v <- (1 - k) v after each step (give factor or rate)",
        },
        Parameter {
            name: "rate",
            unit: "1/s",
            kind: Kind::Number,
            requirement: Requirement::Optional,
            maximum: None,
            doc: ">= 0: v <- exp(-c h) v after each step, or D = c M inside the solve \
                  with implicit",
        },
        Parameter {
            name: "implicit",
            unit: "",
            kind: Kind::Flag,
            requirement: Requirement::Default(Value::Flag(false)),
            maximum: None,
            doc: "only with rate: damp inside the solve (D = c M)",
        },
    ],
    strength: Some("rate"),
    build: build_ether_drag,
};

fn build_ether_drag(arguments: &Arguments<'_>) -> Result<Box<dyn Damping>, DampingError> {
    let implicit = arguments.flag("implicit").unwrap_or(false);
    match (arguments.number("factor"), arguments.number("rate")) {
        (Some(_), None) if implicit => Err(DampingError::Conflict {
            parameter: "implicit",
            reason: "implicit ether drag takes a rate (1/s), not a per-step factor".into(),
        }),
        (Some(factor), None) => Ok(Box::new(EtherDrag::factor(factor)?)),
        (None, Some(rate)) if implicit => Ok(Box::new(EtherDrag::implicit(rate)?)),
        (None, Some(rate)) => Ok(Box::new(EtherDrag::rate(rate)?)),
        _ => Err(DampingError::Conflict {
            parameter: "factor",
            reason: format!(
                "{} needs exactly one of factor (per step) or rate (1/s)",
                ether_drag::NAME
            ),
        }),
    }
}

const PBD: Model = Model {
    name: pbd::NAME,
    summary: "position-based-dynamics damping: each component's velocities pulled towards \
              its best rigid motion (Mueller et al. 2007)",
    parameters: &[Parameter {
        name: "factor",
        unit: "1",
        kind: Kind::Number,
        requirement: Requirement::Required,
        maximum: Some(1.0),
        doc: "in [0, 1]: the fraction of the non-rigid velocity removed per step",
    }],
    strength: Some("factor"),
    build: |arguments| Ok(Box::new(PbdDamping::new(arguments.required("factor")?)?)),
};

/// `mass` (a1) as lagged Rayleigh and Laplacian damping both declare it.
const MASS: Parameter = Parameter {
    name: "mass",
    unit: "1/s",
    kind: Kind::Number,
    requirement: Requirement::Default(Value::Number(0.0)),
    maximum: None,
    doc: ">= 0: a1, the a1 M part of D",
};

const RAYLEIGH_LAGGED: Model = Model {
    name: rayleigh_lagged::NAME,
    summary: "lagged Rayleigh damping D = a1 M + a2 K(x_n), the elastic Hessian at the start \
              of each step (refactored every step)",
    parameters: &[
        MASS,
        Parameter {
            name: "stiffness",
            unit: "s",
            kind: Kind::Number,
            requirement: Requirement::Required,
            maximum: None,
            doc: ">= 0: a2, times the elastic Hessian K(x_n)",
        },
    ],
    strength: Some("stiffness"),
    build: |arguments| {
        Ok(Box::new(RayleighLagged::new(
            arguments.required("stiffness")?,
            arguments.required("mass")?,
        )?))
    },
};

const LAPLACIAN: Model = Model {
    name: laplacian::NAME,
    summary: "the paper's Laplacian damping D = a2 L_d + a1 M, constant, factored once",
    parameters: &[
        Parameter {
            name: "stiffness",
            unit: "s",
            kind: Kind::Number,
            requirement: Requirement::Required,
            maximum: None,
            doc: ">= 0: a2, times the damping Laplacian L_d",
        },
        MASS,
        Parameter {
            name: "preserve_rotation",
            unit: "",
            kind: Kind::Flag,
            requirement: Requirement::Default(Value::Flag(false)),
            maximum: None,
            doc: "give back, per free body, the angular momentum the damping removed",
        },
    ],
    strength: Some("stiffness"),
    build: |arguments| {
        Ok(Box::new(LaplacianDamping::new(
            arguments.required("stiffness")?,
            arguments.required("mass")?,
            arguments.flag("preserve_rotation").unwrap_or(false),
        )?))
    },
};

/// Every model, in the order messages and tables list them.
const MODELS: &[Model] = &[NONE, ETHER_DRAG, PBD, RAYLEIGH_LAGGED, LAPLACIAN];

/// The coefficients of the measured comparisons (`docs/damping-table.md`,
/// `docs/performance.md`), in table order.
const PRESETS: &[Preset] = &[
    Preset {
        name: none::NAME,
        model: none::NAME,
        arguments: &[],
        description: "",
    },
    Preset {
        name: ether_drag::NAME,
        model: ether_drag::NAME,
        arguments: &[("rate", Value::Number(1.0))],
        description: "rate 1/s",
    },
    Preset {
        name: "ether-drag-implicit",
        model: ether_drag::NAME,
        arguments: &[
            ("rate", Value::Number(1.0)),
            ("implicit", Value::Flag(true)),
        ],
        description: "implicit 1/s",
    },
    Preset {
        name: pbd::NAME,
        model: pbd::NAME,
        arguments: &[("factor", Value::Number(0.05))],
        description: "factor 0.05",
    },
    Preset {
        name: rayleigh_lagged::NAME,
        model: rayleigh_lagged::NAME,
        arguments: &[("stiffness", Value::Number(0.003))],
        description: "0.003 s",
    },
    Preset {
        name: laplacian::NAME,
        model: laplacian::NAME,
        arguments: &[("stiffness", Value::Number(0.003))],
        description: "0.003 s",
    },
    Preset {
        name: "laplacian-rot",
        model: laplacian::NAME,
        arguments: &[
            ("stiffness", Value::Number(0.003)),
            ("preserve_rotation", Value::Flag(true)),
        ],
        description: "0.003 s, preserve_rotation",
    },
];

/// The name of the model that does not damp: the baseline comparisons
/// measure the others against.
pub const UNDAMPED: &str = none::NAME;

/// Every model.
pub fn models() -> &'static [Model] {
    MODELS
}

/// The model called `name`.
pub fn model(name: &str) -> Option<&'static Model> {
    MODELS.iter().find(|m| m.name == name)
}

/// The names of every model, in registry order.
pub fn model_names() -> Vec<&'static str> {
    MODELS.iter().map(|m| m.name).collect()
}

/// Every parameter name of every model, each once, in registry order (the
/// keys a scene's `[damping]` table may hold besides `model`).
pub fn parameter_names() -> &'static [&'static str] {
    static NAMES: LazyLock<Vec<&'static str>> = LazyLock::new(|| {
        let mut names = Vec::new();
        for parameter in MODELS.iter().flat_map(|m| m.parameters) {
            if !names.contains(&parameter.name) {
                names.push(parameter.name);
            }
        }
        names
    });
    &NAMES
}

/// The kind of value the parameter `name` takes in every model that has it.
pub fn parameter_kind(name: &str) -> Option<Kind> {
    MODELS
        .iter()
        .flat_map(|m| m.parameters)
        .find(|p| p.name == name)
        .map(|p| p.kind)
}

/// Every preset, in table order.
pub fn presets() -> &'static [Preset] {
    PRESETS
}

/// The preset called `name`.
pub fn preset(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name == name)
}

/// The names of every preset, in table order.
pub fn preset_names() -> Vec<&'static str> {
    PRESETS.iter().map(|p| p.name).collect()
}

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
        spec.create()?;
        Ok(spec)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_presets_build() {
        for (i, model) in MODELS.iter().enumerate() {
            assert!(MODELS[..i].iter().all(|m| m.name != model.name));
            if let Some(strength) = model.strength {
                assert!(model.parameter(strength).is_some(), "{}", model.name);
            }
        }
        for (i, preset) in PRESETS.iter().enumerate() {
            assert!(PRESETS[..i].iter().all(|p| p.name != preset.name));
            let spec = preset.spec().unwrap();
            assert_eq!(spec.create().unwrap().name(), preset.model);
        }
        // Every model has a main preset, so `pd compare` can run each.
        for model in MODELS {
            assert!(preset(model.name).is_some_and(Preset::is_main));
        }
    }

    #[test]
    fn a_parameter_name_has_one_kind_in_every_model() {
        for parameter in MODELS.iter().flat_map(|m| m.parameters) {
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
        assert!(reason.contains("viscous") && reason.contains(laplacian::NAME));

        // The first unknown key in registry order, whatever the given order.
        let err = DampingSpec::new(pbd::NAME, [("stiffness", number), ("rate", number)]);
        assert_eq!(
            err.unwrap_err().key_and_reason().unwrap(),
            (
                "rate",
                format!("is not a parameter of model \"{}\"", pbd::NAME)
            )
        );
        let err = DampingSpec::new(pbd::NAME, [("factor", number), ("zz", number)]);
        assert_eq!(err.unwrap_err().key_and_reason().unwrap().0, "zz");

        let err = DampingSpec::new(laplacian::NAME, [("mass", number)]).unwrap_err();
        assert_eq!(
            err,
            DampingError::MissingParameter {
                model: laplacian::NAME,
                parameter: "stiffness"
            }
        );
        let err = DampingSpec::new(laplacian::NAME, [("stiffness", Value::Flag(true))]);
        assert!(matches!(
            err,
            Err(DampingError::WrongType {
                parameter: "stiffness",
                ..
            })
        ));
        let err = DampingSpec::new(pbd::NAME, [("factor", number), ("factor", number)]);
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
            ether_drag::NAME,
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
            let spec = DampingSpec::new(ether_drag::NAME, arguments.iter().copied()).unwrap();
            spec.create().unwrap().implicit_matrix().mass
        };
        assert_eq!(matrix(&[rate, implicit]), 1.0);
        assert_eq!(matrix(&[rate]), 0.0);
        assert_eq!(matrix(&[factor, ("implicit", Value::Flag(false))]), 0.0);
    }

    #[test]
    fn domain_errors_come_from_the_constructor() {
        let err = DampingSpec::new(pbd::NAME, [("factor", Value::Number(2.0))]).unwrap_err();
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
            laplacian::NAME,
            [
                ("stiffness", Value::Number(0.003)),
                ("mass", Value::Number(0.0)),
            ],
        )
        .unwrap();
        assert_eq!(given, preset(laplacian::NAME).unwrap().spec().unwrap());
        assert_eq!(DampingSpec::new(none::NAME, []).unwrap(), DampingSpec::None);
        let stronger = given.with("stiffness", Value::Number(1.0)).unwrap();
        assert_eq!(stronger.number("stiffness"), Some(1.0));
        assert_eq!(stronger.flag("preserve_rotation"), Some(false));
    }
}
