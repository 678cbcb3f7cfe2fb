//! Writers for VTK XML unstructured grids (`.vtu`, one per frame) and the
//! ParaView collection file (`.pvd`) that lists the frames with their times,
//! so that ParaView opens a run as one animated data set.
//!
//! The files are ASCII XML (no compression, no base64; data values one
//! tuple per line, unindented), with `Float64`
//! points and fields written so that they read back to the same bits, and
//! are replaced atomically like every file of this crate (see
//! [`crate::frames`]). Written by hand: no XML dependency.

use std::io::{self, Write};
use std::path::Path;

use pd_mesh::Point;

use crate::atomic::write_atomically;
use crate::error::{Error, Result};
use crate::frames::{Cells, Float, check_frame};

/// Writes one frame as a VTK XML unstructured grid: `Points` (m), the cells
/// (tetrahedra, then triangles, then lines, as VTK types 10, 5 and 3), and,
/// when given, the point field `velocity` (3 components, m/s) and the cell
/// field `strain` (one value per cell in the same order, dimensionless; see
/// [`crate::strain`]).
///
/// # Errors
/// [`Error::Content`] if a position, velocity or strain is not finite, a
/// cell refers to a vertex beyond `positions`, or `velocities` or `strain`
/// has the wrong length; [`Error::Io`] naming `path` if it cannot be
/// written.
///
/// ```
/// use pd_io::frames::Cells;
/// use pd_io::vtu::write_vtu;
/// use pd_mesh::Point;
///
/// let dir = std::env::temp_dir().join(format!("pd-io-doc-vtu-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let positions = [Point::new(0.0, 0.0, 0.0), Point::new(1.0, 0.0, 0.0)];
/// let cells = Cells { lines: &[[0, 1]], ..Cells::default() };
/// write_vtu(&dir.join("f.vtu"), &positions, &cells, None, Some(&[0.5])).unwrap();
/// let text = std::fs::read_to_string(dir.join("f.vtu")).unwrap();
/// assert!(text.contains(r#"<Piece NumberOfPoints="2" NumberOfCells="1">"#));
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn write_vtu(
    path: &Path,
    positions: &[Point],
    cells: &Cells<'_>,
    velocities: Option<&[Point]>,
    strain: Option<&[f64]>,
) -> Result<()> {
    check_frame(path, positions, cells, velocities)?;
    let num_cells = cells.len();
    if let Some(strain) = strain {
        if strain.len() != num_cells {
            return Err(content(
                path,
                format!(
                    "{} strain values given for {num_cells} cells; a frame needs one per cell",
                    strain.len()
                ),
            ));
        }
        if let Some(cell) = strain.iter().position(|s| !s.is_finite()) {
            return Err(content(
                path,
                format!("strain of cell {cell} is not finite"),
            ));
        }
    }

    write_atomically(path, |w| {
        writeln!(w, r#"<?xml version="1.0"?>"#)?;
        writeln!(
            w,
            r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
        )?;
        writeln!(w, "  <UnstructuredGrid>")?;
        writeln!(
            w,
            r#"    <Piece NumberOfPoints="{}" NumberOfCells="{num_cells}">"#,
            positions.len()
        )?;
        if let Some(velocities) = velocities {
            writeln!(w, r#"      <PointData Vectors="velocity">"#)?;
            vectors(w, "velocity", velocities)?;
            writeln!(w, "      </PointData>")?;
        }
        if let Some(strain) = strain {
            writeln!(w, r#"      <CellData Scalars="strain">"#)?;
            writeln!(
                w,
                r#"        <DataArray type="Float64" Name="strain" format="ascii">"#
            )?;
            for s in strain {
                writeln!(w, "{}", Float(*s))?;
            }
            writeln!(w, "        </DataArray>")?;
            writeln!(w, "      </CellData>")?;
        }
        writeln!(w, "      <Points>")?;
        vectors(w, "Points", positions)?;
        writeln!(w, "      </Points>")?;
        writeln!(w, "      <Cells>")?;
        writeln!(
            w,
            r#"        <DataArray type="Int64" Name="connectivity" format="ascii">"#
        )?;
        connectivity(w, cells.tets)?;
        connectivity(w, cells.triangles)?;
        connectivity(w, cells.lines)?;
        writeln!(w, "        </DataArray>")?;
        writeln!(
            w,
            r#"        <DataArray type="Int64" Name="offsets" format="ascii">"#
        )?;
        let mut offset = 0;
        for (size, _) in cells.vtk_types() {
            offset += size;
            writeln!(w, "{offset}")?;
        }
        writeln!(w, "        </DataArray>")?;
        writeln!(
            w,
            r#"        <DataArray type="UInt8" Name="types" format="ascii">"#
        )?;
        for (_, cell_type) in cells.vtk_types() {
            writeln!(w, "{cell_type}")?;
        }
        writeln!(w, "        </DataArray>")?;
        writeln!(w, "      </Cells>")?;
        writeln!(w, "    </Piece>")?;
        writeln!(w, "  </UnstructuredGrid>")?;
        writeln!(w, "</VTKFile>")
    })
}

/// One frame of a `.pvd` collection.
#[derive(Debug, Clone, PartialEq)]
pub struct PvdEntry {
    /// Simulated time of the frame, s.
    pub time: f64,
    /// The frame file, relative to the `.pvd` file's folder, with `/`
    /// separators (e.g. `frames/frame_00003.vtu`).
    pub file: String,
}

/// Writes (or atomically replaces) a ParaView collection file listing
/// `entries` as time steps, in the order given. Call it again with the
/// longer list after each new frame: ParaView reading the file at any
/// moment sees a complete list of complete frames.
///
/// # Errors
/// [`Error::Content`] if a time is not finite; [`Error::Io`] naming `path`.
pub fn write_pvd(path: &Path, entries: &[PvdEntry]) -> Result<()> {
    if let Some(entry) = entries.iter().find(|e| !e.time.is_finite()) {
        return Err(content(
            path,
            format!("the time of frame `{}` is not finite", entry.file),
        ));
    }
    write_atomically(path, |w| {
        writeln!(w, r#"<?xml version="1.0"?>"#)?;
        writeln!(
            w,
            r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#
        )?;
        writeln!(w, "  <Collection>")?;
        for entry in entries {
            writeln!(
                w,
                r#"    <DataSet timestep="{}" group="" part="0" file="{}"/>"#,
                Float(entry.time),
                escape(&entry.file)
            )?;
        }
        writeln!(w, "  </Collection>")?;
        writeln!(w, "</VTKFile>")
    })
}

fn content(path: &Path, message: String) -> Error {
    Error::Content {
        path: path.to_path_buf(),
        message,
    }
}

/// Escapes the characters XML attribute values cannot hold as they are.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

fn vectors(w: &mut impl Write, name: &str, values: &[Point]) -> io::Result<()> {
    writeln!(
        w,
        r#"        <DataArray type="Float64" Name="{name}" NumberOfComponents="3" format="ascii">"#
    )?;
    for v in values {
        writeln!(w, "{} {} {}", Float(v.x), Float(v.y), Float(v.z))?;
    }
    writeln!(w, "        </DataArray>")
}

fn connectivity<const K: usize>(w: &mut impl Write, cells: &[[usize; K]]) -> io::Result<()> {
    for cell in cells {
        let [first, rest @ ..] = cell.as_slice() else {
            continue;
        };
        write!(w, "{first}")?;
        for index in rest {
            write!(w, " {index}")?;
        }
        writeln!(w)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::escape;

    #[test]
    fn attribute_text_is_escaped() {
        assert_eq!(escape(r#"a&b<c>"d'"#), "a&amp;b&lt;c&gt;&quot;d&apos;");
        assert_eq!(escape("frames/frame_00001.vtu"), "frames/frame_00001.vtu");
    }
}
