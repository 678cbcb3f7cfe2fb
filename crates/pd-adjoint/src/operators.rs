//! The step objective's derivatives (docs/design/gradients.md): the exact
//! elastic Hessian `K(q)` assembled from every constraint's element Hessian
//! (not made positive semi-definite: the adjoint needs the true one), the
//! damping Laplacian `L_d`, the Caughey series' powers `L_ff (M_f^-1
//! L_ff)^j` on the free vertices, and the operators built from them, all
//! over every vertex (the free ones are picked where the derivation needs
//! them).

use pd_constraints::assembly::{LaplacianKind, laplacian};
use pd_constraints::{ConstraintBlock, CsrMatrix, Stencil};
use pd_integrators::StepCoefficients;
use pd_mesh::Point;

/// What one step's derivatives are built from.
pub(crate) struct Operators {
    pub blocks: Vec<Box<dyn ConstraintBlock>>,
    /// Each block's stencils.
    stencils: Vec<Vec<Stencil>>,
    pub masses: Vec<f64>,
    pub fixed: Vec<bool>,
    /// The damping Laplacian `L_d` (n x n, symmetric).
    pub damping_laplacian: CsrMatrix,
    /// `h` in s.
    pub h: f64,
    /// `a1` in 1/s and `a2` in s.
    pub a1: f64,
    pub a2: f64,
    /// The Caughey series' `a3, a4, ...` (s^3, s^5, ...), up to the last
    /// non-zero one: `a_(j+2)` multiplies `P_j = L_ff (M_f^-1 L_ff)^j`.
    pub series: Vec<f64>,
}

impl Operators {
    pub fn new(
        blocks: Vec<Box<dyn ConstraintBlock>>,
        masses: Vec<f64>,
        fixed: Vec<bool>,
        h: f64,
        (a1, a2, series): (f64, f64, &[f64]),
    ) -> Self {
        let n = masses.len();
        let damping_laplacian = laplacian(&blocks, n, LaplacianKind::Damping);
        let stencils = blocks
            .iter()
            .map(|b| (0..b.len()).map(|i| b.stencil(i)).collect())
            .collect();
        Self {
            blocks,
            stencils,
            masses,
            fixed,
            damping_laplacian,
            h,
            a1,
            a2,
            series: series.to_vec(),
        }
    }

    /// The chain `z_0 = w_f`, `z_m = M_f^-1 L_ff z_(m-1)` for `m` up to
    /// `powers` (zero at fixed vertices): `P_j w = L_ff z_j`.
    pub fn series_chain(&self, w: &[Point], powers: usize) -> Vec<Vec<Point>> {
        series_chain(
            &self.damping_laplacian,
            &self.masses,
            &self.fixed,
            w,
            powers,
        )
    }

    /// `L_ff z` (zero at fixed vertices) for `z` zero at fixed vertices.
    pub fn laplacian_free(&self, z: &[Point]) -> Vec<Point> {
        laplacian_free(&self.damping_laplacian, &self.fixed, z)
    }

    /// The elastic Hessian `K(q)`: every constraint's exact energy Hessian
    /// at `q` (3 STENCIL x 3 STENCIL each), kept per element and applied
    /// without assembly.
    pub fn elastic_hessian(&self, q: &[Point]) -> ElementHessians {
        let blocks = self
            .blocks
            .iter()
            .map(|block| {
                let len = block.hessian_len();
                let mut values = vec![0.0; len * block.len()];
                block.hessian_range(q, 0, false, &mut values);
                (values, len)
            })
            .collect();
        ElementHessians { blocks }
    }

    /// `out = (M/h^2 + c1 c2 gamma D) w` with `D = a1 M + a2 L_d + sum_j
    /// a_(j+2) P_j` (the series on the free vertices only) scaled by
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
        if !self.series.is_empty() {
            let chain = self.series_chain(w, self.series.len());
            for (z, &a) in chain[1..].iter().zip(&self.series) {
                if a != 0.0 {
                    let factor = scale * damping * a;
                    for (o, p) in out.iter_mut().zip(self.laplacian_free(z)) {
                        *o += p * factor;
                    }
                }
            }
        }
    }

    /// `out += scale K w`.
    pub fn add_elastic(&self, k: &ElementHessians, w: &[Point], scale: f64, out: &mut [Point]) {
        for ((values, len), stencils) in k.blocks.iter().zip(&self.stencils) {
            for (h, stencil) in values.chunks_exact(*len).zip(stencils) {
                let size = 3 * stencil.len();
                for (a, &va) in stencil.iter().enumerate() {
                    let mut sum = Point::zeros();
                    for (b, &vb) in stencil.iter().enumerate() {
                        let wb = w[vb];
                        for i in 0..3 {
                            let row = &h[(3 * a + i) * size + 3 * b..][..3];
                            sum[i] += row[0] * wb.x + row[1] * wb.y + row[2] * wb.z;
                        }
                    }
                    out[va] += sum * scale;
                }
            }
        }
    }

    /// `out = H w` over every vertex, `H = M/h^2 + c1 c2^2 K + c1 c2 gamma D`
    /// the Hessian of the step objective with respect to the new positions.
    pub fn hessian_product(
        &self,
        c: StepCoefficients,
        k: &ElementHessians,
        w: &[Point],
        out: &mut [Point],
    ) {
        out.iter_mut().for_each(|o| *o = Point::zeros());
        self.add_inertia_damping(c, w, 1.0, out);
        self.add_elastic(k, w, c.c1 * c.c2 * c.c2, out);
    }
}

/// The exact element Hessians of every block at one point: values
/// (`hessian_len` per constraint) and that length.
pub(crate) struct ElementHessians {
    blocks: Vec<(Vec<f64>, usize)>,
}

/// The chain `z_0 = w_f`, `z_m = M_f^-1 L_ff z_(m-1)` (`m <= powers`) of
/// the damping Laplacian `laplacian` restricted to the free vertices (zero
/// at fixed ones): the Caughey series' `P_j w = L_ff z_j`.
pub(crate) fn series_chain(
    laplacian: &CsrMatrix,
    masses: &[f64],
    fixed: &[bool],
    w: &[Point],
    powers: usize,
) -> Vec<Vec<Point>> {
    let mut z = w.to_vec();
    mask_fixed(&mut z, fixed);
    let mut chain = Vec::with_capacity(powers + 1);
    for _ in 0..powers {
        let mut next = laplacian_free(laplacian, fixed, &z);
        for (n, m) in next.iter_mut().zip(masses) {
            if *m > 0.0 {
                *n /= *m;
            }
        }
        chain.push(std::mem::replace(&mut z, next));
    }
    chain.push(z);
    chain
}

/// `L_ff z` over the free rows (zero at fixed vertices), for `z` zero at
/// fixed vertices.
pub(crate) fn laplacian_free(laplacian: &CsrMatrix, fixed: &[bool], z: &[Point]) -> Vec<Point> {
    (0..z.len())
        .map(|i| {
            if fixed[i] {
                Point::zeros()
            } else {
                laplacian.row_dot(i, z)
            }
        })
        .collect()
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
