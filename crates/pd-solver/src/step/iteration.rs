//! The iteration seam: how the positions of one step are found.
//!
//! Everything around it (the integrator's targets, the damping model's
//! contribution, the constant part of the right-hand side before; the
//! velocity update, the damping filters and the divergence check after) is
//! the same for every method. A [`PositionSolver`] receives a
//! [`StepProblem`], which starts at the inertial target and offers the
//! building blocks: one local-global iteration (local step, right-hand side,
//! prefactored solve), the step objective (the merit function every method
//! lowers), and the convergence test of [`crate::Settings::tolerance`].
//! Today's method is [`LocalGlobal`]; accelerated and converged methods plug
//! in beside it through [`crate::Simulation::set_position_solver`].

use std::time::Instant;

use pd_damping::DampingMatrix;
use pd_integrators::{StepCoefficients, StepTargets};
use pd_mesh::Point;
use rayon::prelude::*;

use super::ray::RayCheck;
use super::tail;
use crate::local::LocalStep;
use crate::system::GlobalStep;
use crate::{Settings, SolverError, StepStats};

/// How the positions of a step are found: a minimiser of the step objective
/// `g(x)` (docs/design/formulation.md, "The step objective") given as a
/// [`StepProblem`].
///
/// ```
/// use pd_solver::{LocalGlobal, PositionSolver};
/// assert_eq!(LocalGlobal.name(), "local-global");
/// ```
pub trait PositionSolver: std::fmt::Debug + Send + Sync {
    /// Name as scenes spell it (`local-global`).
    fn name(&self) -> &'static str;

    /// Moves `step`'s displacement towards the minimiser of the step
    /// objective, within the iteration budget of [`StepProblem::iterations`].
    ///
    /// # Errors
    /// A method that fails outright (the step then stops with the error).
    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError>;

    /// Whether the method works with colliders (docs/design/contact.md). The
    /// contact forces advance with each local-global iteration and are not
    /// part of the step objective, so a method that judges iterates by the
    /// objective must say no (the default).
    fn handles_contact(&self) -> bool {
        false
    }

    /// Whether the method runs hyperelastic materials (energy elements,
    /// `docs/design/materials.md`): it must add their gradient to the local-global
    /// one. Plain PD methods (the default) do not, and a step of a model
    /// with materials refuses them with [`SolverError::Unsupported`].
    fn handles_materials(&self) -> bool {
        false
    }

    /// Whether the method runs with a lagged damping model
    /// (`rayleigh-lagged`), whose step matrix is the lagged 3n system, not
    /// the prefactored n x n one. Local-global methods do (the default).
    fn handles_lagged_damping(&self) -> bool {
        true
    }

    /// Whether the method runs with damping set per body (`[[body]]
    /// damping`), which weighs the damping matrices body by body. The
    /// default says yes.
    fn handles_per_body_damping(&self) -> bool {
        true
    }

    /// Whether the method runs with rotation-preserving Laplacian damping
    /// (`preserve_rotation`), whose step matrix is the prefactored one
    /// minus a low-rank term per body, applied inside the global solve
    /// (docs/design/damping.md). A method that only solves with the step
    /// matrix, or also corrects its own products with it, does (the
    /// default); one that assembles its own matrix must say no.
    fn handles_rotation_preserving_damping(&self) -> bool {
        true
    }

    /// Whether the method runs with a Caughey series damping (`a3 L_d
    /// M^-1 L_d + ...`), whose terms live only in the prefactored matrix's
    /// wider pattern. The default says yes.
    fn handles_series_damping(&self) -> bool {
        true
    }

    /// Whether the method's error estimate needs the local-global map's
    /// contraction measured by plain iterations (step/estimate.rs): its own
    /// ratios are its faster convergence, which says nothing of the slow
    /// modes' error. With an accuracy target, a step of such a method
    /// before any contraction is measured is solved by plain local-global,
    /// which measures it (unless the model has materials plain PD cannot
    /// run). The default says no.
    fn estimate_needs_contraction(&self) -> bool {
        false
    }

