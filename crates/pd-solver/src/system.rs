//! The global step behind one interface: the constant operators over the
//! free vertices ([`GlobalSystem`]) and the matrix of the coming step, either
//! a cached factor of the constant `A = alpha M + beta L_sys + delta L_d`
//! or the lagged 3n x 3n system that adds `K(x_n)`
//! (docs/design/formulation.md, "The global step" and "Damping matrices").
//! Which of the two a simulation has is decided once, from the damping
//! model's [`DampingMatrix`]; callers never see the difference. The system
//! owns its right-hand side: callers hand it one point per free vertex and
//! read the solution back, per free vertex.

use pd_constraints::{ConstraintBlock, CsrMatrix};
use pd_damping::DampingMatrix;
use pd_integrators::StepCoefficients;
use pd_mesh::Point;
use rayon::prelude::*;

use crate::SolverError;
use crate::global::{GlobalSystem, MatrixCoefficients};
use crate::lagged::LaggedSystem;
use crate::local::LocalStep;
use crate::rotation::{RotationProjection, StepMotion};
use crate::weights::DampingWeights;

/// The matrix of the coming step and its factorisation.
#[derive(Debug)]
enum StepMatrix {
    /// A constant model: the index of the cached factor of this step's
    /// coefficients, and the right-hand side and solution (one point per
    /// free vertex).
    Constant { factor: usize, rhs: Vec<Point> },
    /// A lagged model: refactorised every step (boxed: it is large and there
    /// is one per simulation).
    Lagged(Box<LaggedSystem>),
}

/// The coefficients of one step's global matrix: `A = mass M + system L_sys
/// + damping L_d + lagged_stiffness K(x_n)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SystemCoefficients {
    pub matrix: MatrixCoefficients,
    pub lagged_stiffness: f64,
}

impl SystemCoefficients {
    /// The matrix of a step with integrator coefficients `c`, damping
    /// matrix `d` and time step `h` (s), docs/design/formulation.md, "The
    /// global step".
    pub fn of(c: StepCoefficients, d: DampingMatrix, h: f64) -> Self {
        let damping_factor = c.c1 * c.c2 * c.gamma;
        Self {
            matrix: MatrixCoefficients {
                mass: 1.0 / (h * h) + damping_factor * d.mass,
                system: c.c1 * c.c2 * c.c2,
                damping: damping_factor * d.damping_laplacian,
                mass_damping: damping_factor * d.mass,
                series: d.series.map(|a| damping_factor * a),
            },
            lagged_stiffness: damping_factor * d.lagged_stiffness,
        }
    }
}

/// What the constant part of the right-hand side is built from
/// ([`GlobalStep::constant_rhs`]); every vector has one entry per vertex.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RhsInput<'a> {
    pub masses: &'a [f64],
    /// `x_n` in m.
    pub positions: &'a [Point],
    /// `y - x_n` in m.
    pub inertial_displacement: &'a [Point],
    /// `x_hat - x_n` in m, the anchor of the mass and lagged terms.
    pub anchor_displacement: &'a [Point],
    /// The anchor of the `L_d` term, m.
    pub laplacian_anchor: &'a [Point],
    pub coefficients: StepCoefficients,
    pub damping: DampingMatrix,
    /// `h` in s.
    pub h: f64,
}

/// The global step: operators, the step's matrix, its factor and its
/// right-hand side.
#[derive(Debug)]
pub(crate) struct GlobalStep {
    system: GlobalSystem,
    matrix: StepMatrix,
    /// Columns of the constant matrix's inverse, for the contact solve of
    /// steps with an accuracy target.
    columns: InverseColumns,
    /// The rotation-preserving damping's projection, when the damping model
    /// asks for it (`rotation.rs`).
    rotation: Option<RotationProjection>,
}

/// Columns of `A^-1` kept beyond the current contacts'
/// ([`GlobalStep::keep_columns`]).
const SPARE_COLUMNS: usize = 64;

