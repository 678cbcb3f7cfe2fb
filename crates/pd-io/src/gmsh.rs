//! Reader for Gmsh `.msh` files, format version 4.1, ASCII.
//!
//! What is read:
//!
//! ```text
//! $MeshFormat
//! 4.1 0 8                          # version, file type (0 = ASCII), size of a double
//! $EndMeshFormat
//! $Nodes
//! <#blocks> <#nodes> <min tag> <max tag>
//! <entity dim> <entity tag> <parametric 0|1> <#nodes in block>
//! <node tag>                       # one line per node of the block
//! ...
//! <x> <y> <z> [<u> [<v> [<w>]]]    # one line per node; u, v, w if parametric
//! ...
//! $EndNodes
//! $Elements
//! <#blocks> <#elements> <min tag> <max tag>
//! <entity dim> <entity tag> <element type> <#elements in block>
//! <element tag> <node tag> ...     # one line per element
//! ...
//! $EndElements
//! ```
//!
//! Other sections (`$PhysicalNames`, `$Entities`, `$NodeData`, ...) are
//! skipped to their `$End...` line. Node tags may be any positive integers,
//! in any order and with gaps; vertex `i` of the mesh is the `i`-th node of
//! the `$Nodes` section in file order. Element types 4 (4-node
//! tetrahedron) and 2 (3-node triangle) are read; points (15) and lines
//! (1, 8) are checked and skipped; any other type (quadrangles, hexahedra,
//! prisms, pyramids, second-order elements) is an error. If the file has
//! tetrahedra, the mesh is made of them (triangles, usually the boundary,
//! are checked and dropped: the boundary is recomputed from the tetrahedra);
//! otherwise of its triangles (a cloth or a spring network over its edges).
//!
//! Binary `.msh` files (file type 1) and versions other than 4.1 (2.2, 4.0)
//! are rejected with a message saying so: save the mesh from Gmsh as
//! "Version 4 ASCII" (`gmsh -3 -format msh41 model.geo`, with the option
//! `Mesh.Binary = 0`, the default).
//!
//! Gmsh orients tetrahedra positively (the convention of [`pd_mesh::Mesh`]),
//! so they are taken as they are; a flat or inverted one is an error naming
//! its line and its index among the tetrahedra (from 0, in file order).

use std::collections::HashMap;
use std::path::Path;

use pd_mesh::{Mesh, Point};

use crate::error::{Error, Result};
use crate::lines::{DataLines, Line, quoted, read_text};
use crate::readers::{build_mesh, check_distinct, finite_point};

