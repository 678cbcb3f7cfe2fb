//! Writers for simulation frames: legacy ASCII VTK (for ParaView and VisIt)
//! and Wavefront OBJ (for anything else).
//!
//! Every file this crate writes is replaced atomically (the crate's
//! `atomic` module): the text goes to a hidden temporary file beside the
//! target, which is flushed and renamed over the target, so a run that is
//! interrupted (Ctrl-C, a crash, a full disk) never leaves a half-written
//! frame under the final name.
//! Floats are written so that parsing them gives back the same `f64` bit for
//! bit.

use std::fmt;
use std::io::{self, Write};
use std::path::Path;

use pd_mesh::Point;

use crate::atomic::write_atomically;
use crate::error::{Error, Result};

/// The elements of a frame, as indices into its positions. Any of the three
/// lists may be empty.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cells<'a> {
    /// Tetrahedra (VTK cell type 10).
    pub tets: &'a [[usize; 4]],
    /// Triangles (VTK cell type 5).
    pub triangles: &'a [[usize; 3]],
    /// Line segments, e.g. springs (VTK cell type 3).
    pub lines: &'a [[usize; 2]],
}

/// VTK cell type of a linear tetrahedron (`VTK_TETRA`).
const VTK_TETRA: u8 = 10;
/// VTK cell type of a triangle (`VTK_TRIANGLE`).
const VTK_TRIANGLE: u8 = 5;
/// VTK cell type of a line segment (`VTK_LINE`).
const VTK_LINE: u8 = 3;

impl Cells<'_> {
    /// The number of cells of every kind.
    pub fn len(&self) -> usize {
        self.tets.len() + self.triangles.len() + self.lines.len()
    }

    /// Whether there are no cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// `(vertices, VTK cell type)` of every cell, in the order the VTK
    /// writers write them: tetrahedra, then triangles, then lines.
    pub(crate) fn vtk_types(&self) -> impl Iterator<Item = (usize, u8)> {
        let repeat = |count: usize, size: usize, cell_type: u8| {
            std::iter::repeat_n((size, cell_type), count)
        };
        repeat(self.tets.len(), 4, VTK_TETRA)
            .chain(repeat(self.triangles.len(), 3, VTK_TRIANGLE))
            .chain(repeat(self.lines.len(), 2, VTK_LINE))
    }
}

/// The checks every VTK-family frame writer makes before it writes:
/// finite positions and velocities, one velocity per position, and cells
/// that refer to existing vertices.
pub(crate) fn check_frame(
    path: &Path,
    positions: &[Point],
    cells: &Cells<'_>,
    velocities: Option<&[Point]>,
) -> Result<()> {
    check_points(path, "position", positions)?;
    if let Some(velocities) = velocities {
        check_points(path, "velocity", velocities)?;
        if velocities.len() != positions.len() {
            return Err(Error::Content {
                path: path.to_path_buf(),
                message: format!(
                    "{} velocities given for {} positions; a frame needs one velocity per vertex",
                    velocities.len(),
                    positions.len()
                ),
            });
        }
    }
    check_cells(path, "tetrahedron", cells.tets, positions.len())?;
    check_cells(path, "triangle", cells.triangles, positions.len())?;
    check_cells(path, "line", cells.lines, positions.len())?;
    Ok(())
}

/// Writes one frame as a legacy ASCII VTK unstructured grid: the positions
/// (in metres) as `POINTS`, the cells, and, when `velocities` is given, a
/// `POINT_DATA` block with a `VECTORS velocity double` field (in m/s).
///
/// The file is replaced atomically (see the [module docs](self)).
///
/// # Errors
/// [`Error::Content`] if a position or velocity is not finite, if a cell
/// refers to a vertex beyond `positions`, or if `velocities` does not have
/// one entry per position; [`Error::Io`] naming `path` if the file cannot be
/// written.
///
/// ```
/// use pd_io::frames::{write_vtk, Cells};
/// use pd_mesh::Point;
///
/// let dir = std::env::temp_dir().join(format!("pd-io-doc-vtk-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let positions = [
///     Point::new(0.0, 0.0, 0.0),
///     Point::new(1.0, 0.0, 0.0),
///     Point::new(0.0, 1.0, 0.0),
///     Point::new(0.0, 0.0, 1.0),
/// ];
/// let cells = Cells { tets: &[[0, 1, 2, 3]], ..Cells::default() };
/// write_vtk(&dir.join("frame_0000.vtk"), &positions, &cells, None).unwrap();
/// let text = std::fs::read_to_string(dir.join("frame_0000.vtk")).unwrap();
/// assert!(text.contains("CELL_TYPES 1\n10\n"));
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn write_vtk(
    path: &Path,
    positions: &[Point],
    cells: &Cells<'_>,
    velocities: Option<&[Point]>,
) -> Result<()> {
    check_frame(path, positions, cells, velocities)?;

    write_atomically(path, |w| {
        writeln!(w, "# vtk DataFile Version 3.0")?;
        writeln!(w, "pd frame")?;
        writeln!(w, "ASCII")?;
        writeln!(w, "DATASET UNSTRUCTURED_GRID")?;
        writeln!(w, "POINTS {} double", positions.len())?;
        write_vectors(w, positions)?;

        let num_cells = cells.len();
        // The size of the CELLS list counts every index plus each cell's
        // leading vertex count.
        let list_size: usize = cells.vtk_types().map(|(size, _)| size + 1).sum();
        writeln!(w, "CELLS {num_cells} {list_size}")?;
        write_vtk_cells(w, cells.tets)?;
        write_vtk_cells(w, cells.triangles)?;
        write_vtk_cells(w, cells.lines)?;
        writeln!(w, "CELL_TYPES {num_cells}")?;
        for (_, cell_type) in cells.vtk_types() {
            writeln!(w, "{cell_type}")?;
        }

        if let Some(velocities) = velocities {
            writeln!(w, "POINT_DATA {}", velocities.len())?;
            writeln!(w, "VECTORS velocity double")?;
            write_vectors(w, velocities)?;
        }
        Ok(())
    })
}

