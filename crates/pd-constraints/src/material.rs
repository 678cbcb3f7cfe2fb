//! Hyperelastic material laws: the strain-energy density `Psi(F)` (J/m^3)
//! of a deformation gradient `F`, its first Piola-Kirchhoff stress
//! `P = dPsi/dF` (Pa) and the stress differential `dP[dF]`, for the
//! isotropic materials a scene names (`docs/design/materials.md`):
//!
//! - `neo-hookean`: the stable Neo-Hookean energy of Smith, de Goes and Kim
//!   (2018), `Psi = m/2 (I_C - 3) + l/2 (J - a)^2 - m/2 log(I_C + 1) - Psi_0`
//!   with `I_C = |F|^2`, their parameters `m = 4/3 mu`,
//!   `l = lambda + 5/6 mu` (so that it linearises to Lame's `(mu, lambda)`),
//!   `a = 1 + 3 m / (4 l)` (zero stress at rest) and the constant `Psi_0`
//!   that makes the rest energy zero. It is defined and smooth for every `F`
//!   (flat and inverted elements included: no `log J` barrier), and the
//!   `log(I_C + 1)` term keeps the collapsed state `F = 0` from being a
//!   local minimum (without it, `F = 0` is stationary with Hessian `m I`;
//!   a fully inverted cube then collapsed and stayed there in our test).
//! - `stvk`: Saint Venant-Kirchhoff, `Psi = mu |E|^2 + lambda/2 tr(E)^2`,
//!   `E = (F^T F - I)/2`.
//! - `corotated`: `Psi = mu |F - R|^2 + lambda/2 (J - 1)^2` (the volume term
//!   in `J`, not `tr(S - I)`), `R` the closest proper rotation (signed SVD,
//!   so inverted elements keep a proper rotation).
//!
//! `J = det F`. These are not Projective Dynamics constraints: they have no
//! projection, and only the objective-judging methods (`lbfgs`, `newton`)
//! see their forces ([`crate::MaterialSet`]).

use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::ConstraintError;
use crate::signed_svd::signed_svd;

/// The 9 x 9 Hessian `d^2 Psi / dF^2` (Pa), index `3 c + a` for entry
/// `F[(a, c)]` (column-major, the layout of the rows of `G x`).
pub type StressHessian = SMatrix<f64, 9, 9>;

/// Which hyperelastic law (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MaterialKind {
    /// `neo-hookean` (stable, inversion-safe).
    NeoHookean,
    /// `stvk` (Saint Venant-Kirchhoff).
    Stvk,
    /// `corotated` with the volume term `lambda/2 (J - 1)^2`.
    Corotated,
}

impl MaterialKind {
    /// Every kind, in the order scenes list them.
    pub const ALL: [MaterialKind; 3] = [Self::NeoHookean, Self::Stvk, Self::Corotated];

    /// The name as scenes spell it.
    pub fn name(self) -> &'static str {
        match self {
            Self::NeoHookean => "neo-hookean",
            Self::Stvk => "stvk",
            Self::Corotated => "corotated",
        }
    }

    /// The kind named `name`, if any.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// Lame's parameters, Pa.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lame {
    /// Shear modulus `mu`, Pa.
    pub mu: f64,
    /// First parameter `lambda`, Pa.
    pub lambda: f64,
}

impl Lame {
    /// From Young's modulus `young` (Pa, > 0) and Poisson's ratio `poisson`
    /// (in `[0, 0.5)`): `mu = E / (2 (1 + nu))`,
    /// `lambda = E nu / ((1 + nu)(1 - 2 nu))`.
    ///
    /// ```
    /// let l = pd_constraints::material::Lame::from_young_poisson(2.6e6, 0.3).unwrap();
    /// assert!((l.mu - 1.0e6).abs() < 1e-6);
    /// assert!((l.lambda - 1.5e6).abs() < 1e-6);
    /// ```
    ///
    /// # Errors
    /// [`ConstraintError::InvalidYoung`] or [`ConstraintError::InvalidPoisson`]
    /// (NaN and infinities included).
    pub fn from_young_poisson(young: f64, poisson: f64) -> Result<Self, ConstraintError> {
        if !(young > 0.0 && young.is_finite()) {
            return Err(ConstraintError::InvalidYoung { young });
        }
        if !((0.0..0.5).contains(&poisson)) {
            return Err(ConstraintError::InvalidPoisson { poisson });
        }
        Ok(Self {
            mu: young / (2.0 * (1.0 + poisson)),
            lambda: young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson)),
        })
    }
}