/// Reads a Gmsh 4.1 ASCII `.msh` file (see the [module docs](self)).
///
/// # Errors
/// - [`Error::Io`] if the file cannot be read;
/// - [`Error::Parse`], naming the file and 1-based line, for: a file that
///   does not start with `$MeshFormat`, a version other than 4.1, a binary
///   file, a missing `$End...` line, a header or block line with the wrong
///   number of fields, a field that is not a number, a non-finite
///   coordinate, a repeated node tag, an element referring to a node tag
///   that `$Nodes` does not define, an element repeating a node, an
///   unsupported element type, counts that disagree with the data, a
///   missing `$Nodes` or `$Elements` section, a file with neither
///   tetrahedra nor triangles, and a flat or inverted tetrahedron or a
///   zero-area triangle (with its index);
/// - [`Error::Mesh`] for any other validation failure of the mesh.
///
/// ```
/// let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n\
///             $Nodes\n1 4 1 40\n3 1 0 4\n10\n20\n30\n40\n\
///             0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n\
///             $Elements\n1 1 1 1\n3 1 4 1\n1 10 20 30 40\n$EndElements\n";
/// let dir = std::env::temp_dir().join(format!("pd-io-doc-gmsh-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("tet.msh");
/// std::fs::write(&path, text).unwrap();
/// let mesh = pd_io::gmsh::read_gmsh(&path).unwrap();
/// assert_eq!(mesh.tets(), &[[0, 1, 2, 3]]);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn read_gmsh(path: &Path) -> Result<Mesh> {
    let text = read_text(path)?;
    let mut lines = DataLines::new(path, &text);

    let first = lines.next_line().ok_or_else(|| {
        lines.error_at_end("the file is empty: a Gmsh file starts with `$MeshFormat`".into())
    })?;
    if first.fields != ["$MeshFormat"] {
        return Err(first.error(format!(
            "expected `$MeshFormat`, found {}: not a Gmsh .msh file",
            quoted(&first.fields.join(" "))
        )));
    }
    read_format(&mut lines)?;

    let mut nodes: Option<Nodes> = None;
    let mut elements: Option<Elements> = None;
    while let Some(line) = lines.next_line() {
        match line.fields[0] {
            "$Nodes" if nodes.is_some() => {
                return Err(line.error("a second `$Nodes` section".into()));
            }
            "$Nodes" => nodes = Some(read_nodes(&mut lines, &line)?),
            "$Elements" if elements.is_some() => {
                return Err(line.error("a second `$Elements` section".into()));
            }
            "$Elements" => {
                let Some(nodes) = &nodes else {
                    return Err(line.error(
                        "`$Elements` comes before `$Nodes`; the nodes must be defined first".into(),
                    ));
                };
                elements = Some(read_elements(&mut lines, &line, nodes)?);
            }
            name if name.starts_with('$')
                && !name.starts_with("$End")
                && line.fields.len() == 1 =>
            {
                skip_section(&mut lines, &line, &name[1..])?;
            }
            _ => {
                return Err(line.error(format!(
                    "expected a section such as `$Nodes` or `$Elements`, found {}",
                    quoted(&line.fields.join(" "))
                )));
            }
        }
    }
    let Some(nodes) = nodes else {
        return Err(lines.error_at_end("the file has no `$Nodes` section".into()));
    };
    let Some(elements) = elements else {
        return Err(lines.error_at_end("the file has no `$Elements` section".into()));
    };
    if !elements.tets.is_empty() {
        build_mesh(
            path,
            nodes.points,
            elements.tets,
            Vec::new(),
            None,
            &elements.tet_lines,
        )
    } else if !elements.triangles.is_empty() {
        build_mesh(
            path,
            nodes.points,
            Vec::new(),
            elements.triangles,
            None,
            &elements.triangle_lines,
        )
    } else {
        Err(lines.error_at_end(
            "the file has no tetrahedra (element type 4) and no triangles (element type 2)".into(),
        ))
    }
}

fn read_format(lines: &mut DataLines<'_>) -> Result<()> {
    let line = lines
        .next_line()
        .ok_or_else(|| lines.error_at_end("the file is truncated inside `$MeshFormat`".into()))?;
    line.expect_fields(3, "version, file type, data size")?;
    let version = line.text(0);
    if version != "4.1" {
        return Err(line.error(format!(
            "Gmsh format version {} is not supported: only 4.1 is (save as \"Version 4 \
             ASCII\", e.g. `gmsh -format msh41`)",
            quoted(version)
        )));
    }
    match line.text(1) {
        "0" => {}
        "1" => {
            return Err(line.error(
                "binary .msh files are not supported: save the mesh as ASCII (Gmsh option \
                 `Mesh.Binary = 0`)"
                    .into(),
            ));
        }
        other => {
            return Err(line.error(format!(
                "the file type must be 0 (ASCII), found {}",
                quoted(other)
            )));
        }
    }
    line.unsigned(2, "data size")?;
    expect_end(lines, "MeshFormat")
}

