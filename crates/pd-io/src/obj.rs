//! Reader for Wavefront OBJ surfaces and line networks (as Blender, Houdini
//! and most modellers export them), for cloth and spring networks.
//!
//! What is read, one statement per line, `#` starting a comment:
//!
//! - `v x y z [w]` or `v x y z r g b`: a vertex (`w` and colours are checked
//!   to be numbers and ignored);
//! - `f v1 v2 v3 ...`: a face, each corner written `v`, `v/vt`, `v//vn` or
//!   `v/vt/vn`; vertex indices are 1-based, or negative to count back from
//!   the last vertex defined so far (`-1` is the latest). Only the vertex
//!   index is used (texture and normal indices are checked to be integers).
//!   A polygon with more than 3 corners is split into a fan of triangles
//!   from its first corner (`v1 v2 v3`, `v1 v3 v4`, ...), which is right for
//!   convex polygons such as quads; export with Blender's "Triangulate
//!   Faces" for anything else;
//! - `l v1 v2 ...`: a polyline, one edge per consecutive pair (joining two
//!   vertices at different positions);
//! - `vt`, `vn`, `vp`, `o`, `g`, `s`, `usemtl`, `mtllib`, `p`: ignored.
//!
//! Any other statement (free-form curves and surfaces: `cstype`, `curv`,
//! `surf`, ...) is an error, as is a line continued with `\`.
//!
//! A file with faces gives a triangle mesh (a cloth; springs use all its
//! edges, diagonals included); a file with only lines gives an edge graph
//! (a spring network). Files with both are rejected, so that no element is
//! silently dropped. Vertex `i` of the mesh is the file's vertex `i + 1`.

use std::path::Path;

use pd_mesh::{Mesh, Point};

use crate::error::Result;
use crate::lines::{DataLines, Line, quoted, read_text};
use crate::readers::{build_mesh, check_distinct, finite_point};

/// Reads a Wavefront OBJ file (see the [module docs](self)).
///
/// # Errors
/// - [`crate::Error::Io`] if the file cannot be read;
/// - [`crate::Error::Parse`], naming the file and the 1-based line, for an
///   unsupported statement, a vertex with the wrong number of fields or a
///   non-finite coordinate, a face with fewer than 3 corners or a line with
///   fewer than 2, an index that is 0, not an integer or refers to a vertex
///   not yet defined, a face repeating a vertex, a line joining two vertices
///   at the same position, a file with both faces and lines or with
///   neither, and a zero-area triangle (named by its index
///   from 0 among the triangles after polygons are split, in file order);
/// - [`crate::Error::Mesh`] for any other validation failure.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("pd-io-doc-obj-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("quad.obj");
/// std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1/1 2/2/1 3/3/1 -1/4/1\n").unwrap();
/// let mesh = pd_io::obj::read_obj(&path).unwrap();
/// assert_eq!(mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
/// assert_eq!(mesh.edges().len(), 5);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn read_obj(path: &Path) -> Result<Mesh> {
    let text = read_text(path)?;
    let mut lines = DataLines::new(path, &text);
    let mut points: Vec<Point> = Vec::new();
    let mut triangles = Vec::new();
    let mut triangle_lines = Vec::new();
    let mut edges = Vec::new();
    let mut edge_lines = Vec::new();
    let mut first_face_line = None;
    let mut first_edge_line = None;

    while let Some(line) = lines.next_line() {
        if line.fields.last().is_some_and(|f| f.ends_with('\\')) {
            return Err(line.error("line continuation with `\\` is not supported".into()));
        }
        match line.fields[0] {
            "v" => {
                if !matches!(line.fields.len(), 4 | 5 | 7) {
                    return Err(line.error(format!(
                        "a vertex needs `v x y z`, `v x y z w` or `v x y z r g b`, found {} \
                         values",
                        line.fields.len() - 1
                    )));
                }
                points.push(finite_point(
                    &line,
                    1,
                    &format!("vertex {}", points.len() + 1),
                )?);
                for f in 4..line.fields.len() {
                    line.number(f, "vertex weight or colour")?;
                }
            }
            "f" => {
                if line.fields.len() < 4 {
                    return Err(line.error(format!(
                        "a face needs at least 3 vertices, found {}",
                        line.fields.len() - 1
                    )));
                }
                let corners = corners(&line, points.len())?;
                let named: Vec<usize> = corners.iter().map(|c| c + 1).collect();
                check_distinct(&line, &named, "the face", 0)?;
                for k in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                    triangle_lines.push(line.line);
                }
                first_face_line.get_or_insert(line.line);
            }
            "l" => {
                if line.fields.len() < 3 {
                    return Err(line.error(format!(
                        "a line needs at least 2 vertices, found {}",
                        line.fields.len() - 1
                    )));
                }
                let corners = corners(&line, points.len())?;
                for pair in corners.windows(2) {
                    if pair[0] == pair[1] {
                        return Err(
                            line.error(format!("the line joins vertex {} to itself", pair[0] + 1))
                        );
                    }
                    // A zero-length edge has no rest length, and lumps no
                    // mass onto its vertices.
                    if points[pair[0]] == points[pair[1]] {
                        return Err(line.error(format!(
                            "the line joins vertices {} and {}, which are at the same position: \
                             an edge must have a non-zero length",
                            pair[0] + 1,
                            pair[1] + 1
                        )));
                    }
                    edges.push([pair[0], pair[1]]);
                    edge_lines.push(line.line);
                }
                first_edge_line.get_or_insert(line.line);
            }
            "vt" | "vn" | "vp" | "o" | "g" | "s" | "usemtl" | "mtllib" | "p" => {}
            other => {
                return Err(line.error(format!(
                    "unsupported OBJ statement {}: only v, f and l are read (vt, vn, vp, o, g, \
                     s, usemtl, mtllib and p are ignored)",
                    quoted(other)
                )));
            }
        }
    }
    match (first_face_line, first_edge_line) {
        (Some(face), Some(edge)) => Err(crate::Error::Parse {
            path: path.to_path_buf(),
            line: face.max(edge),
            message: format!(
                "the file has both faces (first on line {face}) and lines (first on line \
                 {edge}); a body is a surface or a line network, not both"
            ),
        }),
        (Some(_), None) => build_mesh(path, points, Vec::new(), triangles, None, &triangle_lines),
        (None, Some(_)) => build_mesh(
            path,
            points,
            Vec::new(),
            Vec::new(),
            Some(edges),
            &edge_lines,
        ),
        (None, None) => Err(lines.error_at_end(
            "the file has no faces (f) and no lines (l): nothing to simulate".into(),
        )),
    }
}

