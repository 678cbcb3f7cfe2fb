//! Corotational membrane strain of a triangle: `w/2 |F - R|^2` with `F` the
//! 3 x 2 deformation gradient in the triangle's rest plane and `R` the
//! closest matrix with orthonormal columns, optionally relaxed to limits on
//! its singular values (`docs/design/constraints.md`, "Triangle strain").

use nalgebra::{Matrix2, Matrix3x2};
use pd_mesh::Point;

use crate::constraint::{energies_one_by_one, project_one_by_one};
use crate::tet_strain::{check_stiffness, check_vertices};
use crate::triangle_frame::{
    IsotropicProjection, clamped_stretch, closest_orthonormal, gradient_of, isotropic_hessian,
    rest_frame, thin_svd,
};
use crate::{Constraint, ConstraintError, TetStrain};

#[cfg(target_arch = "x86_64")]
mod batch;

/// A triangle membrane-strain constraint.
///
/// `G = B^T [-1 | I]` (2 x 3) with `B` the inverse rest edge matrix in the
/// triangle's own plane, so the rows of `G x` are the columns of the 3 x 2
/// gradient `F` (`crate::triangle_frame`). The projection is `U V^T` from
/// the thin SVD `F = U S V^T` (the closest matrix with orthonormal columns:
/// a rigid motion of the rest triangle), computed as `Q Rot` from the
/// factors `F = Q R` and the rotation closest to `R`, without
/// trigonometry; or with limits `[min, max]` the matrix
/// `U clamp(S, min, max) V^T`, computed as `Q` times the clamped 2 x 2 SVD
/// of `R` in closed form, again without trigonometry.
/// [`Constraint::project_many`] projects triangles with and without
/// limits several at a time in SIMD lanes, with the same bits. The weight
/// is `stiffness * rest area` with `stiffness = E t` in N/m: for small
/// strains this is plane-stress linear elasticity with Young's modulus
/// `E`, thickness `t` and Poisson ratio 0.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleStrain {
    vertices: [usize; 3],
    weight: f64,
    operator: [[f64; 3]; 2],
    limits: Option<(f64, f64)>,
}

impl TriangleStrain {
    /// Builds the constraint of `triangle` from rest positions.
    ///
    /// `stiffness` is `E t` in N/m; `limits`, if given, bound the principal
    /// stretches, `0 <= min <= 1 <= max`.
    ///
    /// # Errors
    /// A zero-area rest triangle, or a negative or non-finite stiffness or
    /// limit.
    pub fn new(
        rest: &[Point],
        triangle: [usize; 3],
        stiffness: f64,
        limits: Option<(f64, f64)>,
    ) -> Result<Self, ConstraintError> {
        check_vertices(rest, &triangle)?;
        check_stiffness(stiffness)?;
        if let Some((min, max)) = limits {
            TetStrain::check_limits(min, max)?;
        }
        let (operator, area) = rest_frame(rest, triangle)?;
        Ok(Self {
            vertices: triangle,
            weight: stiffness * area,
            operator,
            limits,
        })
    }

    /// The stretch limits, if any.
    pub fn limits(&self) -> Option<(f64, f64)> {
        self.limits
    }

    fn bounds(&self) -> (f64, f64) {
        self.limits.unwrap_or((1.0, 1.0))
    }

    /// The projection of the gradient `f`: [`closest_orthonormal`], or
    /// with limits [`clamped_stretch`].
    fn target(&self, f: &Matrix3x2<f64>) -> Matrix3x2<f64> {
        match self.limits {
            None => closest_orthonormal(f),
            Some((min, max)) => clamped_stretch(f, min, max),
        }
    }
}

