//! One time step, in named phases (docs/design/solver.md):
//!
//! 1. [`Simulation::prepare_matrix`]: the global matrix of the step (a
//!    cached factor, or the lagged refactorisation);
//! 2. [`Simulation::prepare_targets`]: the integrator's targets `y` and
//!    `x_hat`, then the damping model's contribution
//!    ([`pd_damping::Damping::begin_step`]), then the constant part of the
//!    right-hand side;
//! 3. the iteration ([`PositionSolver`]): how the step's positions are
//!    found, local-global by default;
//! 4. [`Simulation::finish_step`]: the integrator's velocity update, the
//!    damping model's end of step (velocity filters), the
//!    divergence check, and the new state.

pub(crate) mod anderson;
pub(crate) mod chebyshev;
pub(crate) mod compatibility;
pub(crate) mod divergence;
pub(crate) mod estimate;
pub(crate) mod fitted;
pub(crate) mod iteration;
#[cfg(feature = "krylov-probe")]
pub(crate) mod krylov;
pub(crate) mod lbfgs;
pub(crate) mod materials;
pub(crate) mod method;
pub(crate) mod newton;
pub(crate) mod objective;
pub(crate) mod ops;
pub(crate) mod predictor;
pub(crate) mod predictor_fit;
pub(crate) mod ray;
pub(crate) mod ritz;
pub(crate) mod tail;

use std::time::Instant;

use divergence::StepState;
use pd_constraints::EnergyBound;
use pd_damping::{DampingContext, DampingTargets, StepContext};
use pd_integrators::StepTargets;
use pd_mesh::Point;

use crate::components::Topology;
use crate::energy::{first_non_finite, zero_fixed};
use crate::system::{RhsInput, SystemCoefficients};
use crate::{Simulation, SolverError, StepStats};
use iteration::IterationBuffers;

/// Plain local-global iterations that measure the contraction of the
/// local-global map for a method whose error estimate needs it
/// ([`PositionSolver::estimate_needs_contraction`]), in the first step of
/// a run with an accuracy target: enough for the largest ratio to leave
/// the fast modes behind. On stiff cloth it still rises after 200 (L-BFGS
/// then ended the clamped strip 6.3% short of its converged sag; with
/// 1,000, 0.05%: docs/design/solver.md, "The contraction carried from step
/// to step"); a one-time cost.
const MEASURING_ITERATIONS: usize = 1000;

pub use anderson::Anderson;
pub use chebyshev::Chebyshev;
pub use fitted::{RecurrenceFit, fit_recurrence};
pub use iteration::{IterationChange, LocalGlobal, PositionSolver, StepProblem};
#[cfg(feature = "krylov-probe")]
pub use krylov::{CgRun, KrylovProbe, KrylovRecord};
pub use lbfgs::Lbfgs;
pub use method::{SolverMethod, SolverSpec, SpectralRadius};
pub use newton::Newton;
pub use predictor::{Predictor, PredictorState};

/// Scratch buffers sized once, so that a step allocates nothing.
#[derive(Debug)]
pub(crate) struct Scratch {
    pub targets: StepTargets,
    pub iteration: IterationBuffers,
    /// The new positions `x_n + displacement`, once the iterations are done.
    pub iterate: Vec<Point>,
    /// The new velocities.
    pub velocities: Vec<Point>,
    /// The anchor of the `L_d` damping term, `x_hat - x_n` unless the damping
    /// model moved it (`pd_damping::DampingTargets::laplacian_anchor`).
    pub laplacian_anchor: Vec<Point>,
    /// Per-vertex scratch of the damping model and the lagged right-hand side.
    pub forces: Vec<Point>,
    /// Per-chunk energy bounds of the divergence check.
    pub energy_partials: Vec<EnergyBound>,
    /// Whether the step starts from a predicted point (step/predictor.rs).
    pub predicted: bool,
    /// The predicted start while the inertial one is evaluated.
    pub predicted_start: Vec<Point>,
    /// The fitted predictor's buffers and Gram cache (step/predictor_fit.rs).
    pub fit: predictor_fit::FitScratch,
}

