//! The initial-state file: vertex positions and, optionally, velocities, to
//! start a simulation from (or to resume one where a previous run stopped).
//!
//! It is JSON, one vertex per line when this module writes it:
//!
//! ```json
//! {
//!   "positions": [
//!     [0.0,0.0,0.0],
//!     [1.0,0.0,0.0]
//!   ],
//!   "velocities": [
//!     [0.0,0.0,0.0],
//!     [0.0,-0.5,0.0]
//!   ]
//! }
//! ```
//!
//! Positions are in metres, velocities in m/s. `velocities` may be left out,
//! meaning all zeros. Numbers are written so that reading them back gives
//! the same `f64` bits. Whether the vertex count matches a scene's mesh is
//! checked by whoever combines the two.

use std::io::Write;
use std::path::Path;

use pd_mesh::Point;
use serde::{Deserialize, Serialize};

use crate::atomic::write_atomically;
use crate::error::{Error, Result};

/// The contents of a state file, as read; [`read_state`] has checked that
/// every number is finite and that there is one velocity per position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateFile {
    /// Vertex positions, in metres.
    pub positions: Vec<[f64; 3]>,
    /// Vertex velocities, in m/s; `None` means all zeros.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocities: Option<Vec<[f64; 3]>>,
}

impl StateFile {
    /// The positions as points, in metres.
    pub fn positions_as_points(&self) -> Vec<Point> {
        self.positions.iter().map(|&p| Point::from(p)).collect()
    }

    /// The velocities as vectors, in m/s: zeros for every vertex if the file
    /// gave none.
    pub fn velocities_as_points(&self) -> Vec<Point> {
        match &self.velocities {
            Some(velocities) => velocities.iter().map(|&v| Point::from(v)).collect(),
            None => vec![Point::zeros(); self.positions.len()],
        }
    }
}

/// Reads and checks a state file.
///
/// # Errors
/// - [`Error::Io`] if the file cannot be read;
/// - [`Error::Parse`] with serde_json's line for malformed JSON, a document
///   that is not an object, a missing or repeated key, or a number too large
///   for an `f64`;
/// - [`Error::Field`] naming the value's path, e.g. `positions[3][1]`, for a
///   value of the wrong type or an array of the wrong length, an unknown key,
///   a non-finite number, or `velocities` of a different length than
///   `positions`.
///
/// ```
/// use pd_io::state::{read_state, write_state};
/// use pd_mesh::Point;
///
/// let dir = std::env::temp_dir().join(format!("pd-io-doc-state-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("state.json");
/// let positions = [Point::new(0.1, 0.2, 0.3), Point::new(1.0 / 3.0, 0.0, -1e-300)];
/// let velocities = [Point::zeros(), Point::new(0.0, -9.81, 0.0)];
/// write_state(&path, &positions, &velocities).unwrap();
///
/// let state = read_state(&path).unwrap();
/// assert_eq!(state.positions_as_points(), positions);
/// assert_eq!(state.velocities_as_points(), velocities);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn read_state(path: &Path) -> Result<StateFile> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::io(path, source))?;
    // serde would read a top-level array as the struct's fields in order and
    // report a baffling `[0]`; say what is expected instead.
    let start = text.trim_start();
    if start.starts_with('[') {
        return Err(Error::Parse {
            path: path.to_path_buf(),
            line: 1 + text[..text.len() - start.len()].matches('\n').count(),
            message: "expected a JSON object `{\"positions\": [...]}`, found an array".into(),
        });
    }
    let mut deserializer = serde_json::Deserializer::from_str(&text);
    let state: StateFile = serde_path_to_error::deserialize(&mut deserializer)
        .map_err(|err| json_error(path, err.path().to_string(), err.into_inner()))?;
    deserializer
        .end()
        .map_err(|err| json_error(path, String::new(), err))?;
    check(path, &state)?;
    Ok(state)
}

