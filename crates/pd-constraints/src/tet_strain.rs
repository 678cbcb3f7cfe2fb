//! Corotational tetrahedral strain: `w/2 |F - R|^2` with `R` the closest
//! proper rotation to the deformation gradient `F`, optionally relaxed to a
//! strain limit on its singular values.

use nalgebra::Matrix3;
use pd_mesh::Point;

use crate::constraint::{energies_one_by_one, project_one_by_one};
use crate::polar::closest_rotation;
use crate::signed_svd::signed_svd;
use crate::{Constraint, ConstraintError, Stencil};

#[cfg(target_arch = "x86_64")]
mod batch;

/// A tetrahedral strain constraint.
///
/// With rest edge matrix `Dm = [X1 - X0, X2 - X0, X3 - X0]` and `B = Dm^-1`,
/// the deformation gradient is `F = Ds B`, and `F^T = G [x0; x1; x2; x3]`
/// with the 3 x 4 operator `G = B^T [-1 | I]`: the rows of `G x` are the
/// columns of `F`. The projection is the closest proper rotation `R = U V^T`
/// from the signed SVD of [`signed_svd`](crate::signed_svd) (so
/// an inverted element projects to a rotation, not a reflection), or with
/// strain limits `[min, max]` the matrix
/// `U clamp(S, min, max) V^T`. The weight is `stiffness * rest volume`; with
/// Poisson ratio 0 the stiffness plays the part of Young's modulus (Pa).
///
/// Stored in 112 bytes (the local step streams them): the vertex indices
/// are 32-bit ([`Constraint::vertices`] widens them into a
/// [`Stencil`]; [`TetStrain::new`] rejects an index beyond `u32::MAX`), the
/// operator's first column `G[r][0] = -(B^T[r][0] + B^T[r][1] + B^T[r][2])`
/// is not stored but recomputed with that same sum (the same bits as
/// storing it), and the optional limits are a pair with an impossible
/// sentinel (`min < 0`) for "none".
#[derive(Debug, Clone, PartialEq)]
pub struct TetStrain {
    vertices: [u32; 4],
    weight: f64,
    /// `B^T`: row `r` holds the operator's entries `G[r][1..4]`.
    inverse_t: [[f64; 3]; 3],
    /// `[min, max]`, or [`NO_LIMITS`].
    limits: [f64; 2],
}

/// The stored limits of an element without strain limits: `min < 0`, which
/// [`TetStrain::check_limits`] never accepts.
const NO_LIMITS: [f64; 2] = [f64::NEG_INFINITY, f64::INFINITY];

/// The operator's first entry of a row from the row's other three,
/// `G[r][0] = -(B^T[r][0] + B^T[r][1] + B^T[r][2])`, summed as `Iterator::sum`
/// sums them (the batched gather repeats this exact sum in its lanes).
#[inline]
fn first_entry(row: &[f64; 3]) -> f64 {
    -row.iter().sum::<f64>()
}

impl TetStrain {
    /// Builds the constraint of tetrahedron `tet` from rest positions.
    ///
    /// `stiffness` is in Pa; `limits`, if given, are the allowed range of the
    /// principal stretches, `0 <= min <= 1 <= max`.
    ///
    /// # Errors
    /// A degenerate rest shape, a negative or non-finite stiffness or
    /// limit, or a vertex index beyond `u32::MAX`.
    pub fn new(
        rest: &[Point],
        tet: [usize; 4],
        stiffness: f64,
        limits: Option<(f64, f64)>,
    ) -> Result<Self, ConstraintError> {
        check_stiffness(stiffness)?;
        if let Some((min, max)) = limits {
            Self::check_limits(min, max)?;
        }
        let mut vertices = [0u32; 4];
        for (compact, &v) in vertices.iter_mut().zip(&tet) {
            *compact = u32::try_from(v).map_err(|_| ConstraintError::VertexIndexTooLarge {
                vertex: v,
                max: u32::MAX as usize,
            })?;
        }
        // After the storage limit, which names an index no mesh can reach.
        check_vertices(rest, &tet)?;
        let [x0, x1, x2, x3] = tet.map(|v| rest[v]);
        let rest_edges = Matrix3::from_columns(&[x1 - x0, x2 - x0, x3 - x0]);
        let volume = rest_edges.determinant() / 6.0;
        let inverse = rest_edges.try_inverse().filter(|_| volume > 0.0).ok_or(
            ConstraintError::DegenerateElement {
                vertices: tet.to_vec(),
            },
        )?;
        // Row `row` of B^T [-1 | I]: B^T[row][j] = B[j][row]; the first
        // column, `-sum_j B^T[row][j]`, is `first_entry`'s.
        let inverse_t = std::array::from_fn(|row| std::array::from_fn(|j| inverse[(j, row)]));
        Ok(Self {
            vertices,
            weight: stiffness * volume,
            inverse_t,
            limits: limits.map_or(NO_LIMITS, |(min, max)| [min, max]),
        })
    }

