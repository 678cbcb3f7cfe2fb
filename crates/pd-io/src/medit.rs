//! Reader for Medit `.mesh` files (ASCII), as written by TetGen (`-g`),
//! mmg, Gmsh and CGAL.
//!
//! ```text
//! MeshVersionFormatted 2
//! Dimension 3
//! Vertices
//! <n>
//! <x> <y> <z> <ref>          # one line per vertex
//! Tetrahedra
//! <n>
//! <v0> <v1> <v2> <v3> <ref>  # 1-based vertex indices
//! Triangles
//! <n>
//! <v0> <v1> <v2> <ref>
//! End
//! ```
//!
//! A keyword's value or count may be on the keyword's line or on the next
//! one (`Dimension 3` or `Dimension` / `3`); each record (vertex, element)
//! must be on one line. `#` starts a comment. Version 1 to 4 are accepted
//! (they differ only in the binary form). `Edges`, `Corners`, `Ridges`,
//! `Required...`, `Normals`, `Tangents`, their `...AtVertices` tables and `TangentAtEdges`
//! are checked for their field count and skipped. Other element kinds
//! (`Quadrilaterals`, `Hexahedra`, `Prisms`, ...) and unknown keywords are
//! errors; binary `.meshb` files are not read. Reading stops at `End` (or at
//! the end of the file).
//!
//! With tetrahedra, the mesh is made of them (triangles are checked and
//! dropped); otherwise of the triangles. Vertex `i` of the mesh is vertex
//! `i + 1` of the file. Tetrahedra are taken in the file's vertex order and
//! must be positively oriented (the convention of [`pd_mesh::Mesh`]); they
//! are not reoriented, so a flat or inverted one (or a file written with
//! the opposite convention) is an error naming its line and its index
//! (from 0, in file order).

use std::path::Path;

use pd_mesh::{Mesh, Point};

use crate::error::Result;
use crate::lines::{DataLines, Line, quoted, read_text};
use crate::readers::{build_mesh, check_distinct, finite_point, vertex_index};

/// Reads a Medit `.mesh` file (see the [module docs](self)).
///
/// # Errors
/// - [`crate::Error::Io`] if the file cannot be read;
/// - [`crate::Error::Parse`], naming the file and 1-based line, for: a
///   missing or unsupported `MeshVersionFormatted` or `Dimension`, an
///   unknown or unsupported keyword, a record with the wrong number of
///   fields, a field that is not a number, a non-finite coordinate, an
///   element referring to a vertex that does not exist (or to one before
///   `Vertices`), an element repeating a vertex, a truncated table, a file
///   with neither tetrahedra nor triangles, and a flat or inverted
///   tetrahedron or a zero-area triangle (with its index);
/// - [`crate::Error::Mesh`] for any other validation failure.
pub fn read_medit(path: &Path) -> Result<Mesh> {
    let text = read_text(path)?;
    let mut lines = DataLines::new(path, &text);
    let mut version_seen = false;
    let mut dimension_seen = false;
    let mut points: Option<Vec<Point>> = None;
    let mut elements = Elements::default();

    while let Some(line) = lines.next_line() {
        let keyword = line.fields[0];
        if !version_seen && keyword != "MeshVersionFormatted" {
            return Err(line.error(format!(
                "expected `MeshVersionFormatted`, found {}: not a Medit .mesh file",
                quoted(keyword)
            )));
        }
        match keyword {
            "End" => {
                line.expect_fields(1, "End")?;
                break;
            }
            "MeshVersionFormatted" => {
                let (value_line, field) = value(&mut lines, line, keyword)?;
                let version = value_line.unsigned(field, "mesh version")?;
                if !(1..=4).contains(&version) {
                    return Err(value_line.error(format!(
                        "MeshVersionFormatted must be 1 to 4, found {version}"
                    )));
                }
                version_seen = true;
            }
            "Dimension" => {
                let (value_line, field) = value(&mut lines, line, keyword)?;
                let dimension = value_line.unsigned(field, "dimension")?;
                if dimension != 3 {
                    return Err(value_line.error(format!(
                        "dimension {dimension} is not supported: only 3D meshes (Dimension 3) are"
                    )));
                }
                dimension_seen = true;
            }
            "Vertices" => {
                if !dimension_seen {
                    return Err(line.error("`Vertices` before `Dimension 3`".into()));
                }
                if points.is_some() {
                    return Err(line.error("a second `Vertices` table".into()));
                }
                points = Some(read_vertices(&mut lines, line)?);
            }
            "Tetrahedra" | "Triangles" => {
                let Some(vertices) = &points else {
                    return Err(line.error(format!(
                        "`{keyword}` before `Vertices`: the vertices must come first"
                    )));
                };
                elements.read(&mut lines, line, keyword, vertices.len())?;
            }
            _ => {
                let Some(fields) = skipped_layout(keyword) else {
                    return Err(line.error(unsupported(keyword)));
                };
                skip_table(&mut lines, line, keyword, fields)?;
            }
        }
    }
    if !version_seen {
        return Err(lines.error_at_end(
            "the file is empty: a Medit file starts with `MeshVersionFormatted`".into(),
        ));
    }
    let Some(points) = points else {
        return Err(lines.error_at_end("the file has no `Vertices` table".into()));
    };
    let Elements {
        tets,
        tet_lines,
        triangles,
        triangle_lines,
    } = elements;
    if !tets.is_empty() {
        build_mesh(path, points, tets, Vec::new(), None, &tet_lines)
    } else if !triangles.is_empty() {
        build_mesh(path, points, Vec::new(), triangles, None, &triangle_lines)
    } else {
        Err(lines.error_at_end("the file has no `Tetrahedra` and no `Triangles`".into()))
    }
}

