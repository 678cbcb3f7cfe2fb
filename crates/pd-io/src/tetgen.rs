//! Reader and writer for TetGen's `.node` / `.ele` tetrahedral meshes, and a
//! reader for its `.face` surfaces ([`read_tetgen_surface`]).
//!
//! The format, as TetGen 1.5 writes it and as this module reads it:
//!
//! ```text
//! # bar.node                  # '#' starts a comment anywhere on a line
//! <#points> <dimension = 3> <#attributes> <#boundary markers = 0 | 1>
//! <index> <x> <y> <z> [attributes...] [boundary marker]
//! ...
//! # bar.ele
//! <#tetrahedra> <nodes per tetrahedron = 4> <#region attributes = 0 | 1>
//! <index> <n0> <n1> <n2> <n3> [region attribute]
//! ...
//! ```
//!
//! Blank lines are skipped and fields are separated by any whitespace.
//! Indices start at 0 or at 1: the first node index of the `.node` file
//! decides, node indices must then be consecutive, and the `.ele` file's
//! node references use the same base. Attributes, boundary markers and
//! region attributes are checked to be numbers and otherwise ignored.
//! Only linear (4-node) tetrahedra are supported; TetGen's orientation
//! convention (positive volume, see [`pd_mesh::Mesh`]) is the one the mesh
//! requires, so tetrahedra are taken as they are.

use std::ffi::OsString;
use std::io::Write;
use std::path::{Path, PathBuf};

use pd_mesh::{Mesh, Point};

use crate::atomic::write_atomically;
use crate::error::{Error, Result};
use crate::frames::Float;
use crate::lines::{DataLines, Line, quoted, read_text};
use crate::readers::{build_mesh, check_distinct};

/// Reads a tetrahedral mesh from a TetGen `.node` file and its `.ele` file.
///
/// # Errors
/// - [`Error::Io`] if a file cannot be read;
/// - [`Error::Parse`], naming the file and the 1-based line, for a missing,
///   short or unsupported header (dimension other than 3, other than 4 nodes
///   per tetrahedron), a field that is not a number, a line with the wrong
///   number of fields, a non-finite coordinate, node indices that do not
///   start at 0 or 1 or are not consecutive, a tetrahedron referring to a
///   node that does not exist, or fewer or more data lines than the header
///   declares;
/// - [`Error::Mesh`], naming the `.ele` file, if the tetrahedra do not form
///   a valid [`Mesh`] (flat or inverted tetrahedra, a repeated vertex). Its
///   element index counts tetrahedra from 0 in file order, whatever the
///   file's own numbering.
pub fn read_tetgen(node: &Path, ele: &Path) -> Result<Mesh> {
    let nodes = read_nodes(node)?;
    let tets = read_elements(ele, node, &nodes)?;
    Mesh::from_tets(nodes.points, tets).map_err(|source| Error::Mesh {
        path: ele.to_path_buf(),
        source,
    })
}

/// Reads `BASE.node` and `BASE.ele` with [`read_tetgen`]. A `base` that
/// already ends in `.node` or `.ele` names the pair too, so
/// `meshes/bar`, `meshes/bar.node` and `meshes/bar.ele` all read the same
/// mesh; TetGen's own output names such as `bar.1` work as they are.
///
/// # Errors
/// As [`read_tetgen`].
///
/// ```
/// use pd_io::tetgen::{read_tetgen_base, write_tetgen};
/// use pd_mesh::generators;
///
/// let dir = std::env::temp_dir().join(format!("pd-io-doc-tetgen-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let beam = generators::box_tets([1.0, 0.2, 0.2], [5, 1, 1]).unwrap();
/// write_tetgen(&dir.join("beam"), &beam).unwrap();
/// let read_back = read_tetgen_base(&dir.join("beam.node")).unwrap();
/// assert_eq!(read_back, beam);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn read_tetgen_base(base: &Path) -> Result<Mesh> {
    let (node, ele) = tetgen_paths(base);
    read_tetgen(&node, &ele)
}