    /// The stretch limits, if any.
    pub fn limits(&self) -> Option<(f64, f64)> {
        self.has_limits()
            .then_some((self.limits[0], self.limits[1]))
    }

    /// Whether the element has strain limits: its `min` is not the
    /// sentinel's (one integer comparison in the batch loop).
    #[inline]
    fn has_limits(&self) -> bool {
        self.limits[0].to_bits() != NO_LIMITS[0].to_bits()
    }

    /// Checks stretch limits: `0 <= min <= 1 <= max`, both finite.
    ///
    /// # Errors
    /// [`ConstraintError::InvalidStrainLimits`] otherwise.
    pub fn check_limits(min: f64, max: f64) -> Result<(), ConstraintError> {
        if (0.0..=1.0).contains(&min) && max.is_finite() && max >= 1.0 {
            Ok(())
        } else {
            Err(ConstraintError::InvalidStrainLimits { min, max })
        }
    }
}

impl Constraint for TetStrain {
    const STENCIL: usize = 4;
    const ROWS: usize = 3;
    const TRANSLATION_INVARIANT: bool = true;
    const KIND: &'static str = "tet-strain";

    type Vertices<'a> = Stencil;

    #[inline]
    fn vertices(&self) -> Stencil {
        Stencil::from_u32x4(self.vertices)
    }

    fn weight(&self) -> f64 {
        self.weight
    }

    #[inline]
    fn operator(&self, row: usize, column: usize) -> f64 {
        let b = &self.inverse_t[row];
        match column {
            0 => first_entry(b),
            _ => b[column - 1],
        }
    }

    fn project(&self, gx: &[Point], out: &mut [Point]) {
        let f = Matrix3::from_columns(&[gx[0], gx[1], gx[2]]);
        let target = match self.limits() {
            None => closest_rotation(&f),
            Some((min, max)) => clamp_singular_values(&f, min, max),
        };
        for (row, p) in out.iter_mut().enumerate() {
            *p = target.column(row).into_owned();
        }
    }

    fn gx_hessian(&self, gx: &[Point], project_psd: bool, out: &mut [f64]) {
        crate::tet_hessian::strain_hessian(self, gx, project_psd, out);
    }

    /// Batches of elements without strain limits (as many as the CPU has
    /// f64 lanes) go through the SIMD polar iteration of [`crate::polar_batch`] (bit-identical to
    /// [`Self::project`]); the rest, one at a time.
    fn project_many(constraints: &[Self], q: &[Point], out: &mut [Point]) {
        #[cfg(target_arch = "x86_64")]
        if crate::lane_rows::project_many(constraints, q, out) {
            return;
        }
        project_one_by_one(constraints, q, out);
    }

    /// As [`Self::project_many`], each SIMD batch's energies from its
    /// lanes of `G q` and of the projection (no second gather); the rest,
    /// one at a time. Bit-identical to the default.
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

    /// Batches of SIMD-lane width gather
    /// `G q` into SIMD lanes as [`Self::project_many`] does (bit-identical
    /// to the default's sums); the rest, one at a time.
    fn energies_many(constraints: &[Self], q: &[Point], projections: &[Point], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if crate::lane_rows::energies_many(constraints, q, projections, out) {
            return;
        }
        energies_one_by_one(constraints, q, projections, out);
    }
}

fn clamp_singular_values(f: &Matrix3<f64>, min: f64, max: f64) -> Matrix3<f64> {
    let (u, s, v) = signed_svd(f);
    let clamped = s.map(|sigma| sigma.clamp(min, max));
    u * Matrix3::from_diagonal(&clamped) * v.transpose()
}