/// Columns of `A^-1` (free indices), each computed by one solve with the
/// cached factor `factor`: the response of the whole body to a unit force
/// on a contact vertex (pd-contact's Delassus solve,
/// docs/design/contact.md, "Friction with an accuracy target").
#[derive(Debug, Default)]
struct InverseColumns {
    factor: usize,
    by_row: std::collections::HashMap<usize, Vec<f64>>,
    scratch: Vec<Point>,
}

impl GlobalStep {
    /// Assembles the operators, analyses the pattern and, for a lagged
    /// damping model (`lagged`), the 3n system. Nothing is factorised yet:
    /// [`GlobalStep::prepare`] does that. `threads` is the step's thread
    /// count and `series_powers` the Caughey series' highest power
    /// ([`GlobalSystem::new`]).
    pub fn new(
        local: &LocalStep,
        masses: &[f64],
        fixed: &[bool],
        rest: &[Point],
        lagged: bool,
        threads: usize,
        series_powers: usize,
    ) -> Result<Self, SolverError> {
        let system = GlobalSystem::new(local, masses, fixed, rest, threads, series_powers)?;
        let matrix = if lagged {
            StepMatrix::Lagged(Box::new(LaggedSystem::new(&system, local.blocks())?))
        } else {
            StepMatrix::Constant {
                factor: usize::MAX,
                rhs: vec![Point::zeros(); system.free.len()],
            }
        };
        Ok(Self {
            system,
            matrix,
            columns: InverseColumns::default(),
            rotation: None,
        })
    }

    /// Makes the step damp `(I - P)^T L_d (I - P)` instead of `L_d` for the
    /// components among `rigid` for which `projected` says yes
    /// (`rotation.rs`); each step then builds `P` at its start
    /// ([`GlobalStep::prepare_rotation`]).
    ///
    /// # Errors
    /// [`SolverError::Unsupported`] naming `damping.preserve_rotation` for a
    /// lagged step matrix or constraints coupling components.
    pub fn set_rotation_projection(
        &mut self,
        rigid: &[pd_damping::rigid::RigidBody],
        projected: impl Fn(usize) -> bool,
    ) -> Result<(), SolverError> {
        if matches!(self.matrix, StepMatrix::Lagged(_)) {
            return Err(SolverError::Unsupported {
                what: "damping.preserve_rotation with a lagged damping term: the projection \
                       needs the prefactored step matrix"
                    .into(),
            });
        }
        self.rotation = Some(RotationProjection::new(&self.system, rigid, projected)?);
        Ok(())
    }

    /// Whether the step damps the projected `L_d` (a rotation-preserving
    /// damping model).
    pub fn projects_rotations(&self) -> bool {
        self.rotation.is_some()
    }

    /// The rotation-preserving projection's reference lever arms, for a
    /// checkpoint (empty without one).
    pub fn rotation_state(&self) -> crate::RotationState {
        self.rotation
            .as_ref()
            .map_or_else(Default::default, RotationProjection::save)
    }

    /// Checks a checkpoint's [`crate::RotationState`] against the
    /// projection.
    ///
    /// # Errors
    /// The reason, naming the field, when it does not fit (arms for a
    /// simulation without the projection, or of another count).
    pub fn check_rotation_state(&self, state: &crate::RotationState) -> Result<(), String> {
        match &self.rotation {
            Some(rotation) => rotation.check(state),
            None if state.is_empty() => Ok(()),
            None => Err(
                "the checkpoint has rotation-preserving reference arms (rotation), \
                         the simulation does not project rotations"
                    .into(),
            ),
        }
    }

    /// Takes a checkpoint's [`crate::RotationState`], checked by
    /// [`GlobalStep::check_rotation_state`].
    pub fn restore_rotation_state(&mut self, state: &crate::RotationState) {
        if let Some(rotation) = &mut self.rotation {
            rotation.load(state);
        }
    }