/// Writes a tetrahedral mesh as `BASE.node` and `BASE.ele` (an extension
/// `.node` or `.ele` on `base` is replaced, as in [`read_tetgen_base`]), with
/// 0-based indices, no attributes or markers, and coordinates that read back
/// to the same bits. Each file is replaced atomically.
///
/// # Errors
/// [`Error::Content`] if the mesh has no tetrahedra (TetGen files hold
/// volume meshes); [`Error::Io`] naming the file that cannot be written.
pub fn write_tetgen(base: &Path, mesh: &Mesh) -> Result<()> {
    let (node, ele) = tetgen_paths(base);
    if mesh.tets().is_empty() {
        return Err(Error::Content {
            path: ele,
            message: "the mesh has no tetrahedra; TetGen files hold tetrahedral meshes".into(),
        });
    }
    write_atomically(&node, |w| {
        writeln!(w, "# Node count, dimension, attributes, boundary markers")?;
        writeln!(w, "{} 3 0 0", mesh.num_vertices())?;
        for (index, p) in mesh.vertices().iter().enumerate() {
            writeln!(w, "{index} {} {} {}", Float(p.x), Float(p.y), Float(p.z))?;
        }
        Ok(())
    })?;
    write_atomically(&ele, |w| {
        writeln!(
            w,
            "# Tetrahedron count, nodes per tetrahedron, region attributes"
        )?;
        writeln!(w, "{} 4 0", mesh.tets().len())?;
        for (index, [a, b, c, d]) in mesh.tets().iter().enumerate() {
            writeln!(w, "{index} {a} {b} {c} {d}")?;
        }
        Ok(())
    })
}

/// Reads a triangle surface from a TetGen `.node` file and its `.face` file
/// (what `tetgen -f` writes: the boundary faces, or all faces), as a
/// [`Mesh`] of triangles: a cloth or a spring network over its edges.
///
/// The `.face` format: a header `<#faces> <#boundary markers = 0 | 1>`, then
/// `<index> <n0> <n1> <n2> [boundary marker]` per face, with the same
/// comment, blank-line and index-base rules as the `.ele` file. The
/// triangles keep the file's vertex order. Every node of the `.node` file
/// becomes a vertex, used by a face or not (a vertex no triangle touches
/// gets mass 0 from a density, which the solver rejects unless it is fixed).
///
/// # Errors
/// - [`Error::Io`] if a file cannot be read;
/// - [`Error::Parse`], naming the file and line, for the same faults as
///   [`read_tetgen`] (header, fields, numbers, index sequence, a node that
///   does not exist, a wrong count of lines) and for a face that repeats a
///   node or has zero area (the message names the face by its file index).
pub fn read_tetgen_surface(node: &Path, face: &Path) -> Result<Mesh> {
    let nodes = read_nodes(node)?;
    let text = read_text(face)?;
    let mut lines = DataLines::new(face, &text);
    let header = lines.header("<#faces> <#boundary markers>", 2)?;
    let num_faces = header.unsigned(0, "number of faces")?;
    let num_markers = header.unsigned(1, "number of boundary markers")?;
    if num_markers > 1 {
        return Err(header.error(format!(
            "the number of boundary markers must be 0 or 1, found {num_markers}"
        )));
    }
    let extra = (num_markers == 1).then_some(Extra::BoundaryMarker);
    let faces = CellSection::new(&header, ("face", "faces"), num_faces, extra)?;
    let (triangles, face_lines) = faces.read(&mut lines, &nodes, node, |line, index, face| {
        check_distinct(line, face, &format!("face {index}"), nodes.first_index)
    })?;
    build_mesh(face, nodes.points, Vec::new(), triangles, None, &face_lines)
}

/// Reads `BASE.node` and `BASE.face` with [`read_tetgen_surface`]; `base`
/// may end in `.node` or `.face`, or in neither (TetGen's `bar.1`).
///
/// # Errors
/// As [`read_tetgen_surface`].
pub fn read_tetgen_surface_base(base: &Path) -> Result<Mesh> {
    let (node, face) = file_pair(base, "face");
    read_tetgen_surface(&node, &face)
}

/// `(BASE.node, BASE.ele)` for a base with or without one of the two
/// extensions.
fn tetgen_paths(base: &Path) -> (PathBuf, PathBuf) {
    file_pair(base, "ele")
}

/// `(BASE.node, BASE.<elements>)` for a base that ends in `.node`, in
/// `.<elements>` or in neither. Appends rather than using
/// `Path::with_extension`, which would turn TetGen's `bar.1` into
/// `bar.node`.
fn file_pair(base: &Path, elements: &str) -> (PathBuf, PathBuf) {
    let stem = match base.extension().and_then(|e| e.to_str()) {
        Some(e) if e == "node" || e == elements => base.with_extension(""),
        _ => base.to_path_buf(),
    };
    let with_suffix = |suffix: &str| {
        let mut name = OsString::from(stem.as_os_str());
        name.push(".");
        name.push(suffix);
        PathBuf::from(name)
    };
    (with_suffix("node"), with_suffix(elements))
}

