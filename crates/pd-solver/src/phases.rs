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
            &mut self.scratch.projections,
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
        let index = match self.lagged {
            Some(_) => None,
            None => Some(self.global.prepare_factor(self.matrix_coefficients().0)?.0),
        };
        let pool = self.pool.take();
        let mut run = || {
            use rayon::prelude::*;
            let s = &mut self.scratch;
            let (projections, rows) = (&s.projections, &self.global.projection_rows);
            s.rhs_points
                .par_iter_mut()
                .enumerate()
                .for_each(|(f, out)| *out = rows.row_dot(f, projections));
            match (&mut self.lagged, index) {
                (Some(lagged), _) => {
                    for (f, p) in s.rhs_points.iter().enumerate() {
                        for k in 0..3 {
                            lagged.rhs[(3 * f + k, 0)] = p[k];
                        }
                    }
                    lagged.solve();
                }
                (None, Some(index)) => {
                    for (f, p) in s.rhs_points.iter().enumerate() {
                        for k in 0..3 {
                            s.rhs[(f, k)] = p[k];
                        }
                    }
                    self.global.solve(index, s.rhs.as_mut());
                }
                (None, None) => unreachable!("a constant model has a cached factor"),
            }
        };
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
        let (coefficients, stiffness) = self.matrix_coefficients();
        let pool = self.pool.take();
        let mut run = || match &mut self.lagged {
            Some(lagged) => lagged.refactorise(
                self.local.blocks(),
                &self.state.positions,
                coefficients,
                stiffness,
            ),
            None => self.global.refactorise_cached(coefficients),
        };
        let result = match &pool {
            Some(pool) => pool.install(run),
            None => run(),
        };
        self.pool = pool;
        result
    }
}
