//! Backward (implicit) Euler.

use crate::{Integrator, Point, StepCoefficients, StepTargets};

/// Backward Euler: `c1 = c2 = 1`, `z = 0`, `y = x_n + h v_n + h^2 a`,
/// `x_hat = x_n`, `gamma = 1/h`, and `v_{n+1} = (x_{n+1} - x_n)/h`.
///
/// First order; its numerical damping ratio for a mode of angular frequency
/// `omega` (rad/s) is about `h omega / 2`, i.e. the mode's amplitude decays
/// at the rate `h omega^2 / 2` (1/s): per step it is multiplied by
/// `1/sqrt(1 + (h omega)^2)` (`docs/design/integrators.md`). It never increases
/// the energy of a convex system solved to convergence.
#[derive(Debug, Clone, Copy, Default)]
pub struct BackwardEuler;

impl BackwardEuler {
    /// The name scenes, the command line and the registry use.
    pub const NAME: &'static str = "backward-euler";

    /// A new backward Euler integrator.
    pub fn new() -> Self {
        Self
    }
}

impl Integrator for BackwardEuler {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn coefficients(&self, h: f64) -> StepCoefficients {
        StepCoefficients {
            c1: 1.0,
            c2: 1.0,
            gamma: 1.0 / h,
        }
    }

    fn prepare(
        &self,
        h: f64,
        _positions: &[Point],
        velocities: &[Point],
        acceleration: Point,
        targets: &mut StepTargets,
    ) {
        targets.set_one_step(h, velocities, acceleration * (h * h));
    }

    fn finish(
        &mut self,
        h: f64,
        previous_positions: &[Point],
        _previous_velocities: &[Point],
        positions: &[Point],
        velocities: &mut [Point],
    ) {
        let inv_h = 1.0 / h;
        for ((v, x), x0) in velocities.iter_mut().zip(positions).zip(previous_positions) {
            *v = (x - x0) * inv_h;
        }
    }
}