/// Expects the line `$End<name>` next.
fn expect_end(lines: &mut DataLines<'_>, name: &str) -> Result<()> {
    let end = format!("$End{name}");
    match lines.next_line() {
        Some(line) if line.fields == [end.as_str()] => Ok(()),
        Some(line) => Err(line.error(format!(
            "expected `{end}`, found {}",
            quoted(&line.fields.join(" "))
        ))),
        None => Err(lines.error_at_end(format!("the file is truncated: `{end}` is missing"))),
    }
}

fn skip_section(lines: &mut DataLines<'_>, start: &Line<'_>, name: &str) -> Result<()> {
    let end = format!("$End{name}");
    while let Some(line) = lines.next_line() {
        if line.fields[0] == end {
            return Ok(());
        }
    }
    Err(lines.error_at_end(format!(
        "the file is truncated: section {} opened on line {} has no {}",
        quoted(&format!("${name}")),
        start.line,
        quoted(&end)
    )))
}

/// The next line, or a truncation error naming what was expected.
fn next<'a>(lines: &mut DataLines<'a>, what: &str) -> Result<Line<'a>> {
    lines
        .next_line()
        .ok_or_else(|| lines.error_at_end(format!("the file is truncated: expected {what}")))
}

struct Nodes {
    points: Vec<Point>,
    index_of_tag: HashMap<usize, usize>,
}

fn read_nodes(lines: &mut DataLines<'_>, start: &Line<'_>) -> Result<Nodes> {
    let header = next(lines, "the `$Nodes` header")?;
    header.expect_fields(4, "#blocks, #nodes, min tag, max tag")?;
    let num_blocks = header.unsigned(0, "number of node blocks")?;
    let num_nodes = header.unsigned(1, "number of nodes")?;
    header.unsigned(2, "minimum node tag")?;
    header.unsigned(3, "maximum node tag")?;
    let capacity = num_nodes.min(1 << 20);
    let mut points = Vec::with_capacity(capacity);
    let mut index_of_tag = HashMap::with_capacity(capacity);
    for _ in 0..num_blocks {
        let block = next(lines, "a node block header")?;
        block.expect_fields(
            4,
            "entity dimension, entity tag, parametric, #nodes in block",
        )?;
        let dim = block.unsigned(0, "entity dimension")?;
        block.signed(1, "entity tag")?;
        let parametric = block.unsigned(2, "parametric flag")?;
        let count = block.unsigned(3, "number of nodes in the block")?;
        if dim > 3 {
            return Err(block.error(format!("the entity dimension must be 0 to 3, found {dim}")));
        }
        if parametric > 1 {
            return Err(block.error(format!(
                "the parametric flag must be 0 or 1, found {parametric}"
            )));
        }
        let first = points.len();
        let mut tags = Vec::with_capacity(count.min(1 << 20));
        for _ in 0..count {
            let line = next(lines, "a node tag")?;
            line.expect_fields(1, "node tag")?;
            let tag = line.unsigned(0, "node tag")?;
            if tag == 0 {
                return Err(line.error("node tags start at 1, found 0".into()));
            }
            if index_of_tag.insert(tag, first + tags.len()).is_some() {
                return Err(line.error(format!("node tag {tag} is defined twice")));
            }
            tags.push(tag);
        }
        let fields = 3 + parametric * dim;
        for tag in tags {
            let line = next(lines, "node coordinates")?;
            line.expect_fields(fields, "x, y, z and the parametric coordinates")?;
            points.push(finite_point(&line, 0, &format!("node {tag}"))?);
            for p in 3..fields {
                line.number(p, "parametric coordinate")?;
            }
        }
    }
    if points.len() != num_nodes {
        return Err(header.error(format!(
            "the header declares {num_nodes} nodes but the blocks hold {}",
            points.len()
        )));
    }
    expect_end(lines, "Nodes").map_err(|e| annotate(e, start))?;
    Ok(Nodes {
        points,
        index_of_tag,
    })
}

/// Adds where the section started to an error.
fn annotate(error: Error, start: &Line<'_>) -> Error {
    match error {
        Error::Parse {
            path,
            line,
            message,
        } => Error::Parse {
            path,
            line,
            message: format!("{message} (section opened on line {})", start.line),
        },
        other => other,
    }
}