/// The 0-based vertex indices of the corners of an `f` or `l` statement.
fn corners(line: &Line<'_>, defined: usize) -> Result<Vec<usize>> {
    (1..line.fields.len())
        .map(|f| {
            let text = line.text(f);
            let mut parts = text.split('/');
            let vertex = parts.next().unwrap_or_default();
            for (i, part) in parts.enumerate() {
                // `v//vn` leaves the texture index empty.
                if i > 1 || (!part.is_empty() && part.parse::<i64>().is_err()) {
                    return Err(line.error(format!(
                        "corner {} must be v, v/vt, v//vn or v/vt/vn with integer indices",
                        quoted(text)
                    )));
                }
            }
            let index: i64 = vertex.parse().map_err(|_| {
                if is_integer_literal(vertex) {
                    // Digits, but too many for any index.
                    line.error(format!(
                        "the vertex index {} of corner {} is out of range: {defined} vertices \
                         are defined before this line (valid: 1 to {defined}, or -1 to \
                         -{defined})",
                        quoted(vertex),
                        quoted(text)
                    ))
                } else {
                    line.error(format!(
                        "the vertex index of corner {} must be an integer, found {}",
                        quoted(text),
                        quoted(vertex)
                    ))
                }
            })?;
            resolve(line, index, defined)
        })
        .collect()
}

/// Whether `text` is an integer as OBJ writes one (an optional sign, then
/// decimal digits), whatever its size.
fn is_integer_literal(text: &str) -> bool {
    let digits = text.strip_prefix(['-', '+']).unwrap_or(text);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// OBJ's 1-based or negative (relative) index to a 0-based one.
fn resolve(line: &Line<'_>, index: i64, defined: usize) -> Result<usize> {
    let out_of_range = || {
        line.error(format!(
            "vertex index {index} is out of range: {defined} vertices are defined before this \
             line (valid: 1 to {defined}, or -1 to -{defined})"
        ))
    };
    let zero_based = if index > 0 {
        usize::try_from(index - 1).map_err(|_| out_of_range())?
    } else if index < 0 {
        let back = usize::try_from(index.unsigned_abs()).map_err(|_| out_of_range())?;
        defined.checked_sub(back).ok_or_else(out_of_range)?
    } else {
        return Err(line.error("vertex index 0 is invalid: OBJ indices start at 1".into()));
    };
    if zero_based < defined {
        Ok(zero_based)
    } else {
        Err(out_of_range())
    }
}
