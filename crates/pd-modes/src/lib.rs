//! Modal analysis of a Projective Dynamics model: the lowest elastic modes
//! of a [`pd_solver::Model`] at rest, and what an integrator does to each.
//! [`elastic_modes`] computes the frequencies `omega`, the mass-normalised
//! shapes and each shape's damping Laplacian quotient `phi^T L_d phi`;
//! [`discrete_mode`] gives the damping ratio a mode of given `omega` and
//! modal damping coefficient actually gets under an integrator's step,
//! numerical damping included. Damping given by ratio (`ratio` and `mode`,
//! or `ratios` and `modes`, in a scene's `[damping]`) is fitted from these
//! when the scene is built: the named modes' frequencies and Laplacian
//! quotients turn the asked ratios into the coefficients `(a1, a2)` of
//! `D = a1 M + a2 Q` ([`pd_damping::ratio`]), and `pd modes` reports the
//! ratio each mode then gets under the scene's integrator
//! (docs/design/damping.md).
//!
//! The modes are the generalized eigenpairs `K phi = omega^2 M phi` of the
//! elastic stiffness `K` (the Hessian of every constraint energy at the
//! rest positions, the exact element Hessians of
//! `ConstraintBlock::hessian_range`, attachments included) and the lumped
//! mass matrix `M`, over the free degrees of freedom (fixed vertices
//! removed).
//!
//! Zero-frequency modes are skipped: the rigid motions a body keeps (six for
//! a free body, three about a pivot, one about a hinge, as
//! [`pd_damping::rigid::RigidFreedom`] classifies them) are deflated
//! explicitly, and any other mode with `omega^2 <= ZERO * scale` (a
//! mechanism, such as the sideways motion of a straight spring chain, which
//! has no stiffness at rest) is counted and left out. `scale` is
//! `max_i K_ii / m_i`, an estimate of the largest `omega^2`.
//!
//! Small systems (at most [`DENSE_LIMIT`] degrees of freedom, or at most
//! [`DENSE_MANY_LIMIT`] when a quarter of them are asked for) are solved
//! densely (`M^-1/2 K M^-1/2`, a symmetric eigensolver: exact to round-off);
//! larger ones by shift-invert block Lanczos (`lanczos.rs`): one
//! sparse Cholesky factorisation of `K + s M` (`s` a small positive shift
//! that makes it definite even with rigid modes present), then three-column
//! solves. Models with mechanisms fall back to shift-invert subspace
//! iteration with Rayleigh-Ritz (`subspace.rs`) on the same factor.
//! See `docs/design/damping.md`.

mod lanczos;
mod refine;
mod response;
mod scatter;
mod series;
mod subspace;

pub use response::{DiscreteMode, discrete_mode};
pub use series::SeriesOperator;

use std::time::Instant;

use nalgebra::{DMatrix, SymmetricEigen};
use pd_constraints::assembly::{self, LaplacianKind};
use pd_damping::rigid::RigidFreedom;
use pd_mesh::Point;

use faer::MatMut;

use pd_linalg::cholesky::{LowerPattern, NumericFactor, SymbolicFactor};
use pd_solver::{Model, SolverError};

/// Systems with at most this many free degrees of freedom are solved with a
/// dense symmetric eigensolver.
pub const DENSE_LIMIT: usize = 300;

/// Up to this many free degrees of freedom, a request for at least a
/// quarter of them is solved densely too: block Lanczos for that many
/// modes costs far more than the dense eigensolver (the bundled
/// cantilever's 1,500 dofs: all of them densely in 3.6 s, by Lanczos over
/// 100 s; 200 of them by Lanczos in 9.8 s).
pub const DENSE_MANY_LIMIT: usize = 3000;

/// A mode with `omega^2 <= ZERO * max_i K_ii / m_i` counts as a zero mode:
/// round-off in the dense eigensolver is about `1e-15` of the largest
/// eigenvalue, while the lowest elastic mode of a mesh with `r` elements
/// along its longest side lies near `(1/r^2)^2` of it (a bending beam), far
/// above `1e-10` for any mesh this solver can factor.
const ZERO: f64 = 1e-10;

