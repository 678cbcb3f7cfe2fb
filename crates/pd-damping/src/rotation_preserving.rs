//! The rotation-preserving Laplacian damping, this project's extension of the
//! paper (`docs/damping.md`, "The rotation-preserving variant"):
//! `D = a2 L_d` damps a free body's rigid rotation (`v^T L_d v > 0` for
//! `v = omega x r`), which a spinning body should keep. The variant does two
//! things per free body (a connected component that nothing outside holds):
//!
//! 1. at the start of the step it moves the damping anchor with the body's
//!    rigid rotation, so that `D` acts on the damping velocity minus that
//!    rotation's: only the strain rate is damped, the matrix is unchanged, and
//!    `L_d`'s zero column sums keep linear momentum exact;
//! 2. at the end of the step it gives the body back the spin it had at the
//!    start, as a rigid rotation about its centre of mass (no linear momentum
//!    change), about every principal axis where that is a rotation the body can
//!    carry ([`RigidFit::spin_restoring_velocity`]).

use crate::rigid::{RigidFit, SpinAtStart};
use crate::{DampingTargets, Point, StepContext};

/// Per-step state of the variant: each free body's spin at the start of the
/// step. Sized at the first step, reused after.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct SpinKeeper {
    spins: Vec<SpinAtStart>,
}

impl SpinKeeper {
    /// Records each free body's spin at `x_n`, `v_n` and moves its damping
    /// anchor by the rigid rotation over `1 / gamma`.
    pub(crate) fn begin_step(
        &mut self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &[Point],
        targets: DampingTargets<'_>,
    ) {
        let masses = step.base.masses;
        self.spins.resize(step.free_bodies.len(), SpinAtStart::ZERO);
        for (spin, body) in self.spins.iter_mut().zip(step.free_bodies) {
            let fit = RigidFit::of(body, masses, positions, velocities);
            let omega = fit.angular_velocity();
            *spin = SpinAtStart {
                angular_momentum: fit.angular_momentum,
                angular_speed: omega.norm(),
                kinetic_energy: body
                    .iter()
                    .map(|&i| 0.5 * masses[i] * velocities[i].norm_squared())
                    .sum(),
            };
            // The rigid rotation's displacement over 1/gamma (one step for
            // backward Euler and implicit midpoint): exact, not linearised,
            // so a rigidly spinning body feels no damping at all. (A linear
            // shift `omega x r / gamma` lies on the tangent, and the damping
            // then stretches a spinning body: on a stiff spinning chain it
            // raised the total energy by 67% in 8 steps.)
            let rotation = nalgebra::Rotation3::new(omega / step.gamma);
            for &i in body {
                let r = positions[i] - fit.centre;
                targets.anchor_displacement[i] += rotation * r - r;
            }
        }
    }

    /// Gives each free body back the spin it had at the start of the step
    /// (angular momentum about its centre of mass), as a rigid rotation about
    /// its centre of mass, which changes no linear momentum. For a free body
    /// the spin is conserved physically (uniform gravity exerts no torque
    /// about the centre of mass), so this removes exactly the remaining loss,
    /// which the anchor shift has made small.
    ///
    /// About a principal axis where giving the spin back would turn the body
    /// far faster than it turns and cost more than a small fraction of its
    /// kinetic energy, nothing is restored: that spin was not lost by the
    /// body's rotation but moved onto an axis where the body has almost no
    /// inertia, and restoring it would take unbounded energy
    /// (`docs/damping.md`). Returns how many axes were left alone.
    pub(crate) fn end_step(
        &self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &mut [Point],
    ) -> usize {
        let mut axes_left = 0;
        for (body, start) in step.free_bodies.iter().zip(&self.spins) {
            let fit = RigidFit::of(body, step.base.masses, positions, velocities);
            let restoration = fit.spin_restoring_velocity(start);
            axes_left += restoration.axes_left;
            let restore = restoration.angular_velocity;
            for &i in body {
                velocities[i] += restore.cross(&(positions[i] - fit.centre));
            }
        }
        axes_left
    }
}
