//! Hooks that run one phase of a step on its own, for benchmarks and
//! profiling (`benches/`, `cargo xtask bench-report`): the local step alone,
//! the global solve alone, and the numeric factorisation alone. They use the
//! simulation's own buffers and thread pool, so they cost what the phase
//! costs inside [`Simulation::step`]. They leave the state unchanged.

use crate::{Simulation, SolverError};

impl Simulation {
    /// Runs the local step once: projects every constraint at the current
    /// positions into the step's projection buffer, with the simulation's
    /// thread pool. Allocates nothing.
    pub fn profile_local_step(&mut self) {
        let run = |local: &crate::local::LocalStep,
                   positions: &[pd_mesh::Point],
                   projections: &mut [pd_mesh::Point]| {
            local.project(positions, projections)
        };
        let (local, positions, projections) = (
            &self.local,
            &self.state.positions,
            &mut self.scratch.iteration.projections,
        );
        match &self.pool {
            Some(pool) => pool.install(|| run(local, positions, projections)),
            None => run(local, positions, projections),
        }
    }

    /// Runs the global step once: the right-hand side `B p` from the last
    /// projections (row-parallel, as in a step) and one solve with the
    /// factor of the coming step (n x 3 for constant damping models, 3n x 1
    /// for lagged ones). The solution is discarded. Allocates nothing once a
    /// factor is cached.
    ///
    /// # Errors
    /// A failed factorisation, if the factor was not cached yet.
    pub fn profile_global_solve(&mut self) -> Result<(), SolverError> {
        // A lagged system keeps the factor of the last step (or of the
        // build); a constant one takes the cached factor of the coming step.
        if !self.damping.implicit_matrix().is_lagged() {
            self.prepare_matrix()?;
        }
        let pool = self.pool.take();
        let mut run = || {
            let b = &mut self.scratch.iteration;
            // The constant part is left out: B p alone, as it was measured
            // before the step was split into phases.
            b.constant_rhs
                .iter_mut()
                .for_each(|p| *p = pd_mesh::Point::zeros());
            self.global
                .rhs_with_projections(&b.constant_rhs, &b.projections, 1.0, &mut b.rhs);
            self.global.solve(&b.rhs);
        };
        match &pool {
            Some(pool) => pool.install(run),
            None => run(),
        }
        self.pool = pool;
        Ok(())
    }

    /// Runs the solve of the global step alone, on the right-hand side left
    /// in the step's buffer (what [`Simulation::profile_global_solve`] does
    /// without assembling `B p`): the part of a global iteration that
    /// reads the factor, which `cargo xtask bench-report` compares with the
    /// streaming bound. The solution is discarded; allocates nothing once a
    /// factor is cached.
    ///
    /// # Errors
    /// A failed factorisation, if the factor was not cached yet.
    pub fn profile_solve(&mut self) -> Result<(), SolverError> {
        if !self.damping.implicit_matrix().is_lagged() {
            self.prepare_matrix()?;
        }
        let pool = self.pool.take();
        let mut run = || self.global.solve(&self.scratch.iteration.rhs);
        match &pool {
            Some(pool) => pool.install(run),
            None => run(),
        }
        self.pool = pool;
        Ok(())
    }

    /// Recomputes the numeric Cholesky factorisation of the coming step's
    /// global matrix into its existing buffer (the symbolic analysis is
    /// reused): for a constant model the cached factor is recomputed with the
    /// same values (so it stays valid, bit for bit); for a lagged model this
    /// is the per-step refactorisation, element Hessians included.
    ///
    /// # Errors
    /// A matrix that is not positive definite.
    pub fn profile_factorise(&mut self) -> Result<(), SolverError> {
        let coefficients = self.system_coefficients();
        let pool = self.pool.take();
        let mut run = || {
            self.global
                .refactorise(coefficients, self.local.blocks(), &self.state.positions)
        };
        let result = match &pool {
            Some(pool) => pool.install(run),
            None => run(),
        };
        self.pool = pool;
        result
    }
}
