//! Checkpoints: everything the next step of a [`Simulation`] depends on,
//! so that a restored simulation continues bit for bit as the saved one
//! would have.
//!
//! The model, settings and damping model are not part of a checkpoint: they
//! come from the scene, which a checkpoint file stores next to this (the
//! `pd-io` crate). Damping models keep no state from one step to the next;
//! the rotation-preserving variant's projection keeps its reference lever
//! arms, which a checkpoint saves ([`RotationState`]; what it solved with
//! them is recomputed on the first step after a restore, bit for bit). The
//! cached factorisations are recomputed on demand and are deterministic
//! functions of the matrix coefficients, so they need no saving.

use pd_integrators::History;
use pd_mesh::Point;

use crate::{Simulation, SolverError, State};

/// The saved state of a [`Simulation`] after some step.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// Steps taken.
    pub steps: usize,
    /// Simulated time, s.
    pub time: f64,
    /// Positions (m) and velocities (m/s).
    pub state: State,
    /// The integrator's name, to refuse restoring into another integrator.
    pub integrator: String,
    /// [`crate::Model::fingerprint`] of the simulation's model, to refuse
    /// restoring into a simulation of another model; 0 for a checkpoint
    /// that does not record it (a checkpoint file written before it was
    /// kept), which is then restored without this check.
    pub model: u64,
    /// The integrator's history (previous states of multistep methods).
    pub history: History,
    /// The total energy the divergence check compares with, J.
    pub energy_reference: f64,
    /// The energy scale of the divergence check, J.
    pub energy_scale: f64,
    /// The contacts active at the end of the step, with their
    /// warm-started forces (empty without contact).
    #[cfg(feature = "contact")]
    pub contact: crate::contact::ContactCheckpoint,
    /// The last step's correction of the extrapolated predictor (empty
    /// without it, step/predictor.rs).
    pub predictor: crate::step::PredictorState,
    /// What the iteration method carries between steps
    /// ([`crate::PositionSolver::carried`]: Chebyshev's estimated `rho`
    /// with `rho = "auto"`; empty for the others).
    pub solver: Vec<f64>,
    /// The local-global contraction the next step's error estimate starts
    /// from (0: none yet; step/estimate.rs). With an accuracy target it
    /// decides where steps stop.
    pub contraction: f64,
    /// The rotation-preserving damping's reference lever arms (empty
    /// without `preserve_rotation` or before the first step).
    pub rotation: RotationState,
}

/// The rotation-preserving damping's reference: the lever arms its
/// projection turns from step to step instead of solving for new ones
/// (docs/design/damping.md, "The rotation-preserving variant").
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RotationState {
    /// The reference lever arms (m), one per projected vertex, the bodies'
    /// vertices one body after the other; empty when there is none.
    pub arms: Vec<Point>,
    /// The step matrix's coefficients they were solved with (mass, system,
    /// damping, mass damping, then the Caughey series'); empty with `arms`.
    pub key: Vec<f64>,
}

impl RotationState {
    /// Whether no reference is stored.
    pub fn is_empty(&self) -> bool {
        self.arms.is_empty() && self.key.is_empty()
    }
}

impl Simulation {
    /// Saves everything the coming steps depend on besides the model, the
    /// settings and the damping model.
    ///
    /// ```
    /// use pd_damping::NoDamping;
    /// use pd_integrators::Bdf2;
    /// use pd_mesh::generators;
    /// use pd_solver::{Model, Settings, Simulation};
    ///
    /// let build = || {
    ///     let chain = generators::chain(4, 1.0).unwrap();
    ///     let masses = vec![0.1; 4];
    ///     let mut model = Model::new();
    ///     let body = model.add_body(chain, masses).unwrap();
    ///     model.add_springs(body, 50.0).unwrap();
    ///     model.fix_vertices(body, &[0]).unwrap();
    ///     let settings = Settings { dt: 0.01, ..Settings::default() };
    ///     Simulation::new(model, Box::new(Bdf2::new()), Box::new(NoDamping), settings).unwrap()
    /// };
    /// let mut a = build();
    /// a.run(3).unwrap();
    /// let saved = a.checkpoint();
    /// a.run(4).unwrap();
    ///
    /// let mut b = build();
    /// b.restore(&saved).unwrap();
    /// b.run(4).unwrap();
    /// assert_eq!(a.state(), b.state()); // bit for bit
    /// assert_eq!(a.time().to_bits(), b.time().to_bits());
    /// ```
    pub fn checkpoint(&self) -> Checkpoint {
        Checkpoint {
            steps: self.steps,
            time: self.time,
            state: self.state.clone(),
            integrator: self.integrator.name().to_string(),
            model: self.model_fingerprint(),
            history: self.integrator.history(),
            energy_reference: self.divergence.reference,
            energy_scale: self.divergence.scale,
            #[cfg(feature = "contact")]
            contact: self
                .contact
                .as_ref()
                .map(crate::contact::ContactState::save)
                .unwrap_or_default(),
            predictor: self.predictor_state.clone(),
            solver: self.position_solver.carried(),
            contraction: self.carried_contraction,
            rotation: self.global.rotation_state(),
        }
    }

