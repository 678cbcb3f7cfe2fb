//! Generators for the meshes that tests, benchmarks and demo scenes need: a
//! box of tetrahedra, a ball of tetrahedra, a chain of springs and a sheet
//! of cloth.
//!
//! All lengths are in metres. Every generator validates its parameters and
//! returns [`MeshError::InvalidParameter`] instead of panicking; meshes with
//! more than 2^31 vertices or elements are refused, and the sizes are
//! computed with checked arithmetic so that absurd cell counts cannot
//! overflow.
//!
//! ```
//! use pd_mesh::generators;
//!
//! let rope = generators::chain(11, 2.0).unwrap();
//! assert_eq!(rope.edges().len(), 10);
//!
//! let sheet = generators::cloth([1.0, 1.0], [4, 4]).unwrap();
//! assert_eq!(sheet.num_vertices(), 25);
//! assert_eq!(sheet.triangles().len(), 32);
//! ```

use crate::{Mesh, MeshError, Point};

mod ball;
pub use ball::{ball, tet_quality};

/// Largest number of vertices or elements a generator will produce.
const MAX_COUNT: usize = 1 << 31;

/// The Kuhn (Freudenthal) split of the unit cube into 6 tetrahedra, as corner
/// offsets. Each tetrahedron follows one monotone path from corner (0,0,0) to
/// corner (1,1,1), one axis step at a time, so all six share that main
/// diagonal. Paths along an odd permutation of the axes have their two middle
/// vertices swapped, which makes every volume positive. Since every cube is
/// split the same way, the diagonals of neighbouring cubes' shared faces
/// coincide and the mesh is conforming.
const KUHN_TETS: [[[usize; 3]; 4]; 6] = [
    // Even permutations: x y z, y z x, z x y.
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]],
    [[0, 0, 0], [0, 1, 0], [0, 1, 1], [1, 1, 1]],
    [[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1]],
    // Odd permutations: x z y, z y x, y x z, middle vertices swapped.
    [[0, 0, 0], [1, 0, 1], [1, 0, 0], [1, 1, 1]],
    [[0, 0, 0], [0, 1, 1], [0, 0, 1], [1, 1, 1]],
    [[0, 0, 0], [1, 1, 0], [0, 1, 0], [1, 1, 1]],
];

/// A conforming tetrahedral mesh of the box `[0, sx] x [0, sy] x [0, sz]`,
/// where `size = [sx, sy, sz]` is in metres.
///
/// The box is divided into `cells = [nx, ny, nz]` equal cuboids, each split
/// into 6 positively oriented tetrahedra around its main diagonal (the Kuhn
/// split), so the mesh has `(nx+1)(ny+1)(nz+1)` vertices and `6 nx ny nz`
/// tetrahedra. Vertex `(i, j, k)` has index `i + (nx+1) (j + (ny+1) k)` and
/// position `(i sx/nx, j sy/ny, k sz/nz)`.
///
/// ```
/// let cube = pd_mesh::generators::box_tets([1.0, 1.0, 1.0], [1, 1, 1]).unwrap();
/// assert_eq!(cube.tets().len(), 6);
/// assert_eq!(cube.surface_triangles().len(), 12);
/// ```
///
/// # Errors
/// [`MeshError::InvalidParameter`] named `cells` if a cell count is 0 or the
/// mesh would have more than 2^31 vertices or tetrahedra, named `size` if a
/// side length is not finite and positive.
pub fn box_tets(size: [f64; 3], cells: [usize; 3]) -> Result<Mesh, MeshError> {
    check_cells(&cells)?;
    check_size(&size)?;
    let [nx, ny, nz] = cells;
    let num_vertices = checked_count(&grid_lines(cells), "vertices")?;
    let num_tets = checked_count(&[nx, ny, nz, KUHN_TETS.len()], "tetrahedra")?;

    let index = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut vertices = Vec::with_capacity(num_vertices);
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                vertices.push(Point::new(
                    grid_coordinate(i, nx, size[0]),
                    grid_coordinate(j, ny, size[1]),
                    grid_coordinate(k, nz, size[2]),
                ));
            }
        }
    }
    let mut tets = Vec::with_capacity(num_tets);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                tets.extend(
                    KUHN_TETS.map(|tet| tet.map(|[di, dj, dk]| index(i + di, j + dj, k + dk))),
                );
            }
        }
    }
    Mesh::from_tets(vertices, tets)
}