    /// Builds this step's projection from `motion` for the step matrix
    /// `coefficients` (prepared). Does nothing without
    /// [`GlobalStep::set_rotation_projection`].
    pub fn prepare_rotation(
        &mut self,
        rigid: &[pd_damping::rigid::RigidBody],
        motion: StepMotion<'_>,
        coefficients: SystemCoefficients,
    ) {
        let Some(rotation) = &mut self.rotation else {
            return;
        };
        let StepMatrix::Constant { factor, .. } = &self.matrix else {
            return;
        };
        let factor = *factor;
        let system = &mut self.system;
        let weights = system.weights.as_ref();
        let solves = rotation.begin_update(system, rigid, motion, coefficients.matrix, |v| {
            weights.map_or((1.0, 1.0), |w| (w.mass[v], w.laplacian[v]))
        });
        if let Some((m, l)) = solves {
            system.solve_points(factor, m);
            if let Some(l) = l {
                system.solve_points(factor, l);
            }
            rotation.finish_update();
        }
    }

    /// Scales the damping terms per body (a per-body damping model:
    /// `per_body` holds one implicit matrix per body of `bodies`, vertex
    /// ranges, each term at most `reference`'s), before the first
    /// factorisation (`weights.rs`).
    ///
    /// # Errors
    /// As [`DampingWeights::new`].
    pub fn set_damping_weights(
        &mut self,
        per_body: &[DampingMatrix],
        reference: DampingMatrix,
        bodies: &[std::ops::Range<usize>],
    ) -> Result<(), SolverError> {
        self.system.weights = Some(DampingWeights::new(
            &self.system,
            per_body,
            reference,
            bodies,
        )?);
        Ok(())
    }

