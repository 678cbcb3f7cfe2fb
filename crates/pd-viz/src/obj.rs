//! Reading the OBJ surface frames `pd run` writes (`v`, `f` and `l` lines).

use std::path::Path;

use crate::{Error, Result};

/// One frame's surface: positions (m), triangles and line segments.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Surface {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Triangles (0-based vertex indices); polygons are fanned.
    pub triangles: Vec<[usize; 3]>,
    /// Line segments (0-based), for bodies without faces (chains).
    pub lines: Vec<[usize; 2]>,
}

/// Reads an OBJ file: `v x y z`, `f a b c ...` (also `a/t/n` forms, and
/// negative relative indices) and `l a b ...`; other lines are ignored.
///
/// # Errors
/// [`Error::Io`], or [`Error::Parse`] with the line for a malformed number,
/// a face with fewer than 3 vertices or an index out of range.
pub fn read_obj(path: &Path) -> Result<Surface> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_obj(&text, path)
}

/// Parses OBJ text; `path` names it in errors.
///
/// # Errors
/// As [`read_obj`].
pub fn parse_obj(text: &str, path: &Path) -> Result<Surface> {
    let mut surface = Surface::default();
    for (index, line) in text.lines().enumerate() {
        let error = |message: String| Error::Parse {
            path: path.to_path_buf(),
            line: index + 1,
            message,
        };
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut p = [0.0; 3];
                for c in &mut p {
                    let word = words
                        .next()
                        .ok_or_else(|| error("a vertex needs x, y and z".into()))?;
                    *c = word
                        .parse()
                        .ok()
                        .filter(|x: &f64| x.is_finite())
                        .ok_or_else(|| error(format!("`{word}` is not a finite number")))?;
                }
                surface.positions.push(p);
            }
            Some(kind @ ("f" | "l")) => {
                let n = surface.positions.len();
                let indices = words
                    .map(|word| {
                        let first = word.split('/').next().unwrap_or("");
                        let i: i64 = first
                            .parse()
                            .map_err(|_| error(format!("`{word}` is not a vertex index")))?;
                        let resolved = if i > 0 { i - 1 } else { n as i64 + i };
                        if i == 0 || resolved < 0 || resolved >= n as i64 {
                            return Err(error(format!(
                                "vertex index {i} is out of range (1..={n} so far)"
                            )));
                        }
                        Ok(resolved as usize)
                    })
                    .collect::<Result<Vec<usize>>>()?;
                if kind == "f" {
                    if indices.len() < 3 {
                        return Err(error("a face needs at least 3 vertices".into()));
                    }
                    for k in 1..indices.len() - 1 {
                        surface
                            .triangles
                            .push([indices[0], indices[k], indices[k + 1]]);
                    }
                } else {
                    if indices.len() < 2 {
                        return Err(error("a line needs at least 2 vertices".into()));
                    }
                    surface
                        .lines
                        .extend(indices.windows(2).map(|w| [w[0], w[1]]));
                }
            }
            _ => {}
        }
    }
    Ok(surface)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_faces_lines_and_relative_indices() {
        let text = "# c\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\nl 1 2 3\nf -1 -2 -3\n";
        let s = parse_obj(text, Path::new("t.obj")).unwrap();
        assert_eq!(s.positions.len(), 4);
        assert_eq!(s.triangles, vec![[0, 1, 3], [0, 3, 2], [3, 2, 1]]);
        assert_eq!(s.lines, vec![[0, 1], [1, 2]]);
    }

    #[test]
    fn malformed_input_names_the_line() {
        for (text, line) in [
            ("v 0 0\n", 1),
            ("v 0 0 0\nv 0 x 0\n", 2),
            ("v 0 0 0\nf 1 2 3\n", 2),
            ("v 0 0 0\nv 0 0 1\nv 1 0 0\nf 1 2\n", 4),
            ("v 0 0 0\nl 0 1\n", 2),
            ("v 0 0 nan\n", 1),
        ] {
            let err = parse_obj(text, Path::new("bad.obj"))
                .unwrap_err()
                .to_string();
            assert!(
                err.starts_with(&format!("bad.obj:{line}:")),
                "{text:?}: {err}"
            );
        }
        assert_eq!(
            parse_obj("", Path::new("e.obj")).unwrap(),
            Surface::default()
        );
    }
}