/// The cofactor matrix `dJ/dF`: columns `f2 x f3`, `f3 x f1`, `f1 x f2`.
fn cofactor(f: &Matrix3<f64>) -> Matrix3<f64> {
    let (f1, f2, f3) = (f.column(0), f.column(1), f.column(2));
    Matrix3::from_columns(&[f2.cross(&f3), f3.cross(&f1), f1.cross(&f2)])
}

/// The differential of [`cofactor`] in direction `df`.
fn cofactor_differential(f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
    let (f1, f2, f3) = (f.column(0), f.column(1), f.column(2));
    let (d1, d2, d3) = (df.column(0), df.column(1), df.column(2));
    Matrix3::from_columns(&[
        d2.cross(&f3) + f2.cross(&d3),
        d3.cross(&f1) + f3.cross(&d1),
        d1.cross(&f2) + f1.cross(&d2),
    ])
}

/// `(m, l, a)` of the stable Neo-Hookean energy: `m = 4/3 mu`,
/// `l = lambda + 5/6 mu`, `a = 1 + 3 m / (4 l)`.
fn neo_hookean_constants(lame: Lame) -> (f64, f64, f64) {
    let m = 4.0 / 3.0 * lame.mu;
    let l = lame.lambda + 5.0 / 6.0 * lame.mu;
    (m, l, 1.0 + 0.75 * m / l)
}

/// Everything the stress and its differential need of one `F`.
#[derive(Debug, Clone, Copy)]
pub struct MaterialPoint {
    kind: MaterialKind,
    lame: Lame,
    f: Matrix3<f64>,
    cofactor: Matrix3<f64>,
    j: f64,
    /// Corotated: the closest proper rotation and `V`, the signed singular
    /// values (identity and zero otherwise).
    rotation: Matrix3<f64>,
    v: Matrix3<f64>,
    sigma: Vector3<f64>,
}

impl MaterialPoint {
    /// Evaluates the invariants of `f` for `kind` with parameters `lame`.
    pub fn new(kind: MaterialKind, lame: Lame, f: Matrix3<f64>) -> Self {
        let (rotation, v, sigma) = if kind == MaterialKind::Corotated {
            let (u, sigma, v) = signed_svd(&f);
            (u * v.transpose(), v, sigma)
        } else {
            (Matrix3::identity(), Matrix3::identity(), Vector3::zeros())
        };
        Self {
            kind,
            lame,
            f,
            cofactor: cofactor(&f),
            j: f.determinant(),
            rotation,
            v,
            sigma,
        }
    }

    /// The energy density `Psi(F)`, J/m^3.
    pub fn energy_density(&self) -> f64 {
        let Lame { mu, lambda } = self.lame;
        let f = &self.f;
        match self.kind {
            MaterialKind::NeoHookean => {
                let (m, l, a) = neo_hookean_constants(self.lame);
                let ic = f.norm_squared();
                let rest = 0.5 * l * (1.0 - a).powi(2) - 0.5 * m * 4.0_f64.ln();
                0.5 * m * (ic - 3.0) + 0.5 * l * (self.j - a).powi(2)
                    - 0.5 * m * (ic + 1.0).ln()
                    - rest
            }
            MaterialKind::Stvk => {
                let e = (f.transpose() * f - Matrix3::identity()) * 0.5;
                mu * e.norm_squared() + 0.5 * lambda * e.trace().powi(2)
            }
            MaterialKind::Corotated => {
                mu * (f - self.rotation).norm_squared() + 0.5 * lambda * (self.j - 1.0).powi(2)
            }
        }
    }

    /// The first Piola-Kirchhoff stress `P = dPsi/dF`, Pa.
    pub fn stress(&self) -> Matrix3<f64> {
        let Lame { mu, lambda } = self.lame;
        let f = &self.f;
        match self.kind {
            MaterialKind::NeoHookean => {
                let (m, l, a) = neo_hookean_constants(self.lame);
                let ic = f.norm_squared();
                f * (m * (1.0 - 1.0 / (ic + 1.0))) + self.cofactor * (l * (self.j - a))
            }
            MaterialKind::Stvk => {
                let e = (f.transpose() * f - Matrix3::identity()) * 0.5;
                f * (e * (2.0 * mu) + Matrix3::identity() * (lambda * e.trace()))
            }
            MaterialKind::Corotated => {
                (f - self.rotation) * (2.0 * mu) + self.cofactor * (lambda * (self.j - 1.0))
            }
        }
    }

