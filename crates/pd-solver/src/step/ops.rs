//! Building blocks the accelerated and converged methods add to
//! [`StepProblem`]: access to the displacement, mass-weighted inner
//! products, and the residual bookkeeping every method shares.

use std::time::Instant;

use pd_constraints::EnergyBound;
use pd_mesh::Point;

use super::iteration::{IterationChange, StepProblem};

/// `sum_v m_v a_v . b_v` (kg m^2 for displacements), summed sequentially so
/// that it does not depend on the thread count.
pub(crate) fn mass_dot(masses: &[f64], a: &[Point], b: &[Point]) -> f64 {
    masses
        .iter()
        .zip(a)
        .zip(b)
        .map(|((m, a), b)| m * a.dot(b))
        .sum()
}

/// `out = a - b`, per vertex.
pub(crate) fn difference(a: &[Point], b: &[Point], out: &mut [Point]) {
    for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
        *o = a - b;
    }
}

impl<'a> StepProblem<'a> {
    /// The current displacement `x - x_n` per vertex (m), to overwrite. It
    /// must stay zero at fixed vertices; every linear combination of
    /// displacements the step produced does.
    pub fn displacement_mut(&mut self) -> &mut [Point] {
        &mut self.buffers.displacement
    }

    /// `|x - y|_M` (m kg^(1/2)): how far the current displacement lies
    /// from the inertial target `y`, over the free vertices, summed in
    /// order (the denominator of the relative error, step/estimate.rs).
    pub(crate) fn distance_from_inertial_target(&self) -> f64 {
        let dx = &self.buffers.displacement;
        let dy = &self.targets.inertial_displacement;
        self.global
            .free()
            .iter()
            .map(|&v| self.masses[v] * (dx[v] - dy[v]).norm_squared())
            .sum::<f64>()
            .sqrt()
    }

    /// The lumped vertex masses, kg.
    pub fn masses(&self) -> &'a [f64] {
        self.masses
    }

    /// Records the step's residual, the mass-norm ratio
    /// `|G(x) - x|_M / |G(x) - x_n|_M` of one local-global map `G` from `x`
    /// (given squared, kg m^2: `change_squared`, `displacement_squared`), in
    /// [`crate::StepStats::relative_change`], and whether it meets the
    /// tolerance (always `false` with tolerance 0) or, with
    /// [`crate::Settings::accuracy`], whether the step's estimated relative
    /// error is at most it; feeds the step's error estimate
    /// (step/estimate.rs). Unlike
    /// [`StepProblem::converged`], it records the residual without a
    /// tolerance too.
    pub fn record_residual(&mut self, change_squared: f64, displacement_squared: f64) -> bool {
        self.estimate.record(change_squared);
        self.estimate
            .note_displacement(change_squared, displacement_squared);
        let ratio = (change_squared / displacement_squared).sqrt();
        // 0/0: a step that does not move at all has converged.
        self.stats.relative_change = if ratio.is_nan() && change_squared == 0.0 {
            0.0
        } else {
            ratio
        };
        let tolerance = self.settings.tolerance;
        if tolerance > 0.0 && change_squared <= tolerance.powi(2) * displacement_squared {
            self.stats.converged = true;
        }
        let accuracy = self.settings.accuracy;
        if accuracy > 0.0 {
            // Only with a target: one more sum over the free vertices.
            let distance = self.distance_from_inertial_target();
            if self.estimate.relative(distance) <= accuracy && !self.contact_needs_more() {
                self.stats.converged = true;
            }
        }
        // A probed method past its time stops, unconverged; so does an
        // iteration that has stopped converging towards an accuracy target.
        let late = self
            .deadline
            .is_some_and(|d| std::time::Instant::now() >= d);
        let stalled = accuracy > 0.0 && self.estimate.stalled();
        self.stats.converged || late || stalled
    }
}

/// The fewest iterations a step whose collider contacts are solved against
/// the Delassus operator takes before its estimate may stop it: that solve
/// settles most of the step's correction in the first iteration, so the
/// ratio of the first two changes says little about what is left (on
/// `contact_stack` at `accuracy = 0.01`, steps stopped after two
/// iterations reported down to 0.05 of their true error;
/// docs/design/solver.md, "How far from converged").
const CONTACT_MIN_ITERATIONS: usize = 3;

