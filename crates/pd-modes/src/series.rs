//! What a Caughey series damping fit needs of a model besides its modes:
//! each mode's series quotients `phi^T L_d (M^-1 L_d)^(k-2) phi` and an
//! upper bound of the spectrum of `M^-1 L_d` (`docs/design/damping.md`,
//! "Caughey series").
//!
//! `L_d` and `M` are restricted to the free vertices, as in the solver's
//! global step: a mode's shape is zero at fixed vertices, so `L_d phi` is
//! taken on the free rows only.

use pd_constraints::assembly::{self, LaplacianKind};
use pd_linalg::CsrMatrix;
use pd_mesh::Point;
use pd_solver::Model;

/// The damping Laplacian and masses of a model, for series quotients.
#[derive(Debug, Clone)]
pub struct SeriesOperator {
    laplacian: CsrMatrix,
    masses: Vec<f64>,
    fixed: Vec<bool>,
}

impl SeriesOperator {
    /// Assembles `L_d` of `model`'s translation-invariant constraints.
    pub fn new(model: &Model) -> Self {
        let blocks = model.constraint_blocks();
        let n = model.num_vertices();
        Self {
            laplacian: assembly::laplacian(&blocks, n, LaplacianKind::Damping),
            masses: model.masses().to_vec(),
            fixed: model.fixed().to_vec(),
        }
    }

    /// `y = L_ff x` on the free rows, zero on fixed ones (`x` zero on fixed
    /// vertices).
    fn apply(&self, x: &[Point], y: &mut [Point]) {
        for (v, out) in y.iter_mut().enumerate() {
            *out = if self.fixed[v] {
                Point::zeros()
            } else {
                self.laplacian.row_dot(v, x)
            };
        }
    }

    /// `[Q_1, ..., Q_terms]` of `shape` (per vertex, zero at fixed
    /// vertices): `Q_1 = phi^T M phi` (1 for a mass-normalised mode),
    /// `Q_k = phi^T L_d (M^-1 L_d)^(k-2) phi` in 1/s^(2k-2), computed as
    /// `u_j . w_j` and `w_j . u_(j+1)` with `w_j = L_d u_j`,
    /// `u_(j+1) = M^-1 w_j`, `u_0 = phi`.
    pub fn quotients(&self, shape: &[Point], terms: usize) -> Vec<f64> {
        let n = shape.len();
        let dot = |a: &[Point], b: &[Point]| a.iter().zip(b).map(|(x, y)| x.dot(y)).sum::<f64>();
        let mut u = shape.to_vec();
        let mut w = vec![Point::zeros(); n];
        let mut out = Vec::with_capacity(terms);
        let mass_form: f64 = shape
            .iter()
            .zip(&self.masses)
            .map(|(p, m)| m * p.norm_squared())
            .sum();
        out.push(mass_form);
        while out.len() < terms {
            self.apply(&u, &mut w);
            out.push(dot(&u, &w));
            if out.len() == terms {
                break;
            }
            for v in 0..n {
                u[v] = if self.fixed[v] {
                    Point::zeros()
                } else {
                    w[v] / self.masses[v]
                };
            }
            out.push(dot(&w, &u));
        }
        out.truncate(terms);
        out
    }

    /// A Gershgorin upper bound of the eigenvalues of `M^-1 L_d` over the
    /// free vertices (1/s^2): `max_i (L_ii + sum_(j free, j != i) |L_ij|) /
    /// m_i`. `M^-1 L_d` is similar to the symmetric `M^-1/2 L_d M^-1/2`,
    /// so its eigenvalues are real, `>= 0`, and inside the Gershgorin discs
    /// of its rows.
    pub fn spectrum_bound(&self) -> f64 {
        (0..self.masses.len())
            .filter(|&v| !self.fixed[v])
            .map(|v| {
                let row: f64 = self
                    .laplacian
                    .row(v)
                    .filter(|(c, _)| !self.fixed[*c])
                    .map(|(c, x)| if c == v { x } else { x.abs() })
                    .sum();
                row / self.masses[v]
            })
            .fold(0.0, f64::max)
    }
}