    /// Checks the method's own parameters (the default has none to check);
    /// [`crate::Simulation::check_position_solver`] and every step call it.
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] naming the parameter.
    fn check_settings(&self) -> Result<(), SolverError> {
        Ok(())
    }

    /// What the method carries from one step to the next and a checkpoint
    /// must keep for a resumed run to continue bit for bit (Chebyshev's
    /// estimated `rho` with `rho = "auto"`); empty (the default) for a
    /// method that starts every step afresh.
    fn carried(&self) -> Vec<f64> {
        Vec::new()
    }

    /// Checks values of [`PositionSolver::carried`] before anything is
    /// restored; the default accepts any (a method that carries nothing
    /// ignores them, so a run may resume with another method).
    ///
    /// # Errors
    /// Why the method cannot take them.
    fn check_carried(&self, values: &[f64]) -> Result<(), String> {
        let _ = values;
        Ok(())
    }

    /// Takes values checked by [`PositionSolver::check_carried`] (the
    /// default ignores them).
    fn restore_carried(&mut self, values: &[f64]) {
        let _ = values;
    }
}

/// Plain Projective Dynamics: local step, then global solve, `iterations`
/// times, stopping early once [`StepProblem::converged`] says so. Each local
/// step and each global step lowers the step objective (docs/design/solver.md).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LocalGlobal;

impl PositionSolver for LocalGlobal {
    fn name(&self) -> &'static str {
        "local-global"
    }

    fn handles_contact(&self) -> bool {
        true
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        step.record_objective();
        let converged = step.plain_iterations();
        // A predicted start can lie past the step objective's line minimum
        // in slow modes, and plain iterations from it stay past it: with
        // implicit midpoint the energy then grows (docs/design/solver.md, "A
        // better start: predictors"), as after an accelerated method's
        // overshoot. Steps from
        // `y` are plain PD's and are never checked.
        if !converged {
            step.check_predicted_end();
        }
        Ok(())
    }
}

/// How much one iteration moved the displacement, in the mass norm:
/// `|dx_new - dx_old|_M^2` and `|dx_new|_M^2` (kg m^2).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IterationChange {
    /// `|dx_new - dx_old|_M^2` in kg m^2.
    pub change_squared: f64,
    /// `|dx_new|_M^2` in kg m^2.
    pub displacement_squared: f64,
}

/// Scratch of the iterations, sized once.
#[derive(Debug)]
pub(crate) struct IterationBuffers {
    /// The step's displacement `x - x_n` (zero at fixed vertices): the
    /// unknown.
    pub displacement: Vec<Point>,
    /// Where the constraints are projected: `x_n + c2 dx`.
    pub q: Vec<Point>,
    /// The stacked projections.
    pub projections: Vec<Point>,
    /// The right-hand side's constant part, one point per free vertex.
    pub constant_rhs: Vec<Point>,
    /// The full right-hand side, one point per free vertex.
    pub rhs: Vec<Point>,
    /// Three per-vertex scratch vectors (the objective's `x - x_hat` of the
    /// mass and `L_d` terms and `K (x - x_hat)`).
    pub scratch: [Vec<Point>; 3],
    /// A second projection buffer, for keeping one point's projections
    /// while another is evaluated (the predictor's safeguard); empty until
    /// first used.
    pub spare_projections: Vec<Point>,
    /// Per-chunk scratch of the objective's energy sum (the predictor's
    /// safeguard); empty until first used.
    pub partials: Vec<pd_constraints::EnergyBound>,
    /// Implicit midpoint's end-of-step check of plain PD's predicted steps
    /// (step/ray.rs); empty until first used.
    pub ray: RayCheck,
    /// The collider contacts' displacements in the solve without their
    /// forces (the Delassus contact solve); empty until first used.
    #[cfg(feature = "contact")]
    pub contact_free: Vec<Point>,
}

impl IterationBuffers {
    pub fn new(vertices: usize, free: usize, projection_rows: usize) -> Self {
        Self {
            displacement: vec![Point::zeros(); vertices],
            q: vec![Point::zeros(); vertices],
            projections: vec![Point::zeros(); projection_rows],
            constant_rhs: vec![Point::zeros(); free],
            rhs: vec![Point::zeros(); free],
            scratch: std::array::from_fn(|_| vec![Point::zeros(); vertices]),
            spare_projections: Vec::new(),
            partials: Vec::new(),
            ray: RayCheck::default(),
            #[cfg(feature = "contact")]
            contact_free: Vec::new(),
        }
    }
}

