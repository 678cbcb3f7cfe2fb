//! The per-step global system of lagged damping models
//! (docs/design/formulation.md, "Damping matrices"):
//! `D_n = a1 M + a2 K(x_n)` couples the x, y and z coordinates, so the
//! system is 3n x 3n and its values change every step. The sparsity pattern
//! (every 3 x 3 vertex block of the scalar pattern) is analysed once; each
//! step recomputes the element Hessians at `x_n`, scatters them through
//! precomputed slot maps and refactorises numerically, without allocating.

use faer::Mat;
use pd_constraints::ConstraintBlock;
use pd_mesh::Point;
use rayon::prelude::*;

use crate::SolverError;
use crate::global::{FIXED, GlobalSystem, MatrixCoefficients, combine};
use pd_linalg::cholesky::{LowerPattern, NumericFactor, SymbolicFactor};

/// Constraints per parallel Hessian task.
const CHUNK: usize = 128;
/// Marks a Hessian entry that does not go into the lower triangle of the
/// free-vertex matrix (upper triangle, or a fixed vertex).
const SKIP: u32 = u32::MAX;

/// Hessian storage and slot map of one translation-invariant block.
#[derive(Debug)]
struct BlockHessians {
    /// Index of the block in the local step's block list.
    block: usize,
    /// `len * hessian_len` values, recomputed each step.
    values: Vec<f64>,
    /// Per value: its slot in the 3n lower pattern, or [`SKIP`].
    slots: Vec<u32>,
}

/// The 3n x 3n system of a lagged damping model.
#[derive(Debug)]
pub(crate) struct LaggedSystem {
    mass_part: Vec<f64>,
    system_part: Vec<f64>,
    damping_part: Vec<f64>,
    hessians: Vec<BlockHessians>,
    symbolic: SymbolicFactor,
    factor: NumericFactor,
    values: Vec<f64>,
    /// The right-hand side and solution, 3 n_free x 1, interleaved x, y, z.
    rhs: Mat<f64>,
}

