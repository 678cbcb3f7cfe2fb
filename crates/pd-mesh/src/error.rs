//! The error type of this crate.

use crate::ElementKind;

/// Everything that can be wrong with a mesh, a generator's parameters or a
/// vertex selection. Each variant names the vertex, element or parameter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex {
        /// Index of the vertex.
        vertex: usize,
    },
    /// An element refers to a vertex that does not exist.
    #[error("{kind} {element} refers to vertex {index}, but the mesh has {num_vertices} vertices")]
    IndexOutOfRange {
        /// Kind of element.
        kind: ElementKind,
        /// Index of the element.
        element: usize,
        /// The offending vertex index.
        index: usize,
        /// Number of vertices in the mesh.
        num_vertices: usize,
    },
    /// An element uses the same vertex twice.
    #[error("{kind} {element} uses vertex {vertex} more than once")]
    RepeatedVertex {
        /// Kind of element.
        kind: ElementKind,
        /// Index of the element.
        element: usize,
        /// The repeated vertex.
        vertex: usize,
    },
    /// An element's rest size (volume, area or edge length, squared or
    /// cubed) overflows `f64`: its coordinates are too large.
    #[error(
        "{kind} {element} is too large: its rest size overflows (coordinates of order 1e100 or \
         more); use other units"
    )]
    SizeOverflow {
        /// Kind of element.
        kind: ElementKind,
        /// Index of the element.
        element: usize,
    },
    /// A tetrahedron has zero or negative rest volume (inverted or flat).
    #[error(
        "tetrahedron {element} has non-positive rest volume {volume:e} m^3 (inverted or flat; \
         swap two of its vertices if it is inverted)"
    )]
    NonPositiveVolume {
        /// Index of the tetrahedron.
        element: usize,
        /// Its signed volume.
        volume: f64,
    },
    /// A triangle has zero rest area.
    #[error("triangle {element} has zero rest area")]
    ZeroArea {
        /// Index of the triangle.
        element: usize,
    },
    /// A density is not finite and positive.
    #[error("density must be finite and > 0, got {density}")]
    InvalidDensity {
        /// The rejected value.
        density: f64,
    },
    /// A corner of a lone tetrahedron (one not part of a [`crate::Mesh`],
    /// given to [`crate::tet_volume`] or
    /// [`crate::generators::tet_quality`]) is not a vertex of the list.
    #[error("tetrahedron corner {corner} is vertex {index}, but there are {num_vertices} vertices")]
    CornerOutOfRange {
        /// Which corner, 0 to 3.
        corner: usize,
        /// The offending vertex index.
        index: usize,
        /// Number of vertices given.
        num_vertices: usize,
    },
    /// A generator or selection parameter is out of its domain.
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// Name of the parameter, e.g. `cells`.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}