    /// Refuses a Caughey series `d` whose polynomial `sum_k a_k s^(k-1)`
    /// is negative somewhere on `[0, bound]`, `bound` the Gershgorin bound
    /// of the spectrum of `M_f^-1 L_ff` (`pd_damping::ratio::series_negative_at`):
    /// `D` would be indefinite and add energy. `masses` per vertex, kg.
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] naming `damping.series`.
    pub fn check_series_positive(
        &self,
        d: &DampingMatrix,
        masses: &[f64],
    ) -> Result<(), SolverError> {
        let system = &self.system;
        let bound = (0..system.free.len())
            .map(|f| {
                let v = system.free[f];
                let row: f64 = system
                    .damping_rows
                    .row(f)
                    .filter(|(c, _)| system.free_index[*c] != crate::global::FIXED)
                    .map(|(c, x)| if c == v { x } else { x.abs() })
                    .sum();
                row / masses[v]
            })
            .fold(0.0, f64::max);
        let coefficients = d.series_coefficients();
        match pd_damping::ratio::series_negative_at(&coefficients, bound) {
            None => Ok(()),
            Some(s) => Err(SolverError::InvalidSetting {
                field: "damping.series",
                reason: format!(
                    "the series {coefficients:?} (a1, a2, a3, ...) is negative at s = {s:e} \
                     1/s^2, inside the spectrum bound {bound:e} of M^-1 L_d: the damping \
                     matrix would be indefinite and add energy"
                ),
            }),
        }
    }

    /// The per-body damping weights, if any.
    pub fn damping_weights(&self) -> Option<&DampingWeights> {
        self.system.weights.as_ref()
    }

    /// The constant operators over the free vertices.
    pub fn system(&self) -> &GlobalSystem {
        &self.system
    }

    /// Global index of each free vertex.
    pub fn free(&self) -> &[usize] {
        &self.system.free
    }

    /// Number of stored values of one Cholesky factor of the scalar system.
    pub fn factor_len(&self) -> usize {
        self.system.factor_len()
    }

    /// Structural non-zeros of one Cholesky factor of the scalar system
    /// (the count CHOLMOD reports as `lnz`).
    pub fn factor_nnz(&self) -> usize {
        self.system.factor_nnz()
    }

    /// Makes the matrix of the coming step ready: the cached factor of a
    /// constant matrix (factorising only on a cache miss), or a fresh
    /// numeric factorisation of the lagged system with `K` at `positions`.
    /// Returns whether it factorised.
    pub fn prepare(
        &mut self,
        coefficients: SystemCoefficients,
        blocks: &[Box<dyn ConstraintBlock>],
        positions: &[Point],
    ) -> Result<bool, SolverError> {
        match &mut self.matrix {
            StepMatrix::Constant { factor, .. } => {
                let (index, factorised) = self.system.prepare_factor(coefficients.matrix)?;
                *factor = index;
                Ok(factorised)
            }
            StepMatrix::Lagged(lagged) => {
                lagged.refactorise(
                    blocks,
                    positions,
                    coefficients.matrix,
                    coefficients.lagged_stiffness,
                )?;
                Ok(true)
            }
        }
    }

    /// Recomputes the numeric factorisation of the coming step's matrix into
    /// its existing buffer (for timing it alone): bit for bit the same
    /// factor for a constant model, the per-step refactorisation for a
    /// lagged one.
    pub fn refactorise(
        &mut self,
        coefficients: SystemCoefficients,
        blocks: &[Box<dyn ConstraintBlock>],
        positions: &[Point],
    ) -> Result<(), SolverError> {
        match &mut self.matrix {
            StepMatrix::Constant { .. } => self.system.refactorise_cached(coefficients.matrix),
            StepMatrix::Lagged(_) => self.prepare(coefficients, blocks, positions).map(|_| ()),
        }
    }

    /// The global matrix for `coefficients` over the free unknowns, full and
    /// symmetric: n_free x n_free for a constant model, 3 n_free x 3 n_free
    /// (x, y, z interleaved) for a lagged one, refactorised at `positions`.
    pub fn matrix(
        &mut self,
        coefficients: SystemCoefficients,
        blocks: &[Box<dyn ConstraintBlock>],
        positions: &[Point],
    ) -> Result<CsrMatrix, SolverError> {
        self.prepare(coefficients, blocks, positions)?;
        Ok(match &self.matrix {
            StepMatrix::Constant { .. } => self.system.matrix(coefficients.matrix),
            StepMatrix::Lagged(lagged) => lagged.matrix(),
        })
    }

    /// The part of the right-hand side that stays the same through a step's
    /// iterations, one point per free vertex, into `out` (docs/design/solver.md):
    ///
    /// `M (y - x_n) / h^2 - c1 c2 L x_n + c1 c2 gamma D (x_hat - x_n)`.
    ///
    /// Every term is built from displacements or, for `L x_n = L_d x_n +
    /// L_anchor x_n`, from the differences `x_j - x_i` across each row of
    /// the translation-invariant `L_d` (only attachments see absolute
    /// positions), so round-off scales with how far the body moves in a
    /// step, not with its distance from the origin. `scratch` (one point per
    /// vertex) holds the lagged `K (x_hat - x_n)`.
    pub fn constant_rhs(
        &self,
        blocks: &[Box<dyn ConstraintBlock>],
        input: &RhsInput<'_>,
        out: &mut [Point],
        scratch: &mut [Point],
    ) {
        let RhsInput {
            masses,
            positions: x_n,
            inertial_displacement: inertial,
            anchor_displacement: anchor,
            laplacian_anchor,
            coefficients: c,
            damping: d,
            h,
        } = *input;
        let energy_factor = c.c1 * c.c2;
        let damping_factor = energy_factor * c.gamma;
        let inv_h2 = 1.0 / (h * h);
        let system = &self.system;
        let use_damping_laplacian = d.damping_laplacian != 0.0;
        out.par_iter_mut().enumerate().for_each(|(f, out)| {
            let v = system.free[f];
            let elastic = system.damping_rows.row_dot_relative(f, x_n[v], x_n)
                + system.anchoring_rows.row_dot(f, x_n);
            let mut b = inertial[v] * (masses[v] * inv_h2) - elastic * energy_factor;
            if d.mass != 0.0 {
                let mut a = damping_factor * d.mass * masses[v];
                if let Some(w) = &system.weights {
                    a *= w.mass[v];
                }
                b += anchor[v] * a;
            }
            if use_damping_laplacian {
                let mut a = damping_factor * d.damping_laplacian;
                if let Some(w) = &system.weights {
                    a *= w.laplacian[v];
                }
                b += system
                    .damping_rows
                    .row_dot_relative(f, laplacian_anchor[v], laplacian_anchor)
                    * a;
            }
            // The series' terms a_(j+3) P_(j+1) (x_hat - x_n), with the
            // Laplacian's anchor (zero at fixed vertices).
            for (rows, &a) in system.series_rows.iter().zip(&d.series) {
                if a != 0.0 {
                    b += rows.row_dot(f, laplacian_anchor) * (damping_factor * a);
                }
            }
            *out = b;
        });
        if use_damping_laplacian && let Some(rotation) = &self.rotation {
            // The projected operator: c (I - P)^T L_d (I - P) on the anchor.
            rotation.add_product_correction(laplacian_anchor, out);
        }
        if let StepMatrix::Lagged(lagged) = &self.matrix {
            // + c1 c2 gamma a3 K(x_n) (x_hat - x_n), on every vertex, then
            // gathered to the free ones.
            scratch.iter_mut().for_each(|f| *f = Point::zeros());
            lagged.add_stiffness_product(
                blocks,
                anchor,
                damping_factor * d.lagged_stiffness,
                scratch,
            );
            for (out, &v) in out.iter_mut().zip(&system.free) {
                *out += scratch[v];
            }
        }
    }

    /// The full right-hand side `constant + energy_factor B p` for the
    /// stacked projections `p`, one point per free vertex, into `out`
    /// (scattered projection by projection, on more threads one range of
    /// vertices per thread or gathered row-parallel,
    /// `projection_scatter.rs`; each row is summed in one fixed order, so
    /// the result does not depend on the thread count).
    pub fn rhs_with_projections(
        &self,
        constant: &[Point],
        projections: &[Point],
        energy_factor: f64,
        out: &mut [Point],
    ) {
        self.system
            .projection_rows
            .rhs(constant, projections, energy_factor, out);
    }

    /// Solves with the step matrix `A` alone, without the rotation-preserving
    /// damping's projection (for another matrix than the step's, whose
    /// projection would not match), in place; as [`GlobalStep::solve`]
    /// otherwise. Constant matrices only: a lagged one is solved as
    /// [`GlobalStep::solve`] does.
    pub fn solve_unprojected(&mut self, rhs: &mut [Point]) {
        match &mut self.matrix {
            StepMatrix::Constant { factor, .. } => self.system.solve_points(*factor, rhs),
            StepMatrix::Lagged(lagged) => {
                lagged.solve(rhs);
                for (f, out) in rhs.iter_mut().enumerate() {
                    *out = lagged.solution(f);
                }
            }
        }
    }

    /// Solves the step's system for `rhs` (one point per free vertex);
    /// [`GlobalStep::solution`] reads the result. Requires a
    /// [`GlobalStep::prepare`] since the last change of coefficients.
    pub fn solve(&mut self, rhs: &[Point]) {
        match &mut self.matrix {
            StepMatrix::Constant {
                factor,
                rhs: points,
            } => {
                points.copy_from_slice(rhs);
                self.system.solve_points(*factor, points);
                if let Some(rotation) = &self.rotation {
                    rotation.correct_solution(points);
                }
            }
            StepMatrix::Lagged(lagged) => lagged.solve(rhs),
        }
    }

    /// Whether the step's matrix is the constant, prefactored one (not the
    /// lagged system refactorised every step).
    pub fn is_constant(&self) -> bool {
        matches!(self.matrix, StepMatrix::Constant { .. })
    }

    /// `[A^-1]_fg` of the constant matrix (free indices), from column `f`,
    /// which costs one solve the first time it is asked for and is kept
    /// until [`GlobalStep::keep_columns`] drops it. `None` for a lagged
    /// matrix. Requires a [`GlobalStep::prepare`] since the last change of
    /// coefficients.
    pub fn inverse_entry(&mut self, f: usize, g: usize) -> Option<f64> {
        let StepMatrix::Constant { factor, .. } = &self.matrix else {
            return None;
        };
        let columns = &mut self.columns;
        if columns.factor != *factor {
            columns.by_row.clear();
            columns.factor = *factor;
        }
        if !columns.by_row.contains_key(&f) {
            let e = &mut columns.scratch;
            e.clear();
            e.resize(self.system.free.len(), Point::zeros());
            e[f].x = 1.0;
            self.system.solve_points(*factor, e);
            columns.by_row.insert(f, e.iter().map(|p| p.x).collect());
        }
        columns.by_row.get(&f).map(|column| column[g])
    }

    /// Once [`GlobalStep::inverse_entry`] holds more than `rows` +
    /// [`SPARE_COLUMNS`] columns, drops those whose row `keep` refuses: a
    /// contact that ends and starts again soon may keep its column, and the
    /// columns held stay within [`SPARE_COLUMNS`] of the current contacts'.
    pub fn keep_columns(&mut self, rows: usize, keep: impl Fn(usize) -> bool) {
        if self.columns.by_row.len() > rows + SPARE_COLUMNS {
            self.columns.by_row.retain(|&f, _| keep(f));
        }
    }

    /// Drops every column [`GlobalStep::inverse_entry`] holds and releases
    /// their memory.
    pub fn drop_columns(&mut self) {
        self.columns.by_row = Default::default();
    }

    /// Free vertex `f`'s entry of the last solution.
    #[inline]
    pub fn solution(&self, f: usize) -> Point {
        match &self.matrix {
            StepMatrix::Constant { rhs, .. } => rhs[f],
            StepMatrix::Lagged(lagged) => lagged.solution(f),
        }
    }

    /// `w <- (I - P) w` (`w` by vertex) with the rotation-preserving
    /// damping's projection of this step; nothing without one.
    pub fn project_rotations(&self, w: &mut [Point]) {
        if let Some(rotation) = &self.rotation {
            rotation.project(w);
        }
    }

    /// `out <- out - c U C U^T w` on the free rows: turns a product `A w`
    /// (one point per free vertex; `w` by vertex, zero at fixed vertices)
    /// into the projected step matrix's `A' w`; nothing without a
    /// rotation-preserving damping.
    pub fn correct_product(&self, w: &[Point], out: &mut [Point]) {
        if let Some(rotation) = &self.rotation {
            rotation.add_product_correction(w, out);
        }
    }

    /// `w^T L_d w` over the free vertices' rows (J s^2/m^2 scale: the
    /// Laplacian's units times m^2), with `L_d` applied on differences;
    /// `w^T W2 L_d w` with per-body weights.
    /// Fixed vertices contribute nothing when `w` vanishes on them.
    pub fn damping_laplacian_form(&self, w: &[Point]) -> f64 {
        let rows = &self.system.damping_rows;
        self.system
            .free
            .iter()
            .enumerate()
            .map(|(f, &v)| {
                let form = w[v].dot(&rows.row_dot_relative(f, w[v], w));
                match &self.system.weights {
                    Some(weights) => form * weights.laplacian[v],
                    None => form,
                }
            })
            .sum()
    }

    /// `w^T P_j w` for each power `j = 1, 2, ...` of the Caughey series'
    /// matrices (`P_j = L_ff (M^-1 L_ff)^j`), weighted by `series` (the
    /// coefficients `a3, a4, ...`) and summed: the series' part of
    /// `w^T D w`. `w` must vanish at fixed vertices. 0 without series.
    pub fn series_form(&self, w: &[Point], series: &[f64]) -> f64 {
        let system = &self.system;
        system
            .series_rows
            .iter()
            .zip(series)
            .filter(|(_, a)| **a != 0.0)
            .map(|(rows, a)| {
                let form: f64 = system
                    .free
                    .iter()
                    .enumerate()
                    .map(|(f, &v)| w[v].dot(&rows.row_dot(f, w)))
                    .sum();
                a * form
            })
            .sum()
    }

    /// `w^T K(x_n) w` with the lagged Hessians of the last refactorisation
    /// (0 for a constant model); `product` (one point per vertex) is
    /// scratch.
    pub fn lagged_stiffness_form(
        &self,
        blocks: &[Box<dyn ConstraintBlock>],
        w: &[Point],
        product: &mut [Point],
    ) -> f64 {
        let StepMatrix::Lagged(lagged) = &self.matrix else {
            return 0.0;
        };
        product.iter_mut().for_each(|p| *p = Point::zeros());
        lagged.add_stiffness_product(blocks, w, 1.0, product);
        w.iter().zip(product.iter()).map(|(a, b)| a.dot(b)).sum()
    }
}