/// One step's minimisation problem, as a [`PositionSolver`] sees it: the
/// current displacement `dx = x - x_n` (starting at the inertial target) and
/// the operations on it. Built by the step; allocates nothing.
#[derive(Debug)]
pub struct StepProblem<'a> {
    pub(crate) local: &'a LocalStep,
    pub(crate) global: &'a mut GlobalStep,
    pub(crate) positions: &'a [Point],
    pub(crate) masses: &'a [f64],
    pub(crate) targets: &'a StepTargets,
    pub(crate) laplacian_anchor: &'a [Point],
    pub(crate) coefficients: StepCoefficients,
    pub(crate) damping: DampingMatrix,
    pub(crate) h: f64,
    pub(crate) settings: &'a Settings,
    pub(crate) buffers: &'a mut IterationBuffers,
    pub(crate) stats: &'a mut StepStats,
    pub(crate) trace: Option<&'a mut Vec<f64>>,
    #[cfg(feature = "contact")]
    pub(crate) contact: Option<&'a mut crate::contact::ContactState>,
    /// Whether the displacement starts from a predicted point rather than
    /// the inertial target (step/predictor.rs): every method but Newton
    /// then runs implicit midpoint's end-of-step check
    /// (step/ray.rs), plain local-global PD included, and the accelerated
    /// ones even when they took no accelerated iterate.
    pub(crate) predicted: bool,
    /// `Some(g)` when the step's projections are those at the current
    /// displacement and `g` is the step objective there, summed from them
    /// (set by the predictor's safeguard, so that a method's first local
    /// step need not project the start again; see
    /// [`StepProblem::take_start_projections`]).
    pub(crate) start_objective: Option<f64>,
    /// The step's error estimate, fed by [`StepProblem::record_residual`]
    /// (step/estimate.rs).
    pub(crate) estimate: super::estimate::ErrorEstimate,
    /// When the step must stop whatever its error (a method probed by
    /// [`crate::Simulation::choose_method`] that has become slower than the
    /// fastest); `None` in every ordinary step.
    pub(crate) deadline: Option<std::time::Instant>,
}

