//! [`VertexSelection`]: which vertices a boundary condition, an attachment or
//! an external force applies to, chosen by index or by region.

use crate::{Mesh, MeshError};

/// A set of vertices of a mesh, described independently of the mesh and
/// resolved against its rest positions with [`VertexSelection::resolve`].
///
/// ```
/// use pd_mesh::{generators, VertexSelection};
///
/// // 5 vertices at x = 0, 0.25, ..., 1 m.
/// let rope = generators::chain(5, 1.0).unwrap();
///
/// let ends = VertexSelection::Indices(vec![4, 0, 4]);
/// assert_eq!(ends.resolve(&rope).unwrap(), vec![0, 4]);
///
/// let first_half = VertexSelection::Box { min: [0.0, 0.0, 0.0], max: [0.5, 0.0, 0.0] };
/// assert_eq!(first_half.resolve(&rope).unwrap(), vec![0, 1, 2]);
///
/// assert!(VertexSelection::Indices(vec![5]).resolve(&rope).is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum VertexSelection {
    /// Explicit vertex indices, in any order, repeats allowed.
    Indices(Vec<usize>),
    /// Every vertex whose rest position lies in an axis-aligned box, bounds
    /// included.
    Box {
        /// Lower corner of the box, in metres.
        min: [f64; 3],
        /// Upper corner of the box, in metres.
        max: [f64; 3],
    },
}

impl VertexSelection {
    /// The selected vertices of `mesh`, sorted and without repeats. A
    /// selection that matches no vertex gives an empty list, not an error.
    ///
    /// Costs one pass over the indices (plus a sort) or over the vertices.
    ///
    /// # Errors
    /// [`MeshError::InvalidParameter`] named `vertices` if an index is out of
    /// range (naming the first such index), named `box` if a bound is not
    /// finite or `min > max` on some axis.
    pub fn resolve(&self, mesh: &Mesh) -> Result<Vec<usize>, MeshError> {
        match self {
            VertexSelection::Indices(indices) => {
                let num_vertices = mesh.num_vertices();
                if let Some(&index) = indices.iter().find(|&&i| i >= num_vertices) {
                    return Err(MeshError::InvalidParameter {
                        name: "vertices",
                        reason: format!(
                            "vertex {index} is out of range: the mesh has {num_vertices} vertices"
                        ),
                    });
                }
                let mut selected = indices.clone();
                selected.sort_unstable();
                selected.dedup();
                Ok(selected)
            }
            VertexSelection::Box { min, max } => {
                let bounds_are_valid = (0..3).all(|axis| {
                    min[axis].is_finite() && max[axis].is_finite() && min[axis] <= max[axis]
                });
                if !bounds_are_valid {
                    return Err(MeshError::InvalidParameter {
                        name: "box",
                        reason: format!(
                            "bounds must be finite with min <= max on every axis, got min {min:?}, max {max:?}"
                        ),
                    });
                }
                Ok(mesh
                    .vertices()
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| {
                        (0..3).all(|axis| min[axis] <= p[axis] && p[axis] <= max[axis])
                    })
                    .map(|(vertex, _)| vertex)
                    .collect())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generators;

    fn block() -> Mesh {
        // 3 x 2 x 2 grid points at x in {0, 0.5, 1}, y and z in {0, 1}.
        generators::box_tets([1.0, 1.0, 1.0], [2, 1, 1]).unwrap()
    }

    #[test]
    fn indices_are_sorted_and_deduplicated() {
        let selection = VertexSelection::Indices(vec![5, 1, 5, 0, 1]);
        assert_eq!(selection.resolve(&block()).unwrap(), vec![0, 1, 5]);
        assert_eq!(
            VertexSelection::Indices(vec![]).resolve(&block()).unwrap(),
            Vec::<usize>::new()
        );
    }

    #[test]
    fn out_of_range_index_is_named() {
        let mesh = generators::chain(10, 1.0).unwrap();
        let err = VertexSelection::Indices(vec![3, 12, 20])
            .resolve(&mesh)
            .unwrap_err();
        assert_eq!(
            err,
            MeshError::InvalidParameter {
                name: "vertices",
                reason: "vertex 12 is out of range: the mesh has 10 vertices".to_owned(),
            }
        );
    }

    #[test]
    fn box_bounds_are_inclusive() {
        // The plane x = 0.5 exactly: a degenerate box selects the vertices on it.
        let middle = VertexSelection::Box {
            min: [0.5, 0.0, 0.0],
            max: [0.5, 1.0, 1.0],
        };
        assert_eq!(middle.resolve(&block()).unwrap(), vec![1, 4, 7, 10]);
        let everything = VertexSelection::Box {
            min: [0.0; 3],
            max: [1.0; 3],
        };
        assert_eq!(
            everything.resolve(&block()).unwrap(),
            (0..12).collect::<Vec<_>>()
        );
    }

    #[test]
    fn box_missing_the_mesh_selects_nothing() {
        let outside = VertexSelection::Box {
            min: [2.0; 3],
            max: [3.0; 3],
        };
        assert!(outside.resolve(&block()).unwrap().is_empty());
    }

    #[test]
    fn invalid_box_is_rejected() {
        for (min, max) in [
            ([0.0, 1.0, 0.0], [1.0, 0.0, 1.0]),
            ([f64::NAN, 0.0, 0.0], [1.0; 3]),
            ([0.0; 3], [1.0, f64::INFINITY, 1.0]),
        ] {
            let err = VertexSelection::Box { min, max }
                .resolve(&block())
                .unwrap_err();
            assert!(
                matches!(err, MeshError::InvalidParameter { name: "box", .. }),
                "{err}"
            );
        }
    }
}