impl Scratch {
    pub fn new(vertices: usize, free: usize, projection_rows: usize, chunks: usize) -> Self {
        Self {
            energy_partials: vec![EnergyBound::default(); chunks],
            targets: StepTargets::with_len(vertices),
            iteration: IterationBuffers::new(vertices, free, projection_rows),
            iterate: vec![Point::zeros(); vertices],
            velocities: vec![Point::zeros(); vertices],
            laplacian_anchor: vec![Point::zeros(); vertices],
            forces: vec![Point::zeros(); vertices],
            predicted: false,
            predicted_start: Vec::new(),
            fit: predictor_fit::FitScratch::default(),
        }
    }
}

/// The damping model's view of the step.
fn step_context<'a>(
    topology: &'a Topology,
    (masses, fixed): (&'a [f64], &'a [bool]),
    h: f64,
    c: pd_integrators::StepCoefficients,
    damping_stencil: &'a [f64],
) -> StepContext<'a> {
    let base = DampingContext {
        h,
        masses,
        bodies: &topology.bodies,
        components: &topology.components,
        fixed,
    };
    // An external force f enters y as c1 c2 h^2 M^-1 f
    // (docs/design/formulation.md, "The step objective").
    StepContext::new(
        base,
        &topology.rigid_bodies,
        (c.gamma, c.c1 * c.c2 * h * h, c.c2),
        damping_stencil,
    )
}

impl Simulation {
    /// Advances one time step on the current thread pool.
    pub(crate) fn step_inner(&mut self) -> Result<StepStats, SolverError> {
        let start = Instant::now();
        let factor_seconds = self.prepare_matrix()?;
        self.prepare_targets();
        let kind = self.apply_predictor();
        let mut stats = StepStats {
            relative_change: f64::NAN,
            factor_seconds,
            ..StepStats::default()
        };
        self.find_positions(&mut stats)?;
        self.finish_step(&mut stats)?;
        self.record_correction(kind);
        stats.total_seconds = start.elapsed().as_secs_f64();
        Ok(stats)
    }

    /// Phase 1: the global matrix of the coming step. Returns the time spent
    /// factorising (0 on a cache hit), s.
    pub(crate) fn prepare_matrix(&mut self) -> Result<f64, SolverError> {
        let start = Instant::now();
        let coefficients = self.system_coefficients();
        let factorised =
            self.global
                .prepare(coefficients, self.local.blocks(), &self.state.positions)?;
        if !factorised {
            return Ok(0.0);
        }
        let seconds = start.elapsed().as_secs_f64();
        self.setup.factor_seconds += seconds;
        self.setup.factorisations += 1;
        Ok(seconds)
    }

    /// The global matrix's coefficients for the coming step.
    pub(crate) fn system_coefficients(&self) -> SystemCoefficients {
        let h = self.settings.dt;
        SystemCoefficients::of(
            self.integrator.coefficients(h),
            self.damping.implicit_matrix(),
            h,
        )
    }

