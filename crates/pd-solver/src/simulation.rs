//! The [`Simulation`]: a model, an integrator, a damping model, a position
//! solver and settings, stepped in time. The step itself, phase by phase, is
//! in `step/`.

use std::time::Instant;

use pd_constraints::CsrMatrix;
use pd_damping::Damping;
use pd_integrators::Integrator;
use pd_mesh::Point;

use crate::components::Topology;
use crate::energy::{first_non_finite, gravity_energy, kinetic_energy};
use crate::local::LocalStep;
use crate::step::divergence::DivergenceCheck;
use crate::step::{LocalGlobal, PositionSolver, Scratch};
use crate::system::GlobalStep;
use crate::{Model, Settings, SolverError};

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
    /// Whether the tolerance (or the accuracy target) was met (always
    /// `false` with neither).
    pub converged: bool,
    /// The step's final relative residual: the last local-global change
    /// `|G(x) - x|_M / |G(x) - x_n|_M` (docs/design/solver.md; 0 for a step that
    /// does not move; NaN before the first iteration).
    pub relative_change: f64,
    /// The step's estimated relative error: the estimated distance from the
    /// positions the step returns to the exact minimiser of its objective,
    /// over the distance from the inertial prediction `y` to them, in the
    /// mass norm (the fraction of the step's correction left undone; 0 for
    /// a step that does not move). A posteriori, from the contraction of
    /// the iteration's successive changes (docs/design/solver.md, "How far
    /// from converged"); it only reads the iterates.
    pub estimated_error: f64,
    /// Step-objective evaluations the iteration method made (each one
    /// projection pass; the merit checks of `anderson`, the line search of
    /// `newton`; 0 for local-global without an objective trace).
    pub objective_evaluations: usize,
    /// Time in the local step (projections), s.
    pub local_seconds: f64,
    /// Time in the global step (right-hand side and solve), s.
    pub global_seconds: f64,
    /// Time spent factorising, s (non-zero only when a factorisation was not
    /// cached yet).
    pub factor_seconds: f64,
    /// Wall time of the whole step, s.
    pub total_seconds: f64,
    /// Contacts active at the end of the step (0 without colliders).
    pub contacts: usize,
    /// Deepest penetration of a vertex into a collider thickened by the
    /// contact thickness at the end of the step, m (0 without colliders).
    pub penetration: f64,
    /// Whether the step's collider contacts, to be solved against the
    /// Delassus operator (an accuracy target), did not fit its memory
    /// budget ([`Simulation::set_delassus_memory`]), so that the step took
    /// one projected Uzawa step per contact and iteration instead.
    pub contact_solve_fallback: bool,
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