/// Constraints per Hessian evaluation batch.
const CHUNK: usize = 256;

/// The shift `s` relative to `max K_ii / m_i`: large enough that `K + s M`
/// is definite to round-off with rigid modes present (condition number about
/// `1 / SHIFT`), small against the lowest elastic `omega^2` of any mesh
/// this solver factors, so that convergence is not slowed.
const SHIFT: f64 = 1e-8;

/// One elastic mode.
#[derive(Debug, Clone, PartialEq)]
pub struct Mode {
    /// Angular frequency `omega` in rad/s.
    pub omega: f64,
    /// The shape per vertex (zero at fixed vertices), mass-normalised:
    /// `sum_i m_i |phi_i|^2 = 1` (units 1/sqrt(kg)).
    pub shape: Vec<Point>,
    /// `phi^T L_d phi` in 1/s^2: the damping Laplacian's Rayleigh quotient
    /// of the mass-normalised mode. Laplacian damping `a2 L_d` gives the mode
    /// the damping coefficient `a2 phi^T L_d phi` (1/s).
    pub laplacian_quotient: f64,
}

impl Mode {
    /// The frequency in Hz, `omega / (2 pi)`.
    pub fn frequency_hz(&self) -> f64 {
        self.omega / std::f64::consts::TAU
    }
}

/// The result of [`elastic_modes`].
#[derive(Debug, Clone, PartialEq)]
pub struct ModalAnalysis {
    /// The lowest elastic modes, lowest first.
    pub modes: Vec<Mode>,
    /// Rigid motions deflated (free bodies, pivots, hinges).
    pub rigid_modes: usize,
    /// Other zero-frequency modes (mechanisms) found and skipped.
    pub mechanisms: usize,
    /// Free degrees of freedom (3 per free vertex).
    pub dofs: usize,
    /// `"dense"`, `"shift-invert block Lanczos"` or `"shift-invert subspace
    /// iteration"`.
    pub method: &'static str,
    /// Blocks expanded (Lanczos) or subspace iterations (0 for the dense
    /// method).
    pub iterations: usize,
    /// Right-hand-side columns solved with the sparse factor (0 for dense).
    pub solved_columns: usize,
    /// Thick restarts of block Lanczos (0 for the other methods).
    pub restarts: usize,
    /// Seconds spent in the sparse Cholesky factorisation (0 for dense).
    pub factor_seconds: f64,
    /// Seconds of the whole analysis, assembly included.
    pub seconds: f64,
    /// Where those seconds went.
    pub phases: Phases,
}

/// Wall-clock seconds of each phase of one analysis (0 for a phase the
/// method does not have).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Phases {
    /// Assembling `K` and `M` at rest over the free degrees of freedom.
    pub assembly: f64,
    /// The rigid motions (connected components and their freedoms).
    pub rigid_basis: f64,
    /// Symbolic and numeric factorisation of `K + s M`.
    pub factorisation: f64,
    /// Solves with the factor.
    pub solves: f64,
    /// M-orthonormalisation (rigid deflation included).
    pub orthonormalisation: f64,
    /// Rayleigh-Ritz: the projected problem, the Ritz vectors, the residual
    /// checks (and Lanczos's restarts).
    pub rayleigh_ritz: f64,
    /// The dense eigensolver (small models).
    pub dense: f64,
    /// The mode shapes and their damping Laplacian quotients.
    pub quotients: f64,
}

/// The Cholesky factor of `K + s M`, `s = SHIFT max_i K_ii / m_i`.
pub(crate) struct ShiftedFactor {
    symbolic: SymbolicFactor,
    numeric: NumericFactor,
    /// `s`, 1/s^2.
    pub shift: f64,
}