impl StepProblem<'_> {
    /// The iteration budget (`Settings::iterations`).
    pub fn iterations(&self) -> usize {
        self.settings.iterations
    }

    /// The relative stopping tolerance (`Settings::tolerance`; 0 = none).
    pub fn tolerance(&self) -> f64 {
        self.settings.tolerance
    }

    /// The current displacement `x - x_n` per vertex (m), zero at fixed
    /// vertices.
    pub fn displacement(&self) -> &[Point] {
        &self.buffers.displacement
    }

    /// One local-global iteration from the current displacement: project
    /// every constraint at `x_n + c2 dx` (in parallel), build the right-hand
    /// side, solve with the prefactored matrix, and make the solution the
    /// new displacement. Counts the iteration and its time in the step's
    /// statistics.
    pub fn local_global_iteration(&mut self) -> IterationChange {
        self.iteration(false, false, false)
    }

    /// A step's first local-global iteration: as
    /// [`StepProblem::local_global_iteration`], but when the predictor's
    /// safeguard left the start's projections in the buffer (see
    /// [`StepProblem::take_start_projections`]) they are its local step,
    /// the same values a second projection pass would give, and the
    /// safeguard's evaluation is not counted twice.
    pub(crate) fn first_local_global_iteration(&mut self) -> IterationChange {
        self.iteration(false, false, true)
    }

    /// [`LocalGlobal`]'s iterations: up to [`StepProblem::iterations`],
    /// stopping once [`StepProblem::converged`] says so (returns whether it
    /// did). The same iterations as [`StepProblem::local_global_iteration`]
    /// in a loop, bit for bit, but each global step's tail also writes the
    /// next local step's `q` (step/tail.rs): between these iterations
    /// nothing moves the displacement (the objective trace only reads it,
    /// and writes `q` with the same expression).
    pub(crate) fn plain_iterations(&mut self) -> bool {
        let iterations = self.iterations();
        for k in 0..iterations {
            let change = self.iteration(k > 0, k + 1 < iterations, k == 0);
            self.record_objective();
            if self.converged(change) {
                return true;
            }
        }
        false
    }

    /// One local-global iteration; `q_current`: the buffers' `q` already
    /// holds `x_n + c2 dx` (the last tail wrote it), `next_q`: the tail
    /// writes it for the new displacement; `reuse_start`: the projections
    /// the predictor's safeguard left are this iteration's local step, if
    /// there are any.
    fn iteration(&mut self, q_current: bool, next_q: bool, reuse_start: bool) -> IterationChange {
        let t0 = Instant::now();
        let c2 = self.coefficients.c2;
        let x_n = self.positions;
        if reuse_start && self.take_start_projections().is_some() {
            self.stats.objective_evaluations = self.stats.objective_evaluations.saturating_sub(1);
        } else {
            let b = &mut *self.buffers;
            if !q_current {
                let displacement = &b.displacement;
                b.q.par_iter_mut()
                    .enumerate()
                    .for_each(|(v, q)| *q = x_n[v] + displacement[v] * c2);
            }
            self.local.project(&b.q, &mut b.projections);
        }
        let t1 = Instant::now();

        self.rhs_from_projections();
        let b = &mut *self.buffers;
        #[cfg(feature = "contact")]
        if let Some(contact) = self.contact.as_deref_mut() {
            contact.apply(x_n, self.masses, &b.displacement, &mut b.rhs);
        }
        self.global.solve(&b.rhs);
        #[cfg(feature = "contact")]
        if let Some(contact) = self.contact.as_deref_mut()
            && contact.delassus()
        {
            solve_contacts(contact, self.global, x_n, b);
        }
        let change = if next_q {
            tail::take_solution_and_q(
                self.global,
                self.masses,
                (x_n, c2),
                &mut b.displacement,
                &mut b.q,
            )
        } else {
            tail::take_solution(self.global, self.masses, &mut b.displacement)
        };
        self.stats.iterations += 1;
        self.stats.local_seconds += (t1 - t0).as_secs_f64();
        self.stats.global_seconds += t1.elapsed().as_secs_f64();
        change
    }

    /// Whether the iteration that moved the displacement by `change` met the
    /// tolerance: `|dx_new - dx_old|_M <= tolerance |dx_new|_M`. Records the
    /// relative change (always) and the verdict in the step's statistics.
    /// Always `false` with tolerance 0.
    pub fn converged(&mut self, change: IterationChange) -> bool {
        self.record_residual(change.change_squared, change.displacement_squared)
    }

    /// The step objective `g(x_n + dx)` at the current displacement, in J
    /// (the function every method minimises, docs/design/formulation.md,
    /// "The step objective").
    /// Costs one energy evaluation (a projection of every constraint).
    pub fn objective(&mut self) -> f64 {
        self.stats.objective_evaluations += 1;
        super::objective::step_objective(self)
    }

    /// Implicit midpoint's end-of-step check (step/ray.rs) of a step that
    /// started at a predicted point and did not converge: such a start can
    /// lie past the step objective's line minimum in slow modes, and
    /// iterations from it stay past it, so that the energy grows
    /// (docs/design/solver.md, "A better start: predictors"). Nothing for other steps and
    /// integrators. Plain PD and Chebyshev call it; Anderson and L-BFGS run
    /// their own.
    pub(crate) fn check_predicted_end(&mut self) {
        if !(self.predicted && RayCheck::applies(self)) {
            return;
        }
        let mut ray = std::mem::take(&mut self.buffers.ray);
        let mut partials = std::mem::take(&mut self.buffers.partials);
        let chunks = self.local_chunks();
        if partials.len() != chunks {
            partials = vec![pd_constraints::EnergyBound::default(); chunks];
        }
        ray.finish(self, &mut partials);
        self.buffers.ray = ray;
        self.buffers.partials = partials;
        self.record_objective();
    }

    /// Appends the current objective to the simulation's objective trace,
    /// when recording is on ([`crate::Simulation::record_objective`]).
    pub fn record_objective(&mut self) {
        if self.trace.is_some() {
            let value = self.objective();
            if let Some(trace) = self.trace.as_mut() {
                trace.push(value);
            }
        }
    }
}

/// With the Delassus contact solve (pd-contact's `delassus.rs`): the
/// global step has just been solved without the collider forces; finds
/// them against the matrix's response and solves again with them.
#[cfg(feature = "contact")]
fn solve_contacts(
    contact: &mut crate::contact::ContactState,
    global: &mut GlobalStep,
    x_n: &[Point],
    b: &mut IterationBuffers,
) {
    contact.collect_contact_rows();
    b.contact_free.clear();
    b.contact_free
        .extend(contact.contact_rows().map(|f| global.solution(f)));
    // `inverse_entry` answers for the constant matrix, which
    // `ContactState::set_delassus` requires.
    let mut entry = |f: usize, g: usize| global.inverse_entry(f, g).unwrap_or(0.0);
    if contact.solve_contacts(x_n, &b.contact_free, &mut entry, &mut b.rhs) {
        global.solve(&b.rhs);
    }
    global.keep_columns(contact.contact_rows().count(), |f| {
        contact.is_contact_row(f)
    });
}