/// Writes one frame as a Wavefront OBJ file: a comment header, `v x y z`
/// per position (in metres), `f a b c` per triangle and `l a b` per line,
/// with OBJ's 1-based indices. OBJ has no tetrahedra: pass the boundary
/// surface of a volume mesh as `triangles`.
///
/// The file is replaced atomically (see the [module docs](self)).
///
/// # Errors
/// [`Error::Content`] if a position is not finite or an element refers to a
/// vertex beyond `positions`; [`Error::Io`] naming `path` if the file cannot
/// be written.
pub fn write_obj(
    path: &Path,
    positions: &[Point],
    triangles: &[[usize; 3]],
    lines: &[[usize; 2]],
) -> Result<()> {
    check_points(path, "position", positions)?;
    check_cells(path, "triangle", triangles, positions.len())?;
    check_cells(path, "line", lines, positions.len())?;

    write_atomically(path, |w| {
        writeln!(
            w,
            "# pd frame: {} vertices, {} triangles, {} lines",
            positions.len(),
            triangles.len(),
            lines.len()
        )?;
        for p in positions {
            writeln!(w, "v {} {} {}", Float(p.x), Float(p.y), Float(p.z))?;
        }
        for [a, b, c] in triangles {
            writeln!(w, "f {} {} {}", a + 1, b + 1, c + 1)?;
        }
        for [a, b] in lines {
            writeln!(w, "l {} {}", a + 1, b + 1)?;
        }
        Ok(())
    })
}

/// Displays an `f64` so that parsing the text gives back the same bits, in
/// a form every reader of our formats accepts: plain decimals for ordinary
/// magnitudes (`0.25`, `-3`), scientific notation (`1.5e-9`, `2e300`) for
/// very small or large ones. Rust's `{}` alone would round-trip too, but
/// spells `1e300` with 300 digits.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Float(pub(crate) f64);

impl fmt::Display for Float {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let magnitude = self.0.abs();
        if magnitude == 0.0 || (1e-5..1e16).contains(&magnitude) || !magnitude.is_finite() {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

fn write_vectors(w: &mut impl Write, vectors: &[Point]) -> io::Result<()> {
    for v in vectors {
        writeln!(w, "{} {} {}", Float(v.x), Float(v.y), Float(v.z))?;
    }
    Ok(())
}

fn write_vtk_cells<const K: usize>(w: &mut impl Write, cells: &[[usize; K]]) -> io::Result<()> {
    for cell in cells {
        write!(w, "{K}")?;
        for index in cell {
            write!(w, " {index}")?;
        }
        writeln!(w)?;
    }
    Ok(())
}

/// Rejects non-finite vectors: readers of VTK and OBJ do not agree on how to
/// spell NaN or infinity, so such a file would not load.
pub(crate) fn check_points(path: &Path, what: &str, points: &[Point]) -> Result<()> {
    match points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(vertex) => Err(Error::Content {
            path: path.to_path_buf(),
            message: format!("{what} of vertex {vertex} is not finite"),
        }),
        None => Ok(()),
    }
}

pub(crate) fn check_cells<const K: usize>(
    path: &Path,
    kind: &str,
    cells: &[[usize; K]],
    num_vertices: usize,
) -> Result<()> {
    for (element, cell) in cells.iter().enumerate() {
        if let Some(index) = cell.iter().find(|&&i| i >= num_vertices) {
            return Err(Error::Content {
                path: path.to_path_buf(),
                message: format!(
                    "{kind} {element} refers to vertex {index}, but the frame has {num_vertices} vertices"
                ),
            });
        }
    }
    Ok(())
}

/// Removes the files named `frame_NNNNN.*` (any extension: the frames of
/// a run, the pictures of `pd render`) numbered `first` or higher in `dir`;
/// other files stay. A missing `dir` has none.
///
/// # Errors
/// [`Error::Io`] naming the folder or the file that could not be read or
/// removed.
pub fn remove_frames_from(dir: &Path, first: usize) -> Result<()> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(dir, e)),
    };
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        let index = name
            .strip_prefix("frame_")
            .and_then(|rest| rest.split('.').next())
            .and_then(|digits| digits.parse::<usize>().ok());
        if index.is_some_and(|i| i >= first) {
            std::fs::remove_file(entry.path()).map_err(|e| Error::io(entry.path(), e))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_text_round_trips_and_avoids_long_spellings() {
        let values = [
            0.0,
            -0.0,
            1.0,
            0.1,
            -2.5,
            1.0 / 3.0,
            1e-5,
            9.999e-6,
            1e16,
            1e300,
            -1e-300,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            123_456_789.123_456_79,
        ];
        for x in values {
            let text = Float(x).to_string();
            let back: f64 = text.parse().unwrap();
            assert_eq!(back.to_bits(), x.to_bits(), "{x} written as {text}");
            assert!(text.len() <= 24, "{x} written as {text}");
        }
        assert_eq!(Float(0.25).to_string(), "0.25");
        assert_eq!(Float(-3.0).to_string(), "-3");
        assert_eq!(Float(2e300).to_string(), "2e300");
    }
}
