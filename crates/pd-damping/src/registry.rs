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
//! implementation and its `NAME`; add one [`Model`] entry to `MODELS` in
//! `registry/models.rs` (parameters and a `build` function that calls the
//! constructor), and a preset to `PRESETS` there if it should appear in the
//! comparisons. Adding a parameter to a model is one more [`Parameter`] in
//! its entry and one more argument read in its `build`. Scene files then accept the new key
//! (`docs/ARCHITECTURE.md`, "Adding a damping model").
//!
//! ```
//! use pd_damping::registry::{self, DampingSpec, Value};
//!
//! // A preset of the comparisons (`pd compare --damping NAME`), and its model.
//! let preset = registry::presets()
//!     .iter()
//!     .find(|p| p.description.contains("preserve_rotation"))
//!     .expect("a preset");
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

mod models;
mod spec;

pub use spec::DampingSpec;

use models::{MODELS, PRESETS};

use crate::{Damping, DampingError, none};

/// A parameter's value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// A number, in the parameter's unit.
    Number(f64),
    /// A flag.
    Flag(bool),
    /// A list of numbers (`ratios = [0.02, 0.05]`), each in the
    /// parameter's unit.
    List(Numbers),
}

/// A short list of numbers (up to [`Numbers::CAPACITY`]), the value of a
/// list parameter (`ratios`, `modes`, `band`, `series`); `Copy` like the
/// other values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Numbers {
    len: usize,
    values: [f64; Numbers::CAPACITY],
}

impl Numbers {
    /// The most numbers a list parameter holds.
    pub const CAPACITY: usize = crate::MAX_SERIES_TERMS;

    /// The list `values`, or `None` when it has more than
    /// [`Numbers::CAPACITY`] entries.
    pub fn new(values: &[f64]) -> Option<Self> {
        if values.len() > Self::CAPACITY {
            return None;
        }
        let mut stored = [0.0; Self::CAPACITY];
        stored[..values.len()].copy_from_slice(values);
        Some(Self {
            len: values.len(),
            values: stored,
        })
    }

    /// The numbers.
    pub fn as_slice(&self) -> &[f64] {
        &self.values[..self.len]
    }
}

impl Value {
    /// The kind of value this is.
    pub fn kind(self) -> Kind {
        match self {
            Self::Number(_) => Kind::Number,
            Self::Flag(_) => Kind::Flag,
            Self::List(_) => Kind::List,
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
    /// A list of `f64`s (at most [`Numbers::CAPACITY`]).
    List,
}

impl Kind {
    /// How messages spell what this kind takes.
    pub fn expected(self) -> &'static str {
        match self {
            Self::Number => "a number",
            Self::Flag => "true or false",
            Self::List => "a list of numbers",
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
    /// The matrix `stiffness` multiplies, for models that take a damping
    /// `ratio` instead ([`crate::ratio`]); `None` for the others.
    pub ratio: Option<crate::ratio::Quotient>,
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
            _ => None,
        }
    }

    fn flag(&self, name: &str) -> Option<bool> {
        match self.get(name)? {
            Value::Flag(b) => Some(b),
            _ => None,
        }
    }

    fn list(&self, name: &str) -> Option<Numbers> {
        match self.get(name)? {
            Value::List(p) => Some(p),
            _ => None,
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

/// Parameters added after the scene format's first version (damping by
/// ratio, then the Caughey series). [`parameter_names`] lists them last, so that the positional form
/// of a `[damping]` table (serde's JSON array) written before them still
/// reads, and messages list the original keys first as before.
pub const ADDED_PARAMETERS: &[&str] = &["ratio", "mode", "ratios", "modes", "band", "series"];

/// Every parameter name of every model, each once, in registry order (the
/// keys a scene's `[damping]` table may hold besides `model`), the
/// [`ADDED_PARAMETERS`] last.
pub fn parameter_names() -> &'static [&'static str] {
    static NAMES: LazyLock<Vec<&'static str>> = LazyLock::new(|| {
        let mut names = Vec::new();
        for parameter in MODELS.iter().flat_map(|m| m.parameters) {
            if !names.contains(&parameter.name) {
                names.push(parameter.name);
            }
        }
        // Added parameters last, in their own order.
        names.retain(|n| !ADDED_PARAMETERS.contains(n));
        names.extend(ADDED_PARAMETERS);
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