impl ShiftedFactor {
    fn new(stiffness: &Stiffness) -> Result<Self, SolverError> {
        let shift = SHIFT * stiffness.scale();
        let mut shifted = stiffness.values.clone();
        for c in 0..stiffness.pattern.n {
            shifted[stiffness.pattern.col_ptr[c]] += shift * stiffness.mass[c];
        }
        let mut symbolic = SymbolicFactor::analyse(stiffness.pattern.clone(), &[])?;
        let numeric = symbolic.factorise(&shifted)?;
        Ok(Self {
            symbolic,
            numeric,
            shift,
        })
    }

    /// Solves in place for up to three columns (the supernodal solve for
    /// exactly three).
    pub fn solve(&mut self, rhs: MatMut<'_, f64>) {
        self.symbolic.solve_in_place(&self.numeric, rhs);
    }

    /// Solves in place for any number of columns (faer's solve).
    pub fn solve_wide(&self, rhs: MatMut<'_, f64>) {
        self.symbolic.solve_in_place_wide(&self.numeric, rhs);
    }
}

/// The elastic stiffness at rest over the free degrees of freedom
/// (`3 f + a` for free vertex `f`, axis `a`), lower triangle.
pub(crate) struct Stiffness {
    pub pattern: LowerPattern,
    pub values: Vec<f64>,
    /// The lumped mass of each degree of freedom, kg.
    pub mass: Vec<f64>,
    /// Global vertex of each free vertex.
    pub free: Vec<usize>,
}

impl Stiffness {
    /// `y = K x`.
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for c in 0..self.pattern.n {
            for s in self.pattern.col_ptr[c]..self.pattern.col_ptr[c + 1] {
                let (r, v) = (self.pattern.row_idx[s], self.values[s]);
                y[r] += v * x[c];
                if r != c {
                    y[c] += v * x[r];
                }
            }
        }
    }

    /// `max_i K_ii / m_i` in 1/s^2, about the largest eigenvalue.
    pub fn scale(&self) -> f64 {
        (0..self.pattern.n)
            .map(|c| self.values[self.pattern.col_ptr[c]] / self.mass[c])
            .fold(0.0, f64::max)
    }
}

/// The lowest `count` elastic modes of `model` at rest (fewer if the model
/// has fewer non-zero modes).
///
/// # Errors
/// [`SolverError::InvalidModel`] for a model without free vertices or with a
/// free vertex of zero mass; [`SolverError::Factorisation`] if the shifted
/// stiffness cannot be factorised.
pub fn elastic_modes(model: &Model, count: usize) -> Result<ModalAnalysis, SolverError> {
    elastic_modes_by(model, count, Method::Auto)
}

/// Which eigensolver [`elastic_modes_by`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Dense up to [`DENSE_LIMIT`] free dofs (or up to
    /// [`DENSE_MANY_LIMIT`] when a quarter of them or more are asked for),
    /// block Lanczos above.
    Auto,
    /// The dense symmetric eigensolver (every mode; cubic in the dofs).
    Dense,
    /// Shift-invert subspace iteration on one sparse Cholesky.
    Subspace,
    /// Shift-invert block Lanczos on one sparse Cholesky; subspace
    /// iteration if the model has mechanisms.
    Lanczos,
}

