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
    /// Where the elastic Hessian's 3 x 3 blocks are.
    pattern: BlockPattern,
    /// The diagonal block of each vertex and the block of each entry of
    /// `damping_laplacian` (row by row), when the pattern has them all: the
    /// step Hessian (but the series) is then assembled whole.
    whole: Option<(Vec<usize>, Vec<usize>)>,
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
            .collect::<Vec<Vec<Stencil>>>();
        let pattern = BlockPattern::new(&stencils, n);
        let diagonal: Option<Vec<usize>> = (0..n).map(|v| pattern.slot(v, v)).collect();
        let laplacian_slots: Option<Vec<usize>> = (0..n)
            .flat_map(|row| {
                let pattern = &pattern;
                damping_laplacian
                    .row(row)
                    .map(move |(column, _)| pattern.slot(row, column))
            })
            .collect();
        let whole = diagonal.zip(laplacian_slots);
        Self {
            blocks,
            stencils,
            pattern,
            whole,
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
    /// at `q` (3 STENCIL x 3 STENCIL each), assembled into 3 x 3 blocks
    /// (one per pair of vertices sharing a constraint). The element
    /// Hessians are evaluated a batch at a time into a small buffer and
    /// added into the blocks, so no per-element storage is kept. With it,
    /// when the pattern allows, the step objective's Hessian for the step
    /// coefficients `c` but the series' terms, `M/h^2 + c1 c2^2 K + c1 c2
    /// gamma (a1 M + a2 L_d)`, in the same blocks: one pass over the blocks
    /// then applies it ([`Operators::hessian_product`]).
    pub fn elastic_hessian(&self, q: &[Point], c: StepCoefficients) -> ElasticHessian {
        /// Elements evaluated per call of `hessian_range`.
        const BATCH: usize = 64;
        let pattern = &self.pattern;
        let mut values = vec![[0.0; 9]; pattern.columns.len()];
        let mut buffer = Vec::new();
        for ((block, stencils), slots) in self.blocks.iter().zip(&self.stencils).zip(&pattern.slots)
        {
            let len = block.hessian_len();
            let count = block.len();
            buffer.resize(len * BATCH.min(count), 0.0);
            let mut first = 0;
            while first < count {
                let batch = BATCH.min(count - first);
                let element_hessians = &mut buffer[..len * batch];
                block.hessian_range(q, first, false, element_hessians);
                for (i, h) in element_hessians.chunks_exact(len).enumerate() {
                    let element = first + i;
                    let s = stencils[element].len();
                    let size = 3 * s;
                    let element_slots = &slots[slots_start(element, s)..][..s * s];
                    for a in 0..s {
                        for b in 0..s {
                            let v = &mut values[element_slots[a * s + b]];
                            for row in 0..3 {
                                let source = &h[(3 * a + row) * size + 3 * b..][..3];
                                for (v, h) in v[3 * row..3 * row + 3].iter_mut().zip(source) {
                                    *v += h;
                                }
                            }
                        }
                    }
                }
                first += batch;
            }
        }
        let step = self.whole.as_ref().map(|(diagonal, laplacian_slots)| {
            let damping = c.c1 * c.c2 * c.gamma;
            let elastic = c.c1 * c.c2 * c.c2;
            let mut step: Vec<[f64; 9]> = values
                .iter()
                .map(|block| block.map(|v| v * elastic))
                .collect();
            let mass = 1.0 / (self.h * self.h) + damping * self.a1;
            for (&slot, m) in diagonal.iter().zip(&self.masses) {
                for i in [0, 4, 8] {
                    step[slot][i] += mass * m;
                }
            }
            if self.a2 != 0.0 {
                let factor = damping * self.a2;
                let mut slots = laplacian_slots.iter();
                for row in 0..self.masses.len() {
                    for ((_, value), &slot) in self.damping_laplacian.row(row).zip(&mut slots) {
                        for i in [0, 4, 8] {
                            step[slot][i] += factor * value;
                        }
                    }
                }
            }
            step
        });
        ElasticHessian { values, step }
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
        self.add_series(c, w, scale, out);
    }

    /// `out += scale c1 c2 gamma sum_j a_(j+2) P_j w`: the series' part of
    /// [`Operators::add_inertia_damping`].
    fn add_series(&self, c: StepCoefficients, w: &[Point], scale: f64, out: &mut [Point]) {
        let damping = c.c1 * c.c2 * c.gamma;
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
    pub fn add_elastic(&self, k: &ElasticHessian, w: &[Point], scale: f64, out: &mut [Point]) {
        self.add_blocks(&k.values, w, scale, out);
    }

    /// `out += scale B w` for the blocks `values` of the pattern.
    fn add_blocks(&self, values: &[[f64; 9]], w: &[Point], scale: f64, out: &mut [Point]) {
        let pattern = &self.pattern;
        for (row, o) in out.iter_mut().enumerate() {
            let range = pattern.row_start[row]..pattern.row_start[row + 1];
            let mut sum = [0.0; 3];
            for (m, &column) in values[range.clone()].iter().zip(&pattern.columns[range]) {
                let x = w[column];
                sum[0] += m[0] * x.x + m[1] * x.y + m[2] * x.z;
                sum[1] += m[3] * x.x + m[4] * x.y + m[5] * x.z;
                sum[2] += m[6] * x.x + m[7] * x.y + m[8] * x.z;
            }
            *o += Point::new(sum[0], sum[1], sum[2]) * scale;
        }
    }

    /// `out = H w` over every vertex, `H = M/h^2 + c1 c2^2 K + c1 c2 gamma D`
    /// the Hessian of the step objective with respect to the new positions
    /// (`c` the coefficients `k` was evaluated with).
    pub fn hessian_product(
        &self,
        c: StepCoefficients,
        k: &ElasticHessian,
        w: &[Point],
        out: &mut [Point],
    ) {
        out.iter_mut().for_each(|o| *o = Point::zeros());
        if let Some(step) = &k.step {
            self.add_blocks(step, w, 1.0, out);
            self.add_series(c, w, 1.0, out);
        } else {
            self.add_inertia_damping(c, w, 1.0, out);
            self.add_elastic(k, w, c.c1 * c.c2 * c.c2, out);
        }
    }
}

/// The elastic Hessian at one point, assembled: one row-major 3 x 3 block
/// per entry of the operators' [`BlockPattern`], and the step Hessian.
pub(crate) struct ElasticHessian {
    values: Vec<[f64; 9]>,
    /// The step Hessian but the series, in the same blocks, when the
    /// pattern holds every vertex's diagonal and every entry of `L_d`.
    step: Option<Vec<[f64; 9]>>,
}

/// Where the 3 x 3 blocks of the elastic Hessian are: block rows by vertex
/// (compressed, columns sorted), and where each constraint's stencil pairs
/// land.
struct BlockPattern {
    /// Row `i`'s blocks are `row_start[i]..row_start[i + 1]`.
    row_start: Vec<usize>,
    /// Each block's column vertex.
    columns: Vec<usize>,
    /// Per constraint block, the block index of each constraint's stencil
    /// pair `(a, b)`: entry `slots_start(i, s) + a s + b` for constraint `i`
    /// of stencil size `s`.
    slots: Vec<Vec<usize>>,
}

/// Where constraint `element`'s slots start in a block of stencil size `s`
/// (every constraint of a block has the same stencil size).
fn slots_start(element: usize, s: usize) -> usize {
    element * s * s
}

impl BlockPattern {
    fn new(stencils: &[Vec<Stencil>], n: usize) -> Self {
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n];
        for stencil in stencils.iter().flatten() {
            for &a in stencil.iter() {
                neighbours[a].extend(stencil.iter().copied());
            }
        }
        let mut row_start = Vec::with_capacity(n + 1);
        row_start.push(0);
        let mut columns = Vec::new();
        for row in &mut neighbours {
            row.sort_unstable();
            row.dedup();
            columns.extend_from_slice(row);
            row_start.push(columns.len());
        }
        let mut pattern = Self {
            row_start,
            columns,
            slots: Vec::new(),
        };
        // Every stencil pair was entered above.
        let slot = |a: usize, b: usize| pattern.slot(a, b).unwrap_or(0);
        let slots = stencils
            .iter()
            .map(|block| {
                let mut slots = Vec::new();
                for stencil in block {
                    for &a in stencil.iter() {
                        for &b in stencil.iter() {
                            slots.push(slot(a, b));
                        }
                    }
                }
                slots
            })
            .collect();
        pattern.slots = slots;
        pattern
    }

    /// The block of row `a`, column `b`, if the pattern has it.
    fn slot(&self, a: usize, b: usize) -> Option<usize> {
        let row = &self.columns[self.row_start[a]..self.row_start[a + 1]];
        row.binary_search(&b).ok().map(|i| self.row_start[a] + i)
    }
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
