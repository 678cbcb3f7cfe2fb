//! Triangle area preservation: `w/2 |F - P(F)|^2` with `P(F)` the closest
//! 3 x 2 matrix whose singular values multiply to 1 (`docs/design/constraints.md`,
//! "Area and volume").

use nalgebra::{Matrix2, Vector2};
use pd_mesh::Point;

use crate::tet_strain::{check_stiffness, check_vertices};
use crate::triangle_frame::{
    IsotropicProjection, gradient_of, isotropic_hessian, rest_frame, thin_svd,
};
use crate::{Constraint, ConstraintError, unit_product};

/// An area-preservation constraint on a triangle.
///
/// Same operator as [`crate::TriangleStrain`] (the rows of `G x` are the
/// columns of the 3 x 2 gradient `F = U diag(s) V^T`); the projection is
/// `U diag(c) V^T` with `c` the closest point to `s` on `c_0 c_1 = 1`. The
/// weight is `stiffness * rest area`, `stiffness` in N/m: for small strains
/// the energy per unit rest area is `stiffness/4 (dA/A)^2`. Rotations,
/// shears and area-preserving stretches cost nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    vertices: [usize; 3],
    weight: f64,
    operator: [[f64; 3]; 2],
}

impl Area {
    /// Builds the constraint of `triangle` from rest positions; `stiffness`
    /// in N/m.
    ///
    /// # Errors
    /// A zero-area rest triangle, or a negative or non-finite stiffness.
    pub fn new(
        rest: &[Point],
        triangle: [usize; 3],
        stiffness: f64,
    ) -> Result<Self, ConstraintError> {
        check_vertices(rest, &triangle)?;
        check_stiffness(stiffness)?;
        let (operator, area) = rest_frame(rest, triangle)?;
        Ok(Self {
            vertices: triangle,
            weight: stiffness * area,
            operator,
        })
    }
}

impl Constraint for Area {
    const STENCIL: usize = 3;
    const ROWS: usize = 2;
    const TRANSLATION_INVARIANT: bool = true;
    const KIND: &'static str = "area";

    type Vertices<'a> = &'a [usize];

    fn vertices(&self) -> &[usize] {
        &self.vertices
    }

    fn weight(&self) -> f64 {
        self.weight
    }

    fn operator(&self, row: usize, column: usize) -> f64 {
        self.operator[row][column]
    }

    fn project(&self, gx: &[Point], out: &mut [Point]) {
        let svd = thin_svd(&gradient_of(gx));
        let (c, _) = unit_product::project(&[svd.s[0], svd.s[1]]);
        let target = svd.u * Matrix2::from_diagonal(&Vector2::new(c[0], c[1])) * svd.v.transpose();
        out[0] = target.column(0).into_owned();
        out[1] = target.column(1).into_owned();
    }

    fn gx_hessian(&self, gx: &[Point], project_psd: bool, out: &mut [f64]) {
        let svd = thin_svd(&gradient_of(gx));
        let (c, j) = unit_product::project(&[svd.s[0], svd.s[1]]);
        let mut jacobian = Matrix2::new(j[0][0], j[0][1], j[1][0], j[1][1]);
        if project_psd && !jacobian.iter().all(|x| x.is_finite()) {
            // Off the main branch: treat the projection as locally frozen
            // (Hessian w on the scaling pair), PSD and bounded.
            jacobian = Matrix2::zeros();
        }
        // Flip eigenvalue where s_0 = s_1: the Jacobian along (1, -1)/sqrt 2.
        let flip_at_equal = 0.5 * (j[0][0] + j[1][1] - j[0][1] - j[1][0]);
        let projection = IsotropicProjection {
            c: Vector2::new(c[0], c[1]),
            jacobian,
            flip_at_equal,
        };
        isotropic_hessian(self.weight, &svd, &projection, project_psd, out);
    }
}