/// [`elastic_modes`] with the eigensolver chosen (to cross-check the two).
///
/// # Errors
/// As [`elastic_modes`].
pub fn elastic_modes_by(
    model: &Model,
    count: usize,
    method: Method,
) -> Result<ModalAnalysis, SolverError> {
    let start = Instant::now();
    let mut phases = Phases::default();
    let blocks = model.constraint_blocks();
    let free_dofs = 3 * model.fixed().iter().filter(|&&fixed| !fixed).count();
    let dense_wanted = match method {
        Method::Auto => {
            free_dofs <= DENSE_LIMIT || (free_dofs <= DENSE_MANY_LIMIT && 4 * count >= free_dofs)
        }
        Method::Dense => true,
        Method::Subspace | Method::Lanczos => false,
    };
    let stiffness = assemble(model, &blocks, !dense_wanted)?;
    phases.assembly = start.elapsed().as_secs_f64();
    let clock = Instant::now();
    let rigid = rigid_basis(model, &blocks, &stiffness);
    phases.rigid_basis = clock.elapsed().as_secs_f64();
    let rigid_modes = rigid.len();
    let dofs = stiffness.pattern.n;
    let solved = if dense_wanted {
        let clock = Instant::now();
        let (pairs, zeros) = dense(&stiffness, count);
        phases.dense = clock.elapsed().as_secs_f64();
        Solved {
            pairs,
            mechanisms: zeros.saturating_sub(rigid_modes),
            iterations: 0,
            columns: 0,
            restarts: 0,
            method: "dense",
        }
    } else {
        sparse(&stiffness, &rigid, count, method, &mut phases)?
    };
    let clock = Instant::now();
    let modes = shapes(model, &blocks, &stiffness, solved.pairs);
    phases.quotients = clock.elapsed().as_secs_f64();
    Ok(ModalAnalysis {
        modes,
        rigid_modes,
        mechanisms: solved.mechanisms,
        dofs,
        method: solved.method,
        iterations: solved.iterations,
        solved_columns: solved.columns,
        restarts: solved.restarts,
        factor_seconds: phases.factorisation,
        seconds: start.elapsed().as_secs_f64(),
        phases,
    })
}

/// What an eigensolver found: `(omega^2, mass-normalised phi)` over the
/// free dofs, lowest first.
struct Solved {
    pairs: Vec<(f64, Vec<f64>)>,
    mechanisms: usize,
    iterations: usize,
    columns: usize,
    restarts: usize,
    method: &'static str,
}

/// The sparse path: one factorisation of `K + s M`, then block Lanczos
/// (unless `method` asks for subspace iteration, or Lanczos sees a
/// mechanism).
fn sparse(
    stiffness: &Stiffness,
    rigid: &[Vec<f64>],
    count: usize,
    method: Method,
    phases: &mut Phases,
) -> Result<Solved, SolverError> {
    let clock = Instant::now();
    let mut factor = ShiftedFactor::new(stiffness)?;
    phases.factorisation = clock.elapsed().as_secs_f64();
    if method != Method::Subspace
        && let lanczos::Outcome::Converged(found) =
            lanczos::solve(stiffness, rigid, count, &mut factor, phases)
    {
        return Ok(Solved {
            pairs: found.pairs,
            mechanisms: 0,
            iterations: found.blocks,
            columns: found.columns,
            restarts: found.restarts,
            method: "shift-invert block Lanczos",
        });
    }
    let result = subspace::solve(stiffness, rigid, count, &factor, phases)?;
    Ok(Solved {
        pairs: result.pairs,
        mechanisms: result.mechanisms,
        iterations: result.iterations,
        columns: result.columns,
        restarts: 0,
        method: "shift-invert subspace iteration",
    })
}

/// The modes of `pairs` as shapes per vertex, with their damping
/// Laplacian quotients.
fn shapes(
    model: &Model,
    blocks: &[Box<dyn pd_constraints::ConstraintBlock>],
    stiffness: &Stiffness,
    pairs: Vec<(f64, Vec<f64>)>,
) -> Vec<Mode> {
    let damping = assembly::laplacian(blocks, model.num_vertices(), LaplacianKind::Damping);
    let n = model.num_vertices();
    pairs
        .into_iter()
        .map(|(lambda, phi)| {
            let mut shape = vec![Point::zeros(); n];
            for (f, &v) in stiffness.free.iter().enumerate() {
                shape[v] = Point::new(phi[3 * f], phi[3 * f + 1], phi[3 * f + 2]);
            }
            let mut product = vec![Point::zeros(); n];
            damping.mul_points(&shape, &mut product);
            let laplacian_quotient = shape.iter().zip(&product).map(|(a, b)| a.dot(b)).sum();
            Mode {
                omega: lambda.max(0.0).sqrt(),
                shape,
                laplacian_quotient,
            }
        })
        .collect()
}