    /// Phase 2: the integrator's targets, the damping model's contribution
    /// to them, and the constant part of the right-hand side; the
    /// displacement starts at the inertial target (zero at fixed vertices).
    fn prepare_targets(&mut self) {
        let h = self.settings.dt;
        let c = self.integrator.coefficients(h);
        let masses = self.model.masses();
        let fixed = self.model.fixed();
        let s = &mut self.scratch;
        let (x_n, v_n) = (&self.state.positions, &self.state.velocities);
        self.integrator
            .prepare(h, x_n, v_n, self.settings.gravity, &mut s.targets);
        s.laplacian_anchor
            .copy_from_slice(&s.targets.anchor_displacement);
        let stencil = self.integrator.damping_stencil();
        let step = step_context(&self.topology, (masses, fixed), h, c, stencil);
        self.damping.begin_step(
            &step,
            x_n,
            v_n,
            DampingTargets::new(
                &mut s.targets.inertial_displacement,
                &mut s.targets.anchor_displacement,
                &mut s.laplacian_anchor,
                &mut s.forces,
            ),
        );
        let motion = crate::rotation::StepMotion {
            positions: x_n,
            masses,
            inertial_displacement: &s.targets.inertial_displacement,
            turn_time: c.c2,
        };
        self.global.prepare_rotation(
            &self.topology.rigid_bodies,
            motion,
            SystemCoefficients::of(c, self.damping.implicit_matrix(), h),
        );
        let input = RhsInput {
            masses,
            positions: x_n,
            inertial_displacement: &s.targets.inertial_displacement,
            anchor_displacement: &s.targets.anchor_displacement,
            laplacian_anchor: &s.laplacian_anchor,
            coefficients: c,
            damping: self.damping.implicit_matrix(),
            h,
        };
        self.global.constant_rhs(
            self.local.blocks(),
            &input,
            &mut s.iteration.constant_rhs,
            &mut s.forces,
        );
        for ((dx, target), &fixed) in s
            .iteration
            .displacement
            .iter_mut()
            .zip(&s.targets.inertial_displacement)
            .zip(fixed)
        {
            *dx = if fixed { Point::zeros() } else { *target };
        }
        #[cfg(feature = "contact")]
        if let Some(contact) = &mut self.contact {
            let g = (h, self.integrator.end_velocity(h), self.settings.gravity);
            contact.begin_step(x_n, v_n, &s.targets.anchor_displacement, g);
            // With an accuracy target, the collider contacts are solved
            // against the constant matrix's response (docs/design/contact.md,
            // "Friction with an accuracy target"); a fixed iteration count
            // keeps the one Uzawa step per iteration, and so does a step
            // whose matrix carries the rotation-preserving projection (its
            // response is not the factor's alone).
            contact.set_delassus(
                self.settings.accuracy > 0.0
                    && self.global.is_constant()
                    && !self.global.projects_rotations(),
            );
        }
    }

    /// Phase 3: the iteration seam.
    fn find_positions(&mut self, stats: &mut StepStats) -> Result<(), SolverError> {
        let h = self.settings.dt;
        if let Some(trace) = &mut self.objective_trace {
            trace.clear();
        }
        self.check_position_solver()?;
        let measure = self.settings.accuracy > 0.0
            && self.carried_contraction == 0.0
            && self.position_solver.estimate_needs_contraction()
            && self.local.blocks().iter().all(|b| !b.is_energy_element());
        // A step with nothing to correct (a body in free fall) reaches
        // round-off at once, and its changes do not shrink from there: the
        // measurement stops at round-off ([`estimate::ROUNDOFF`]) rather
        // than run its whole budget on nothing.
        let measuring = measure.then(|| crate::Settings {
            iterations: MEASURING_ITERATIONS.min(self.settings.iterations),
            accuracy: 0.0,
            tolerance: estimate::ROUNDOFF,
            ..self.settings.clone()
        });
        let mut problem = StepProblem {
            local: &self.local,
            global: &mut self.global,
            positions: &self.state.positions,
            masses: self.model.masses(),
            targets: &self.scratch.targets,
            laplacian_anchor: &self.scratch.laplacian_anchor,
            coefficients: self.integrator.coefficients(h),
            damping: self.damping.implicit_matrix(),
            h,
            settings: &self.settings,
            buffers: &mut self.scratch.iteration,
            stats,
            trace: self.objective_trace.as_mut(),
            #[cfg(feature = "contact")]
            contact: self.contact.as_mut(),
            predicted: self.scratch.predicted,
            start_objective: None,
            estimate: estimate::ErrorEstimate::carrying(self.carried_contraction),
            deadline: self.probe_deadline,
        };
        if problem.predicted {
            predictor::keep_the_better_start(&mut problem, &mut self.scratch.predicted_start);
        }
        if let Some(plain) = &measuring {
            // Plain iterations measure the contraction the method's
            // estimate needs (step/estimate.rs), then the method goes on
            // from where they got to.
            problem.settings = plain;
            LocalGlobal.find_positions(&mut problem)?;
            problem.settings = &self.settings;
            problem.estimate.adopt_measured_contraction();
        }
        self.position_solver.find_positions(&mut problem)?;
        let distance = problem.distance_from_inertial_target();
        problem.stats.estimated_error = problem.estimate.relative(distance);
        self.carried_contraction = problem.estimate.carry_out(self.carried_contraction);
        Ok(())
    }

