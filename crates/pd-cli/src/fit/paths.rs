//! The scene values `pd fit` can fit, named by their field paths as the
//! scene loader's messages spell them (`damping.stiffness`,
//! `body[0].constraints[1].stiffness`), and the scene's value tree they are
//! read from and written into.
//!
//! The tree is the scene file parsed as data (TOML or JSON, both as a JSON
//! value), so a fitted value goes through the loader's own validation, and
//! the fitted scene is written out from the same tree.

use std::path::Path;

use serde_json::Value;

/// The field paths `pd fit` takes, `i`, `j`, `k` standing for indices: all
/// positive quantities, fitted in log space.
pub(crate) const SUPPORTED: &[&str] = &[
    "damping.stiffness",
    "damping.mass",
    "damping.ratio",
    "damping.ratios[k]",
    "damping.series[k]",
    "body[i].density",
    "body[i].vertex_mass",
    "body[i].constraints[j].stiffness",
    "body[i].constraints[j].young",
    "body[i].damping.stiffness",
    "body[i].damping.mass",
    "body[i].damping.ratio",
    "body[i].damping.ratios[k]",
];

/// One step of a field path: a table key or a list index.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Step {
    Key(String),
    Index(usize),
}

/// A fitted scene value: its path as written and its steps in the tree.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct FieldPath {
    /// As the user (and the loader) spell it.
    pub text: String,
    steps: Vec<Step>,
}

/// The supported paths, for messages.
fn supported_list() -> String {
    SUPPORTED.join(", ")
}

impl FieldPath {
    /// Parses `text` and checks it is one of [`SUPPORTED`].
    pub(crate) fn parse(text: &str) -> Result<Self, String> {
        let text = text.trim();
        let unsupported = || {
            format!(
                "--fit: `{text}` is not a scene value pd fit can fit; supported: {} \
                 (i, j, k indices from 0)",
                supported_list()
            )
        };
        let mut steps = Vec::new();
        let mut pattern = Vec::new();
        for segment in text.split('.') {
            let (name, indices) = match segment.find('[') {
                Some(at) => segment.split_at(at),
                None => (segment, ""),
            };
            if name.is_empty() || !name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
                return Err(unsupported());
            }
            steps.push(Step::Key(name.to_string()));
            let mut piece = name.to_string();
            let mut rest = indices;
            while !rest.is_empty() {
                let close = rest.find(']').ok_or_else(unsupported)?;
                let index: usize = rest[1..close].parse().map_err(|_| unsupported())?;
                steps.push(Step::Index(index));
                piece.push_str("[_]");
                rest = &rest[close + 1..];
                if !rest.is_empty() && !rest.starts_with('[') {
                    return Err(unsupported());
                }
            }
            pattern.push(piece);
        }
        let pattern = pattern.join(".");
        let known = SUPPORTED.iter().any(|s| {
            s.replace("[i]", "[_]")
                .replace("[j]", "[_]")
                .replace("[k]", "[_]")
                == pattern
        });
        if !known {
            return Err(unsupported());
        }
        Ok(Self {
            text: text.to_string(),
            steps,
        })
    }

    /// The value at this path in `tree`, which must be a positive finite
    /// number (the starting point of the fit).
    pub(crate) fn read(&self, tree: &Value, source: &Path) -> Result<f64, String> {
        let mut node = tree;
        for step in &self.steps {
            let next = match step {
                Step::Key(key) => node.get(key.as_str()),
                Step::Index(index) => node.get(*index),
            };
            node = next.ok_or_else(|| {
                format!(
                    "{}: {}: the scene does not set it; pd fit starts from the scene's value, \
                     so give it one",
                    source.display(),
                    self.text
                )
            })?;
        }
        let value = node.as_f64().ok_or_else(|| {
            format!(
                "{}: {}: is not a number ({node}); pd fit fits numbers only",
                source.display(),
                self.text
            )
        })?;
        if !(value > 0.0 && value.is_finite()) {
            return Err(format!(
                "{}: {}: is {value}; pd fit fits positive values (in log space), so start it \
                 from a positive one",
                source.display(),
                self.text
            ));
        }
        Ok(value)
    }

    /// Sets the value at this path in `tree` (where [`FieldPath::read`]
    /// found a number).
    pub(crate) fn write(&self, tree: &mut Value, value: f64) {
        let mut node = Some(tree);
        for step in &self.steps {
            node = node.and_then(|n| match step {
                Step::Key(key) => n.get_mut(key.as_str()),
                Step::Index(index) => n.get_mut(*index),
            });
        }
        if let Some(node) = node {
            *node = Value::from(value);
        }
    }
}