impl StepProblem<'_> {
    /// Whether this step has collider contacts solved against the Delassus
    /// operator and has run fewer than [`CONTACT_MIN_ITERATIONS`].
    fn contact_needs_more(&self) -> bool {
        #[cfg(feature = "contact")]
        if self.stats.iterations < CONTACT_MIN_ITERATIONS
            && let Some(contact) = self.contact.as_deref()
        {
            return contact.delassus() && contact.contact_rows().next().is_some();
        }
        false
    }
}

/// A local-global iteration in two halves, for methods that judge a trial
/// point by the objective before solving from it: the local half projects
/// at the trial point and returns the objective from those projections (no
/// second projection pass), and the global half solves from them.
///
/// These bypass [`StepProblem::local_global_iteration`]: a hook added there
/// (a contact term, say) must be added to these halves too.
impl StepProblem<'_> {
    /// The local half at the current displacement: projects every
    /// constraint at `x_n + c2 dx` into the step's projections and returns
    /// the step objective there, in J, with the elastic energy summed from
    /// those projections (`sum w/2 |G q - P(G q)|^2`, the energy itself).
    /// `partials` (one per [`crate::local::LocalStep::num_chunks`]) is
    /// scratch. Counts one objective evaluation; the next
    /// [`StepProblem::global_half`] takes it back as its own local step.
    pub(crate) fn project_with_objective(&mut self, partials: &mut [EnergyBound]) -> f64 {
        let t0 = Instant::now();
        let value = super::objective::objective_with(self, |local, q, projections| {
            local.project_with_energy(q, projections, partials)
        });
        self.stats.objective_evaluations += 1;
        self.stats.local_seconds += t0.elapsed().as_secs_f64();
        value
    }

    /// The local half without the objective: projects every constraint at
    /// `x_n + c2 dx` into the step's projections. For a start whose
    /// objective nothing reads (Anderson's first iteration judges no trial).
    /// Counts one objective evaluation, as
    /// [`StepProblem::project_with_objective`] does, which the next
    /// [`StepProblem::global_half`] takes back as its own local step.
    pub(crate) fn project_here(&mut self) {
        let t0 = Instant::now();
        let c2 = self.coefficients.c2;
        let x_n = self.positions;
        let b = &mut *self.buffers;
        for ((q, x), d) in b.q.iter_mut().zip(x_n).zip(&b.displacement) {
            *q = x + d * c2;
        }
        self.local.project(&b.q, &mut b.projections);
        self.stats.objective_evaluations += 1;
        self.stats.local_seconds += t0.elapsed().as_secs_f64();
    }

    /// The objective at the start, when the step's projections are already
    /// those at the current displacement (the predictor's safeguard
    /// evaluated it there): `Some(g)` in J, `None` otherwise (the caller
    /// projects). Only the first call of a step can return `Some`. Counts
    /// nothing: the safeguard's evaluation, already counted, becomes the
    /// local step the next [`StepProblem::global_half`] takes back.
    pub(crate) fn take_start_projections(&mut self) -> Option<f64> {
        self.start_objective.take()
    }

    /// The global step's right-hand side from the step's current
    /// projections, into the step's `rhs` buffer (contact forces not
    /// included: [`StepProblem::local_global_iteration`] adds them).
    pub(crate) fn rhs_from_projections(&mut self) {
        let energy_factor = self.coefficients.c1 * self.coefficients.c2;
        let b = &mut *self.buffers;
        self.global.rhs_with_projections(
            &b.constant_rhs,
            &b.projections,
            energy_factor,
            &mut b.rhs,
        );
    }

    /// The global half: the right-hand side from the current projections,
    /// the prefactored solve, the solution as the new displacement. Returns
    /// the change, as [`StepProblem::local_global_iteration`] does, and
    /// counts one iteration (and un-counts the projection pass it uses as
    /// its local step).
    pub(crate) fn global_half(&mut self) -> IterationChange {
        let t0 = Instant::now();
        self.rhs_from_projections();
        let b = &mut *self.buffers;
        self.global.solve(&b.rhs);
        let change = super::tail::take_solution(self.global, self.masses, &mut b.displacement);
        self.stats.iterations += 1;
        self.stats.objective_evaluations = self.stats.objective_evaluations.saturating_sub(1);
        self.stats.global_seconds += t0.elapsed().as_secs_f64();
        change
    }

    /// Chunks of the local step (the length of the `partials` scratch of
    /// [`StepProblem::project_with_objective`]).
    pub(crate) fn local_chunks(&self) -> usize {
        self.local.num_chunks()
    }
}