/// The `Vertices` table whose keyword is on `line`: `x y z reference` per
/// vertex.
fn read_vertices<'a>(lines: &mut DataLines<'a>, line: Line<'a>) -> Result<Vec<Point>> {
    let (count_line, field) = value(lines, line, "Vertices")?;
    let count = count_line.unsigned(field, "number of vertices")?;
    let mut table = Vec::with_capacity(count.min(1 << 20));
    for k in 0..count {
        let record = record(lines, &count_line, count, k, "vertex")?;
        record.expect_fields(4, "x, y, z, reference")?;
        table.push(finite_point(&record, 0, &format!("vertex {}", k + 1))?);
        record.signed(3, "reference")?;
    }
    Ok(table)
}

/// The tetrahedra and triangles read so far, with the line of each.
#[derive(Default)]
struct Elements {
    tets: Vec<[usize; 4]>,
    tet_lines: Vec<usize>,
    triangles: Vec<[usize; 3]>,
    triangle_lines: Vec<usize>,
}

impl Elements {
    /// The `Tetrahedra` or `Triangles` table (`keyword`) whose keyword is
    /// on `line`: 1-based vertex indices below `num_vertices`, then a
    /// reference, per element.
    fn read<'a>(
        &mut self,
        lines: &mut DataLines<'a>,
        line: Line<'a>,
        keyword: &str,
        num_vertices: usize,
    ) -> Result<()> {
        let corners = if keyword == "Tetrahedra" { 4 } else { 3 };
        let what = if corners == 4 {
            "tetrahedron"
        } else {
            "triangle"
        };
        let (count_line, field) = value(lines, line, keyword)?;
        let count = count_line.unsigned(field, &format!("number of {what} records"))?;
        for k in 0..count {
            let record = record(lines, &count_line, count, k, what)?;
            record.expect_fields(corners + 1, "vertex indices, reference")?;
            let name = format!("{what} {}", k + 1);
            let mut element = [0; 4];
            for (c, v) in element.iter_mut().take(corners).enumerate() {
                *v = vertex_index(&record, c, 1, num_vertices, &name)?;
            }
            record.signed(corners, "reference")?;
            check_distinct(&record, &element[..corners], &name, 1)?;
            if corners == 4 {
                self.tets.push(element);
                self.tet_lines.push(record.line);
            } else {
                self.triangles.push([element[0], element[1], element[2]]);
                self.triangle_lines.push(record.line);
            }
        }
        Ok(())
    }
}

/// A table this reader checks but does not use (`keyword` on `line`):
/// `fields` numbers per record.
fn skip_table<'a>(
    lines: &mut DataLines<'a>,
    line: Line<'a>,
    keyword: &str,
    fields: usize,
) -> Result<()> {
    let (count_line, field) = value(lines, line, keyword)?;
    let count = count_line.unsigned(field, &format!("number of {keyword} records"))?;
    for k in 0..count {
        let record = record(lines, &count_line, count, k, keyword)?;
        record.expect_fields(fields, keyword)?;
        for f in 0..fields {
            record.number(f, "value")?;
        }
    }
    Ok(())
}

/// The value of a keyword: on its own line (`Dimension 3`) or on the next
/// (`Dimension` / `3`). Returns the line holding it and the field index.
fn value<'a>(
    lines: &mut DataLines<'a>,
    keyword_line: Line<'a>,
    keyword: &str,
) -> Result<(Line<'a>, usize)> {
    match keyword_line.fields.len() {
        2 => Ok((keyword_line, 1)),
        1 => {
            let next = lines.next_line().ok_or_else(|| {
                lines.error_at_end(format!(
                    "the file is truncated: `{keyword}` on line {} has no value",
                    keyword_line.line
                ))
            })?;
            next.expect_fields(1, &format!("the value of `{keyword}`"))?;
            Ok((next, 0))
        }
        n => Err(keyword_line.error(format!(
            "`{keyword}` takes one value, found {} fields",
            n - 1
        ))),
    }
}

/// Record `k` of `count` announced on `count_line`.
fn record<'a>(
    lines: &mut DataLines<'a>,
    count_line: &Line<'_>,
    count: usize,
    k: usize,
    what: &str,
) -> Result<Line<'a>> {
    lines.next_line().ok_or_else(|| {
        lines.error_at_end(format!(
            "the file is truncated: line {} announces {count} {what} records, found {k}",
            count_line.line
        ))
    })
}

/// Number of fields of each record of a table that is read and ignored.
fn skipped_layout(keyword: &str) -> Option<usize> {
    Some(match keyword {
        "Edges" => 3,
        "Corners" | "Ridges" | "RequiredVertices" | "RequiredEdges" | "RequiredTriangles"
        | "RequiredTetrahedra" => 1,
        "Normals" | "Tangents" => 3,
        "NormalAtVertices" | "TangentAtVertices" | "TangentAtEdges" => 2,
        "NormalAtTriangleVertices" => 3,
        _ => return None,
    })
}

fn unsupported(keyword: &str) -> String {
    match keyword {
        "Quadrilaterals" | "Hexahedra" | "Prisms" | "Pentahedra" | "Pyramids" => format!(
            "`{keyword}` are not supported: only tetrahedra and triangles are (convert the \
             mesh to tetrahedra)"
        ),
        k if k.ends_with("P2") || k.contains("Order") => format!(
            "{}: higher-order elements are not supported, only linear ones",
            quoted(keyword)
        ),
        _ => format!("unknown or unsupported keyword {}", quoted(keyword)),
    }
}
