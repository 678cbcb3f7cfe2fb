//! The Projective Dynamics time step.
//!
//! A [`Model`] holds the bodies, masses, constraints and fixed vertices; a
//! [`Simulation`] steps it with an integrator from `pd-integrators` and a
//! damping model from `pd-damping`: a parallel local step (rayon) projects
//! every constraint, and a global step solves the n x n system
//! (docs/design/formulation.md, "The global step") with a sparse Cholesky
//! factor (faer; AMD or nested-dissection ordering) that is computed once
//! and cached per set of coefficients, for all three coordinate columns at
//! once. The mathematics is in `docs/design/solver.md`.
//!
//! Results are bit-identical for every thread count: each projection and
//! each right-hand-side row is computed independently, and every reduction
//! that steers the computation is sequential.
//!
//! ```
//! use pd_damping::NoDamping;
//! use pd_integrators::BackwardEuler;
//! use pd_mesh::generators;
//! use pd_mesh::Point;
//! use pd_solver::{Model, Settings, Simulation};
//!
//! // A free chain of springs, no gravity: momentum is conserved.
//! let chain = generators::chain(5, 1.0).unwrap();
//! let masses = vec![0.1; 5];
//! let mut model = Model::new();
//! let body = model.add_body(chain, masses).unwrap();
//! model.add_springs(body, 50.0).unwrap();
//! let settings = Settings { gravity: Point::zeros(), ..Settings::default() };
//! let mut sim = Simulation::new(model, Box::new(BackwardEuler), Box::new(NoDamping), settings).unwrap();
//! sim.add_rigid_velocity(0, Point::new(0.0, 1.0, 0.0), Point::zeros()).unwrap();
//! sim.run(20).unwrap();
//! assert!((sim.linear_momentum() - Point::new(0.0, 0.5, 0.0)).norm() < 1e-12);
//! ```

mod builder;
mod checkpoint;
mod components;
#[cfg(feature = "contact")]
pub mod contact;
mod energy;
mod global;
pub mod hash;
mod lagged;
mod local;
mod method_choice;
mod model;
mod phases;
mod projection_scatter;
mod rotation;
mod settings;
mod simulation;
mod step;
mod system;
mod weights;

pub use builder::SimulationBuilder;
pub use checkpoint::{Checkpoint, RotationState};
pub use method_choice::{MethodChoice, PROBE_STEPS, ProbeOutcome, ProbeResult};
pub use model::{Body, BodyId, ConstraintGroup, Model};
pub use settings::Settings;
pub use simulation::{Energies, SetupStats, Simulation, State, StepStats};
pub use step::{
    Anderson, Chebyshev, IterationChange, Lbfgs, LocalGlobal, Newton, PositionSolver, Predictor,
    PredictorState, RecurrenceFit, SolverMethod, SolverSpec, SpectralRadius, StepProblem,
    fit_recurrence,
};
/// A measuring [`PositionSolver`], not a method: plain PD against conjugate
/// gradients preconditioned with the PD matrix on a step's linearisation
/// (docs/design/solver.md, "The Krylov bound"). Behind the `krylov-probe`
/// feature, which `benches/examples/krylov_bound.rs` turns on.
#[cfg(feature = "krylov-probe")]
pub use step::{CgRun, KrylovProbe, KrylovRecord};

/// Everything that can go wrong building or stepping a simulation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SolverError {
    /// A setting is out of its domain.
    #[error("invalid setting {field}: {reason}")]
    InvalidSetting {
        /// The setting's name.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The model cannot be simulated.
    #[error("invalid model: {reason}")]
    InvalidModel {
        /// What is wrong.
        reason: String,
    },
    /// A constraint's parameters are invalid.
    #[error("body {body}: {source}")]
    Constraint {
        /// The body.
        body: usize,
        /// The constraint error.
        #[source]
        source: pd_constraints::ConstraintError,
    },
    /// A state given from outside is invalid.
    #[error("invalid state: {reason}")]
    InvalidState {
        /// What is wrong.
        reason: String,
    },
    /// The global matrix could not be factorised.
    #[error("factorisation failed: {reason}")]
    Factorisation {
        /// Why.
        reason: String,
    },
    /// A combination this version does not implement.
    #[error("not supported: {what}")]
    Unsupported {
        /// What.
        what: String,
    },
    /// The simulation blew up; the state is left at the last good step.
    #[error("simulation diverged at step {step} (t = {time} s): {reason}")]
    Diverged {
        /// The step that failed (1-based).
        step: usize,
        /// Simulated time at the end of that step, s.
        time: f64,
        /// What was detected, naming the vertex where there is one.
        reason: String,
    },
}

impl From<pd_linalg::FactorError> for SolverError {
    fn from(error: pd_linalg::FactorError) -> Self {
        SolverError::Factorisation {
            reason: error.reason,
        }
    }
}
