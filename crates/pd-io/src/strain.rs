//! Per-element strain measures for frame files: computed from the rest
//! shape and the current positions alone, so the writers need nothing from
//! the solver's constraints.
//!
//! - **Tetrahedra**: the Frobenius norm of the Green-Lagrange strain
//!   `E = (F^T F - I) / 2`, with the deformation gradient
//!   `F = D_s D_m^{-1}`, where `D_m` and `D_s` hold the edge vectors
//!   `x1 - x0, x2 - x0, x3 - x0` at rest and now. `||E||_F` is zero exactly
//!   for rigid motions (it does not see rotation) and is, for small strains,
//!   the norm of the small-strain tensor.
//! - **Triangles**: the same, in 2D: `F` is the 3x2 map from an orthonormal
//!   frame of the rest triangle's plane to the current edge vectors, and
//!   `E = (F^T F - I) / 2` is 2x2.
//! - **Edges (springs)**: the relative elongation `|x_a - x_b| / L - 1`
//!   (signed: negative in compression), `L` the rest length.
//!
//! All are dimensionless.

use nalgebra::{Matrix2, Matrix3, Matrix3x2};
use pd_mesh::Point;

use crate::frames::Cells;

/// The rest shape of a frame's cells, prepared to measure their strain.
#[derive(Debug, Clone, Default)]
pub struct StrainMeasure {
    tets: Vec<([usize; 4], Matrix3<f64>)>,
    triangles: Vec<([usize; 3], Matrix2<f64>)>,
    lines: Vec<([usize; 2], f64)>,
}

impl StrainMeasure {
    /// Prepares the measure for `cells` with rest positions `rest`.
    /// A degenerate rest element (which a validated mesh never has) gets a
    /// NaN strain, which the writers reject, naming the frame file.
    ///
    /// # Panics
    /// If a cell refers to a vertex beyond `rest` (a programming error: the
    /// recorder builds both from the same model).
    pub fn new(rest: &[Point], cells: &Cells<'_>) -> Self {
        let nan3 = Matrix3::from_element(f64::NAN);
        let tets = cells
            .tets
            .iter()
            .map(|&t| {
                let dm = edge_matrix(rest, t);
                (t, dm.try_inverse().unwrap_or(nan3))
            })
            .collect();
        let triangles = cells
            .triangles
            .iter()
            .map(|&t| {
                let (d1, d2) = (rest[t[1]] - rest[t[0]], rest[t[2]] - rest[t[0]]);
                let e1 = d1.normalize();
                let e2 = (d2 - e1 * e1.dot(&d2)).normalize();
                let dm = Matrix2::new(e1.dot(&d1), e1.dot(&d2), e2.dot(&d1), e2.dot(&d2));
                (
                    t,
                    dm.try_inverse().unwrap_or(Matrix2::from_element(f64::NAN)),
                )
            })
            .collect();
        let lines = cells
            .lines
            .iter()
            .map(|&[a, b]| ([a, b], (rest[a] - rest[b]).norm()))
            .collect();
        Self {
            tets,
            triangles,
            lines,
        }
    }

    /// Number of cells: tetrahedra, then triangles, then lines.
    pub fn len(&self) -> usize {
        self.tets.len() + self.triangles.len() + self.lines.len()
    }

    /// Whether there are no cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The strain of every cell at `positions`, in the order tetrahedra,
    /// triangles, lines (the order of the cells in a VTU frame), written
    /// into `out` (cleared first).
    ///
    /// # Panics
    /// If `positions` is shorter than the rest shape.
    pub fn measure_into(&self, positions: &[Point], out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.tets.iter().map(|(t, dm_inv)| {
            let f = edge_matrix(positions, *t) * dm_inv;
            // nalgebra's matrix norm is the Frobenius norm.
            0.5 * (f.transpose() * f - Matrix3::identity()).norm()
        }));
        out.extend(self.triangles.iter().map(|(t, dm_inv)| {
            let (x0, x1, x2) = (positions[t[0]], positions[t[1]], positions[t[2]]);
            let ds = Matrix3x2::from_columns(&[x1 - x0, x2 - x0]);
            let f = ds * dm_inv;
            0.5 * (f.transpose() * f - Matrix2::identity()).norm()
        }));
        out.extend(
            self.lines
                .iter()
                .map(|([a, b], rest)| (positions[*a] - positions[*b]).norm() / rest - 1.0),
        );
    }
}

fn edge_matrix(x: &[Point], t: [usize; 4]) -> Matrix3<f64> {
    Matrix3::from_columns(&[x[t[1]] - x[t[0]], x[t[2]] - x[t[0]], x[t[3]] - x[t[0]]])
}
