//! The serde image of a scene file, and parsing TOML or JSON text into it.
//!
//! Every optional key is an `Option`, so that validation, not serde, decides
//! what is missing and names it. Unknown keys are rejected here, with the
//! line they are on.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::LazyLock;

use pd_damping::registry::{self, Kind, Numbers, Value};
use serde::Deserialize;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};

use crate::{Error, Result};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Scene {
    pub(super) simulation: Simulation,
    pub(super) damping: Option<Damping>,
    #[serde(rename = "body", default)]
    pub(super) bodies: Vec<Body>,
    pub(super) output: Option<Output>,
    pub(super) solver: Option<super::solver::Solver>,
    #[serde(rename = "collider", default)]
    pub(super) colliders: Vec<super::contact::RawCollider>,
    pub(super) contact: Option<super::contact::RawContact>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Simulation {
    pub(super) dt: f64,
    pub(super) steps: usize,
    pub(super) gravity: Option<[f64; 3]>,
    pub(super) integrator: Option<String>,
    pub(super) iterations: Option<usize>,
    pub(super) tolerance: Option<f64>,
    pub(super) accuracy: Option<f64>,
    pub(super) threads: Option<usize>,
    pub(super) divergence_energy_factor: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Body {
    pub(super) name: Option<String>,
    pub(super) mesh: Mesh,
    pub(super) density: Option<f64>,
    pub(super) vertex_mass: Option<f64>,
    #[serde(default)]
    pub(super) constraints: Vec<Constraint>,
    pub(super) fixed: Option<Selection>,
    pub(super) initial_state: Option<PathBuf>,
    pub(super) initial_velocity: Option<[f64; 3]>,
    pub(super) angular_velocity: Option<[f64; 3]>,
    pub(super) translate: Option<[f64; 3]>,
    pub(super) damping: Option<Damping>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Mesh {
    pub(super) generator: Option<String>,
    pub(super) file: Option<PathBuf>,
    pub(super) size: Option<Vec<f64>>,
    pub(super) cells: Option<Vec<usize>>,
    pub(super) points: Option<usize>,
    pub(super) length: Option<f64>,
    pub(super) radius: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Constraint {
    pub(super) kind: String,
    pub(super) stiffness: Option<f64>,
    /// Materials (scene/material.rs): Young's modulus, Pa.
    pub(super) young: Option<f64>,
    /// Materials: Poisson's ratio.
    pub(super) poisson: Option<f64>,
    pub(super) limits: Option<[f64; 2]>,
    pub(super) vertices: Option<Vec<usize>>,
    #[serde(rename = "box")]
    pub(super) bounds: Option<Bounds>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Selection {
    pub(super) vertices: Option<Vec<usize>>,
    #[serde(rename = "box")]
    pub(super) bounds: Option<Bounds>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Bounds {
    pub(super) min: [f64; 3],
    pub(super) max: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Output {
    pub(super) every: Option<usize>,
    pub(super) formats: Option<Vec<String>>,
    pub(super) probes: Option<Vec<usize>>,
}
/// The `[damping]` table: the model's name and the parameters given, in
/// file order. The keys it accepts are `model` and every parameter of every
/// model of the [registry](pd_damping::registry), each read as the number
/// or flag the registry declares; which of them the chosen model takes is
/// validation's business.
#[derive(Debug)]
pub(super) struct Damping {
    pub(super) model: String,
    pub(super) arguments: Vec<(&'static str, Value)>,
}

/// `model`, then the registry's parameter names: the keys of [`Damping`].
fn damping_keys() -> &'static [&'static str] {
    static KEYS: LazyLock<Vec<&'static str>> = LazyLock::new(|| {
        std::iter::once("model")
            .chain(registry::parameter_names().iter().copied())
            .collect()
    });
    &KEYS
}

// Written out rather than derived because the keys come from the registry.
// It reports what serde's derive would for a struct with these fields (an
// unknown key at the key, a duplicate, a missing `model`), so messages and
// lines are those of any other table.
impl<'de> Deserialize<'de> for Damping {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_struct("Damping", damping_keys(), DampingVisitor)
    }
}

/// A list-valued damping parameter (`ratios = [0.02, 0.05]`): at most
/// [`Numbers::CAPACITY`] numbers (how many a parameter takes is the
/// registry's check).
struct List(Numbers);

impl<'de> Deserialize<'de> for List {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let list = Vec::<f64>::deserialize(deserializer)?;
        Numbers::new(&list).map(List).ok_or_else(|| {
            let expected = format!("a list of at most {} numbers", Numbers::CAPACITY);
            de::Error::invalid_length(list.len(), &expected.as_str())
        })
    }
}

/// A key of the `[damping]` table, as its index in [`damping_keys`].
struct Key(usize);

impl<'de> Deserialize<'de> for Key {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_identifier(KeyVisitor)
    }
}

struct KeyVisitor;

impl Visitor<'_> for KeyVisitor {
    type Value = Key;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("field identifier")
    }

    fn visit_str<E: de::Error>(self, key: &str) -> Result<Key, E> {
        let keys = damping_keys();
        match keys.iter().position(|k| *k == key) {
            Some(index) => Ok(Key(index)),
            None => Err(E::unknown_field(key, keys)),
        }
    }
}