/// [`ConstraintError::VertexOutOfRange`] unless every one of an element's
/// `vertices` has a rest position.
pub(crate) fn check_vertices(rest: &[Point], vertices: &[usize]) -> Result<(), ConstraintError> {
    match vertices.iter().find(|&&v| v >= rest.len()) {
        Some(&vertex) => Err(ConstraintError::VertexOutOfRange {
            vertices: vertices.to_vec(),
            vertex,
            count: rest.len(),
        }),
        None => Ok(()),
    }
}

pub(crate) fn check_stiffness(stiffness: f64) -> Result<(), ConstraintError> {
    if stiffness.is_finite() && stiffness >= 0.0 {
        Ok(())
    } else {
        Err(ConstraintError::InvalidStiffness { stiffness })
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;

    fn is_proper_rotation(r: &Matrix3<f64>) -> bool {
        // Orthonormality and det = +1 hold to a few ulps of the SVD's
        // 1e-14 accuracy.
        (r.transpose() * r - Matrix3::identity()).norm() < 1e-12
            && (r.determinant() - 1.0).abs() < 1e-12
    }

    #[test]
    fn inverted_and_degenerate_gradients_project_to_rotations() {
        let cases = [
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            Matrix3::from_diagonal(&Vector3::new(2.0, 0.5, -0.1)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0)),
            Matrix3::zeros(),
            Matrix3::new(0.3, -1.2, 0.5, 2.0, 0.1, -0.7, -0.4, 0.9, 0.2),
            -Matrix3::identity(),
        ];
        for f in cases {
            let r = closest_rotation(&f);
            assert!(is_proper_rotation(&r), "F = {f}, R = {r}");
        }
    }

    #[test]
    fn rotation_of_a_rotation_is_itself() {
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
        assert!((closest_rotation(&r) - r).norm() < 1e-12);
        assert!((closest_rotation(&(r * 2.5)) - r).norm() < 1e-12);
    }

    #[test]
    fn reflection_projects_to_closest_rotation() {
        // F = diag(3, 2, -1): the closest rotation flips the axis of the
        // smallest |sigma| only, giving diag(1, 1, 1) at distance |(-1) - 1| = 2
        // (flipping any other axis costs more).
        let f = Matrix3::from_diagonal(&Vector3::new(3.0, 2.0, -1.0));
        let r = closest_rotation(&f);
        assert!((r - Matrix3::identity()).norm() < 1e-12, "{r}");
    }

    #[test]
    fn strain_limits_clamp_stretches() {
        let f = Matrix3::from_diagonal(&Vector3::new(1.5, 0.5, 1.0));
        let p = clamp_singular_values(&f, 0.9, 1.1);
        assert!((p - Matrix3::from_diagonal(&Vector3::new(1.1, 0.9, 1.0))).norm() < 1e-12);
    }

    #[test]
    fn operator_reproduces_deformation_gradient() {
        let rest = vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 2.0, 0.0),
            Point::new(0.0, 0.0, 0.5),
        ];
        let c = TetStrain::new(&rest, [0, 1, 2, 3], 10.0, None).unwrap();
        assert!((c.weight() - 10.0 * (1.0 / 6.0)).abs() < 1e-14);
        let a = Matrix3::new(1.1, 0.2, -0.3, 0.0, 0.9, 0.4, 0.5, -0.1, 1.3);
        let deformed: Vec<Point> = rest
            .iter()
            .map(|x| a * x + Point::new(1.0, 2.0, 3.0))
            .collect();
        let mut gx = [Point::zeros(); 3];
        crate::constraint::apply_operator(&c, &deformed, &mut gx);
        let f = Matrix3::from_columns(&gx);
        assert!((f - a).norm() < 1e-12, "{f} vs {a}");
    }

    #[test]
    fn batched_projection_is_bit_identical_to_one_by_one() {
        // 11 elements (two full batches and a remainder of 3), one with
        // strain limits, positions perturbed so that some elements invert
        // or flatten: the batched path must reproduce `project` exactly.
        let rest = vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
            Point::new(1.0, 1.0, 1.0),
        ];
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4], [0, 1, 2, 3], [1, 2, 3, 4]];
        let constraints: Vec<TetStrain> = (0..11)
            .map(|i| {
                let limits = (i == 6).then_some((0.9, 1.1));
                TetStrain::new(&rest, tets[i % 4], 1e5, limits).unwrap()
            })
            .collect();
        let deformations = [
            Matrix3::identity(),
            Matrix3::new(1.1, 0.2, -0.3, 0.0, 0.9, 0.4, 0.5, -0.1, 1.3),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0)),
        ];
        for a in deformations {
            let q: Vec<Point> = rest
                .iter()
                .map(|x| a * x + Point::new(0.1, 0.0, -0.2))
                .collect();
            let mut batched = vec![Point::zeros(); 33];
            TetStrain::project_many(&constraints, &q, &mut batched);
            let mut gx = [Point::zeros(); 3];
            for (c, rows) in constraints.iter().zip(batched.chunks_exact(3)) {
                crate::constraint::apply_operator(c, &q, &mut gx);
                let mut one = [Point::zeros(); 3];
                c.project(&gx, &mut one);
                assert_eq!(rows, &one[..], "F = {a}");
            }
        }
    }

    /// The compact storage gives the operator `B^T [-1 | I]` exactly as
    /// storing all twelve entries did (the first column summed by
    /// `Iterator::sum`, in the same order), keeps the limits, and takes 112
    /// bytes (it took 160, then 128 with `usize` indices).
    #[test]
    fn compact_storage_keeps_operator_and_limits() {
        assert_eq!(std::mem::size_of::<TetStrain>(), 112);
        let rest = vec![
            Point::new(0.1, -0.2, 0.0),
            Point::new(1.3, 0.1, -0.4),
            Point::new(-0.2, 0.9, 0.3),
            Point::new(0.4, 0.2, 1.1),
        ];
        for limits in [None, Some((0.0, 1.0)), Some((0.9, 1.1)), Some((-0.0, 3.0))] {
            let c = TetStrain::new(&rest, [0, 1, 2, 3], 7.0, limits).unwrap();
            assert_eq!(c.limits(), limits);
            assert_eq!(c.has_limits(), limits.is_some());
            let edges =
                Matrix3::from_columns(&[rest[1] - rest[0], rest[2] - rest[0], rest[3] - rest[0]]);
            let inverse = edges.try_inverse().unwrap();
            for row in 0..3 {
                let first = -(0..3).map(|j| inverse[(j, row)]).sum::<f64>();
                assert_eq!(c.operator(row, 0).to_bits(), first.to_bits());
                for j in 0..3 {
                    assert_eq!(
                        c.operator(row, j + 1).to_bits(),
                        inverse[(j, row)].to_bits()
                    );
                }
            }
        }
    }

    /// 32-bit storage: the largest index round-trips, the next one is an
    /// error naming it (not a panic or a silent wrap).
    #[test]
    fn vertex_indices_are_stored_in_32_bits() {
        let big = u32::MAX as usize;
        let mut rest = vec![Point::zeros(); 4];
        rest[1] = Point::x();
        rest[2] = Point::y();
        rest[3] = Point::z();
        // No 4-billion-point mesh: the largest index is set directly.
        let c = TetStrain::new(&rest, [0, 1, 2, 3], 1.0, None).unwrap();
        assert_eq!(&*c.vertices(), &[0, 1, 2, 3]);
        let mut wide = c.clone();
        wide.vertices = [0, 1, 2, u32::MAX];
        assert_eq!(&*wide.vertices(), &[0, 1, 2, big]);
        assert_eq!(
            TetStrain::new(&rest, [0, 1, 2, big + 1], 1.0, None),
            Err(ConstraintError::VertexIndexTooLarge {
                vertex: big + 1,
                max: big
            })
        );
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        let rest = vec![Point::zeros(), Point::x(), Point::y(), Point::z()];
        assert!(matches!(
            TetStrain::new(&rest, [0, 1, 2, 3], -1.0, None),
            Err(ConstraintError::InvalidStiffness { .. })
        ));
        assert!(TetStrain::new(&rest, [0, 1, 2, 3], f64::NAN, None).is_err());
        assert!(TetStrain::new(&rest, [0, 1, 2, 3], 1.0, Some((1.2, 2.0))).is_err());
        assert!(TetStrain::new(&rest, [0, 2, 1, 3], 1.0, None).is_err());
    }
}
