//! Writer for PLY (Stanford polygon) surface frames, which Blender, Houdini
//! and MeshLab import: ASCII PLY 1.0 with `double` vertex coordinates
//! (written to read back to the same bits), triangle faces and, for line
//! networks, edges.
//!
//! ```text
//! ply
//! format ascii 1.0
//! comment pd frame
//! element vertex <n>
//! property double x
//! property double y
//! property double z
//! element face <m>
//! property list uchar int vertex_indices
//! element edge <k>             # only when there are edges
//! property int vertex1
//! property int vertex2
//! end_header
//! <x> <y> <z>                  # n lines
//! 3 <a> <b> <c>                # m lines, 0-based indices
//! <a> <b>                      # k lines
//! ```

use std::io::Write;
use std::path::Path;

use pd_mesh::Point;

use crate::atomic::write_atomically;
use crate::error::{Error, Result};
use crate::frames::{Float, check_cells, check_points};

/// Writes one frame as an ASCII PLY file (see the [module docs](self)):
/// `positions` (m), `triangles` (pass the boundary surface of a volume
/// mesh) and `edges` (chains; may be empty, then no `edge` element is
/// declared).
///
/// # Errors
/// [`Error::Content`] if a position is not finite, an element refers to a
/// vertex beyond `positions`, or there are more than `i32::MAX` vertices
/// (PLY's `int` indices); [`Error::Io`] naming `path`.
pub fn write_ply(
    path: &Path,
    positions: &[Point],
    triangles: &[[usize; 3]],
    edges: &[[usize; 2]],
) -> Result<()> {
    check_points(path, "position", positions)?;
    check_cells(path, "triangle", triangles, positions.len())?;
    check_cells(path, "edge", edges, positions.len())?;
    if i32::try_from(positions.len()).is_err() {
        return Err(Error::Content {
            path: path.to_path_buf(),
            message: format!(
                "{} vertices is more than PLY's int indices can address",
                positions.len()
            ),
        });
    }
    write_atomically(path, |w| {
        writeln!(w, "ply")?;
        writeln!(w, "format ascii 1.0")?;
        writeln!(w, "comment pd frame")?;
        writeln!(w, "element vertex {}", positions.len())?;
        for axis in ["x", "y", "z"] {
            writeln!(w, "property double {axis}")?;
        }
        writeln!(w, "element face {}", triangles.len())?;
        writeln!(w, "property list uchar int vertex_indices")?;
        if !edges.is_empty() {
            writeln!(w, "element edge {}", edges.len())?;
            writeln!(w, "property int vertex1")?;
            writeln!(w, "property int vertex2")?;
        }
        writeln!(w, "end_header")?;
        for p in positions {
            writeln!(w, "{} {} {}", Float(p.x), Float(p.y), Float(p.z))?;
        }
        for [a, b, c] in triangles {
            writeln!(w, "3 {a} {b} {c}")?;
        }
        for [a, b] in edges {
            writeln!(w, "{a} {b}")?;
        }
        Ok(())
    })
}