/// A Projective Dynamics simulation.
///
/// Setup (operators, symbolic analysis, buffers) happens in
/// [`Simulation::new`]; [`Simulation::step`] reuses it. Each step: the
/// integrator prepares its targets, then `iterations` times the local step
/// projects every constraint (in parallel) and the global step solves
/// `A dx = b` for the step's displacement `dx = x - x_n` with a cached
/// Cholesky factor of `A` (docs/design/solver.md); the integrator then updates the
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
    pub(crate) model: Model,
    pub(crate) settings: Settings,
    pub(crate) integrator: Box<dyn Integrator>,
    pub(crate) damping: Box<dyn Damping>,
    pub(crate) position_solver: Box<dyn PositionSolver>,
    pub(crate) local: LocalStep,
    pub(crate) global: GlobalStep,
    pub(crate) topology: Topology,
    pub(crate) state: State,
    pub(crate) time: f64,
    pub(crate) steps: usize,
    pub(crate) pool: Option<rayon::ThreadPool>,
    pub(crate) divergence: DivergenceCheck,
    pub(crate) setup: SetupStats,
    pub(crate) scratch: Scratch,
    /// The step objective after each iteration of the last step, when
    /// recording was asked for ([`Simulation::record_objective`]).
    pub(crate) objective_trace: Option<Vec<f64>>,
    /// Contact with colliders, when a scene asks for it (docs/design/contact.md).
    #[cfg(feature = "contact")]
    pub(crate) contact: Option<crate::contact::ContactState>,
    /// Where each step starts, and the last step's correction (step/predictor.rs).
    pub(crate) predictor: crate::step::Predictor,
    pub(crate) predictor_state: crate::step::PredictorState,
    /// While [`Simulation::choose_method`] probes a method: when its steps
    /// must stop (they have taken longer than the fastest method so far).
    pub(crate) probe_deadline: Option<std::time::Instant>,
    /// What the last [`Simulation::choose_method`] measured and chose.
    pub(crate) method_choice: Option<crate::MethodChoice>,
    /// The local-global contraction observed in earlier steps, which the
    /// next step's error estimate starts from (step/estimate.rs; 0: none).
    pub(crate) carried_contraction: f64,
    /// [`Model::fingerprint`] of the model, computed on the first
    /// checkpoint or restore (checkpoint.rs).
    pub(crate) model_fingerprint: std::sync::OnceLock<u64>,
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
        // Named by body and the body's own vertex number, before the global
        // system, which knows only the model's numbering, would refuse it.
        model.check_free_masses()?;
        let d = damping.implicit_matrix();
        for (field, value) in [
            ("damping.mass", d.mass),
            ("damping.stiffness", d.damping_laplacian),
            ("damping.lagged_stiffness", d.lagged_stiffness),
        ] {
            // With a Caughey series only the whole polynomial must be
            // positive (checked below): a2 may be negative.
            let signed = d.has_series() && field == "damping.stiffness";
            if !(value.is_finite() && (signed || value >= 0.0)) {
                return Err(SolverError::InvalidSetting {
                    field,
                    reason: format!("must be finite and >= 0, got {value}"),
                });
            }
        }
        if d.has_series() {
            if let Some(a) = d.series.iter().find(|a| !a.is_finite()) {
                return Err(SolverError::InvalidSetting {
                    field: "damping.series",
                    reason: format!("must be finite, got {a}"),
                });
            }
            if d.is_lagged() || damping.body_coefficients().is_some() {
                return Err(SolverError::InvalidSetting {
                    field: "damping.series",
                    reason: "a Caughey series does not combine with a lagged or per-body \
                             damping matrix"
                        .into(),
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
        let mut global = GlobalStep::new(
            &local,
            model.masses(),
            model.fixed(),
            model.rest_positions(),
            d.is_lagged(),
            pool.as_ref()
                .map_or_else(rayon::current_num_threads, |p| p.current_num_threads()),
            d.series_powers(),
        )?;
        if d.has_series() {
            global.check_series_positive(&d, model.masses())?;
        }
        if let Some(per_body) = damping.body_coefficients() {
            let bodies: Vec<_> = model.bodies().iter().map(|b| b.vertices()).collect();
            global.set_damping_weights(per_body, d, &bodies)?;
        }
        let topology = Topology::of(&model, local.blocks());
        if damping.preserves_rotation() {
            let body_of = |rigid: usize| {
                let first = topology.rigid_bodies[rigid].vertices[0];
                topology.bodies.iter().position(|b| b.contains(&first))
            };
            global.set_rotation_projection(&topology.rigid_bodies, |rigid| {
                body_of(rigid).is_some_and(|b| damping.preserves_rotation_of_body(b))
            })?;
        }
        let setup = SetupStats {
            analysis_seconds: analysis_start.elapsed().as_secs_f64(),
            ..SetupStats::default()
        };
        let n = model.num_vertices();
        let scratch_len = (global.free().len(), local.total_rows(), local.num_chunks());
        let state = State {
            positions: model.rest_positions().to_vec(),
            velocities: vec![Point::zeros(); n],
        };
        let mut sim = Self {
            divergence: DivergenceCheck::new(settings.divergence_energy_factor),
            model,
            settings,
            integrator,
            damping,
            position_solver: Box::new(LocalGlobal),
            local,
            global,
            topology,
            state,
            time: 0.0,
            steps: 0,
            pool,
            setup,
            scratch: Scratch::new(0, 0, 0, 0),
            objective_trace: None,
            #[cfg(feature = "contact")]
            contact: None,
            predictor: crate::step::Predictor::Inertial,
            predictor_state: crate::step::PredictorState::default(),
            probe_deadline: None,
            method_choice: None,
            carried_contraction: 0.0,
            model_fingerprint: std::sync::OnceLock::new(),
        };
        if !d.is_lagged() {
            sim.prepare_matrix()?;
        }
        // The step's buffers come after the first factorisation, whose
        // scratch is gone by then, so that the two never add up in the peak
        // memory (docs/design/performance.md, "Memory").
        let (free, rows, chunks) = scratch_len;
        sim.scratch = Scratch::new(n, free, rows, chunks);
        sim.reset_energy_reference();
        Ok(sim)
    }

    /// Replaces the state (e.g. from an initial-state file). Fixed vertices
    /// keep their given positions and get zero velocity. Resets the
    /// integrator's history and the predictor's stored correction.
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
        self.replace_predictor_state(crate::step::PredictorState::default());
        self.reset_energy_reference();
        Ok(())
    }

    /// Adds the rigid velocity field `linear + angular x (x - c)` to every
    /// free vertex of a body, with `c` the body's centre of mass (m/s and
    /// rad/s).
    ///
    /// # Errors
    /// [`SolverError::InvalidState`] for a body index out of range, a
    /// velocity that is not finite, or one that would make a vertex's
    /// velocity overflow; the state is then unchanged.
    pub fn add_rigid_velocity(
        &mut self,
        body: usize,
        linear: Point,
        angular: Point,
    ) -> Result<(), SolverError> {
        let invalid = |reason: String| Err(SolverError::InvalidState { reason });
        let Some(range) = self.topology.bodies.get(body).cloned() else {
            return invalid(format!(
                "rigid velocity of body {body}: the model has {} bodies",
                self.topology.bodies.len()
            ));
        };
        if !(linear.iter().chain(angular.iter()).all(|c| c.is_finite())) {
            return invalid(format!(
                "rigid velocity of body {body} is not finite: linear {:?} m/s, angular {:?} rad/s",
                linear.as_slice(),
                angular.as_slice()
            ));
        }
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
        let added = |v: usize| linear + angular.cross(&(self.state.positions[v] - centre));
        let fixed = self.model.fixed();
        if let Some(v) = range.clone().find(|&v| {
            !fixed[v]
                && !(self.state.velocities[v] + added(v))
                    .iter()
                    .all(|c| c.is_finite())
        }) {
            return invalid(format!(
                "rigid velocity of body {body}: the velocity of vertex {v} would not be finite"
            ));
        }
        for v in range {
            if !fixed[v] {
                self.state.velocities[v] += added(v);
            }
        }
        self.reset_energy_reference();
        Ok(())
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

    /// Turns on (or off) recording the step objective `g(x)`
    /// (docs/design/formulation.md, "The step objective"; the function each step minimises, in J) at the start iterate
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

    /// Replaces how the positions of each step are found (the iteration
    /// seam, [`PositionSolver`]); the default is [`LocalGlobal`], plain
    /// local-global Projective Dynamics.
    ///
    /// ```
    /// # use pd_damping::NoDamping;
    /// # use pd_integrators::BackwardEuler;
    /// # use pd_mesh::generators;
    /// use pd_solver::{LocalGlobal, Model, Settings, Simulation};
    /// # let chain = generators::chain(3, 1.0).unwrap();
    /// # let mut model = Model::new();
    /// # let body = model.add_body(chain, vec![0.1; 3]).unwrap();
    /// # model.add_springs(body, 10.0).unwrap();
    /// # let mut sim = Simulation::new(model, Box::new(BackwardEuler), Box::new(NoDamping), Settings::default()).unwrap();
    /// sim.set_position_solver(Box::new(LocalGlobal));
    /// assert_eq!(sim.position_solver_name(), "local-global");
    /// ```
    pub fn set_position_solver(&mut self, solver: Box<dyn PositionSolver>) {
        self.position_solver = solver;
    }

    /// The position solver's name.
    pub fn position_solver_name(&self) -> &'static str {
        self.position_solver.name()
    }

    /// Advances `steps` time steps; stops at the first error.
    ///
    /// # Errors
    /// As [`Simulation::step`].
    pub fn run(&mut self, steps: usize) -> Result<Vec<StepStats>, SolverError> {
        (0..steps).map(|_| self.step()).collect()
    }

    /// The initial energy and the scale for the divergence check
    /// (docs/design/solver.md): the total energy now, and the sum of the kinetic and
    /// elastic energy, the work gravity does over the body's size, and the
    /// kinetic energy of moving the whole mass by its size in one second.
    fn reset_energy_reference(&mut self) {
        let energies = self.energies();
        self.divergence.reset(
            energies.total(),
            energies.kinetic + energies.elastic,
            self.model.masses(),
            &self.state.positions,
            self.settings.gravity,
        );
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
        let coefficients = self.system_coefficients();
        self.global
            .matrix(coefficients, self.local.blocks(), &self.state.positions)
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

    /// The damping model's implicit matrix coefficients (`a1` in 1/s, `a2`
    /// and `a3` in s): what a `ratio` in the scene was turned into.
    pub fn damping_matrix(&self) -> pd_damping::DampingMatrix {
        self.damping.implicit_matrix()
    }

    /// Each body's own implicit damping coefficients, in scene order, when
    /// the damping model damps bodies differently (per-body damping);
    /// `None` when [`Simulation::damping_matrix`] holds for every body.
    pub fn damping_body_coefficients(&self) -> Option<&[pd_damping::DampingMatrix]> {
        self.damping.body_coefficients()
    }

    /// Simulated time in s.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The energy scale of the divergence check (J, docs/design/solver.md): at the
    /// start (or the last `set_state`), the kinetic plus elastic energy, the
    /// work gravity does over the body's size, and the kinetic energy of
    /// moving the whole mass by its size in one second. A step diverges when
    /// the kinetic plus gravitational energy exceeds the initial total by
    /// `Settings::divergence_energy_factor` times this.
    pub fn energy_scale(&self) -> f64 {
        self.divergence.scale
    }

    /// Steps taken.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Number of free (unknown) vertices.
    pub fn num_free_vertices(&self) -> usize {
        self.global.free().len()
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

impl Simulation {
    /// Whether contact is on.
    #[cfg(feature = "contact")]
    pub(crate) fn has_contact(&self) -> bool {
        self.contact.is_some()
    }

    /// Whether contact is on: never without the `contact` feature.
    #[cfg(not(feature = "contact"))]
    pub(crate) fn has_contact(&self) -> bool {
        false
    }
}

/// What a differentiating caller (the `pd-adjoint` crate) reads of a
/// simulation: not for users.
impl Simulation {
    /// Global index of each free vertex, in the order of the global
    /// system's unknowns.
    #[doc(hidden)]
    pub fn free_vertices(&self) -> &[usize] {
        self.global.free()
    }

    /// Whether contact (colliders, contact between or within bodies) is on.
    #[doc(hidden)]
    pub fn uses_contact(&self) -> bool {
        self.has_contact()
    }

    /// The integrator's coefficients `(c1, c2, gamma)` for the coming step
    /// (docs/design/formulation.md, "The step objective").
    #[doc(hidden)]
    pub fn step_coefficients(&self) -> pd_integrators::StepCoefficients {
        self.integrator.coefficients(self.settings.dt)
    }

    /// Sets the iteration cap and the relative stopping tolerance
    /// ([`Settings::iterations`], [`Settings::tolerance`]) and turns the
    /// accuracy target off.
    ///
    /// # Errors
    /// As [`Settings::validate`]; the settings are then unchanged.
    #[doc(hidden)]
    pub fn set_stopping(&mut self, iterations: usize, tolerance: f64) -> Result<(), SolverError> {
        let settings = Settings {
            iterations,
            tolerance,
            accuracy: 0.0,
            ..self.settings.clone()
        };
        settings.validate()?;
        self.settings = settings;
        Ok(())
    }

    /// Solves `A z = rhs` in place (one point per free vertex, the three
    /// columns at once) with the cached Cholesky factor of the global
    /// matrix `A` for the integrator coefficients `c` and the simulation's
    /// damping (factorising on a cache miss): the preconditioner of an
    /// adjoint solve.
    ///
    /// # Errors
    /// [`SolverError::Unsupported`] for a lagged damping model (its matrix
    /// changes every step); a failed factorisation.
    #[doc(hidden)]
    pub fn solve_step_matrix(
        &mut self,
        c: pd_integrators::StepCoefficients,
        rhs: &mut [Point],
    ) -> Result<(), SolverError> {
        let d = self.damping.implicit_matrix();
        if d.is_lagged() {
            return Err(SolverError::Unsupported {
                what: "solving with the step matrix of a lagged damping model".into(),
            });
        }
        if rhs.len() != self.global.free().len() {
            return Err(SolverError::InvalidState {
                reason: format!(
                    "{} right-hand-side points for {} free vertices",
                    rhs.len(),
                    self.global.free().len()
                ),
            });
        }
        let coefficients = crate::system::SystemCoefficients::of(c, d, self.settings.dt);
        if self
            .global
            .prepare(coefficients, self.local.blocks(), &self.state.positions)?
        {
            self.setup.factorisations += 1;
        }
        // `A` itself: a rotation-preserving damping's projection belongs to
        // the step's own coefficients.
        self.global.solve_unprojected(rhs);
        Ok(())
    }
}

impl Simulation {
    /// The damping model (what it damps and how: rotation preservation,
    /// explicit forces, per-body coefficients).
    #[doc(hidden)]
    pub fn damping_model(&self) -> &dyn pd_damping::Damping {
        self.damping.as_ref()
    }
}