/// Visits each element Hessian entry at the rest positions that lies in
/// the lower triangle over the free dofs (`3 f + a` for free vertex `f`,
/// axis `a`), as `(row, column, value)`, element by element in block
/// order; entries of fixed vertices and exact zeros are skipped. Both
/// assemblies of `K` (the triplets below, the scatter of `scatter.rs`) add
/// in this order.
fn for_each_lower_hessian_entry(
    rest: &[Point],
    blocks: &[Box<dyn pd_constraints::ConstraintBlock>],
    free_index: &[usize],
    mut visit: impl FnMut(usize, usize, f64),
) {
    for block in blocks {
        if block.is_empty() {
            continue;
        }
        let (len, size) = (block.hessian_len(), 3 * block.stencil(0).len());
        let mut out = vec![0.0; CHUNK * len];
        for first in (0..block.len()).step_by(CHUNK) {
            let count = CHUNK.min(block.len() - first);
            let out = &mut out[..count * len];
            block.hessian_range(rest, first, false, out);
            for (c, h) in out.chunks_exact(len).enumerate() {
                let stencil = block.stencil(first + c);
                for (i, row) in h.chunks_exact(size).enumerate() {
                    for (j, &value) in row.iter().enumerate() {
                        let (fi, fj) = (free_index[stencil[i / 3]], free_index[stencil[j / 3]]);
                        if fi == usize::MAX || fj == usize::MAX || value == 0.0 {
                            continue;
                        }
                        let (r, col) = (3 * fi + i % 3, 3 * fj + j % 3);
                        if r >= col {
                            visit(r, col, value);
                        }
                    }
                }
            }
        }
    }
}

/// Assembles `K` at the rest positions over the free degrees of freedom:
/// `scattered` into a pattern from the stencils (`scatter.rs`, for
/// the sparse eigensolvers), else from sorted triplets (the dense path).
fn assemble(
    model: &Model,
    blocks: &[Box<dyn pd_constraints::ConstraintBlock>],
    scattered: bool,
) -> Result<Stiffness, SolverError> {
    model.check_free_masses()?;
    let n = model.num_vertices();
    let mut free_index = vec![usize::MAX; n];
    let mut free = Vec::new();
    for (v, (index, &fixed)) in free_index.iter_mut().zip(model.fixed()).enumerate() {
        if !fixed {
            *index = free.len();
            free.push(v);
        }
    }
    if free.is_empty() {
        return Err(SolverError::InvalidModel {
            reason: "every vertex is fixed: the model has no modes".into(),
        });
    }
    if scattered {
        let mass = free.iter().flat_map(|&v| [model.masses()[v]; 3]).collect();
        let rest = model.rest_positions();
        return Ok(scatter::assemble(rest, blocks, &free_index, free, mass));
    }
    let nd = 3 * free.len();
    // (column, row, value), lower triangle, diagonal of every dof included.
    let mut triplets: Vec<(usize, usize, f64)> = (0..nd).map(|d| (d, d, 0.0)).collect();
    let rest = model.rest_positions();
    for_each_lower_hessian_entry(rest, blocks, &free_index, |r, col, value| {
        triplets.push((col, r, value));
    });
    triplets.sort_unstable_by_key(|&(c, r, _)| (c, r));
    let mut col_ptr = vec![0; nd + 1];
    let mut row_idx = Vec::new();
    let mut values: Vec<f64> = Vec::new();
    let mut last = (usize::MAX, usize::MAX);
    for (c, r, v) in triplets {
        if (c, r) == last {
            *values.last_mut().expect("a previous entry") += v;
        } else {
            row_idx.push(r);
            values.push(v);
            col_ptr[c + 1] = row_idx.len();
            last = (c, r);
        }
    }
    for c in 0..nd {
        col_ptr[c + 1] = col_ptr[c + 1].max(col_ptr[c]);
    }
    let mass = free.iter().flat_map(|&v| [model.masses()[v]; 3]).collect();
    Ok(Stiffness {
        pattern: LowerPattern {
            n: nd,
            col_ptr,
            row_idx,
        },
        values,
        mass,
        free,
    })
}

