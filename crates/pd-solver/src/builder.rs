//! [`SimulationBuilder`]: a [`Simulation`] configured in any order and
//! checked as a whole when it is built.

use pd_damping::{Damping, NoDamping};
use pd_integrators::{BackwardEuler, Integrator};
use pd_mesh::Point;

#[cfg(feature = "contact")]
use crate::contact::{BodyContactSettings, ContactSettings, SurfacePairs};
use crate::{Model, PositionSolver, Predictor, Settings, Simulation, SolverError, SolverSpec};

/// How the iteration of each step is chosen.
enum SolverChoice {
    /// Plain local-global PD (no `[solver]` table).
    Default,
    /// A method of the `[solver]` table.
    Spec(SolverSpec),
    /// A position solver of the caller's own.
    Custom(Box<dyn PositionSolver>),
}

/// Builds a [`Simulation`] from a [`Model`]: every setting has a default
/// (backward Euler, no damping, [`Settings::default`], plain local-global
/// iterations, no contact), the setters may be called in any order, and
/// [`SimulationBuilder::build`] checks the whole combination at once (the
/// settings' domains, the model's masses, whether the method can run this
/// damping, these materials and these colliders), so that a simulation that
/// builds can step.
///
/// ```
/// use pd_damping::LaplacianDamping;
/// use pd_integrators::ImplicitMidpoint;
/// use pd_solver::{Model, Simulation};
///
/// let beam = pd_mesh::generators::box_tets([1.0, 0.1, 0.1], [10, 1, 1]).unwrap();
/// let masses = beam.lumped_masses(1000.0).unwrap();
/// let mut model = Model::new();
/// let body = model.add_body(beam, masses).unwrap();
/// model.add_tet_strain(body, 1e6, None).unwrap();
/// model.fix_vertices(body, &[0, 1, 2, 3]).unwrap();
/// let mut sim = Simulation::builder(model)
///     .integrator(ImplicitMidpoint)
///     .damping(LaplacianDamping::new(0.01, 0.0, false).unwrap())
///     .dt(0.01)
///     .build()
///     .unwrap();
/// sim.run(10).unwrap();
/// ```
pub struct SimulationBuilder {
    model: Model,
    integrator: Box<dyn Integrator>,
    damping: Box<dyn Damping>,
    settings: Settings,
    solver: SolverChoice,
    predictor: Option<Predictor>,
    #[cfg(feature = "contact")]
    contact: Option<ContactSettings>,
    #[cfg(feature = "contact")]
    body_contact: Option<(BodyContactSettings, Option<SurfacePairs>)>,
}

impl std::fmt::Debug for SimulationBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimulationBuilder")
            .field("vertices", &self.model.num_vertices())
            .field("integrator", &self.integrator.name())
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

impl Simulation {
    /// A [`SimulationBuilder`] for `model`, with every setting at its
    /// default.
    pub fn builder(model: Model) -> SimulationBuilder {
        SimulationBuilder {
            model,
            integrator: Box::new(BackwardEuler),
            damping: Box::new(NoDamping),
            settings: Settings::default(),
            solver: SolverChoice::Default,
            predictor: None,
            #[cfg(feature = "contact")]
            contact: None,
            #[cfg(feature = "contact")]
            body_contact: None,
        }
    }
}

impl SimulationBuilder {
    /// The time integrator (default: backward Euler).
    pub fn integrator(self, integrator: impl Integrator + 'static) -> Self {
        self.integrator_boxed(Box::new(integrator))
    }

    /// The time integrator, already boxed (for example from
    /// `pd_integrators::registry`).
    pub fn integrator_boxed(mut self, integrator: Box<dyn Integrator>) -> Self {
        self.integrator = integrator;
        self
    }

    /// The damping model (default: none).
    pub fn damping(self, damping: impl Damping + 'static) -> Self {
        self.damping_boxed(Box::new(damping))
    }

    /// The damping model, already boxed (for example from
    /// `pd_damping::DampingSpec::create`).
    pub fn damping_boxed(mut self, damping: Box<dyn Damping>) -> Self {
        self.damping = damping;
        self
    }

    /// Every setting at once, replacing those set before.
    pub fn settings(mut self, settings: Settings) -> Self {
        self.settings = settings;
        self
    }

    /// The time step, s.
    pub fn dt(mut self, dt: f64) -> Self {
        self.settings.dt = dt;
        self
    }

    /// Local-global iterations per step (with a method: its cap).
    pub fn iterations(mut self, iterations: usize) -> Self {
        self.settings.iterations = iterations;
        self
    }

    /// Gravity, m/s^2.
    pub fn gravity(mut self, gravity: Point) -> Self {
        self.settings.gravity = gravity;
        self
    }

    /// Threads of the local step and the solve (results are the same bits
    /// for any count).
    pub fn threads(mut self, threads: usize) -> Self {
        self.settings.threads = threads;
        self
    }

    /// The iteration method of the `[solver]` table (default: plain
    /// local-global).
    pub fn solver(mut self, spec: SolverSpec) -> Self {
        self.solver = SolverChoice::Spec(spec);
        self
    }

    /// A position solver of the caller's own, in place of local-global.
    pub fn position_solver(mut self, solver: impl PositionSolver + 'static) -> Self {
        self.solver = SolverChoice::Custom(Box::new(solver));
        self
    }

    /// Where each step's iteration starts (default: the inertial target).
    pub fn predictor(mut self, predictor: Predictor) -> Self {
        self.predictor = Some(predictor);
        self
    }

    /// Contact with static colliders.
    #[cfg(feature = "contact")]
    pub fn contact(mut self, settings: ContactSettings) -> Self {
        self.contact = Some(settings);
        self
    }

    /// Contact between the bodies (every pair of distinct bodies).
    #[cfg(feature = "contact")]
    pub fn body_contact(mut self, settings: BodyContactSettings) -> Self {
        self.body_contact = Some((settings, None));
        self
    }

    /// Contact between bodies, within each body (self-contact), or both.
    #[cfg(feature = "contact")]
    pub fn surface_contact(mut self, settings: BodyContactSettings, pairs: SurfacePairs) -> Self {
        self.body_contact = Some((settings, Some(pairs)));
        self
    }

    /// The simulation, at rest in the model's positions.
    ///
    /// # Errors
    /// A setting out of its domain, a model that cannot be simulated, or a
    /// combination the chosen method cannot run (a method that cannot take
    /// this damping, these materials or colliders), each naming the setting.
    pub fn build(self) -> Result<Simulation, SolverError> {
        let mut sim = Simulation::new(self.model, self.integrator, self.damping, self.settings)?;
        match self.solver {
            SolverChoice::Default => {}
            SolverChoice::Spec(spec) => sim.set_position_solver(spec.create()?),
            SolverChoice::Custom(solver) => sim.set_position_solver(solver),
        }
        if let Some(predictor) = self.predictor {
            sim.set_predictor(predictor);
        }
        #[cfg(feature = "contact")]
        {
            if let Some(contact) = self.contact {
                sim.set_contact(contact)?;
            }
            match self.body_contact {
                Some((settings, Some(pairs))) => sim.set_surface_contact(settings, pairs)?,
                Some((settings, None)) => sim.set_body_contact(settings)?,
                None => {}
            }
        }
        sim.check_position_solver()?;
        Ok(sim)
    }
}
