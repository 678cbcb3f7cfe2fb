//! Tetrahedral volume preservation: `w/2 |F - P(F)|^2` with `P(F)` the
//! closest matrix of determinant 1 (`docs/design/constraints.md`, "Area and
//! volume").

use nalgebra::{Matrix3, Vector3};
use pd_mesh::Point;

use crate::signed_svd::signed_svd;
use crate::{Constraint, ConstraintError, Stencil, TetStrain, unit_product};

/// A volume-preservation constraint on a tetrahedron.
///
/// Same operator as [`TetStrain`] (the rows of `G x` are the columns of
/// `F`); with the signed SVD `F = U diag(s) V^T` the projection is
/// `U diag(c) V^T`, `c` the closest point to `s` on `c_0 c_1 c_2 = 1`,
/// `c > 0` (so an inverted element projects to a proper, un-inverted one).
/// The weight is `stiffness * rest volume`, `stiffness` in Pa: for small
/// strains the energy per unit rest volume is `stiffness/6 (dV/V)^2`.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    /// A tet-strain constraint of stiffness 1 holds the stencil and operator.
    shape: TetStrain,
    weight: f64,
}

impl Volume {
    /// Builds the constraint of `tet` from rest positions; `stiffness` in
    /// Pa.
    ///
    /// # Errors
    /// A flat or inverted rest tetrahedron, or a negative or non-finite
    /// stiffness.
    pub fn new(rest: &[Point], tet: [usize; 4], stiffness: f64) -> Result<Self, ConstraintError> {
        crate::tet_strain::check_stiffness(stiffness)?;
        let shape = TetStrain::new(rest, tet, 1.0, None)?;
        Ok(Self {
            weight: stiffness * shape.weight(),
            shape,
        })
    }
}

impl Constraint for Volume {
    const STENCIL: usize = 4;
    const ROWS: usize = 3;
    const TRANSLATION_INVARIANT: bool = true;
    const KIND: &'static str = "volume";

    type Vertices<'a> = Stencil;

    fn vertices(&self) -> Stencil {
        self.shape.vertices()
    }

    fn weight(&self) -> f64 {
        self.weight
    }

    fn operator(&self, row: usize, column: usize) -> f64 {
        self.shape.operator(row, column)
    }

    fn project(&self, gx: &[Point], out: &mut [Point]) {
        let (u, s, v) = signed_svd(&Matrix3::from_columns(&[gx[0], gx[1], gx[2]]));
        let (c, _) = unit_product::project(&[s[0], s[1], s[2]]);
        let target = u * Matrix3::from_diagonal(&Vector3::from(c)) * v.transpose();
        for (row, p) in out.iter_mut().enumerate().take(3) {
            *p = target.column(row).into_owned();
        }
    }

    fn gx_hessian(&self, gx: &[Point], project_psd: bool, out: &mut [f64]) {
        volume_hessian(self.weight, gx, project_psd, out);
    }
}

/// `w (I - dP/dF)` (9 x 9, index `3 r + a` for `F[(a, r)]`) from the modes
/// of `tet_hessian.rs`: the scaling triple couples through `dc/ds`; flip and
/// twist `ij` have `dP/dF` eigenvalues `(c_i -+ c_j) / (s_i -+ s_j)`.
fn volume_hessian(w: f64, gx: &[Point], project_psd: bool, out: &mut [f64]) {
    let out = &mut out[..81];
    let (u, s, v) = signed_svd(&Matrix3::from_columns(&[gx[0], gx[1], gx[2]]));
    let (c, j) = unit_product::project(&[s[0], s[1], s[2]]);
    if !s.iter().all(|x| x.is_finite()) {
        out.fill(f64::NAN);
        return;
    }
    out.fill(0.0);
    let mode = |i: usize, k: usize, sign: f64| -> [f64; 9] {
        let m = (u.column(i) * v.column(k).transpose()
            + u.column(k) * v.column(i).transpose() * sign)
            .normalize();
        let mut x = [0.0; 9];
        x.copy_from_slice(m.as_slice());
        x
    };
    let mut add = |eigen: f64, a: &[f64; 9], b: &[f64; 9]| {
        if eigen == 0.0 {
            return;
        }
        for (r, &ar) in a.iter().enumerate() {
            for (q, &bq) in b.iter().enumerate() {
                out[9 * r + q] += w * eigen * ar * bq;
            }
        }
    };
    let clamp = |x: f64| if project_psd { x.max(0.0) } else { x };
    let mut jacobian = Matrix3::from_fn(|a, b| j[a][b]);
    if project_psd && !jacobian.iter().all(|x| x.is_finite()) {
        jacobian = Matrix3::zeros();
    }
    let mut block = Matrix3::identity() - jacobian;
    if project_psd {
        let eig = nalgebra::SymmetricEigen::new(block);
        let clamped = eig.eigenvalues.map(|x| x.max(0.0));
        block = eig.eigenvectors * Matrix3::from_diagonal(&clamped) * eig.eigenvectors.transpose();
    }
    let scaling = [mode(0, 0, 1.0), mode(1, 1, 1.0), mode(2, 2, 1.0)];
    for a in 0..3 {
        for b in 0..3 {
            add(block[(a, b)], &scaling[a], &scaling[b]);
        }
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let flip = unit_product::flip_slope(
            [c[a], c[b]],
            [s[a], s[b]],
            0.5 * (j[a][a] + j[b][b] - j[a][b] - j[b][a]),
        );
        add(clamp(1.0 - flip), &mode(a, b, 1.0), &mode(a, b, 1.0));
        let sum = s[a] + s[b];
        let twist = if c[a] + c[b] == sum {
            1.0
        } else if sum > 0.0 {
            (c[a] + c[b]) / sum
        } else {
            f64::INFINITY
        };
        add(clamp(1.0 - twist), &mode(a, b, -1.0), &mode(a, b, -1.0));
    }
    for row in 1..9 {
        for col in 0..row {
            let mean = 0.5 * (out[9 * row + col] + out[9 * col + row]);
            out[9 * row + col] = mean;
            out[9 * col + row] = mean;
        }
    }
}