/// A chain of `points` vertices evenly spaced along the x axis from the
/// origin to `(length, 0, 0)`, with an edge between each consecutive pair:
/// a rope or a hair of `points - 1` springs. `length` is in metres.
///
/// ```
/// let rope = pd_mesh::generators::chain(3, 1.0).unwrap();
/// assert_eq!(rope.edges(), &[[0, 1], [1, 2]]);
/// assert_eq!(rope.vertices()[1].x, 0.5);
/// ```
///
/// # Errors
/// [`MeshError::InvalidParameter`] named `points` if `points < 2` or
/// `points > 2^31`, named `length` unless `length` is finite and positive.
pub fn chain(points: usize, length: f64) -> Result<Mesh, MeshError> {
    if !(2..=MAX_COUNT).contains(&points) {
        return Err(MeshError::InvalidParameter {
            name: "points",
            reason: format!("a chain needs between 2 and 2^31 points, got {points}"),
        });
    }
    if !(length.is_finite() && length > 0.0) {
        return Err(MeshError::InvalidParameter {
            name: "length",
            reason: format!("must be finite and > 0 m, got {length}"),
        });
    }
    let segments = points - 1;
    let vertices = (0..points)
        .map(|i| Point::new(grid_coordinate(i, segments, length), 0.0, 0.0))
        .collect();
    let edges = (0..segments).map(|i| [i, i + 1]).collect();
    Mesh::from_edges(vertices, edges)
}

/// A sheet of cloth: a triangle grid in the x-z plane at `y = 0` covering
/// `[0, sx] x [0, sz]`, where `size = [sx, sz]` is in metres.
///
/// The sheet is divided into `cells = [nx, nz]` equal rectangles, each split
/// into 2 triangles along the diagonal from grid point `(i, k)` to
/// `(i+1, k+1)`, so the mesh has `(nx+1)(nz+1)` vertices and `2 nx nz`
/// triangles, all with normal `(b - a) x (c - a)` along `+y`. Vertex `(i, k)`
/// has index `i + (nx+1) k` and position `(i sx/nx, 0, k sz/nz)`. The edges,
/// diagonals included, are derived from the triangles.
///
/// ```
/// let sheet = pd_mesh::generators::cloth([2.0, 1.0], [2, 1]).unwrap();
/// assert_eq!(sheet.num_vertices(), 6);
/// // 7 grid lines plus one diagonal per cell.
/// assert_eq!(sheet.edges().len(), 9);
/// ```
///
/// # Errors
/// [`MeshError::InvalidParameter`] named `cells` if a cell count is 0 or the
/// mesh would have more than 2^31 vertices or triangles, named `size` if a
/// side length is not finite and positive.
pub fn cloth(size: [f64; 2], cells: [usize; 2]) -> Result<Mesh, MeshError> {
    check_cells(&cells)?;
    check_size(&size)?;
    let [nx, nz] = cells;
    let num_vertices = checked_count(&grid_lines(cells), "vertices")?;
    let num_triangles = checked_count(&[nx, nz, 2], "triangles")?;

    let index = |i: usize, k: usize| i + (nx + 1) * k;
    let mut vertices = Vec::with_capacity(num_vertices);
    for k in 0..=nz {
        for i in 0..=nx {
            vertices.push(Point::new(
                grid_coordinate(i, nx, size[0]),
                0.0,
                grid_coordinate(k, nz, size[1]),
            ));
        }
    }
    let mut triangles = Vec::with_capacity(num_triangles);
    for k in 0..nz {
        for i in 0..nx {
            let corner = index(i, k);
            let across_x = index(i + 1, k);
            let across_z = index(i, k + 1);
            let opposite = index(i + 1, k + 1);
            // Both ordered so that (b - a) x (c - a) points along +y.
            triangles.push([corner, across_z, opposite]);
            triangles.push([corner, opposite, across_x]);
        }
    }
    Mesh::from_triangles(vertices, triangles)
}

