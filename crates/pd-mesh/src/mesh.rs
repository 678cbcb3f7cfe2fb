//! The [`Mesh`] type: vertices plus tetrahedra, triangles and edges.

use nalgebra::Vector3;

use crate::MeshError;

/// A point or vector in 3D, in metres.
pub type Point = Vector3<f64>;

/// Which kind of element an error or a query refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ElementKind {
    /// A tetrahedron (4 vertices).
    Tet,
    /// A triangle (3 vertices).
    Triangle,
    /// An edge or spring (2 vertices).
    Edge,
}

impl std::fmt::Display for ElementKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ElementKind::Tet => "tetrahedron",
            ElementKind::Triangle => "triangle",
            ElementKind::Edge => "edge",
        })
    }
}

/// A validated mesh: rest positions and elements.
///
/// Invariants, checked by every constructor: all coordinates are finite, every
/// element index is in range, no element repeats a vertex, every tetrahedron
/// has positive volume (vertices ordered so that
/// `(x1 - x0) . ((x2 - x0) x (x3 - x0)) > 0`) and every triangle has positive
/// area. `edges` always holds the unique edges of the mesh: the constructors
/// derive them from the tetrahedra or triangles unless they are given.
///
/// ```
/// use pd_mesh::{Mesh, Point};
/// let vertices = vec![
///     Point::new(0.0, 0.0, 0.0),
///     Point::new(1.0, 0.0, 0.0),
///     Point::new(0.0, 1.0, 0.0),
///     Point::new(0.0, 0.0, 1.0),
/// ];
/// let mesh = Mesh::from_tets(vertices, vec![[0, 1, 2, 3]]).unwrap();
/// assert_eq!(mesh.edges().len(), 6);
/// assert!((mesh.tet_volumes()[0] - 1.0 / 6.0).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    vertices: Vec<Point>,
    tets: Vec<[usize; 4]>,
    triangles: Vec<[usize; 3]>,
    edges: Vec<[usize; 2]>,
}

impl Mesh {
    /// Builds a tetrahedral mesh; its edges are derived from the tetrahedra.
    ///
    /// # Errors
    /// Any violated invariant of [`Mesh`], naming the vertex or element.
    pub fn from_tets(vertices: Vec<Point>, tets: Vec<[usize; 4]>) -> Result<Self, MeshError> {
        Self::new(vertices, tets, Vec::new(), None)
    }

    /// Builds a triangle mesh (a surface or a cloth); its edges are derived
    /// from the triangles.
    ///
    /// # Errors
    /// Any violated invariant of [`Mesh`], naming the vertex or element.
    pub fn from_triangles(
        vertices: Vec<Point>,
        triangles: Vec<[usize; 3]>,
    ) -> Result<Self, MeshError> {
        Self::new(vertices, Vec::new(), triangles, None)
    }

    /// Builds an edge graph (a spring network). Duplicate edges are merged.
    ///
    /// # Errors
    /// Any violated invariant of [`Mesh`], naming the vertex or edge.
    pub fn from_edges(vertices: Vec<Point>, edges: Vec<[usize; 2]>) -> Result<Self, MeshError> {
        Self::new(vertices, Vec::new(), Vec::new(), Some(edges))
    }