/// Parses the `--fit` list: each path once.
pub(crate) fn parse_list(paths: &[String]) -> Result<Vec<FieldPath>, String> {
    let mut parsed: Vec<FieldPath> = Vec::new();
    for text in paths.iter().filter(|p| !p.trim().is_empty()) {
        let path = FieldPath::parse(text)?;
        if parsed.iter().any(|p| p.steps == path.steps) {
            return Err(format!("--fit: `{}` is given twice", path.text));
        }
        parsed.push(path);
    }
    if parsed.is_empty() {
        return Err(format!(
            "--fit: name at least one scene value to fit; supported: {}",
            supported_list()
        ));
    }
    Ok(parsed)
}

/// Mesh and state file keys hold paths relative to the scene's folder:
/// made absolute (against `folder`) in `tree`, so that a scene written
/// elsewhere finds the same files.
pub(crate) fn absolute_file_paths(tree: &mut Value, folder: &Path) {
    let fix = |node: Option<&mut Value>| {
        if let Some(node) = node
            && let Some(text) = node.as_str()
            && Path::new(text).is_relative()
        {
            let joined = folder.join(text);
            let absolute = std::path::absolute(&joined).unwrap_or(joined);
            *node = Value::from(absolute.to_string_lossy().into_owned());
        }
    };
    if let Some(bodies) = tree.get_mut("body").and_then(Value::as_array_mut) {
        for body in bodies {
            fix(body.get_mut("mesh").and_then(|m| m.get_mut("file")));
            fix(body.get_mut("initial_state"));
        }
    }
    if let Some(colliders) = tree.get_mut("collider").and_then(Value::as_array_mut) {
        for collider in colliders {
            fix(collider.get_mut("file"));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn supported_paths_parse_and_others_are_refused_with_the_list() {
        for ok in [
            "damping.stiffness",
            "damping.ratios[1]",
            "damping.series[0]",
            "body[0].constraints[2].stiffness",
            "body[3].density",
            " body[1].damping.mass ",
        ] {
            assert!(FieldPath::parse(ok).is_ok(), "{ok}");
        }
        for bad in [
            "damping.model",
            "damping",
            "body[0].constraints.stiffness",
            "body[x].density",
            "body[0]].density",
            "body[-1].density",
            "simulation.dt",
            "body[0].constraints[0].stiffness.x",
            "",
        ] {
            let err = FieldPath::parse(bad).unwrap_err();
            assert!(
                err.contains("not a scene value pd fit can fit")
                    && err.contains("body[i].constraints[j].stiffness"),
                "{bad}: {err}"
            );
        }
    }

    #[test]
    fn values_are_read_and_written_at_their_path() {
        let mut tree: Value = serde_json::json!({
            "damping": { "model": "laplacian", "stiffness": 0.01, "mass": 0 },
            "body": [ { "density": 1000, "constraints": [ { "kind": "tet-strain", "stiffness": 1e5 } ] } ]
        });
        let source = Path::new("beam.toml");
        let stiffness = FieldPath::parse("body[0].constraints[0].stiffness").unwrap();
        assert_eq!(stiffness.read(&tree, source), Ok(1e5));
        stiffness.write(&mut tree, 2.5e5);
        assert_eq!(stiffness.read(&tree, source), Ok(2.5e5));
        let density = FieldPath::parse("body[0].density").unwrap();
        assert_eq!(density.read(&tree, source), Ok(1000.0));

        let zero = FieldPath::parse("damping.mass")
            .unwrap()
            .read(&tree, source);
        assert!(zero.unwrap_err().contains("beam.toml: damping.mass: is 0"));
        let missing = FieldPath::parse("body[1].density")
            .unwrap()
            .read(&tree, source);
        assert!(
            missing
                .unwrap_err()
                .contains("body[1].density: the scene does not set it")
        );
        let missing = FieldPath::parse("damping.ratio")
            .unwrap()
            .read(&tree, source);
        assert!(
            missing
                .unwrap_err()
                .contains("damping.ratio: the scene does not set it")
        );
    }

    #[test]
    fn a_path_given_twice_is_refused() {
        let list = ["damping.mass".to_string(), "damping.mass".to_string()];
        assert!(parse_list(&list).unwrap_err().contains("given twice"));
        assert!(parse_list(&[]).unwrap_err().contains("at least one"));
    }

    #[test]
    fn relative_file_paths_become_absolute() {
        let mut tree: Value = serde_json::json!({
            "body": [ { "mesh": { "file": "meshes/beam.msh" }, "initial_state": "/abs/state.json" } ],
            "collider": [ { "shape": "mesh", "file": "bowl.obj" } ]
        });
        absolute_file_paths(&mut tree, Path::new("/data/scenes"));
        assert_eq!(
            tree["body"][0]["mesh"]["file"],
            "/data/scenes/meshes/beam.msh"
        );
        assert_eq!(tree["body"][0]["initial_state"], "/abs/state.json");
        assert_eq!(tree["collider"][0]["file"], "/data/scenes/bowl.obj");
    }
}
