//! Scene files: TOML or JSON with the same structure (reference in
//! `docs/reference/scene-format.md`). Parsing rejects unknown keys; validation checks
//! every value and reports it by its field path (`body[0].density`); building
//! turns a valid scene into a ready [`Simulation`](pd_solver::Simulation).
//!
//! One file per stage:
//! - `raw`: the serde image of the file and the TOML / JSON parsers (syntax
//!   errors and unknown keys, with their line);
//! - `validate`: raw to typed, every value checked, errors by field path;
//! - `spec`: the typed scene ([`Scene`], [`BodySpec`], [`MeshSource`], ...);
//! - `build`: [`Scene::build`], the scene to a model and a simulation (the
//!   checks that need the meshes).
//!
//! Damping models and their parameters are not listed here: the `[damping]`
//! table takes the keys of [`pd_damping::registry`], and [`DampingSpec`] is
//! the registry's.

mod build;
mod contact;
mod material;
mod per_body;
mod ratio;
mod raw;
mod solver;
mod solver_fitted;
mod spec;
mod validate;

use std::path::Path;

pub use pd_damping::registry::DampingSpec;
pub use spec::{
    BodySpec, ConstraintSpec, FrameFormat, IntegratorKind, MassSpec, MeshSource, OutputSpec, Scene,
};
pub use validate::{ACCURACY_ITERATIONS, DEFAULT_ACCURACY, check_accuracy};

use crate::{Error, Result};

/// Scene file syntax, chosen by extension (`.json` is JSON, anything else TOML).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Syntax {
    /// TOML.
    Toml,
    /// JSON.
    Json,
}

impl Syntax {
    /// The syntax a file name implies.
    pub fn of(path: &Path) -> Self {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("json") => Syntax::Json,
            _ => Syntax::Toml,
        }
    }
}

impl Scene {
    /// Reads and validates a scene file.
    ///
    /// # Errors
    /// The file cannot be read, is malformed (file, line and field path), has
    /// unknown keys, or holds an invalid value (field path).
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse(&text, Syntax::of(path), path)
    }

    /// Parses and validates scene text; `source` names it in messages and
    /// anchors relative paths.
    ///
    /// # Errors
    /// As [`Scene::load`].
    pub fn parse(text: &str, syntax: Syntax, source: &Path) -> Result<Self> {
        let raw = match syntax {
            Syntax::Toml => raw::parse_toml(text, source)?,
            Syntax::Json => raw::parse_json(text, source)?,
        };
        validate::Validator { source }.scene(raw)
    }
}

/// An invalid value of the scene file `source` at `field`.
fn field_error(source: &Path, field: impl Into<String>, message: impl std::fmt::Display) -> Error {
    Error::Field {
        path: source.to_path_buf(),
        field: field.into(),
        message: message.to_string(),
    }
}