    /// The stress differential `dP[df]`, Pa.
    pub fn stress_differential(&self, df: &Matrix3<f64>) -> Matrix3<f64> {
        let Lame { mu, lambda } = self.lame;
        let f = &self.f;
        let c = &self.cofactor;
        let dj = c.dot(df);
        match self.kind {
            MaterialKind::NeoHookean => {
                let (m, l, a) = neo_hookean_constants(self.lame);
                let ic1 = f.norm_squared() + 1.0;
                df * (m * (1.0 - 1.0 / ic1))
                    + f * (2.0 * m * f.dot(df) / (ic1 * ic1))
                    + c * (l * dj)
                    + cofactor_differential(f, df) * (l * (self.j - a))
            }
            MaterialKind::Stvk => {
                let identity = Matrix3::identity();
                let e = (f.transpose() * f - identity) * 0.5;
                let de = (df.transpose() * f + f.transpose() * df) * 0.5;
                let s = e * (2.0 * mu) + identity * (lambda * e.trace());
                let ds = de * (2.0 * mu) + identity * (lambda * de.trace());
                df * s + f * ds
            }
            MaterialKind::Corotated => {
                (df - self.rotation_differential(df)) * (2.0 * mu)
                    + c * (lambda * dj)
                    + cofactor_differential(f, df) * (lambda * (self.j - 1.0))
            }
        }
    }

    /// `dR[df]` of the polar factor: with `F = R S`, `W = R^T dR = [w]x`
    /// solves `(tr(S) I - S) w = axial(R^T dF - dF^T R)`; in the basis `V`
    /// of `S = V diag(sigma) V^T` the matrix is diagonal with entries
    /// `sigma_j + sigma_k`, which the signed SVD keeps >= 0 (the negative
    /// singular value is the smallest in magnitude). Where a sum vanishes
    /// (a degenerate element) it is floored at 1e-12 of the largest
    /// singular value: the rotation's derivative is unbounded there, and the
    /// Hessian's PSD projection clamps the resulting negative curvature.
    fn rotation_differential(&self, df: &Matrix3<f64>) -> Matrix3<f64> {
        let r = &self.rotation;
        let m = r.transpose() * df - df.transpose() * r;
        let axial = Vector3::new(m[(2, 1)], m[(0, 2)], m[(1, 0)]);
        let s = &self.sigma;
        let floor = 1e-12 * s.amax().max(f64::MIN_POSITIVE);
        let sums = Vector3::new(s[1] + s[2], s[0] + s[2], s[0] + s[1]);
        let local = self.v.transpose() * axial;
        let w_local = Vector3::from_fn(|i, _| local[i] / sums[i].max(floor));
        let w = self.v * w_local;
        r * w.cross_matrix()
    }

    /// The 9 x 9 Hessian `d^2 Psi / dF^2` (Pa), symmetrised (it is symmetric
    /// up to round-off), each column `dP[E_(a,c)]`.
    pub fn stress_hessian(&self) -> StressHessian {
        let mut h = StressHessian::zeros();
        for column in 0..9 {
            let mut df = Matrix3::zeros();
            df.as_mut_slice()[column] = 1.0;
            let dp = self.stress_differential(&df);
            for row in 0..9 {
                h[(row, column)] = dp.as_slice()[row];
            }
        }
        (h + h.transpose()) * 0.5
    }
}

/// Clamps the negative eigenvalues of a symmetric 9 x 9 matrix to zero.
pub fn project_psd(h: &StressHessian) -> StressHessian {
    let eigen = h.symmetric_eigen();
    if eigen.eigenvalues.iter().all(|&l| l >= 0.0) {
        return *h;
    }
    let clamped = eigen.eigenvalues.map(|l| l.max(0.0));
    let q = &eigen.eigenvectors;
    q * StressHessian::from_diagonal(&clamped) * q.transpose()
}