    /// [`crate::Model::fingerprint`] of this simulation's model, computed
    /// once.
    pub fn model_fingerprint(&self) -> u64 {
        *self
            .model_fingerprint
            .get_or_init(|| self.model.fingerprint())
    }

    /// Restores a checkpoint taken of a simulation of the same model,
    /// settings, integrator and damping model.
    ///
    /// # Errors
    /// [`SolverError::InvalidState`] if the checkpoint belongs to another
    /// integrator or another model (its [`Checkpoint::model`] is not this
    /// model's fingerprint), has the wrong number of vertices, a non-finite value, a
    /// history the integrator cannot hold, a predictor correction of the
    /// wrong length, a method state the method cannot take, or
    /// rotation-preserving reference arms that do not fit the simulation's
    /// projection; the simulation is then unchanged.
    pub fn restore(&mut self, checkpoint: &Checkpoint) -> Result<(), SolverError> {
        let invalid = |reason: String| SolverError::InvalidState { reason };
        if checkpoint.integrator != self.integrator.name() {
            return Err(invalid(format!(
                "the checkpoint is of integrator {:?}, the simulation uses {:?}",
                checkpoint.integrator,
                self.integrator.name()
            )));
        }
        let n = self.model.num_vertices();
        if checkpoint.model != 0 && checkpoint.model != self.model_fingerprint() {
            return Err(invalid(format!(
                "the checkpoint is of another model (fingerprint {:016x}, this simulation's \
                 model has {:016x}): its bodies, masses, fixed vertices or constraints differ",
                checkpoint.model,
                self.model_fingerprint()
            )));
        }
        let state = &checkpoint.state;
        for (name, values) in [
            ("positions", &state.positions),
            ("velocities", &state.velocities),
        ] {
            if values.len() != n {
                return Err(invalid(format!("{} {name} for {n} vertices", values.len())));
            }
            if let Some(v) = values.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                return Err(invalid(format!("{name} of vertex {v} are not finite")));
            }
        }
        for (name, value) in [
            ("time", checkpoint.time),
            ("energy_reference", checkpoint.energy_reference),
            ("energy_scale", checkpoint.energy_scale),
        ] {
            if !value.is_finite() {
                return Err(invalid(format!("{name} is not finite")));
            }
        }
        if !(0.0..1.0).contains(&checkpoint.contraction) {
            return Err(invalid(format!(
                "contraction is {}; it must be in [0, 1)",
                checkpoint.contraction
            )));
        }
        if checkpoint.time < 0.0 {
            return Err(invalid(format!("time is {} s, below 0", checkpoint.time)));
        }
        // The divergence check's scale is positive by construction
        // (step/divergence.rs); another one would make it fire at once.
        if checkpoint.energy_scale <= 0.0 {
            return Err(invalid(format!(
                "energy_scale is {} J; it must be > 0",
                checkpoint.energy_scale
            )));
        }
        Self::check_predictor_state(&checkpoint.predictor, n)?;
        self.global
            .check_rotation_state(&checkpoint.rotation)
            .map_err(invalid)?;
        self.position_solver
            .check_carried(&checkpoint.solver)
            .map_err(|reason| invalid(format!("solver: {reason}")))?;
        let before = self.integrator.history();
        if let Err(reason) = self.integrator.restore_history(&checkpoint.history, n) {
            // Leave the simulation as it was.
            self.integrator
                .restore_history(&before, n)
                .expect("the integrator's own history restores");
            return Err(invalid(reason.to_string()));
        }
        // Checked before it changes anything; the history goes back if not.
        #[cfg(feature = "contact")]
        let contact = match &mut self.contact {
            Some(contact) => contact
                .load(&checkpoint.contact)
                .map_err(|e| e.reason().to_owned()),
            None if !checkpoint.contact.is_empty() => {
                Err("the checkpoint has contacts, the simulation has no contact".into())
            }
            None => Ok(()),
        };
        #[cfg(feature = "contact")]
        if let Err(reason) = contact {
            self.integrator
                .restore_history(&before, n)
                .expect("the integrator's own history restores");
            return Err(invalid(reason));
        }
        self.state = checkpoint.state.clone();
        self.replace_predictor_state(checkpoint.predictor.clone());
        self.position_solver.restore_carried(&checkpoint.solver);
        self.steps = checkpoint.steps;
        self.time = checkpoint.time;
        self.carried_contraction = checkpoint.contraction;
        self.global.restore_rotation_state(&checkpoint.rotation);
        self.divergence.reference = checkpoint.energy_reference;
        self.divergence.scale = checkpoint.energy_scale;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use pd_damping::NoDamping;
    use pd_integrators::{BackwardEuler, Bdf2, Integrator};
    use pd_mesh::generators;

