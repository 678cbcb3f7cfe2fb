//! The entries of the registry: one [`Model`] per damping model (its
//! parameters and the `build` function that calls its constructor), and the
//! presets. Adding a model is one entry in `MODELS` here (and a preset in
//! `PRESETS` if the comparisons should run it).

use super::{Arguments, Kind, Model, Numbers, Parameter, Preset, Requirement, Value};
use crate::ratio::Quotient;
use crate::{
    Damping, DampingError, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged,
    ether_drag, laplacian, none, pbd, rayleigh_lagged,
};

pub(super) const NONE: Model = Model {
    name: none::NAME,
    summary: "no damping (backward Euler's own numerical damping remains)",
    parameters: &[],
    strength: None,
    ratio: None,
    build: |_| Ok(Box::new(NoDamping)),
};

const ETHER_DRAG: Model = Model {
    name: ether_drag::NAME,
    summary: "every velocity decays towards zero, as in a viscous medium at rest \
              (rigid motion too)",
    parameters: &[
        number(
            "factor",
            "1",
            Requirement::Optional,
            Some(1.0),
            "in [0, 1]: v <- (1 - k) v after each step (give factor or rate)",
        ),
        number(
            "rate",
            "1/s",
            Requirement::Optional,
            None,
            ">= 0: v <- exp(-c h) v after each step, or D = c M inside the solve \
                  with implicit",
        ),
        flag(
            "implicit",
            "only with rate: damp inside the solve (D = c M)",
        ),
    ],
    strength: Some("rate"),
    ratio: None,
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
    parameters: &[number(
        "factor",
        "1",
        Requirement::Required,
        Some(1.0),
        "in [0, 1]: the fraction of the non-rigid velocity removed per step",
    )],
    strength: Some("factor"),
    ratio: None,
    build: |arguments| Ok(Box::new(PbdDamping::new(arguments.required("factor")?)?)),
};

/// A number parameter: name, SI unit, requirement, largest value, doc.
const fn number(
    name: &'static str,
    unit: &'static str,
    requirement: Requirement,
    maximum: Option<f64>,
    doc: &'static str,
) -> Parameter {
    Parameter {
        name,
        unit,
        kind: Kind::Number,
        requirement,
        maximum,
        doc,
    }
}

/// A flag parameter, `false` unless given.
const fn flag(name: &'static str, doc: &'static str) -> Parameter {
    Parameter {
        name,
        unit: "",
        kind: Kind::Flag,
        requirement: Requirement::Default(Value::Flag(false)),
        maximum: None,
        doc,
    }
}

/// `mass` (a1) as lagged Rayleigh and Laplacian damping both declare it.
const MASS: Parameter = number(
    "mass",
    "1/s",
    Requirement::Default(Value::Number(0.0)),
    None,
    ">= 0: a1, the a1 M part of D",
);

/// `ratio`: the damping ratio of one elastic mode instead of `stiffness`.
const RATIO: Parameter = number(
    "ratio",
    "1",
    Requirement::Optional,
    None,
    ">= 0: damping ratio (1 = critical) of elastic mode `mode`; a2 is solved from the \
     scene's modes instead of given as stiffness",
);

/// `mode`: which elastic mode `ratio` is for.
const MODE: Parameter = number(
    "mode",
    "1",
    Requirement::Optional,
    None,
    "whole number >= 1: the elastic mode `ratio` is for (1 = lowest, the default)",
);

/// `ratios`: damping ratios of two modes, fitting a1 and a2 (or of three
/// or more, fitting a Caughey series).
const RATIOS: Parameter = Parameter {
    name: "ratios",
    unit: "1",
    kind: Kind::List,
    requirement: Requirement::Optional,
    maximum: None,
    doc: "[zeta_1, zeta_2, ...] >= 0: damping ratios of the `modes`; two fit a1 and a2, \
          three or more (laplacian) a Caughey series a1 M + a2 L_d + a3 L_d M^-1 L_d + ...",
};

