//! Time-stepping settings.

use pd_mesh::Point;

use crate::SolverError;

/// How the simulation steps. Every field is checked by
/// [`Settings::validate`] before a simulation is built.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Time step h in s, > 0.
    pub dt: f64,
    /// Local-global iterations per step (the maximum when `tolerance` or
    /// `accuracy` is set), >= 1.
    pub iterations: usize,
    /// Relative stopping tolerance, >= 0; 0 always runs `iterations`. The
    /// step stops once `|x_{k+1} - x_k|_M <= tolerance |x_{k+1} - x_n|_M`.
    /// Because the objective's gradient after a local step is
    /// `A (x_k - x_{k+1})`, this bounds the residual of the step's equations.
    pub tolerance: f64,
    /// Target of the step's estimated relative error
    /// ([`crate::StepStats::estimated_error`]), in `(0, 1)`; 0 (the
    /// default) for none. With a target, `iterations` is the cap and each
    /// step stops once its estimate is at most this (docs/design/solver.md,
    /// "How far from converged"). Not together with `tolerance`.
    pub accuracy: f64,
    /// Uniform gravitational acceleration in m/s^2.
    pub gravity: Point,
    /// Threads for the local step and the right-hand side, at most
    /// [`Settings::MAX_THREADS`]; 0 uses rayon's global pool. Results are
    /// bit-identical for every thread count.
    pub threads: usize,
    /// The run is declared divergent when the total energy (kinetic,
    /// gravitational and elastic) exceeds its initial total by more than
    /// this many times the system's energy scale (see `docs/design/solver.md`).
    pub divergence_energy_factor: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            dt: 0.01,
            iterations: 10,
            tolerance: 0.0,
            accuracy: 0.0,
            gravity: Point::new(0.0, -9.81, 0.0),
            threads: 0,
            divergence_energy_factor: 1e3,
        }
    }
}

impl Settings {
    /// The most `threads` accepted: far more than any machine has cores
    /// (each thread beyond a core only adds scheduling), and few enough
    /// that a mistyped count fails at once instead of spawning threads for
    /// minutes.
    pub const MAX_THREADS: usize = 1024;

    /// The largest gravity accepted, m/s^2: 1e154, where the square of its
    /// magnitude is still a finite `f64` (its largest value is 1.8e308).
    /// Past it the quantities a step forms from gravity (its magnitude, the
    /// divergence check's energy scale `M |g| size`) overflow: `gravity =
    /// -1e300` ran until the divergence check reported a bound of `inf` J.
    /// Below it, an absurd gravity still runs, and a run it makes diverge
    /// stops with the divergence error at the step where an energy
    /// overflows.
    pub const MAX_GRAVITY: f64 = 1e154;

    /// Checks every field.
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] naming the first invalid field.
    pub fn validate(&self) -> Result<(), SolverError> {
        let bad = |field: &'static str, reason: String| {
            Err(SolverError::InvalidSetting { field, reason })
        };
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return bad("dt", format!("must be finite and > 0 s, got {}", self.dt));
        }
        if self.iterations == 0 {
            return bad("iterations", "must be at least 1".into());
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return bad(
                "tolerance",
                format!("must be finite and >= 0, got {}", self.tolerance),
            );
        }
        if !(self.accuracy == 0.0 || (self.accuracy > 0.0 && self.accuracy < 1.0)) {
            return bad(
                "accuracy",
                format!(
                    "must be in (0, 1) (a relative error), got {}",
                    self.accuracy
                ),
            );
        }
        if self.accuracy > 0.0 && self.tolerance > 0.0 {
            return bad(
                "accuracy",
                format!(
                    "cannot be combined with tolerance ({}): accuracy is the stopping rule",
                    self.tolerance
                ),
            );
        }
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return bad(
                "gravity",
                format!("must be finite, got {:?}", self.gravity.as_slice()),
            );
        }
        // The largest component first: the norm of 1e300 overflows.
        if self.gravity.amax() > Self::MAX_GRAVITY || self.gravity.norm() > Self::MAX_GRAVITY {
            return bad(
                "gravity",
                format!(
                    "is {:?} m/s^2; its magnitude must be at most {:e} m/s^2 (SI units)",
                    self.gravity.as_slice(),
                    Self::MAX_GRAVITY
                ),
            );
        }
        if self.threads > Self::MAX_THREADS {
            return bad(
                "threads",
                format!(
                    "must be at most {} (0: all cores), got {}",
                    Self::MAX_THREADS,
                    self.threads
                ),
            );
        }
        if !(self.divergence_energy_factor.is_finite() && self.divergence_energy_factor > 0.0) {
            return bad(
                "divergence_energy_factor",
                format!(
                    "must be finite and > 0, got {}",
                    self.divergence_energy_factor
                ),
            );
        }
        Ok(())
    }
}