    /// Phase 4: new positions and velocities, the damping model's end of
    /// step, the divergence check; the state changes only if all pass.
    fn finish_step(&mut self, stats: &mut StepStats) -> Result<(), SolverError> {
        let h = self.settings.dt;
        let c = self.integrator.coefficients(h);
        let masses = self.model.masses();
        let fixed = self.model.fixed();
        let s = &mut self.scratch;
        let (x_n, v_n) = (&self.state.positions, &self.state.velocities);
        for ((x, x0), dx) in s.iterate.iter_mut().zip(x_n).zip(&s.iteration.displacement) {
            *x = x0 + dx;
        }
        #[cfg(feature = "contact")]
        if let Some(contact) = &mut self.contact {
            let measured = contact.report(&s.iterate);
            (stats.contacts, stats.penetration) = (measured.contacts, measured.penetration);
            contact.project(&mut s.iterate);
            if contact.delassus_fell_back() {
                stats.contact_solve_fallback = true;
                self.global.drop_columns();
            }
        }
        let step = self.steps + 1;
        // From the step count, so that time does not drift by round-off.
        let time = step as f64 * h;
        if let Some(v) = first_non_finite(&s.iterate) {
            return Err(SolverError::Diverged {
                step,
                time,
                reason: format!("position of vertex {v} is not finite"),
            });
        }
        // A stop without restitution: the step's velocity is the one-step
        // `(x_{n+1} - x_n) / h` (a multistep method restarts; one-step
        // methods are unaffected). With a bounce as well, the bounce's
        // placement assumed the integrator's own end velocity: kept.
        #[cfg(feature = "contact")]
        let impact = self
            .contact
            .as_ref()
            .map_or((false, false), |c| (c.bounced(), c.stopped()));
        #[cfg(feature = "contact")]
        if impact == (false, true) {
            self.integrator.reset();
        }
        self.integrator
            .finish(h, x_n, v_n, &s.iterate, &mut s.velocities);
        zero_fixed(&mut s.velocities, fixed);
        let stencil = self.integrator.damping_stencil();
        let context = step_context(&self.topology, (masses, fixed), h, c, stencil);
        // The integrator sees what the damping model changed (a velocity
        // filter), so that a multistep
        // history follows it (docs/design/integrators.md).
        let damping = &mut self.damping;
        let iterate = &s.iterate;
        #[cfg(feature = "contact")]
        let contact = self.contact.as_ref();
        self.integrator
            .filter_velocities(h, &mut s.velocities, &mut |velocities| {
                damping.end_step(&context, iterate, velocities);
                #[cfg(feature = "contact")]
                if let Some(contact) = contact {
                    contact.filter_velocities(velocities);
                }
                zero_fixed(velocities, fixed);
            });
        // An impact sets its vertices' end velocity (from the restitution,
        // or to rest against the collider), not the motion a multistep
        // history remembers: that history would carry the approach velocity
        // into the next steps and lift the body above the bounce (BDF-2:
        // 0.31 m instead of 0.05 m for e = 0.5 from 0.2 m), so the
        // integrator starts afresh.
        #[cfg(feature = "contact")]
        if impact.0 || impact.1 {
            self.integrator.reset();
        }
        let elastic =
            self.local
                .energy_bound(&s.iterate, &s.iteration.projections, &mut s.energy_partials);
        let new_state = StepState {
            masses,
            positions: &s.iterate,
            velocities: &s.velocities,
            gravity: self.settings.gravity,
        };
        self.divergence
            .check(step, time, new_state, elastic, &self.local)?;

        std::mem::swap(&mut self.state.positions, &mut s.iterate);
        std::mem::swap(&mut self.state.velocities, &mut s.velocities);
        self.steps = step;
        self.time = time;
        Ok(())
    }
}