impl Constraint for TriangleStrain {
    const STENCIL: usize = 3;
    const ROWS: usize = 2;
    const TRANSLATION_INVARIANT: bool = true;
    const KIND: &'static str = "triangle-strain";

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
        let target = self.target(&gradient_of(gx));
        out[0] = target.column(0).into_owned();
        out[1] = target.column(1).into_owned();
    }

    /// Batches of triangles with or without limits (as many as the CPU has
    /// f64 lanes) in SIMD lanes, bit-identical to [`Self::project`]; the
    /// rest, one at a time.
    fn project_many(constraints: &[Self], q: &[Point], out: &mut [Point]) {
        #[cfg(target_arch = "x86_64")]
        if crate::lane_rows::project_many(constraints, q, out) {
            return;
        }
        project_one_by_one(constraints, q, out);
    }

    /// As [`Self::project_many`], each SIMD batch's energies from its lanes
    /// of `G q` and of the projection (no second gather); the rest, one at
    /// a time. Bit-identical to the default.
    fn project_many_with_energies(
        constraints: &[Self],
        q: &[Point],
        out: &mut [Point],
        energies: &mut [f64],
    ) {
        #[cfg(target_arch = "x86_64")]
        if crate::lane_rows::project_many_with_energies(constraints, q, out, energies) {
            return;
        }
        project_one_by_one(constraints, q, out);
        energies_one_by_one(constraints, q, out, energies);
    }

    /// Batches of SIMD-lane width gather `G q` into lanes as
    /// [`Self::project_many`] does (bit-identical to the default's sums);
    /// the rest, one at a time.
    fn energies_many(constraints: &[Self], q: &[Point], projections: &[Point], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if crate::lane_rows::energies_many(constraints, q, projections, out) {
            return;
        }
        energies_one_by_one(constraints, q, projections, out);
    }

    fn gx_hessian(&self, gx: &[Point], project_psd: bool, out: &mut [f64]) {
        let svd = thin_svd(&gradient_of(gx));
        let (min, max) = self.bounds();
        // Strictly inside the limits the clamp follows `s` (slope 1); on a
        // limit the larger one-sided value (slope 0) as for tetrahedra.
        let slope = |s: f64| if min < s && s < max { 1.0 } else { 0.0 };
        let projection = IsotropicProjection {
            c: svd.s.map(|s| s.clamp(min, max)),
            jacobian: Matrix2::from_diagonal(&svd.s.map(slope)),
            flip_at_equal: slope(svd.s[0]),
        };
        isotropic_hessian(self.weight, &svd, &projection, project_psd, out);
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Rotation3, Vector3};

    use super::*;
    use crate::constraint::apply_operator;

    fn rest() -> Vec<Point> {
        vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(2.0, 0.0, 0.0),
            Point::new(0.5, 1.0, 0.3),
        ]
    }

    #[test]
    fn rigid_motions_cost_nothing_and_stretch_costs_e_t_area() {
        let rest = rest();
        let c = TriangleStrain::new(&rest, [0, 1, 2], 10.0, None).unwrap();
        let area = 0.5 * (rest[1] - rest[0]).cross(&(rest[2] - rest[0])).norm();
        assert!((c.weight() - 10.0 * area).abs() < 1e-14);
        let r = Rotation3::from_euler_angles(0.4, -1.3, 2.2);
        let moved: Vec<Point> = rest
            .iter()
            .map(|x| r * x + Vector3::new(1.0, -2.0, 0.5))
            .collect();
        let mut gx = [Point::zeros(); 2];
        let mut p = [Point::zeros(); 2];
        apply_operator(&c, &moved, &mut gx);
        c.project(&gx, &mut p);
        // Round-off of the rotation and the projection on O(1) entries.
        assert!((gx[0] - p[0]).norm() + (gx[1] - p[1]).norm() < 1e-13);
        // A uniform in-plane stretch by 1 + e: |F - R|^2 = 2 e^2.
        let e = 0.01;
        let centroid = (rest[0] + rest[1] + rest[2]) / 3.0;
        let stretched: Vec<Point> = rest
            .iter()
            .map(|x| centroid + (x - centroid) * (1.0 + e))
            .collect();
        apply_operator(&c, &stretched, &mut gx);
        c.project(&gx, &mut p);
        let distance2 = (gx[0] - p[0]).norm_squared() + (gx[1] - p[1]).norm_squared();
        assert!((distance2 - 2.0 * e * e).abs() < 1e-15, "{distance2}");
    }

    #[test]
    fn limits_clamp_stretches_in_plane() {
        let rest = rest();
        let c = TriangleStrain::new(&rest, [0, 1, 2], 1.0, Some((0.9, 1.1))).unwrap();
        let f = Matrix3x2::new(1.5, 0.0, 0.0, 0.5, 0.0, 0.0);
        let mut p = [Point::zeros(); 2];
        c.project(&[f.column(0).into(), f.column(1).into()], &mut p);
        assert!((p[0] - Point::new(1.1, 0.0, 0.0)).norm() < 1e-13);
        assert!((p[1] - Point::new(0.0, 0.9, 0.0)).norm() < 1e-13);
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        let rest = rest();
        assert!(TriangleStrain::new(&rest, [0, 1, 2], -1.0, None).is_err());
        assert!(TriangleStrain::new(&rest, [0, 1, 2], 1.0, Some((1.2, 2.0))).is_err());
        assert!(TriangleStrain::new(&rest, [0, 1, 1], 1.0, None).is_err());
    }
}