struct DampingVisitor;

impl DampingVisitor {
    /// Reads the value of parameter `name` as its registry kind; `null`
    /// (JSON) is as good as leaving the key out.
    fn value<'de, A: MapAccess<'de>>(map: &mut A, name: &str) -> Result<Option<Value>, A::Error> {
        Ok(match registry::parameter_kind(name) {
            Some(Kind::Flag) => map.next_value::<Option<bool>>()?.map(Value::Flag),
            Some(Kind::List) => map.next_value::<Option<List>>()?.map(|p| Value::List(p.0)),
            _ => map.next_value::<Option<f64>>()?.map(Value::Number),
        })
    }
}

impl<'de> Visitor<'de> for DampingVisitor {
    type Value = Damping;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("struct Damping")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Damping, A::Error> {
        let keys = damping_keys();
        let mut seen = vec![false; keys.len()];
        let mut model = None;
        let mut arguments = Vec::new();
        while let Some(Key(index)) = map.next_key()? {
            if std::mem::replace(&mut seen[index], true) {
                return Err(de::Error::duplicate_field(keys[index]));
            }
            if index == 0 {
                model = Some(map.next_value::<String>()?);
            } else if let Some(value) = Self::value(&mut map, keys[index])? {
                arguments.push((keys[index], value));
            }
        }
        let model = model.ok_or_else(|| de::Error::missing_field("model"))?;
        Ok(Damping { model, arguments })
    }

    /// The keys' values in [`damping_keys`] order, as serde's derive reads
    /// a struct from a JSON array.
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Damping, A::Error> {
        let keys = damping_keys();
        // The registry's added parameters come last and may be left out, so
        // that arrays written before they existed still read.
        let required = keys.len() - registry::ADDED_PARAMETERS.len();
        let short = |found: usize| {
            let expected = format!("struct Damping with {required} elements");
            de::Error::invalid_length(found, &expected.as_str())
        };
        let model: String = seq.next_element()?.ok_or_else(|| short(0))?;
        let mut arguments = Vec::new();
        for (index, &name) in keys.iter().enumerate().skip(1) {
            let value = match registry::parameter_kind(name) {
                Some(Kind::Flag) => seq
                    .next_element::<Option<bool>>()?
                    .map(|v| v.map(Value::Flag)),
                Some(Kind::List) => seq
                    .next_element::<Option<List>>()?
                    .map(|v| v.map(|p| Value::List(p.0))),
                _ => seq
                    .next_element::<Option<f64>>()?
                    .map(|v| v.map(Value::Number)),
            };
            let value = match value {
                None if index >= required => break,
                other => other,
            };
            if let Some(value) = value.ok_or_else(|| short(index))? {
                arguments.push((name, value));
            }
        }
        Ok(Damping { model, arguments })
    }
}

/// Parses TOML scene text; errors carry the line and the field path.
pub(super) fn parse_toml(text: &str, source: &Path) -> Result<Scene> {
    let line_of = |span: Option<std::ops::Range<usize>>| {
        span.map_or(1, |s| {
            text[..s.start.min(text.len())].matches('\n').count() + 1
        })
    };
    let deserializer = toml::Deserializer::parse(text).map_err(|e| Error::Parse {
        path: source.to_path_buf(),
        line: line_of(e.span()),
        message: e.message().to_string(),
    })?;
    serde_path_to_error::deserialize(deserializer).map_err(|e| {
        let field = e.path().to_string();
        let inner = e.into_inner();
        Error::Parse {
            path: source.to_path_buf(),
            line: line_of(inner.span()),
            message: format!("{}: {}", display_field(&field), inner.message()),
        }
    })
}

/// Parses JSON scene text; errors carry the line and the field path.
pub(super) fn parse_json(text: &str, source: &Path) -> Result<Scene> {
    let mut deserializer = serde_json::Deserializer::from_str(text);
    let to_error = |field: Option<String>, inner: serde_json::Error| {
        let message = inner.to_string();
        // serde_json appends " at line L column C"; the line goes in its own field.
        let message = message
            .rsplit_once(" at line ")
            .map_or(message.as_str(), |(m, _)| m)
            .to_string();
        let message = match field {
            Some(field) => format!("{}: {message}", display_field(&field)),
            None => message,
        };
        Error::Parse {
            path: source.to_path_buf(),
            line: inner.line().max(1),
            message,
        }
    };
    let scene = serde_path_to_error::deserialize(&mut deserializer).map_err(|e| {
        let field = e.path().to_string();
        // `?` is serde_path_to_error's "no path known" (a syntax error):
        // there is no field to name, only the line.
        let field = (field != "?").then_some(field);
        to_error(field, e.into_inner())
    })?;
    // Anything after the scene object is an error, not silently ignored.
    deserializer.end().map_err(|e| to_error(None, e))?;
    Ok(scene)
}

/// serde_path_to_error prints the root as `.`; scenes call it `scene`.
fn display_field(field: &str) -> &str {
    if field == "." { "scene" } else { field }
}
