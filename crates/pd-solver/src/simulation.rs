//! The [`Simulation`]: a model, an integrator, a damping model and settings,
//! stepped in time.

use std::ops::Range;
use std::time::Instant;

use faer::Mat;
use pd_constraints::CsrMatrix;
use pd_damping::rigid::{RigidFit, SpinAtStart};
use pd_damping::{Damping, DampingContext, DampingMatrix};
use pd_integrators::{Integrator, StepCoefficients, StepTargets};
use pd_mesh::Point;
use rayon::prelude::*;

use crate::global::{GlobalSystem, MatrixCoefficients};
use crate::lagged::LaggedSystem;
use crate::local::LocalStep;
use crate::{Model, Settings, SolverError};

// Saving and restoring a simulation; its own file, a child of this module
// so that it can reach the private fields.
#[path = "checkpoint.rs"]
mod checkpoint;
pub use checkpoint::Checkpoint;

// Phase-by-phase hooks for benchmarks; a child module so it can reach the
// step's buffers without widening their visibility.
#[path = "phases.rs"]
mod phases;

/// Positions (m) and velocities (m/s) of every vertex, global numbering.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// Positions in m.
    pub positions: Vec<Point>,
    /// Velocities in m/s.
    pub velocities: Vec<Point>,
}

/// What one step did and what it cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepStats {
    /// Local-global iterations run.
    pub iterations: usize,
    /// Whether the tolerance was met (always `false` with tolerance 0).
    pub converged: bool,
    /// The last relative change `|x_{k+1} - x_k|_M / |x_{k+1} - x_n|_M`
    /// (computed only with a tolerance; else NaN).
    pub relative_change: f64,
    /// Time in the local step (projections), s.
    pub local_seconds: f64,
    /// Time in the global step (right-hand side and solve), s.
    pub global_seconds: f64,
    /// Time spent factorising, s (non-zero only when a factorisation was not
    /// cached yet).
    pub factor_seconds: f64,
    /// Wall time of the whole step, s.
    pub total_seconds: f64,
    /// Principal axes (summed over the bodies) about which the
    /// rotation-preserving Laplacian damping left the spin alone instead of
    /// restoring it, because restoring it would have turned the body far
    /// faster than it turns (docs/damping.md). Always 0 with other models.
    pub spin_axes_left: usize,
}

/// What building the simulation cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SetupStats {
    /// Assembling the operators and analysing the pattern (ordering,
    /// symbolic factorisation), s.
    pub analysis_seconds: f64,
    /// Numeric factorisations so far (the first at build, more when a
    /// coefficient changes), s.
    pub factor_seconds: f64,
    /// Number of numeric factorisations so far.
    pub factorisations: usize,
}

/// Energies of the current state, in J.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Energies {
    /// `1/2 sum m v^2`.
    pub kinetic: f64,
    /// Constraint energy `E(x)`, attachments included.
    pub elastic: f64,
    /// Gravitational potential `-sum m g . x` (zero at the origin).
    pub gravity: f64,
}

impl Energies {
    /// Kinetic + elastic + gravitational.
    pub fn total(&self) -> f64 {
        self.kinetic + self.elastic + self.gravity
    }
}

/// Scratch buffers sized once, so that a step allocates nothing.
#[derive(Debug)]
struct Scratch {
    targets: StepTargets,
    /// The step's displacement `x - x_n` (zero at fixed vertices): the
    /// global step's unknown.
    displacement: Vec<Point>,
    /// The new positions `x_n + displacement`, once the iterations are done.
    iterate: Vec<Point>,
    q: Vec<Point>,
    projections: Vec<Point>,
    constant_rhs: Vec<Point>,
    rhs_points: Vec<Point>,
    rhs: Mat<f64>,
    velocities: Vec<Point>,
    forces: Vec<Point>,
    /// Spin, angular speed and kinetic energy of each rotating body at the
    /// start of the step.
    spins: Vec<SpinAtStart>,
}

