//! The step objective's derivatives (docs/design/gradients.md): the exact
//! elastic Hessian `K(q)` assembled from every constraint's element Hessian
//! (not made positive semi-definite: the adjoint needs the true one), the
//! damping Laplacian `L_d`, and the operators built from them, all over
//! every vertex (the free ones are picked where the derivation needs them).

use pd_constraints::assembly::{LaplacianKind, laplacian};
use pd_constraints::{ConstraintBlock, CsrMatrix, Triplet};
use pd_integrators::StepCoefficients;
use pd_mesh::Point;

/// What one step's derivatives are built from.
pub(crate) struct Operators {
    pub blocks: Vec<Box<dyn ConstraintBlock>>,
    pub masses: Vec<f64>,
    pub fixed: Vec<bool>,
    /// The damping Laplacian `L_d` (n x n, symmetric).
    pub damping_laplacian: CsrMatrix,
    /// `h` in s.
    pub h: f64,
    /// `a1` in 1/s and `a2` in s.
    pub a1: f64,
    pub a2: f64,
}

impl Operators {
    pub fn new(
        blocks: Vec<Box<dyn ConstraintBlock>>,
        masses: Vec<f64>,
        fixed: Vec<bool>,
        h: f64,
        (a1, a2): (f64, f64),
    ) -> Self {
        let n = masses.len();
        let damping_laplacian = laplacian(&blocks, n, LaplacianKind::Damping);
        Self {
            blocks,
            masses,
            fixed,
            damping_laplacian,
            h,
            a1,
            a2,
        }
    }

    /// The elastic Hessian `K(q)` (3n x 3n, x, y, z interleaved per vertex):
    /// the sum of every constraint's exact energy Hessian at `q`.
    pub fn elastic_hessian(&self, q: &[Point]) -> CsrMatrix {
        let n = q.len();
        let mut triplets = Vec::new();
        let mut values = Vec::new();
        for block in &self.blocks {
            let len = block.hessian_len();
            let count = block.len();
            values.resize(len * count, 0.0);
            block.hessian_range(q, 0, false, &mut values);
            for (i, h) in values.chunks_exact(len).enumerate() {
                let stencil = block.stencil(i);
                let size = 3 * stencil.len();
                for (k, &vk) in stencil.iter().enumerate() {
                    for (l, &vl) in stencil.iter().enumerate() {
                        for a in 0..3 {
                            for b in 0..3 {
                                let value = h[(3 * k + a) * size + 3 * l + b];
                                if value != 0.0 {
                                    triplets.push(Triplet::new(3 * vk + a, 3 * vl + b, value));
                                }
                            }
                        }
                    }
                }
            }
        }
        CsrMatrix::from_triplet_vec(3 * n, 3 * n, triplets)
    }

    /// `out = (M/h^2 + c1 c2 gamma D) w` with `D = a1 M + a2 L_d` scaled by
    /// `scale`, added to `out`: the inertial and damping part `P w` of the
    /// step objective's Hessian (every vertex).
    pub fn add_inertia_damping(
        &self,
        c: StepCoefficients,
        w: &[Point],
        scale: f64,
        out: &mut [Point],
    ) {
        let damping = c.c1 * c.c2 * c.gamma;
        let mass = scale * (1.0 / (self.h * self.h) + damping * self.a1);
        for ((o, wi), m) in out.iter_mut().zip(w).zip(&self.masses) {
            *o += wi * (mass * m);
        }
        if self.a2 != 0.0 {
            let factor = scale * damping * self.a2;
            for (i, o) in out.iter_mut().enumerate() {
                *o += self.damping_laplacian.row_dot(i, w) * factor;
            }
        }
    }

    /// `out += scale K w`.
    pub fn add_elastic(k: &CsrMatrix, w: &[Point], scale: f64, out: &mut [Point]) {
        for (i, o) in out.iter_mut().enumerate() {
            for a in 0..3 {
                let sum: f64 = k.row(3 * i + a).map(|(col, v)| v * w[col / 3][col % 3]).sum();
                o[a] += scale * sum;
            }
        }
    }

    /// `out = H w` over every vertex, `H = M/h^2 + c1 c2^2 K + c1 c2 gamma D`
    /// the Hessian of the step objective with respect to the new positions.
    pub fn hessian_product(
        &self,
        c: StepCoefficients,
        k: &CsrMatrix,
        w: &[Point],
        out: &mut [Point],
    ) {
        out.iter_mut().for_each(|o| *o = Point::zeros());
        self.add_inertia_damping(c, w, 1.0, out);
        Self::add_elastic(k, w, c.c1 * c.c2 * c.c2, out);
    }
}

/// Zeroes the entries of fixed vertices.
pub(crate) fn mask_fixed(w: &mut [Point], fixed: &[bool]) {
    for (w, &f) in w.iter_mut().zip(fixed) {
        if f {
            *w = Point::zeros();
        }
    }
}

/// `sum_i a_i . b_i`.
pub(crate) fn dot(a: &[Point], b: &[Point]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a.dot(b)).sum()
}