/// Writes a state file (see the [module docs](self) for its layout),
/// replacing any existing file atomically.
///
/// # Errors
/// [`Error::Content`] if `velocities` does not have one entry per position
/// or a value is not finite (JSON cannot hold NaN or infinity);
/// [`Error::Io`] naming `path` if the file cannot be written.
pub fn write_state(path: &Path, positions: &[Point], velocities: &[Point]) -> Result<()> {
    let content_error = |message: String| Error::Content {
        path: path.to_path_buf(),
        message,
    };
    if velocities.len() != positions.len() {
        return Err(content_error(format!(
            "{} velocities given for {} positions; a state needs one velocity per vertex",
            velocities.len(),
            positions.len()
        )));
    }
    for (name, vectors) in [("position", positions), ("velocity", velocities)] {
        if let Some(vertex) = vectors
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(content_error(format!(
                "{name} of vertex {vertex} is not finite; JSON cannot hold it"
            )));
        }
    }
    write_atomically(path, |w| {
        writeln!(w, "{{")?;
        write_vectors(w, "positions", positions)?;
        writeln!(w, ",")?;
        write_vectors(w, "velocities", velocities)?;
        writeln!(w, "\n}}")
    })
}

/// Writes `  "name": [ ... ]`, one vector per line, with serde_json's number
/// formatting (shortest text that reads back to the same bits).
fn write_vectors(w: &mut impl Write, name: &str, vectors: &[Point]) -> std::io::Result<()> {
    write!(w, "  \"{name}\": [")?;
    for (i, v) in vectors.iter().enumerate() {
        w.write_all(if i == 0 { b"\n    " } else { b",\n    " })?;
        serde_json::to_writer(&mut *w, &[v.x, v.y, v.z])?;
    }
    if !vectors.is_empty() {
        write!(w, "\n  ")?;
    }
    write!(w, "]")
}

/// Converts a serde_json error: a wrong value inside the document names its
/// path; anything else (syntax, a missing or unknown key) its line.
fn json_error(path: &Path, field: String, err: serde_json::Error) -> Error {
    let at_a_value = !field.is_empty() && field != ".";
    if err.classify() == serde_json::error::Category::Data && at_a_value {
        Error::Field {
            path: path.to_path_buf(),
            field,
            message: err.to_string(),
        }
    } else {
        Error::Parse {
            path: path.to_path_buf(),
            // serde_json reports line 0 only for errors without a position.
            line: err.line().max(1),
            message: without_position(&err),
        }
    }
}

/// serde_json's message without its trailing " at line L column C", which
/// [`Error::Parse`] shows itself; the column is kept.
fn without_position(err: &serde_json::Error) -> String {
    let text = err.to_string();
    let suffix = format!(" at line {} column {}", err.line(), err.column());
    match text.strip_suffix(&suffix) {
        Some(message) => format!("{message} (column {})", err.column()),
        None => text,
    }
}

/// Checks what serde cannot: finite numbers (serde_json turns some
/// overflowing literals into infinity rather than failing), and one
/// velocity per position.
fn check(path: &Path, state: &StateFile) -> Result<()> {
    let field_error = |field: String, message: String| Error::Field {
        path: path.to_path_buf(),
        field,
        message,
    };
    let mut lists = vec![("positions", &state.positions)];
    if let Some(velocities) = &state.velocities {
        lists.push(("velocities", velocities));
        if velocities.len() != state.positions.len() {
            return Err(field_error(
                "velocities".into(),
                format!(
                    "has {} entries but positions has {}; give one velocity per vertex or \
                     leave velocities out",
                    velocities.len(),
                    state.positions.len()
                ),
            ));
        }
    }
    for (name, vectors) in lists {
        for (vertex, vector) in vectors.iter().enumerate() {
            if let Some(axis) = vector.iter().position(|c| !c.is_finite()) {
                return Err(field_error(
                    format!("{name}[{vertex}][{axis}]"),
                    format!("{} is not a finite number", vector[axis]),
                ));
            }
        }
    }
    Ok(())
}