/// A Projective Dynamics simulation.
///
/// Setup (operators, symbolic analysis, buffers) happens in
/// [`Simulation::new`]; [`Simulation::step`] reuses it. Each step: the
/// integrator prepares its targets, then `iterations` times the local step
/// projects every constraint (in parallel) and the global step solves
/// `A dx = b` for the step's displacement `dx = x - x_n` with a cached
/// Cholesky factor of `A` (docs/solver.md); the integrator then updates the
/// velocities and the damping model filters them.
///
/// ```
/// use pd_damping::NoDamping;
/// use pd_integrators::BackwardEuler;
/// use pd_mesh::{generators, VertexSelection};
/// use pd_solver::{Model, Settings, Simulation};
///
/// let beam = generators::box_tets([1.0, 0.2, 0.2], [5, 1, 1]).unwrap();
/// let clamp = VertexSelection::Box { min: [-1.0; 3], max: [1e-9, 1.0, 1.0] }.resolve(&beam).unwrap();
/// let masses = beam.lumped_masses(1000.0).unwrap();
/// let mut model = Model::new();
/// let body = model.add_body(beam, masses).unwrap();
/// model.add_tet_strain(body, 1e6, None).unwrap();
/// model.fix_vertices(body, &clamp).unwrap();
///
/// let settings = Settings { dt: 0.01, iterations: 10, ..Settings::default() };
/// let mut sim = Simulation::new(model, Box::new(BackwardEuler), Box::new(NoDamping), settings).unwrap();
/// sim.run(10).unwrap();
/// // The free end sags under gravity.
/// assert!(sim.state().positions.iter().any(|p| p.y < -1e-4));
/// ```
#[derive(Debug)]
pub struct Simulation {
    model: Model,
    settings: Settings,
    integrator: Box<dyn Integrator>,
    damping: Box<dyn Damping>,
    local: LocalStep,
    global: GlobalSystem,
    lagged: Option<LaggedSystem>,
    bodies: Vec<Range<usize>>,
    /// Free vertices of each connected component.
    components: Vec<Vec<usize>>,
    /// The components without any fixed vertex (free rigid bodies).
    rotating_bodies: Vec<Vec<usize>>,
    state: State,
    time: f64,
    steps: usize,
    pool: Option<rayon::ThreadPool>,
    energy_reference: f64,
    energy_scale: f64,
    setup: SetupStats,
    scratch: Scratch,
    /// The step objective after each iteration of the last step, when
    /// recording was asked for ([`Simulation::record_objective`]).
    objective_trace: Option<Vec<f64>>,
}