    use crate::{Model, Settings, Simulation};

    fn chain(integrator: Box<dyn Integrator>) -> Simulation {
        let mesh = generators::chain(4, 1.0).unwrap();
        let mut model = Model::new();
        let body = model.add_body(mesh, vec![0.1; 4]).unwrap();
        model.add_springs(body, 50.0).unwrap();
        model.fix_vertices(body, &[0]).unwrap();
        let settings = Settings {
            dt: 0.01,
            ..Settings::default()
        };
        Simulation::new(model, integrator, Box::new(NoDamping), settings).unwrap()
    }

    #[test]
    fn refuses_mismatched_checkpoints_and_changes_nothing() {
        let mut bdf = chain(Box::new(Bdf2::new()));
        bdf.run(2).unwrap();
        let saved = bdf.checkpoint();
        assert_eq!(saved.history.states.len(), 1);

        let mut be = chain(Box::new(BackwardEuler));
        let before = be.checkpoint();
        let err = be.restore(&saved).unwrap_err().to_string();
        assert!(err.contains("bdf2"), "{err}");
        assert_eq!(be.checkpoint(), before);

        let mut other = chain(Box::new(Bdf2::new()));
        let before = other.checkpoint();
        let mut short = saved.clone();
        short.state.positions.pop();
        assert!(other.restore(&short).is_err());
        let mut nan = saved.clone();
        nan.state.velocities[2].x = f64::NAN;
        assert!(other.restore(&nan).is_err());
        let mut bad_history = saved.clone();
        bad_history.history.states[0].0.pop();
        assert!(other.restore(&bad_history).is_err());
        assert_eq!(other.checkpoint(), before);

        other.restore(&saved).unwrap();
        assert_eq!(other.checkpoint(), saved);
    }

    /// A chain of 4 vertices with springs of `stiffness` N/m, masses
    /// `mass` kg and vertex `fixed` held.
    fn variant(stiffness: f64, mass: f64, fixed: usize) -> Simulation {
        let mesh = generators::chain(4, 1.0).unwrap();
        let mut model = Model::new();
        let body = model.add_body(mesh, vec![mass; 4]).unwrap();
        model.add_springs(body, stiffness).unwrap();
        model.fix_vertices(body, &[fixed]).unwrap();
        let settings = Settings {
            dt: 0.01,
            ..Settings::default()
        };
        Simulation::new(model, Box::new(Bdf2::new()), Box::new(NoDamping), settings).unwrap()
    }

    #[test]
    fn refuses_a_checkpoint_of_another_model_with_as_many_vertices() {
        let mut saved = variant(50.0, 0.1, 0);
        saved.run(2).unwrap();
        let saved = saved.checkpoint();
        assert_ne!(saved.model, 0);
        // Each differs from the saved model in one thing only.
        for (what, mut other) in [
            ("stiffness", variant(51.0, 0.1, 0)),
            ("mass", variant(50.0, 0.2, 0)),
            ("fixed vertex", variant(50.0, 0.1, 3)),
        ] {
            let before = other.checkpoint();
            let err = other.restore(&saved).unwrap_err().to_string();
            assert!(err.contains("another model"), "{what}: {err}");
            assert_eq!(other.checkpoint(), before, "{what}");
        }
        let mut same = variant(50.0, 0.1, 0);
        same.restore(&saved).unwrap();
        assert_eq!(same.checkpoint(), saved);
        // A checkpoint that records no fingerprint is restored unchecked.
        let mut unrecorded = saved.clone();
        unrecorded.model = 0;
        variant(51.0, 0.1, 0).restore(&unrecorded).unwrap();
    }
}
