//! Which combinations of position solver and model a step refuses, in one
//! place: a scene loader asks before it writes anything
//! ([`Simulation::check_position_solver`]), and every step asks again
//! before it iterates.

use crate::{Simulation, SolverError};

impl Simulation {
    /// Whether the position solver can run this simulation as it is set
    /// up: its own parameters ([`crate::PositionSolver::check_settings`]),
    /// its colliders ([`crate::PositionSolver::handles_contact`]), its
    /// hyperelastic materials ([`crate::PositionSolver::handles_materials`])
    /// and its damping ([`crate::PositionSolver::handles_lagged_damping`],
    /// [`crate::PositionSolver::handles_per_body_damping`]). Each step
    /// checks the same before it iterates; calling this after
    /// [`Simulation::set_position_solver`], [`Simulation::set_contact`] and
    /// [`Simulation::set_surface_contact`] reports a refused combination
    /// before the first step.
    ///
    /// ```
    /// use pd_damping::NoDamping;
    /// use pd_integrators::BackwardEuler;
    /// use pd_mesh::generators;
    /// use pd_solver::{Anderson, Model, Settings, Simulation};
    ///
    /// let mut model = Model::new();
    /// let body = model.add_body(generators::chain(3, 1.0).unwrap(), vec![1.0; 3]).unwrap();
    /// model.add_springs(body, 10.0).unwrap();
    /// let mut sim = Simulation::new(model, Box::new(BackwardEuler), Box::new(NoDamping), Settings::default()).unwrap();
    /// sim.set_position_solver(Box::new(Anderson::new(5)));
    /// assert!(sim.check_position_solver().is_ok());
    /// ```
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] for a parameter of the method out of
    /// range; [`SolverError::Unsupported`] saying which part of the model
    /// the method cannot run and what to use instead. Nothing is changed.
    pub fn check_position_solver(&self) -> Result<(), SolverError> {
        self.position_solver.check_settings()?;
        #[cfg(feature = "contact")]
        if self.contact.is_some() {
            self.check_solver_handles_contact()?;
        }
        self.check_solver_handles_materials()?;
        self.check_solver_handles_damping()
    }

    /// `Unsupported` if the damping needs what the method cannot do.
    fn check_solver_handles_damping(&self) -> Result<(), SolverError> {
        let name = self.position_solver.name();
        if self.damping.implicit_matrix().lagged_stiffness != 0.0
            && !self.position_solver.handles_lagged_damping()
        {
            return Err(SolverError::Unsupported {
                what: format!(
                    "solver method \"{name}\" with a lagged damping model (rayleigh-lagged): \
                     its step matrix is the lagged 3n system; use another method"
                ),
            });
        }
        if self.global.projects_rotations()
            && !self.position_solver.handles_rotation_preserving_damping()
        {
            return Err(SolverError::Unsupported {
                what: format!(
                    "solver method \"{name}\" with rotation-preserving damping \
                     (damping.preserve_rotation = true): its own matrix does not hold the \
                     projected damping; use another method or preserve_rotation = false"
                ),
            });
        }
        if self.damping.implicit_matrix().has_series()
            && !self.position_solver.handles_series_damping()
        {
            return Err(SolverError::Unsupported {
                what: format!(
                    "solver method \"{name}\" with a Caughey series damping (three or more \
                     ratios, or band): use another method"
                ),
            });
        }
        if self.global.damping_weights().is_some()
            && !self.position_solver.handles_per_body_damping()
        {
            return Err(SolverError::Unsupported {
                what: format!(
                    "solver method \"{name}\" with per-body damping ([[body]] damping): use \
                     another method or one [damping] for every body"
                ),
            });
        }
        Ok(())
    }
}