impl Simulation {
    /// Builds the simulation: validates the settings, assembles the
    /// operators, analyses the global matrix and factorises it for the first
    /// step. The state starts at rest in the rest configuration.
    ///
    /// # Errors
    /// Invalid settings, a model that cannot be simulated (a free vertex
    /// without mass, every vertex fixed), or a failed factorisation.
    pub fn new(
        model: Model,
        integrator: Box<dyn Integrator>,
        damping: Box<dyn Damping>,
        settings: Settings,
    ) -> Result<Self, SolverError> {
        settings.validate()?;
        let d = damping.implicit_matrix();
        for (field, value) in [
            ("damping.mass", d.mass),
            ("damping.stiffness", d.damping_laplacian),
            ("damping.lagged_stiffness", d.lagged_stiffness),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(SolverError::InvalidSetting {
                    field,
                    reason: format!("must be finite and >= 0, got {value}"),
                });
            }
        }
        let pool = match settings.threads {
            0 => None,
            t => {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(t)
                    .build()
                    .map_err(|e| SolverError::InvalidSetting {
                        field: "threads",
                        reason: e.to_string(),
                    })?;
                // Workers start asynchronously, and a starting thread
                // allocates (its name, thread-local registrations). Running
                // one job on every worker now makes that happen here rather
                // than inside some later step, whose time it would inflate
                // and whose "no allocation after the first step" promise it
                // would break on a loaded machine.
                pool.broadcast(|_| ());
                Some(pool)
            }
        };
        let analysis_start = Instant::now();
        let local = LocalStep::new(model.constraint_blocks());
        let global = GlobalSystem::new(
            &local,
            model.masses(),
            model.fixed(),
            model.rest_positions(),
        )?;
        let lagged = if d.is_lagged() {
            Some(LaggedSystem::new(&global, local.blocks())?)
        } else {
            None
        };
        let (components, rotating_bodies) = connected_components(&model);
        let setup = SetupStats {
            analysis_seconds: analysis_start.elapsed().as_secs_f64(),
            ..SetupStats::default()
        };
        let n = model.num_vertices();
        let nf = global.free.len();
        let scratch = Scratch {
            targets: StepTargets::with_len(n),
            displacement: vec![Point::zeros(); n],
            iterate: vec![Point::zeros(); n],
            q: vec![Point::zeros(); n],
            projections: vec![Point::zeros(); local.total_rows()],
            constant_rhs: vec![Point::zeros(); nf],
            rhs_points: vec![Point::zeros(); nf],
            rhs: Mat::zeros(nf, 3),
            velocities: vec![Point::zeros(); n],
            forces: vec![Point::zeros(); n],
            spins: vec![SpinAtStart::ZERO; rotating_bodies.len()],
        };
        let bodies = model.bodies().iter().map(|b| b.vertices()).collect();
        let state = State {
            positions: model.rest_positions().to_vec(),
            velocities: vec![Point::zeros(); n],
        };
        let mut sim = Self {
            model,
            settings,
            integrator,
            damping,
            local,
            global,
            lagged,
            bodies,
            components,
            rotating_bodies,
            state,
            time: 0.0,
            steps: 0,
            pool,
            energy_reference: 0.0,
            energy_scale: 0.0,
            setup,
            scratch,
            objective_trace: None,
        };
        if sim.lagged.is_none() {
            sim.factor_for_next_step()?;
        }
        sim.reset_energy_reference();
        Ok(sim)
    }

    /// Replaces the state (e.g. from an initial-state file). Fixed vertices
    /// keep their given positions and get zero velocity. Resets the
    /// integrator's history.
    ///
    /// # Errors
    /// Wrong lengths or non-finite values, naming the vertex.
    pub fn set_state(&mut self, state: State) -> Result<(), SolverError> {
        let n = self.model.num_vertices();
        for (name, values) in [
            ("positions", &state.positions),
            ("velocities", &state.velocities),
        ] {
            if values.len() != n {
                return Err(SolverError::InvalidState {
                    reason: format!("{} {name} for {n} vertices", values.len()),
                });
            }
            if let Some(v) = first_non_finite(values) {
                return Err(SolverError::InvalidState {
                    reason: format!("{name} of vertex {v} are not finite"),
                });
            }
        }
        self.state = state;
        for (v, fixed) in self.state.velocities.iter_mut().zip(self.model.fixed()) {
            if *fixed {
                *v = Point::zeros();
            }
        }
        self.integrator.reset();
        self.reset_energy_reference();
        Ok(())
    }

    /// Adds the rigid velocity field `linear + angular x (x - c)` to every
    /// free vertex of a body, with `c` the body's centre of mass (m/s and
    /// rad/s). Does nothing for a body index out of range.
    pub fn add_rigid_velocity(&mut self, body: usize, linear: Point, angular: Point) {
        let Some(range) = self.bodies.get(body).cloned() else {
            return;
        };
        let masses = &self.model.masses()[range.clone()];
        let positions = &self.state.positions[range.clone()];
        let total: f64 = masses.iter().sum();
        let centre = if total > 0.0 {
            positions
                .iter()
                .zip(masses)
                .map(|(x, m)| x * *m)
                .sum::<Point>()
                / total
        } else {
            Point::zeros()
        };
        for v in range {
            if !self.model.fixed()[v] {
                self.state.velocities[v] +=
                    linear + angular.cross(&(self.state.positions[v] - centre));
            }
        }
        self.reset_energy_reference();
    }

    /// Advances one time step.
    ///
    /// # Errors
    /// [`SolverError::Diverged`] (non-finite positions or an energy blow-up),
    /// naming the step, time and vertex; the state is left at the last good
    /// step. A failed factorisation.
    pub fn step(&mut self) -> Result<StepStats, SolverError> {
        match self.pool.take() {
            Some(pool) => {
                let result = pool.install(|| self.step_inner());
                self.pool = Some(pool);
                result
            }
            None => self.step_inner(),
        }
    }

    /// Turns on (or off) recording the step objective `g(x)` of DESIGN.md
    /// 3.1-3.2 (the function each step minimises, in J) at the start iterate
    /// and after every local-global iteration, for
    /// [`Simulation::objective_trace`]. Off by default: it costs one energy
    /// evaluation per iteration and allocates, so it is for tests and
    /// diagnostics, not production runs.
    pub fn record_objective(&mut self, enabled: bool) {
        self.objective_trace = enabled.then(Vec::new);
    }

    /// The step objective recorded over the last step (`iterations + 1`
    /// values, J), or `None` unless [`Simulation::record_objective`] is on.
    /// Each local step and each global step lowers it, so it never
    /// increases from one value to the next (up to round-off).
    pub fn objective_trace(&self) -> Option<&[f64]> {
        self.objective_trace.as_deref()
    }

    /// Advances `steps` time steps; stops at the first error.
    ///
    /// # Errors
    /// As [`Simulation::step`].
    pub fn run(&mut self, steps: usize) -> Result<Vec<StepStats>, SolverError> {
        (0..steps).map(|_| self.step()).collect()
    }

    /// Matrix coefficients of the coming step: `A = mass M + system L_sys +
    /// damping L_d` (DESIGN.md 3.2), and the factor of the lagged `K(x_n)`.
    fn matrix_coefficients(&self) -> (MatrixCoefficients, f64) {
        let h = self.settings.dt;
        let c = self.integrator.coefficients(h);
        let d = self.damping.implicit_matrix();
        let damping_factor = c.c1 * c.c2 * c.gamma;
        (
            MatrixCoefficients {
                mass: 1.0 / (h * h) + damping_factor * d.mass,
                system: c.c1 * c.c2 * c.c2,
                damping: damping_factor * d.damping_laplacian,
            },
            damping_factor * d.lagged_stiffness,
        )
    }

    /// Makes the global matrix of the coming step ready: the cached factor of
    /// a constant matrix (factorising only on a cache miss), or a fresh
    /// numeric factorisation of the lagged system. Returns the cache index
    /// for the constant case.
    fn factor_for_next_step(&mut self) -> Result<Option<usize>, SolverError> {
        let start = Instant::now();
        let (coefficients, stiffness) = self.matrix_coefficients();
        let (index, factorised) = match &mut self.lagged {
            Some(lagged) => {
                lagged.refactorise(
                    self.local.blocks(),
                    &self.state.positions,
                    coefficients,
                    stiffness,
                )?;
                (None, true)
            }
            None => {
                let (index, factorised) = self.global.prepare_factor(coefficients)?;
                (Some(index), factorised)
            }
        };
        if factorised {
            self.setup.factor_seconds += start.elapsed().as_secs_f64();
            self.setup.factorisations += 1;
        }
        Ok(index)
    }

    fn step_inner(&mut self) -> Result<StepStats, SolverError> {
        let start = Instant::now();
        let h = self.settings.dt;
        let factorisations = self.setup.factorisations;
        let factor = self.factor_for_next_step()?;
        let factor_seconds = if self.setup.factorisations > factorisations {
            start.elapsed().as_secs_f64()
        } else {
            0.0
        };
        let c = self.integrator.coefficients(h);
        let d = self.damping.implicit_matrix();
        let masses = self.model.masses();
        let fixed = self.model.fixed();
        let s = &mut self.scratch;
        let x_n = &self.state.positions;
        let v_n = &self.state.velocities;
        let context = DampingContext {
            h,
            masses,
            bodies: &self.bodies,
            components: &self.components,
            fixed,
        };

        self.integrator
            .prepare(h, x_n, v_n, self.settings.gravity, &mut s.targets);
        if self.damping.preserves_rotation() {
            // Damp only the strain rate: move each free body's damping anchor
            // with its rigid rotation at the start of the step, so that D acts
            // on v_d minus that rotation's velocity (docs/damping.md). The matrix is
            // unchanged; L_d's zero column sums keep linear momentum exact.
            for (spin, body) in s.spins.iter_mut().zip(&self.rotating_bodies) {
                let fit = RigidFit::of(body, masses, x_n, v_n);
                let omega = fit.angular_velocity();
                *spin = SpinAtStart {
                    angular_momentum: fit.angular_momentum,
                    angular_speed: omega.norm(),
                    kinetic_energy: body
                        .iter()
                        .map(|&i| 0.5 * masses[i] * v_n[i].norm_squared())
                        .sum(),
                };
                // The rigid rotation's displacement over 1/gamma (one step for
                // backward Euler and implicit midpoint): exact, not linearised,
                // so a rigidly spinning body feels no damping at all. (A
                // linear shift `omega x r / gamma` lies on the tangent, and
                // the damping then stretches a spinning body: on a stiff
                // spinning chain it raised the total energy by 67% in 8 steps.)
                let rotation = nalgebra::Rotation3::new(omega / c.gamma);
                for &i in body {
                    let r = x_n[i] - fit.centre;
                    s.targets.anchor_displacement[i] += rotation * r - r;
                }
            }
        }
        if self.damping.has_explicit_force() {
            s.forces.iter_mut().for_each(|f| *f = Point::zeros());
            self.damping
                .add_explicit_force(&context, x_n, v_n, &mut s.forces);
            // An external force f enters y as c1 c2 h^2 M^-1 f (DESIGN.md 3.1).
            let scale = c.c1 * c.c2 * h * h;
            for ((y, f), m) in s
                .targets
                .inertial_displacement
                .iter_mut()
                .zip(&s.forces)
                .zip(masses)
            {
                if *m > 0.0 {
                    *y += f * (scale / m);
                }
            }
        }

        // The global step solves for the displacement `x - x_n` (zero at
        // fixed vertices), docs/solver.md:
        //   A (x - x_n) = M (y - x_n) / h^2 + c1 c2 (B p - L x_n)
        //                 + c1 c2 gamma D (x_hat - x_n).
        // Every term is built from displacements or, for `L x_n = L_d x_n +
        // L_anchor x_n`, from the differences `x_j - x_i` across each row of
        // the translation-invariant `L_d` (only attachments see absolute
        // positions), so round-off scales with how far the body moves in a
        // step, not with its distance from the origin. Constant part, over
        // the free vertices:
        let energy_factor = c.c1 * c.c2;
        let damping_factor = energy_factor * c.gamma;
        let inv_h2 = 1.0 / (h * h);
        let global = &self.global;
        let use_damping_laplacian = d.damping_laplacian != 0.0;
        let anchor = &s.targets.anchor_displacement;
        s.constant_rhs
            .par_iter_mut()
            .enumerate()
            .for_each(|(f, out)| {
                let v = global.free[f];
                let elastic = global.damping_rows.row_dot_relative(f, x_n[v], x_n)
                    + global.anchoring_rows.row_dot(f, x_n);
                let mut b = s.targets.inertial_displacement[v] * (masses[v] * inv_h2)
                    - elastic * energy_factor;
                if d.mass != 0.0 {
                    b += anchor[v] * (damping_factor * d.mass * masses[v]);
                }
                if use_damping_laplacian {
                    b += global.damping_rows.row_dot_relative(f, anchor[v], anchor)
                        * (damping_factor * d.damping_laplacian);
                }
                *out = b;
            });
        if let Some(lagged) = &self.lagged {
            // + c1 c2 gamma a3 K(x_n) (x_hat - x_n), on every vertex, then
            // gathered to the free ones.
            s.forces.iter_mut().for_each(|f| *f = Point::zeros());
            lagged.add_stiffness_product(
                self.local.blocks(),
                anchor,
                damping_factor * d.lagged_stiffness,
                &mut s.forces,
            );
            for (out, &v) in s.constant_rhs.iter_mut().zip(&global.free) {
                *out += s.forces[v];
            }
        }

        // Start from the inertial target; fixed vertices stay where they are.
        for ((dx, target), &fixed) in s
            .displacement
            .iter_mut()
            .zip(&s.targets.inertial_displacement)
            .zip(fixed)
        {
            *dx = if fixed { Point::zeros() } else { *target };
        }

        let mut stats = StepStats {
            relative_change: f64::NAN,
            factor_seconds,
            ..StepStats::default()
        };
        if let Some(trace) = &mut self.objective_trace {
            trace.clear();
            trace.push(step_objective(
                &self.local,
                &self.global,
                self.lagged.as_ref(),
                masses,
                &s.targets,
                (c, d, h),
                (x_n, &s.displacement),
                [&mut s.q, &mut s.velocities, &mut s.forces],
            ));
        }
        for _ in 0..self.settings.iterations {
            let t0 = Instant::now();
            let (c2, displacement) = (c.c2, &s.displacement);
            s.q.par_iter_mut()
                .enumerate()
                .for_each(|(v, q)| *q = x_n[v] + displacement[v] * c2);
            self.local.project(&s.q, &mut s.projections);
            let t1 = Instant::now();

            let (projections, constant) = (&s.projections, &s.constant_rhs);
            let projection_rows = &self.global.projection_rows;
            s.rhs_points
                .par_iter_mut()
                .enumerate()
                .for_each(|(f, out)| {
                    *out = constant[f] + projection_rows.row_dot(f, projections) * energy_factor;
                });
            // The n x 3 system of constant models, or the interleaved 3n x 1
            // system of lagged ones.
            let interleaved = self.lagged.is_some();
            let solution: &Mat<f64> = match (&mut self.lagged, factor) {
                (Some(lagged), _) => {
                    for (f, p) in s.rhs_points.iter().enumerate() {
                        for k in 0..3 {
                            lagged.rhs[(3 * f + k, 0)] = p[k];
                        }
                    }
                    lagged.solve();
                    &lagged.rhs
                }
                (None, Some(index)) => {
                    for (f, p) in s.rhs_points.iter().enumerate() {
                        for k in 0..3 {
                            s.rhs[(f, k)] = p[k];
                        }
                    }
                    self.global.solve(index, s.rhs.as_mut());
                    &s.rhs
                }
                (None, None) => unreachable!("a constant model always has a cached factor"),
            };

            let mut change2 = 0.0;
            let mut displacement2 = 0.0;
            for (f, &v) in self.global.free.iter().enumerate() {
                let new = if interleaved {
                    Point::new(
                        solution[(3 * f, 0)],
                        solution[(3 * f + 1, 0)],
                        solution[(3 * f + 2, 0)],
                    )
                } else {
                    Point::new(solution[(f, 0)], solution[(f, 1)], solution[(f, 2)])
                };
                if self.settings.tolerance > 0.0 {
                    change2 += masses[v] * (new - s.displacement[v]).norm_squared();
                    displacement2 += masses[v] * new.norm_squared();
                }
                s.displacement[v] = new;
            }
            if let Some(trace) = &mut self.objective_trace {
                trace.push(step_objective(
                    &self.local,
                    &self.global,
                    self.lagged.as_ref(),
                    masses,
                    &s.targets,
                    (c, d, h),
                    (x_n, &s.displacement),
                    [&mut s.q, &mut s.velocities, &mut s.forces],
                ));
            }
            stats.iterations += 1;
            stats.local_seconds += (t1 - t0).as_secs_f64();
            stats.global_seconds += t1.elapsed().as_secs_f64();
            if self.settings.tolerance > 0.0 {
                stats.relative_change = (change2 / displacement2).sqrt();
                if change2 <= self.settings.tolerance.powi(2) * displacement2 {
                    stats.converged = true;
                    break;
                }
            }
        }

        for ((x, x0), dx) in s.iterate.iter_mut().zip(x_n).zip(&s.displacement) {
            *x = x0 + dx;
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
        self.integrator
            .finish(h, x_n, v_n, &s.iterate, &mut s.velocities);
        zero_fixed(&mut s.velocities, fixed);
        if self.damping.preserves_rotation() {
            stats.spin_axes_left = restore_spin(
                &self.rotating_bodies,
                &s.spins,
                masses,
                &s.iterate,
                &mut s.velocities,
            );
        }
        self.damping
            .filter_velocities(&context, &s.iterate, &mut s.velocities);
        zero_fixed(&mut s.velocities, fixed);
        if let Some(v) = first_non_finite(&s.velocities) {
            return Err(SolverError::Diverged {
                step,
                time,
                reason: format!("velocity of vertex {v} is not finite"),
            });
        }
        let energy = kinetic_energy(masses, &s.velocities)
            + gravity_energy(masses, &s.iterate, self.settings.gravity);
        let limit =
            self.energy_reference + self.settings.divergence_energy_factor * self.energy_scale;
        // A non-finite energy is divergence even when the bound itself
        // overflowed (an enormous gravity makes the scale infinite).
        if !(energy.is_finite() && energy <= limit) {
            return Err(SolverError::Diverged {
                step,
                time,
                reason: format!(
                    "kinetic + gravitational energy {energy:.6e} J exceeds the bound {limit:.6e} J \
                     (initial energy {:.6e} J plus {} x the energy scale {:.6e} J)",
                    self.energy_reference,
                    self.settings.divergence_energy_factor,
                    self.energy_scale
                ),
            });
        }

        std::mem::swap(&mut self.state.positions, &mut s.iterate);
        std::mem::swap(&mut self.state.velocities, &mut s.velocities);
        self.steps = step;
        self.time = time;
        stats.total_seconds = start.elapsed().as_secs_f64();
        Ok(stats)
    }

    /// The initial energy and the scale for the divergence check
    /// (docs/solver.md): the total energy now, and the sum of the kinetic and
    /// elastic energy, the work gravity does over the body's size, and the
    /// kinetic energy of moving the whole mass by its size in one second.
    fn reset_energy_reference(&mut self) {
        let energies = self.energies();
        let masses = self.model.masses();
        let total_mass: f64 = masses.iter().sum();
        let (lo, hi) = bounding_box(&self.state.positions);
        let size = (hi - lo).norm();
        self.energy_reference = energies.total();
        self.energy_scale = energies.kinetic
            + energies.elastic
            + total_mass * self.settings.gravity.norm() * size
            + 0.5 * total_mass * size * size;
        if !(self.energy_scale > 0.0) {
            self.energy_scale = f64::MIN_POSITIVE;
        }
    }

    /// The global matrix `A` of the coming step over the free unknowns, full
    /// and symmetric: n_free x n_free for constant damping models (one
    /// matrix for x, y and z), 3 n_free x 3 n_free (x, y, z interleaved per
    /// vertex) for lagged ones, whose `K(x_n)` it computes at the current
    /// state. For inspection and tests; stepping never builds it.
    ///
    /// # Errors
    /// A failed factorisation of a lagged system.
    pub fn global_matrix(&mut self) -> Result<CsrMatrix, SolverError> {
        let (coefficients, stiffness) = self.matrix_coefficients();
        match &mut self.lagged {
            Some(lagged) => {
                lagged.refactorise(
                    self.local.blocks(),
                    &self.state.positions,
                    coefficients,
                    stiffness,
                )?;
                Ok(lagged.matrix())
            }
            None => Ok(self.global.matrix(coefficients)),
        }
    }

    /// What setup and factorisation cost so far.
    pub fn setup_stats(&self) -> SetupStats {
        self.setup
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The model being simulated.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The integrator's name.
    pub fn integrator_name(&self) -> &'static str {
        self.integrator.name()
    }

    /// The damping model's name.
    pub fn damping_name(&self) -> &'static str {
        self.damping.name()
    }

    /// Simulated time in s.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The energy scale of the divergence check (J, docs/solver.md): at the
    /// start (or the last `set_state`), the kinetic plus elastic energy, the
    /// work gravity does over the body's size, and the kinetic energy of
    /// moving the whole mass by its size in one second. A step diverges when
    /// the kinetic plus gravitational energy exceeds the initial total by
    /// `Settings::divergence_energy_factor` times this.
    pub fn energy_scale(&self) -> f64 {
        self.energy_scale
    }

    /// Steps taken.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Number of free (unknown) vertices.
    pub fn num_free_vertices(&self) -> usize {
        self.global.free.len()
    }

    /// Number of stored values in one Cholesky factor (8 bytes each).
    pub fn factor_len(&self) -> usize {
        self.global.factor_len()
    }

    /// Structural non-zeros of the Cholesky factor `L` (diagonal included,
    /// supernode padding excluded): the count CHOLMOD reports as `lnz`.
    pub fn factor_nnz(&self) -> usize {
        self.global.factor_nnz()
    }

    /// Kinetic, elastic and gravitational energy of the current state (J).
    /// The elastic part costs one projection of every constraint.
    pub fn energies(&self) -> Energies {
        let masses = self.model.masses();
        let compute = || Energies {
            kinetic: kinetic_energy(masses, &self.state.velocities),
            elastic: self.local.energy(&self.state.positions),
            gravity: gravity_energy(masses, &self.state.positions, self.settings.gravity),
        };
        match &self.pool {
            Some(pool) => pool.install(compute),
            None => compute(),
        }
    }

    /// Total linear momentum `sum m v` (kg m/s).
    pub fn linear_momentum(&self) -> Point {
        self.model
            .masses()
            .iter()
            .zip(&self.state.velocities)
            .map(|(m, v)| v * *m)
            .sum()
    }

    /// Total angular momentum about the origin `sum x x m v` (kg m^2/s).
    pub fn angular_momentum(&self) -> Point {
        self.model
            .masses()
            .iter()
            .zip(&self.state.positions)
            .zip(&self.state.velocities)
            .map(|((m, x), v)| x.cross(&(v * *m)))
            .sum()
    }
}