/// `modes`: the modes `ratios` are for.
const MODES: Parameter = Parameter {
    name: "modes",
    unit: "1",
    kind: Kind::List,
    requirement: Requirement::Optional,
    maximum: None,
    doc: "[i, j, ...], whole numbers >= 1: the elastic modes `ratios` are for",
};

/// `band`: a frequency band over which `ratio` is fitted by a series.
const BAND: Parameter = Parameter {
    name: "band",
    unit: "Hz",
    kind: Kind::List,
    requirement: Requirement::Optional,
    maximum: None,
    doc: "[f_lo, f_hi] in Hz, with ratio: a three-term Caughey series as flat at `ratio` as \
          it can be over the elastic modes in the band (least squares)",
};

/// `series`: the Caughey series' terms beyond a2.
const SERIES: Parameter = Parameter {
    name: "series",
    unit: "s^3, s^5, ...",
    kind: Kind::List,
    requirement: Requirement::Optional,
    maximum: None,
    doc: "[a3, a4, ...]: Caughey series terms a3 L_d M^-1 L_d + a4 L_d (M^-1 L_d)^2 + ... \
          (usually fitted from ratios or band)",
};

/// The `stiffness` of a spec that gives it; a spec with a ratio must be
/// resolved against the scene's modes first ([`super::DampingSpec::resolved`]).
fn stiffness(arguments: &Arguments<'_>) -> Result<f64, DampingError> {
    match crate::ratio::target(|n| arguments.number(n), |n| arguments.list(n))? {
        None => arguments.required("stiffness"),
        Some(_) => Err(DampingError::Conflict {
            parameter: "ratio",
            reason: "is turned into a stiffness from the scene's elastic modes \
                     (pd_modes), which were not computed for this spec"
                .into(),
        }),
    }
}

const RAYLEIGH_LAGGED: Model = Model {
    name: rayleigh_lagged::NAME,
    summary: "lagged Rayleigh damping D = a1 M + a2 K(x_n), the elastic Hessian at the start \
              of each step (refactored every step)",
    parameters: &[
        MASS,
        number(
            "stiffness",
            "s",
            Requirement::Optional,
            None,
            ">= 0: a2, times the elastic Hessian K(x_n) (or give ratio)",
        ),
        RATIO,
        MODE,
        RATIOS,
        MODES,
    ],
    strength: Some("stiffness"),
    ratio: Some(Quotient::Stiffness),
    build: |arguments| {
        Ok(Box::new(RayleighLagged::new(
            stiffness(arguments)?,
            arguments.required("mass")?,
        )?))
    },
};

const LAPLACIAN: Model = Model {
    name: laplacian::NAME,
    summary: "the paper's Laplacian damping D = a2 L_d + a1 M (+ a Caughey series \
              a3 L_d M^-1 L_d + ...), constant, factored once",
    parameters: &[
        number(
            "stiffness",
            "s",
            Requirement::Optional,
            None,
            ">= 0: a2, times the damping Laplacian L_d (or give ratio)",
        ),
        MASS,
        flag(
            "preserve_rotation",
            "give back, per free body, the angular momentum the damping removed",
        ),
        RATIO,
        MODE,
        RATIOS,
        MODES,
        BAND,
        SERIES,
    ],
    strength: Some("stiffness"),
    ratio: Some(Quotient::Laplacian),
    build: |arguments| {
        let series = arguments.list("series");
        Ok(Box::new(LaplacianDamping::with_series(
            stiffness(arguments)?,
            arguments.required("mass")?,
            arguments.flag("preserve_rotation").unwrap_or(false),
            series.as_ref().map_or(&[], Numbers::as_slice),
        )?))
    },
};

/// Every model, in the order messages and tables list them.
pub(super) const MODELS: &[Model] = &[NONE, ETHER_DRAG, PBD, RAYLEIGH_LAGGED, LAPLACIAN];

/// The coefficients of the measured comparisons (`docs/reports/damping-table.md`,
/// `docs/design/performance.md`), in table order.
pub(super) const PRESETS: &[Preset] = &[
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