    /// Builds a mesh from any mix of elements. With `edges = None` the edges
    /// are derived from the tetrahedra and triangles.
    ///
    /// # Errors
    /// Any violated invariant of [`Mesh`], naming the vertex or element.
    pub fn new(
        vertices: Vec<Point>,
        tets: Vec<[usize; 4]>,
        triangles: Vec<[usize; 3]>,
        edges: Option<Vec<[usize; 2]>>,
    ) -> Result<Self, MeshError> {
        if let Some(vertex) = vertices
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(MeshError::NonFiniteVertex { vertex });
        }
        let n = vertices.len();
        check_elements(ElementKind::Tet, &tets, n)?;
        check_elements(ElementKind::Triangle, &triangles, n)?;
        for (element, t) in tets.iter().enumerate() {
            let volume = signed_volume(&vertices, t);
            // Relative threshold: a tet whose volume is at round-off level
            // compared with its edge lengths cubed is degenerate.
            let scale = max_edge_length(&vertices, t).powi(3);
            if !(volume.is_finite() && scale.is_finite()) {
                let kind = ElementKind::Tet;
                return Err(MeshError::SizeOverflow { kind, element });
            }
            if !(volume > 1e-12 * scale) {
                return Err(MeshError::NonPositiveVolume { element, volume });
            }
        }
        for (element, t) in triangles.iter().enumerate() {
            let area = triangle_area(&vertices, t);
            let scale = max_edge_length(&vertices, t).powi(2);
            if !(area.is_finite() && scale.is_finite()) {
                let kind = ElementKind::Triangle;
                return Err(MeshError::SizeOverflow { kind, element });
            }
            if !(area > 1e-12 * scale) {
                return Err(MeshError::ZeroArea { element });
            }
        }
        let edges = match edges {
            Some(edges) => {
                check_elements(ElementKind::Edge, &edges, n)?;
                unique_edges(edges.iter().copied())
            }
            None => unique_edges(
                tets.iter()
                    .flat_map(|t| {
                        [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]].map(|[a, b]| [t[a], t[b]])
                    })
                    .chain(
                        triangles
                            .iter()
                            .flat_map(|t| [[0, 1], [1, 2], [2, 0]].map(|[a, b]| [t[a], t[b]])),
                    ),
            ),
        };
        Ok(Self {
            vertices,
            tets,
            triangles,
            edges,
        })
    }

    /// Rest positions of the vertices, in metres.
    pub fn vertices(&self) -> &[Point] {
        &self.vertices
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Tetrahedra, positively oriented.
    pub fn tets(&self) -> &[[usize; 4]] {
        &self.tets
    }

    /// Triangles.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// Unique edges, each stored as `[low, high]`, sorted.
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    /// Number of volume or surface elements (tetrahedra, else triangles,
    /// else edges): what a user calls "the elements" of this mesh.
    pub fn num_elements(&self) -> usize {
        if !self.tets.is_empty() {
            self.tets.len()
        } else if !self.triangles.is_empty() {
            self.triangles.len()
        } else {
            self.edges.len()
        }
    }

    /// Rest volume of every tetrahedron, in m^3 (all positive by construction).
    pub fn tet_volumes(&self) -> Vec<f64> {
        self.tets
            .iter()
            .map(|t| signed_volume(&self.vertices, t))
            .collect()
    }

    /// Rest area of every triangle, in m^2.
    pub fn triangle_areas(&self) -> Vec<f64> {
        self.triangles
            .iter()
            .map(|t| triangle_area(&self.vertices, t))
            .collect()
    }

    /// Axis-aligned bounding box `(min, max)`; `None` for a mesh without
    /// vertices.
    pub fn bounding_box(&self) -> Option<(Point, Point)> {
        let first = *self.vertices.first()?;
        Some(
            self.vertices
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }

    /// Lumped vertex masses from a density, in kg.
    ///
    /// The density's unit follows the mesh's highest-dimensional elements:
    /// kg/m^3 for tetrahedra (each tet gives `rho V / 4` to each vertex),
    /// kg/m^2 for triangles (`rho A / 3`), kg/m for edges (`rho l / 2`).
    /// A vertex that no element touches gets no mass.
    ///
    /// # Errors
    /// [`MeshError::InvalidDensity`] unless `density` is finite and positive.
    pub fn lumped_masses(&self, density: f64) -> Result<Vec<f64>, MeshError> {
        if !(density.is_finite() && density > 0.0) {
            return Err(MeshError::InvalidDensity { density });
        }
        let mut masses = vec![0.0; self.vertices.len()];
        if !self.tets.is_empty() {
            for t in &self.tets {
                let share = density * signed_volume(&self.vertices, t) / 4.0;
                t.iter().for_each(|&v| masses[v] += share);
            }
        } else if !self.triangles.is_empty() {
            for t in &self.triangles {
                let share = density * triangle_area(&self.vertices, t) / 3.0;
                t.iter().for_each(|&v| masses[v] += share);
            }
        } else {
            for e in &self.edges {
                let share = density * (self.vertices[e[1]] - self.vertices[e[0]]).norm() / 2.0;
                e.iter().for_each(|&v| masses[v] += share);
            }
        }
        Ok(masses)
    }

    /// Returns a copy of this mesh with its vertices moved by `offset`.
    pub fn translated(&self, offset: Point) -> Self {
        let mut moved = self.clone();
        moved.vertices.iter_mut().for_each(|p| *p += offset);
        moved
    }
}

fn check_elements<const K: usize>(
    kind: ElementKind,
    elements: &[[usize; K]],
    num_vertices: usize,
) -> Result<(), MeshError> {
    for (element, e) in elements.iter().enumerate() {
        if let Some(&index) = e.iter().find(|&&i| i >= num_vertices) {
            return Err(MeshError::IndexOutOfRange {
                kind,
                element,
                index,
                num_vertices,
            });
        }
        for a in 0..K {
            for b in a + 1..K {
                if e[a] == e[b] {
                    return Err(MeshError::RepeatedVertex {
                        kind,
                        element,
                        vertex: e[a],
                    });
                }
            }
        }
    }
    Ok(())
}

fn unique_edges(edges: impl Iterator<Item = [usize; 2]>) -> Vec<[usize; 2]> {
    let mut edges: Vec<[usize; 2]> = edges.map(|[a, b]| [a.min(b), a.max(b)]).collect();
    edges.sort_unstable();
    edges.dedup();
    // A tet mesh lists each edge some five times over before the dedup:
    // keep only what is left (10 MB of 12 for a 100k-tet beam; the mesh
    // lives as long as its simulation).
    edges.shrink_to_fit();
    edges
}

/// Signed volume of the tetrahedron `t` of `vertices`: positive when its
/// corners are ordered so that `(x1 - x0) . ((x2 - x0) x (x3 - x0)) > 0`.
///
/// ```
/// use pd_mesh::{Point, tet_volume};
///
/// let corners = [Point::zeros(), Point::x(), Point::y(), Point::z()];
/// assert_eq!(tet_volume(&corners, &[0, 1, 2, 3]).unwrap(), 1.0 / 6.0);
/// assert!(tet_volume(&corners, &[0, 1, 2, 4]).is_err());
/// ```
///
/// # Errors
/// [`MeshError::CornerOutOfRange`] if a corner is not an index of
/// `vertices`.
pub fn tet_volume(vertices: &[Point], t: &[usize; 4]) -> Result<f64, MeshError> {
    check_corners(vertices, t)?;
    Ok(signed_volume(vertices, t))
}

/// [`MeshError::CornerOutOfRange`] for the first corner of `t` that is not
/// an index of `vertices`.
fn check_corners(vertices: &[Point], t: &[usize; 4]) -> Result<(), MeshError> {
    match t.iter().position(|&i| i >= vertices.len()) {
        Some(corner) => Err(MeshError::CornerOutOfRange {
            corner,
            index: t[corner],
            num_vertices: vertices.len(),
        }),
        None => Ok(()),
    }
}

/// [`tet_volume`] of corners known to be in range (a validated mesh's).
fn signed_volume(vertices: &[Point], t: &[usize; 4]) -> f64 {
    let [a, b, c, d] = t.map(|i| vertices[i]);
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

fn triangle_area(vertices: &[Point], t: &[usize; 3]) -> f64 {
    let [a, b, c] = t.map(|i| vertices[i]);
    (b - a).cross(&(c - a)).norm() / 2.0
}

fn max_edge_length<const K: usize>(vertices: &[Point], e: &[usize; K]) -> f64 {
    let mut longest: f64 = 0.0;
    for a in 0..K {
        for b in a + 1..K {
            longest = longest.max((vertices[e[a]] - vertices[e[b]]).norm());
        }
    }
    longest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lone_tetrahedron_with_a_corner_out_of_range_is_an_error_not_a_panic() {
        let corners = unit_tet();
        for (t, corner, index) in [([4, 1, 2, 3], 0, 4), ([0, 1, 2, usize::MAX], 3, usize::MAX)] {
            let expected = MeshError::CornerOutOfRange {
                corner,
                index,
                num_vertices: 4,
            };
            assert_eq!(tet_volume(&corners, &t), Err(expected.clone()));
            assert_eq!(
                crate::generators::tet_quality(&corners, &t),
                Err(expected.clone())
            );
            let shown = expected.to_string();
            assert!(shown.contains(&format!("vertex {index}")), "{shown}");
        }
        assert_eq!(
            tet_volume(&[], &[0, 0, 0, 0]).unwrap_err().to_string(),
            "tetrahedron corner 0 is vertex 0, but there are 0 vertices"
        );
        // A regular tetrahedron's quality is 1 (the measure's definition).
        let s = 1.0 / 2.0_f64.sqrt();
        let regular = [
            Point::new(1.0, 0.0, -s),
            Point::new(-1.0, 0.0, -s),
            Point::new(0.0, 1.0, s),
            Point::new(0.0, -1.0, s),
        ];
        let q = crate::generators::tet_quality(&regular, &[0, 1, 2, 3]).unwrap();
        assert!((q.abs() - 1.0).abs() < 1e-12, "{q}");
    }

    fn unit_tet() -> Vec<Point> {
        vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
        ]
    }

    #[test]
    fn inverted_tet_is_rejected_with_its_index() {
        let err = Mesh::from_tets(unit_tet(), vec![[0, 1, 2, 3], [0, 2, 1, 3]]).unwrap_err();
        assert!(
            matches!(err, MeshError::NonPositiveVolume { element: 1, .. }),
            "{err}"
        );
    }

    #[test]
    fn elements_whose_size_overflows_say_so() {
        // Edge lengths of 1e120 m: the volume (order 1e360) overflows; a
        // triangle of 1e160 m edges has an area of order 1e320.
        let huge: Vec<Point> = unit_tet().iter().map(|p| p * 1e120).collect();
        let err = Mesh::from_tets(huge, vec![[0, 1, 2, 3]]).unwrap_err();
        assert!(
            matches!(err, MeshError::SizeOverflow { element: 0, .. }),
            "{err}"
        );
        let huge: Vec<Point> = unit_tet()[..3].iter().map(|p| p * 1e160).collect();
        let err = Mesh::from_triangles(huge, vec![[0, 1, 2]]).unwrap_err();
        assert!(
            err.to_string().starts_with("triangle 0 is too large"),
            "{err}"
        );
        // At 1e100 m a tetrahedron still fits (volume 1e300).
        let large: Vec<Point> = unit_tet().iter().map(|p| p * 1e100).collect();
        assert!(Mesh::from_tets(large, vec![[0, 1, 2, 3]]).is_ok());
    }

    #[test]
    fn flat_tet_is_rejected() {
        let mut v = unit_tet();
        v[3] = Point::new(0.3, 0.3, 0.0);
        let err = Mesh::from_tets(v, vec![[0, 1, 2, 3]]).unwrap_err();
        assert!(matches!(
            err,
            MeshError::NonPositiveVolume { element: 0, .. }
        ));
        assert!(err.to_string().contains("tetrahedron 0"), "{err}");
    }

    #[test]
    fn out_of_range_and_repeated_indices_are_rejected() {
        let err = Mesh::from_tets(unit_tet(), vec![[0, 1, 2, 4]]).unwrap_err();
        assert!(matches!(err, MeshError::IndexOutOfRange { index: 4, .. }));
        let err = Mesh::from_edges(unit_tet(), vec![[1, 1]]).unwrap_err();
        assert!(matches!(err, MeshError::RepeatedVertex { vertex: 1, .. }));
    }

    #[test]
    fn nan_vertex_is_rejected() {
        let mut v = unit_tet();
        v[2].y = f64::NAN;
        let err = Mesh::from_tets(v, vec![[0, 1, 2, 3]]).unwrap_err();
        assert!(matches!(err, MeshError::NonFiniteVertex { vertex: 2 }));
    }

    #[test]
    fn lumped_mass_sums_to_density_times_measure() {
        let mesh = Mesh::from_tets(unit_tet(), vec![[0, 1, 2, 3]]).unwrap();
        let masses = mesh.lumped_masses(600.0).unwrap();
        // Total mass = rho V = 600 / 6 exactly, split equally.
        assert!(masses.iter().all(|&m| (m - 25.0).abs() < 1e-12));
        assert!(mesh.lumped_masses(-1.0).is_err());
        assert!(mesh.lumped_masses(f64::NAN).is_err());
    }

    #[test]
    fn edge_masses_use_length() {
        let v = vec![
            Point::zeros(),
            Point::new(2.0, 0.0, 0.0),
            Point::new(2.0, 1.0, 0.0),
        ];
        let mesh = Mesh::from_edges(v, vec![[0, 1], [2, 1], [1, 0]]).unwrap();
        assert_eq!(mesh.edges(), &[[0, 1], [1, 2]]);
        let m = mesh.lumped_masses(3.0).unwrap();
        assert_eq!(m, vec![3.0, 4.5, 1.5]);
    }
}