/// Connected components of every body's mesh graph (edges, which include
/// those of tetrahedra and triangles): their free vertices, and separately
/// the components without any fixed vertex.
fn connected_components(model: &Model) -> (Vec<Vec<usize>>, Vec<Vec<usize>>) {
    let n = model.num_vertices();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    for body in model.bodies() {
        for e in body.mesh.edges() {
            let (a, b) = (
                root(&mut parent, e[0] + body.offset),
                root(&mut parent, e[1] + body.offset),
            );
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut index_of_root = vec![usize::MAX; n];
    let mut all: Vec<(Vec<usize>, bool)> = Vec::new();
    for v in 0..n {
        let r = root(&mut parent, v);
        if index_of_root[r] == usize::MAX {
            index_of_root[r] = all.len();
            all.push((Vec::new(), false));
        }
        let (vertices, has_fixed) = &mut all[index_of_root[r]];
        if model.fixed()[v] {
            *has_fixed = true;
        } else {
            vertices.push(v);
        }
    }
    let rotating = all
        .iter()
        .filter(|(vertices, has_fixed)| !has_fixed && !vertices.is_empty())
        .map(|(vertices, _)| vertices.clone())
        .collect();
    let components = all
        .into_iter()
        .map(|(vertices, _)| vertices)
        .filter(|vertices| !vertices.is_empty())
        .collect();
    (components, rotating)
}

/// Second half of the rotation-preserving Laplacian variant (docs/damping.md;
/// the first half shifts the damping anchor by the rigid rotation): gives
/// each free body back the spin (angular momentum about its centre of mass)
/// it had at the start of the step, as a rigid rotation about its centre of
/// mass, which changes no linear momentum. For a free body the spin is
/// conserved physically (uniform gravity exerts no torque about the centre
/// of mass), so this removes exactly the remaining loss, which the anchor
/// shift has made small.
///
/// About a principal axis where giving the spin back would turn the body
/// far faster than it turns and cost more than a small fraction of its
/// kinetic energy, nothing is restored
/// ([`RigidFit::spin_restoring_velocity`]): that spin was not lost by the
/// body's rotation but moved onto an axis where the body has almost no
/// inertia, and restoring it would take unbounded energy (docs/damping.md).
/// Returns how many axes were left alone.
fn restore_spin(
    rotating_bodies: &[Vec<usize>],
    spins: &[SpinAtStart],
    masses: &[f64],
    positions: &[Point],
    velocities: &mut [Point],
) -> usize {
    let mut axes_left = 0;
    for (body, start) in rotating_bodies.iter().zip(spins) {
        let fit = RigidFit::of(body, masses, positions, velocities);
        let restoration = fit.spin_restoring_velocity(start);
        axes_left += restoration.axes_left;
        let restore = restoration.angular_velocity;
        for &i in body {
            velocities[i] += restore.cross(&(positions[i] - fit.centre));
        }
    }
    axes_left
}

/// The step objective (DESIGN.md 3.1-3.2) at `x = x_n + dx`, in J:
/// `g(x) = 1/(2h^2) |x - y|_M^2 + c1 E(x_n + c2 dx)
///   + 1/2 c1 c2 gamma (x - x_hat)^T D (x - x_hat)`, with
/// `D = a1 M + a2 L_d + a3 K(x_n)`. Fixed vertices sit at `x_n`, where
/// `x - x_hat` vanishes, so `L_d`'s rows of the free vertices suffice; their
/// inertia term is a constant of the step. The three buffers (`q`,
/// `x - x_hat`, `K (x - x_hat)`) are scratch.
#[allow(clippy::too_many_arguments)]
fn step_objective(
    local: &LocalStep,
    global: &GlobalSystem,
    lagged: Option<&LaggedSystem>,
    masses: &[f64],
    targets: &StepTargets,
    (c, d, h): (StepCoefficients, DampingMatrix, f64),
    (x_n, dx): (&[Point], &[Point]),
    [q, offset, product]: [&mut [Point]; 3],
) -> f64 {
    let mut inertia = 0.0;
    let mut mass_form = 0.0;
    for v in 0..x_n.len() {
        q[v] = x_n[v] + dx[v] * c.c2;
        offset[v] = dx[v] - targets.anchor_displacement[v];
        inertia += masses[v] * (dx[v] - targets.inertial_displacement[v]).norm_squared();
        mass_form += masses[v] * offset[v].norm_squared();
    }
    let mut laplacian_form = 0.0;
    if d.damping_laplacian != 0.0 {
        for (f, &v) in global.free.iter().enumerate() {
            laplacian_form +=
                offset[v].dot(&global.damping_rows.row_dot_relative(f, offset[v], offset));
        }
    }
    let mut lagged_form = 0.0;
    if let Some(lagged) = lagged {
        product.iter_mut().for_each(|p| *p = Point::zeros());
        lagged.add_stiffness_product(local.blocks(), offset, 1.0, product);
        lagged_form = offset
            .iter()
            .zip(product.iter())
            .map(|(a, b)| a.dot(b))
            .sum();
    }
    let damping_form = d.mass * mass_form
        + d.damping_laplacian * laplacian_form
        + d.lagged_stiffness * lagged_form;
    inertia / (2.0 * h * h) + c.c1 * local.energy(q) + 0.5 * c.c1 * c.c2 * c.gamma * damping_form
}

/// Index of the first point with a non-finite coordinate.
fn first_non_finite(points: &[Point]) -> Option<usize> {
    points.iter().position(|p| !p.iter().all(|c| c.is_finite()))
}

/// Hard-fixed vertices never move: their velocity is zero.
fn zero_fixed(velocities: &mut [Point], fixed: &[bool]) {
    for (v, &fixed) in velocities.iter_mut().zip(fixed) {
        if fixed {
            *v = Point::zeros();
        }
    }
}

fn kinetic_energy(masses: &[f64], velocities: &[Point]) -> f64 {
    0.5 * masses
        .iter()
        .zip(velocities)
        .map(|(m, v)| m * v.norm_squared())
        .sum::<f64>()
}

fn gravity_energy(masses: &[f64], positions: &[Point], gravity: Point) -> f64 {
    -masses
        .iter()
        .zip(positions)
        .map(|(m, x)| m * gravity.dot(x))
        .sum::<f64>()
}

fn bounding_box(points: &[Point]) -> (Point, Point) {
    points.iter().fold(
        (
            Point::repeat(f64::INFINITY),
            Point::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}