struct Elements {
    tets: Vec<[usize; 4]>,
    tet_lines: Vec<usize>,
    triangles: Vec<[usize; 3]>,
    triangle_lines: Vec<usize>,
}

/// Name of an unsupported Gmsh element type, for messages.
fn type_name(element_type: usize) -> &'static str {
    match element_type {
        3 => "4-node quadrangle",
        5 => "8-node hexahedron",
        6 => "6-node prism",
        7 => "5-node pyramid",
        9 => "6-node second-order triangle",
        10 => "9-node second-order quadrangle",
        11 => "10-node second-order tetrahedron",
        _ => "element",
    }
}

fn read_elements(lines: &mut DataLines<'_>, start: &Line<'_>, nodes: &Nodes) -> Result<Elements> {
    let header = next(lines, "the `$Elements` header")?;
    header.expect_fields(4, "#blocks, #elements, min tag, max tag")?;
    let num_blocks = header.unsigned(0, "number of element blocks")?;
    let num_elements = header.unsigned(1, "number of elements")?;
    header.unsigned(2, "minimum element tag")?;
    header.unsigned(3, "maximum element tag")?;
    let mut elements = Elements {
        tets: Vec::new(),
        tet_lines: Vec::new(),
        triangles: Vec::new(),
        triangle_lines: Vec::new(),
    };
    let mut total = 0usize;
    for _ in 0..num_blocks {
        let block = next(lines, "an element block header")?;
        block.expect_fields(4, "entity dimension, entity tag, element type, #elements")?;
        block.unsigned(0, "entity dimension")?;
        block.signed(1, "entity tag")?;
        let element_type = block.unsigned(2, "element type")?;
        let count = block.unsigned(3, "number of elements in the block")?;
        let num_nodes = match element_type {
            4 => 4,
            2 => 3,
            1 => 2,
            8 => 3,
            15 => 1,
            other => {
                return Err(block.error(format!(
                    "element type {other} ({}) is not supported: only 4-node tetrahedra \
                     (type 4) and 3-node triangles (type 2) are read, points and lines skipped",
                    type_name(other)
                )));
            }
        };
        for _ in 0..count {
            let line = next(lines, "an element line")?;
            line.expect_fields(1 + num_nodes, "element tag and its node tags")?;
            let tag = line.unsigned(0, "element tag")?;
            let mut vertices = [0usize; 4];
            for (k, vertex) in vertices.iter_mut().take(num_nodes).enumerate() {
                let node_tag = line.unsigned(1 + k, "node tag")?;
                *vertex = *nodes.index_of_tag.get(&node_tag).ok_or_else(|| {
                    line.error(format!(
                        "element {tag} refers to node tag {node_tag}, which `$Nodes` does not \
                         define"
                    ))
                })?;
            }
            let vertices = &vertices[..num_nodes];
            // Compare tags, not indices, so the message names what the file says.
            let tags: Vec<usize> = (1..=num_nodes)
                .map(|k| line.unsigned(k, "node tag"))
                .collect::<Result<_>>()?;
            check_distinct(&line, &tags, &format!("element {tag}"), 0)?;
            match element_type {
                4 => {
                    elements
                        .tets
                        .push([vertices[0], vertices[1], vertices[2], vertices[3]]);
                    elements.tet_lines.push(line.line);
                }
                2 => {
                    elements
                        .triangles
                        .push([vertices[0], vertices[1], vertices[2]]);
                    elements.triangle_lines.push(line.line);
                }
                _ => {}
            }
            total += 1;
        }
    }
    if total != num_elements {
        return Err(header.error(format!(
            "the header declares {num_elements} elements but the blocks hold {total}"
        )));
    }
    expect_end(lines, "Elements").map_err(|e| annotate(e, start))?;
    Ok(elements)
}
