//! Helpers shared by the mesh readers: coordinates, element checks, and
//! turning a mesh validation error into a message at the element's line.

use std::path::Path;

use pd_mesh::{Mesh, MeshError, Point};

use crate::error::{Error, Result};
use crate::lines::{Line, quoted};

/// Fields `start..start + 3` of `line` as a finite point; `what` names the
/// vertex in messages (e.g. `vertex 3`).
pub(crate) fn finite_point(line: &Line<'_>, start: usize, what: &str) -> Result<Point> {
    let mut coordinates = [0.0; 3];
    for (axis, (name, coordinate)) in ["x", "y", "z"].iter().zip(&mut coordinates).enumerate() {
        let value = line.number(start + axis, &format!("{name} coordinate"))?;
        if !value.is_finite() {
            return Err(line.error(format!(
                "{name} coordinate of {what} is not finite: {}",
                quoted(line.text(start + axis))
            )));
        }
        *coordinate = value;
    }
    Ok(Point::from(coordinates))
}

/// Rejects an element that uses a vertex twice; `base` is added to the
/// 0-based vertex index to name it as the file does.
pub(crate) fn check_distinct(
    line: &Line<'_>,
    vertices: &[usize],
    what: &str,
    base: usize,
) -> Result<()> {
    for (i, v) in vertices.iter().enumerate() {
        if vertices[..i].contains(v) {
            return Err(line.error(format!("{what} uses vertex {} more than once", v + base)));
        }
    }
    Ok(())
}

/// Builds and validates the mesh read from `path`. `element_lines[e]` is the
/// line of element `e` of the kind the mesh is made of (tetrahedra if there
/// are any, else triangles, else edges), so that a flat or inverted element
/// is reported at its line, with its index (0-based, in file order) from
/// the mesh's own validation.
pub(crate) fn build_mesh(
    path: &Path,
    points: Vec<Point>,
    tets: Vec<[usize; 4]>,
    triangles: Vec<[usize; 3]>,
    edges: Option<Vec<[usize; 2]>>,
    element_lines: &[usize],
) -> Result<Mesh> {
    Mesh::new(points, tets, triangles, edges).map_err(|source| {
        let element = match source {
            MeshError::NonPositiveVolume { element, .. } | MeshError::ZeroArea { element } => {
                Some(element)
            }
            MeshError::RepeatedVertex { element, .. } => Some(element),
            _ => None,
        };
        match element.and_then(|e| element_lines.get(e)) {
            Some(&line) => Error::Parse {
                path: path.to_path_buf(),
                line,
                message: source.to_string(),
            },
            None => Error::Mesh {
                path: path.to_path_buf(),
                source,
            },
        }
    })
}

/// Converts a 1-based (or other `base`) vertex reference to a 0-based index
/// below `count`, or an error at `line` naming `what`.
pub(crate) fn vertex_index(
    line: &Line<'_>,
    field: usize,
    base: usize,
    count: usize,
    what: &str,
) -> Result<usize> {
    let value = line.unsigned(field, "vertex index")?;
    value
        .checked_sub(base)
        .filter(|&v| v < count)
        .ok_or_else(|| {
            if count == 0 {
                line.error(format!(
                    "{what} refers to vertex {value}, but no vertex is defined"
                ))
            } else {
                line.error(format!(
                    "{what} refers to vertex {value}, but there are {count} vertices numbered \
                     {base} to {}",
                    base + count - 1
                ))
            }
        })
}