/// The nodes of a `.node` file.
struct Nodes {
    points: Vec<Point>,
    /// The index of the first node, 0 or 1.
    first_index: usize,
}

fn read_nodes(path: &Path) -> Result<Nodes> {
    let text = read_text(path)?;
    let mut lines = DataLines::new(path, &text);

    let header = lines.header("<#points> <dimension> <#attributes> <#boundary markers>", 4)?;
    let num_points = header.unsigned(0, "number of points")?;
    let dimension = header.unsigned(1, "dimension")?;
    let num_attributes = header.unsigned(2, "number of attributes")?;
    let num_markers = header.unsigned(3, "number of boundary markers")?;
    if dimension != 3 {
        return Err(header.error(format!(
            "dimension {dimension} is not supported: only 3D meshes (dimension 3) are"
        )));
    }
    if num_markers > 1 {
        return Err(header.error(format!(
            "the number of boundary markers must be 0 or 1, found {num_markers}"
        )));
    }
    if num_points == 0 {
        return Err(header.error("the header declares no points".into()));
    }

    // Saturating: a nonsense attribute count must fail on the first line,
    // not overflow.
    let num_fields = 4usize
        .saturating_add(num_attributes)
        .saturating_add(num_markers);
    let layout = node_line_layout(num_attributes, num_markers);
    // Capped: the header's count is not trusted until the lines are there.
    let mut points = Vec::with_capacity(num_points.min(1 << 20));
    let mut first_index = 0;
    for position in 0..num_points {
        let line = lines.data_line(header.line, position, num_points, "node")?;
        line.expect_fields(num_fields, &layout)?;
        let index = line.sequence_index(position, &mut first_index, "node")?;
        let mut coordinates = [0.0; 3];
        for (axis, (name, coordinate)) in ["x", "y", "z"].iter().zip(&mut coordinates).enumerate() {
            let value = line.number(1 + axis, &format!("{name} coordinate"))?;
            if !value.is_finite() {
                return Err(line.error(format!(
                    "{name} coordinate of node {index} is not finite: {}",
                    quoted(line.text(1 + axis))
                )));
            }
            *coordinate = value;
        }
        for attribute in 0..num_attributes {
            line.number(4 + attribute, "attribute")?;
        }
        if num_markers == 1 {
            line.signed(4 + num_attributes, "boundary marker")?;
        }
        points.push(Point::from(coordinates));
    }
    lines.expect_end(header.line, num_points, "nodes")?;
    Ok(Nodes {
        points,
        first_index,
    })
}

fn node_line_layout(num_attributes: usize, num_markers: usize) -> String {
    let mut layout = String::from("index, x, y, z");
    if num_attributes > 0 {
        layout += &format!(", {num_attributes} attribute(s)");
    }
    if num_markers > 0 {
        layout += ", boundary marker";
    }
    layout
}

fn read_elements(path: &Path, node_path: &Path, nodes: &Nodes) -> Result<Vec<[usize; 4]>> {
    let text = read_text(path)?;
    let mut lines = DataLines::new(path, &text);

    let header = lines.header(
        "<#tetrahedra> <nodes per tetrahedron> <#region attributes>",
        3,
    )?;
    let num_tets = header.unsigned(0, "number of tetrahedra")?;
    let nodes_per_tet = header.unsigned(1, "number of nodes per tetrahedron")?;
    let num_regions = header.unsigned(2, "number of region attributes")?;
    match nodes_per_tet {
        4 => {}
        10 => {
            return Err(header.error(
                "10-node (quadratic) tetrahedra are not supported: only 4-node linear \
                 tetrahedra are (run TetGen without -o2)"
                    .into(),
            ));
        }
        n => {
            return Err(header.error(format!(
                "a tetrahedron must have 4 nodes, the header says {n}"
            )));
        }
    }
    if num_regions > 1 {
        return Err(header.error(format!(
            "the number of region attributes must be 0 or 1, found {num_regions}"
        )));
    }
    let extra = (num_regions == 1).then_some(Extra::RegionAttribute);
    let tetrahedra = CellSection::new(&header, ("tetrahedron", "tetrahedra"), num_tets, extra)?;
    let (tets, _) = tetrahedra.read(&mut lines, nodes, node_path, |_, _, _| Ok(()))?;
    Ok(tets)
}