/// Coordinate `i side / n` of grid line `i` of `n` equal intervals over
/// `[0, side]`; computed as `(i / n) side` because that lands exactly on
/// `side` for `i = n`, whereas `(i side) / n` may be off by an ulp.
fn grid_coordinate(i: usize, n: usize, side: f64) -> f64 {
    i as f64 / n as f64 * side
}

fn check_cells(cells: &[usize]) -> Result<(), MeshError> {
    if cells.contains(&0) {
        return Err(MeshError::InvalidParameter {
            name: "cells",
            reason: format!("every cell count must be >= 1, got {cells:?}"),
        });
    }
    Ok(())
}

fn check_size(size: &[f64]) -> Result<(), MeshError> {
    if !size.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(MeshError::InvalidParameter {
            name: "size",
            reason: format!("every side length must be finite and > 0 m, got {size:?}"),
        });
    }
    Ok(())
}

/// Number of grid lines (vertices) along each axis: one more than the cells.
/// Saturates instead of overflowing; a saturated count is far above
/// [`MAX_COUNT`] and is refused by [`checked_count`].
fn grid_lines<const D: usize>(cells: [usize; D]) -> [usize; D] {
    cells.map(|n| n.saturating_add(1))
}

/// The product of `factors`, or an error naming `what` if it exceeds
/// [`MAX_COUNT`] (or overflows `usize`).
fn checked_count(factors: &[usize], what: &'static str) -> Result<usize, MeshError> {
    factors
        .iter()
        .try_fold(1usize, |product, &factor| product.checked_mul(factor))
        .filter(|&count| count <= MAX_COUNT)
        .ok_or_else(|| MeshError::InvalidParameter {
            name: "cells",
            reason: format!("the mesh would have more than 2^31 {what}"),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tet_volume;

    #[test]
    fn kuhn_split_fills_the_unit_cube_with_positive_tets() {
        let corners: Vec<Point> = (0..8)
            .map(|c| Point::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64))
            .collect();
        let tets: Vec<[usize; 4]> = KUHN_TETS
            .iter()
            .map(|tet| tet.map(|[i, j, k]| i + 2 * j + 4 * k))
            .collect();
        for tet in &tets {
            // Each Kuhn tet has volume exactly 1/6: the determinant of three
            // integer vectors, divided by 6, is exact in floating point
            // up to the final division.
            assert_eq!(tet_volume(&corners, tet), Ok(1.0 / 6.0), "{tet:?}");
        }
    }

    #[test]
    fn last_grid_line_is_exactly_on_the_side() {
        // 3 * 0.7 / 3 rounds to 0.6999999999999998.
        assert_eq!(grid_coordinate(3, 3, 0.7), 0.7);
        assert_eq!(grid_coordinate(7, 7, 0.3), 0.3);
        assert_eq!(grid_coordinate(0, 7, 0.3), 0.0);
    }

    #[test]
    fn overflowing_cell_counts_are_refused_without_panicking() {
        let huge = usize::MAX;
        for cells in [
            [huge, 1, 1],
            [huge, huge, huge],
            [1 << 11, 1 << 11, 1 << 11],
        ] {
            let err = box_tets([1.0; 3], cells).unwrap_err();
            assert!(
                matches!(err, MeshError::InvalidParameter { name: "cells", .. }),
                "{err}"
            );
        }
        let err = cloth([1.0; 2], [huge, huge]).unwrap_err();
        assert!(
            matches!(err, MeshError::InvalidParameter { name: "cells", .. }),
            "{err}"
        );
    }

    #[test]
    fn tet_count_limit_is_checked_separately_from_vertex_count() {
        // A column of 2^29 - 1 cubes has exactly 2^31 vertices (the limit)
        // but 6 (2^29 - 1) > 2^31 tetrahedra.
        let err = box_tets([1.0; 3], [(1 << 29) - 1, 1, 1]).unwrap_err();
        assert!(err.to_string().contains("tetrahedra"), "{err}");
    }
}
