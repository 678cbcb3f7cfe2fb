//! The implicit midpoint rule.

use crate::{Integrator, Point, StepCoefficients, StepTargets};

/// Implicit midpoint: forces (elastic and damping) at the midpoint
/// `(x_n + x_{n+1})/2`. `c1 = 1`, `c2 = 1/2`, `z = x_n/2`,
/// `y = x_n + h v_n + h^2/2 a`, `x_hat = x_n`, `gamma = 1/h` (the damping
/// velocity is the midpoint velocity `(x - x_n)/h`), and
/// `v_{n+1} = 2 (x_{n+1} - x_n)/h - v_n`.
///
/// Second order and symplectic: no numerical damping, energy conserved
/// exactly for quadratic energies, angular momentum conserved when the solve
/// converges. With a damping force evaluated at the midpoint it is the
/// forced variational midpoint scheme of Kharevych et al. 2006
/// (`docs/design/integrators.md`).
#[derive(Debug, Clone, Copy, Default)]
pub struct ImplicitMidpoint;

impl ImplicitMidpoint {
    /// The name scenes, the command line and the registry use.
    pub const NAME: &'static str = "implicit-midpoint";

    /// A new implicit midpoint integrator.
    pub fn new() -> Self {
        Self
    }
}

impl Integrator for ImplicitMidpoint {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn coefficients(&self, h: f64) -> StepCoefficients {
        StepCoefficients {
            c1: 1.0,
            c2: 0.5,
            gamma: 1.0 / h,
        }
    }

    /// `v_{n+1} = 2 (x - x_n) / h - v_n = (2 / h) (x - x_n - (h / 2) v_n)`.
    fn end_velocity(&self, h: f64) -> (f64, f64) {
        (2.0 / h, 0.5 * h)
    }

    fn prepare(
        &self,
        h: f64,
        _positions: &[Point],
        velocities: &[Point],
        acceleration: Point,
        targets: &mut StepTargets,
    ) {
        targets.set_one_step(h, velocities, acceleration * (0.5 * h * h));
    }

    fn finish(
        &mut self,
        h: f64,
        previous_positions: &[Point],
        previous_velocities: &[Point],
        positions: &[Point],
        velocities: &mut [Point],
    ) {
        let two_over_h = 2.0 / h;
        for ((v, x), (x0, v0)) in velocities
            .iter_mut()
            .zip(positions)
            .zip(previous_positions.iter().zip(previous_velocities))
        {
            *v = (x - x0) * two_over_h - v0;
        }
    }
}