/// The rigid motions each connected component keeps, as M-orthonormal
/// vectors over the free degrees of freedom.
fn rigid_basis(
    model: &Model,
    blocks: &[Box<dyn pd_constraints::ConstraintBlock>],
    stiffness: &Stiffness,
) -> Vec<Vec<f64>> {
    let mut dof_of = vec![usize::MAX; model.num_vertices()];
    for (f, &v) in stiffness.free.iter().enumerate() {
        dof_of[v] = 3 * f;
    }
    let rest = model.rest_positions();
    let axes = [Point::x(), Point::y(), Point::z()];
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for body in &model.rigid_bodies(blocks) {
        let field = |velocity: &dyn Fn(&Point) -> Point| {
            let mut out = vec![0.0; stiffness.pattern.n];
            for &v in &body.vertices {
                let u = velocity(&rest[v]);
                out[dof_of[v]..dof_of[v] + 3].copy_from_slice(u.as_slice());
            }
            out
        };
        let mut fields = Vec::new();
        match body.freedom {
            RigidFreedom::Free => {
                let mass: f64 = body.vertices.iter().map(|&v| model.masses()[v]).sum();
                let centre = body
                    .vertices
                    .iter()
                    .map(|&v| rest[v] * model.masses()[v])
                    .sum::<Point>()
                    / mass;
                for axis in axes {
                    fields.push(field(&|_| axis));
                    fields.push(field(&|p| axis.cross(&(p - centre))));
                }
            }
            RigidFreedom::Pivot { point } => {
                for axis in axes {
                    fields.push(field(&|p| axis.cross(&(p - point))));
                }
            }
            RigidFreedom::Hinge { point, axis } => {
                fields.push(field(&|p| axis.cross(&(p - point))))
            }
            RigidFreedom::Held => {}
        }
        for mut f in fields {
            // Twice-applied Gram-Schmidt in the M inner product.
            for _ in 0..2 {
                for b in &basis {
                    let projection = mass_dot(&stiffness.mass, b, &f);
                    f.iter_mut().zip(b).for_each(|(x, y)| *x -= projection * y);
                }
            }
            let norm = mass_dot(&stiffness.mass, &f, &f).sqrt();
            if norm > 1e-12 {
                f.iter_mut().for_each(|x| *x /= norm);
                basis.push(f);
            }
        }
    }
    basis
}

/// `a^T M b` for the per-dof masses `mass`.
pub(crate) fn mass_dot(mass: &[f64], a: &[f64], b: &[f64]) -> f64 {
    mass.iter().zip(a).zip(b).map(|((m, x), y)| m * x * y).sum()
}

/// Every eigenpair by a dense symmetric eigensolver; returns the lowest
/// `count` non-zero ones `(omega^2, mass-normalised phi)` and the number of
/// zero modes.
fn dense(stiffness: &Stiffness, count: usize) -> (Vec<(f64, Vec<f64>)>, usize) {
    let nd = stiffness.pattern.n;
    let scale: Vec<f64> = stiffness.mass.iter().map(|m| 1.0 / m.sqrt()).collect();
    let mut a = DMatrix::<f64>::zeros(nd, nd);
    for c in 0..nd {
        for s in stiffness.pattern.col_ptr[c]..stiffness.pattern.col_ptr[c + 1] {
            let r = stiffness.pattern.row_idx[s];
            let v = stiffness.values[s] * scale[r] * scale[c];
            a[(r, c)] = v;
            a[(c, r)] = v;
        }
    }
    let eigen = SymmetricEigen::new(a);
    let mut order: Vec<usize> = (0..nd).collect();
    order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
    let threshold = ZERO * stiffness.scale();
    let zeros = order
        .iter()
        .filter(|&&i| eigen.eigenvalues[i] <= threshold)
        .count();
    let pairs = order
        .into_iter()
        .filter(|&i| eigen.eigenvalues[i] > threshold)
        .take(count)
        .map(|i| {
            let phi = eigen
                .eigenvectors
                .column(i)
                .iter()
                .zip(&scale)
                .map(|(u, s)| u * s)
                .collect();
            (eigen.eigenvalues[i], phi)
        })
        .collect();
    (pairs, zeros)
}