impl LaggedSystem {
    /// Builds the 3n pattern from the scalar one, analyses it and sizes every
    /// buffer.
    pub fn new(
        global: &GlobalSystem,
        blocks: &[Box<dyn ConstraintBlock>],
    ) -> Result<Self, SolverError> {
        let scalar = &global.pattern;
        let nf = scalar.n;
        // Column 3j+b: the diagonal block's rows 3j+b..3j+3, then every
        // off-diagonal block row 3i..3i+3 of scalar column j (rows sorted).
        let mut col_ptr = Vec::with_capacity(3 * nf + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for j in 0..nf {
            let rows = &scalar.row_idx[scalar.col_ptr[j]..scalar.col_ptr[j + 1]];
            for b in 0..3 {
                for &i in rows {
                    let first = if i == j { 3 * j + b } else { 3 * i };
                    row_idx.extend(first..3 * i + 3);
                }
                col_ptr.push(row_idx.len());
            }
        }
        let pattern = LowerPattern {
            n: 3 * nf,
            col_ptr,
            row_idx,
        };
        if pattern.row_idx.len() >= SKIP as usize {
            return Err(SolverError::Unsupported {
                what: "a lagged damping system with more than 2^32 matrix entries".into(),
            });
        }
        let len = pattern.row_idx.len();
        let mut parts = [vec![0.0; len], vec![0.0; len], vec![0.0; len]];
        for j in 0..nf {
            for s in scalar.col_ptr[j]..scalar.col_ptr[j + 1] {
                let i = scalar.row_idx[s];
                for a in 0..3 {
                    let slot = pattern
                        .slot(3 * i + a, 3 * j + a)
                        .expect("the 3n pattern holds every scalar entry's diagonal");
                    parts[0][slot] = global.mass_part[s];
                    parts[1][slot] = global.system_part[s];
                    parts[2][slot] = global.damping_part[s];
                }
            }
        }
        let mut hessians = Vec::new();
        for (index, block) in blocks.iter().enumerate() {
            if !block.translation_invariant() {
                continue;
            }
            let h_len = block.hessian_len();
            let mut slots = Vec::with_capacity(block.len() * h_len);
            for c in 0..block.len() {
                let stencil = block.stencil(c);
                for k in 0..stencil.len() {
                    for a in 0..3 {
                        for l in 0..stencil.len() {
                            for b in 0..3 {
                                let (fu, fw) =
                                    (global.free_index[stencil[k]], global.free_index[stencil[l]]);
                                let slot = if fu == FIXED || fw == FIXED {
                                    SKIP
                                } else {
                                    let (row, col) = (3 * fu + a, 3 * fw + b);
                                    if row < col {
                                        SKIP
                                    } else {
                                        pattern.slot(row, col).map_or(SKIP, |s| s as u32)
                                    }
                                };
                                slots.push(slot);
                            }
                        }
                    }
                }
            }
            hessians.push(BlockHessians {
                block: index,
                values: vec![0.0; block.len() * h_len],
                slots,
            });
        }
        // The scalar system's order with each vertex's x, y, z together.
        let candidates: Vec<Vec<usize>> = global
            .order
            .iter()
            .map(|order| {
                order
                    .iter()
                    .flat_map(|&v| [3 * v, 3 * v + 1, 3 * v + 2])
                    .collect()
            })
            .collect();
        let mut symbolic = SymbolicFactor::analyse(pattern, &candidates)?;
        let [mass_part, system_part, damping_part] = parts;
        // A first numeric factorisation sizes the factor buffer; it is
        // recomputed before every step.
        let values: Vec<f64> = mass_part.clone();
        let factor = symbolic.factorise(&values)?;
        Ok(Self {
            mass_part,
            system_part,
            damping_part,
            hessians,
            symbolic,
            factor,
            values,
            rhs: Mat::zeros(3 * nf, 1),
        })
    }

    /// Recomputes the element Hessians at `positions` (projected to PSD) and
    /// factorises `A = mass M + system L + damping L_d + stiffness K`.
    pub fn refactorise(
        &mut self,
        blocks: &[Box<dyn ConstraintBlock>],
        positions: &[Point],
        coefficients: MatrixCoefficients,
        stiffness: f64,
    ) -> Result<(), SolverError> {
        self.assemble(blocks, positions, coefficients, stiffness, true);
        self.symbolic.refactorise(&self.values, &mut self.factor)?;
        Ok(())
    }

    /// Recomputes the element Hessians at `positions` (projected to PSD with
    /// `project_psd`, else the true ones) and assembles
    /// `mass M + system L + damping L_d + stiffness K` without factorising
    /// it: for [`LaggedSystem::product`] (the true Hessian need not be
    /// positive definite).
    pub fn assemble(
        &mut self,
        blocks: &[Box<dyn ConstraintBlock>],
        positions: &[Point],
        coefficients: MatrixCoefficients,
        stiffness: f64,
        project_psd: bool,
    ) {
        for h in &mut self.hessians {
            let block = &blocks[h.block];
            let chunk = CHUNK * block.hessian_len();
            h.values
                .par_chunks_mut(chunk)
                .enumerate()
                .for_each(|(i, out)| block.hessian_range(positions, i * CHUNK, project_psd, out));
        }
        combine(
            &mut self.values,
            coefficients,
            [&self.mass_part, &self.system_part, &self.damping_part],
        );
        for h in &self.hessians {
            for (&slot, &v) in h.slots.iter().zip(&h.values) {
                if slot != SKIP {
                    self.values[slot as usize] += stiffness * v;
                }
            }
        }
    }

    /// `out = S w` over the free vertices (one point each), `S` the matrix of
    /// the last [`LaggedSystem::assemble`] (or refactorisation), symmetric,
    /// from its lower triangle (the Krylov probe's `H w`).
    #[cfg(feature = "krylov-probe")]
    pub fn product(&self, w: &[Point], out: &mut [Point]) {
        out.iter_mut().for_each(|o| *o = Point::zeros());
        let pattern = self.symbolic.pattern();
        for j in 0..pattern.n {
            let wj = w[j / 3][j % 3];
            let range = pattern.col_ptr[j]..pattern.col_ptr[j + 1];
            let mut column = 0.0;
            for (&i, &value) in pattern.row_idx[range.clone()]
                .iter()
                .zip(&self.values[range])
            {
                out[i / 3][i % 3] += value * wj;
                if i != j {
                    column += value * w[i / 3][i % 3];
                }
            }
            out[j / 3][j % 3] += column;
        }
    }

    /// Factorises the matrix of the last [`LaggedSystem::assemble`].
    ///
    /// # Errors
    /// A matrix that is not positive definite.
    #[cfg(feature = "krylov-probe")]
    pub fn factorise_assembled(&mut self) -> Result<(), SolverError> {
        self.symbolic.refactorise(&self.values, &mut self.factor)?;
        Ok(())
    }

    /// Adds `scale * K w` (K the Hessians of the last refactorisation, over
    /// all vertices) to `out`, one entry per vertex.
    pub fn add_stiffness_product(
        &self,
        blocks: &[Box<dyn ConstraintBlock>],
        w: &[Point],
        scale: f64,
        out: &mut [Point],
    ) {
        for h in &self.hessians {
            let block = &blocks[h.block];
            let h_len = block.hessian_len();
            for (c, hessian) in h.values.chunks_exact(h_len).enumerate() {
                let stencil = block.stencil(c);
                let size = 3 * stencil.len();
                for (k, &u) in stencil.iter().enumerate() {
                    let mut acc = Point::zeros();
                    for (l, &v) in stencil.iter().enumerate() {
                        for a in 0..3 {
                            for b in 0..3 {
                                acc[a] += hessian[(3 * k + a) * size + 3 * l + b] * w[v][b];
                            }
                        }
                    }
                    out[u] += acc * scale;
                }
            }
        }
    }

    /// The matrix of the last refactorisation (full symmetric, 3n interleaved).
    pub fn matrix(&self) -> pd_constraints::CsrMatrix {
        self.symbolic.pattern().to_symmetric(&self.values)
    }

    /// Solves `A u = rhs` (one point per free vertex) with the current
    /// factorisation; [`LaggedSystem::solution`] reads `u`.
    pub fn solve(&mut self, rhs: &[Point]) {
        for (f, p) in rhs.iter().enumerate() {
            for k in 0..3 {
                self.rhs[(3 * f + k, 0)] = p[k];
            }
        }
        self.symbolic
            .solve_in_place(&self.factor, self.rhs.as_mut());
    }

    /// Free vertex `f`'s entry of the last solution.
    #[inline]
    pub fn solution(&self, f: usize) -> Point {
        Point::new(
            self.rhs[(3 * f, 0)],
            self.rhs[(3 * f + 1, 0)],
            self.rhs[(3 * f + 2, 0)],
        )
    }
}