/// The optional last field of an element line.
#[derive(Debug, Clone, Copy)]
enum Extra {
    /// A `.ele` region attribute: any number.
    RegionAttribute,
    /// A `.face` boundary marker: an integer.
    BoundaryMarker,
}

/// The data lines of an element file (`.ele` or `.face`) after its header:
/// `<index> <n_0> ... <n_N-1> [extra]` per element, `count` of them.
struct CellSection {
    /// An element, in messages (`tetrahedron`).
    what: &'static str,
    /// Elements, in messages (`tetrahedra`).
    plural: &'static str,
    count: usize,
    header_line: usize,
    extra: Option<Extra>,
}

impl CellSection {
    /// The section of `count` elements declared on `header`; `names` are an
    /// element's and the elements' names in messages.
    ///
    /// # Errors
    /// A header that declares no elements.
    fn new(
        header: &Line<'_>,
        (what, plural): (&'static str, &'static str),
        count: usize,
        extra: Option<Extra>,
    ) -> Result<Self> {
        if count == 0 {
            return Err(header.error(format!("the header declares no {plural}")));
        }
        Ok(Self {
            what,
            plural,
            count,
            header_line: header.line,
            extra,
        })
    }

    /// Reads the elements as 0-based vertex indices of `nodes` (read from
    /// `node_path`), with the line of each; `check` sees every element,
    /// with its file index, before the next line is read.
    fn read<const N: usize>(
        &self,
        lines: &mut DataLines<'_>,
        nodes: &Nodes,
        node_path: &Path,
        check: impl Fn(&Line<'_>, usize, &[usize; N]) -> Result<()>,
    ) -> Result<(Vec<[usize; N]>, Vec<usize>)> {
        let what = self.what;
        let (num_points, first_node) = (nodes.points.len(), nodes.first_index);
        let layout = match self.extra {
            None => format!("index, {N} nodes"),
            Some(Extra::RegionAttribute) => format!("index, {N} nodes, region attribute"),
            Some(Extra::BoundaryMarker) => format!("index, {N} nodes, boundary marker"),
        };
        // Capped: the header's count is not trusted until the lines are there.
        let mut cells = Vec::with_capacity(self.count.min(1 << 20));
        let mut cell_lines = Vec::with_capacity(self.count.min(1 << 20));
        let mut first_index = 0;
        for position in 0..self.count {
            let line = lines.data_line(self.header_line, position, self.count, what)?;
            line.expect_fields(1 + N + usize::from(self.extra.is_some()), &layout)?;
            let index = line.sequence_index(position, &mut first_index, what)?;
            let mut cell = [0; N];
            for (corner, vertex) in cell.iter_mut().enumerate() {
                let node = line.unsigned(1 + corner, "node index")?;
                *vertex = node
                    .checked_sub(first_node)
                    .filter(|&v| v < num_points)
                    .ok_or_else(|| {
                        line.error(format!(
                            "{what} {index} refers to node {node}, but {} has {num_points} \
                             nodes numbered {first_node} to {}",
                            node_path.display(),
                            first_node + num_points - 1
                        ))
                    })?;
            }
            match self.extra {
                Some(Extra::RegionAttribute) => {
                    line.number(1 + N, "region attribute")?;
                }
                Some(Extra::BoundaryMarker) => {
                    line.signed(1 + N, "boundary marker")?;
                }
                None => {}
            }
            check(&line, index, &cell)?;
            cells.push(cell);
            cell_lines.push(line.line);
        }
        lines.expect_end(self.header_line, self.count, self.plural)?;
        Ok((cells, cell_lines))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_names_keep_tetgen_iteration_numbers() {
        let (node, ele) = tetgen_paths(Path::new("meshes/bar.1"));
        assert_eq!(node, Path::new("meshes/bar.1.node"));
        assert_eq!(ele, Path::new("meshes/bar.1.ele"));
        for base in ["meshes/bar", "meshes/bar.node", "meshes/bar.ele"] {
            let (node, ele) = tetgen_paths(Path::new(base));
            assert_eq!(node, Path::new("meshes/bar.node"), "{base}");
            assert_eq!(ele, Path::new("meshes/bar.ele"), "{base}");
        }
    }
}
