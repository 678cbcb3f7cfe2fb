//! The rotation-preserving Laplacian damping, this project's extension of the
//! paper (`docs/design/damping.md`, "The rotation-preserving variant"):
//! `D = a2 L_d` damps a body's rigid rotation (`v^T L_d v > 0` for
//! `v = omega x r`), which a spinning body or a swinging pendulum should
//! keep. The variant does two things per connected component
//! ([`crate::rigid::RigidBody`]):
//!
//! 1. at the start of the step it moves the anchor of the `L_d` term with the
//!    body's rigid rotation, exactly as the integrator's damping velocity
//!    sees a rigid rotation (its [`StepContext::damping_stencil`] applied to
//!    the rotating trajectory), so that `a2 L_d` acts on the damping
//!    velocity minus that rotation's: only the strain rate is damped, the
//!    matrix is unchanged, and `L_d`'s zero column sums keep linear momentum
//!    exact. The mass term `a1 M` keeps its anchor: it damps spin and
//!    translation alike, as ether drag does;
//! 2. at the end of the step it gives the body back the spin that the `L_d`
//!    term took: the spin at the start times what `a1 M` alone leaves of it
//!    ([`StepContext::mass_damping_factor`]), as a rigid rotation about the
//!    centre of mass (no linear momentum change), about every principal axis
//!    where that is a rotation the body can carry
//!    ([`RigidFit::spin_restoring_velocity`]).
//!
//! What it preserves, exactly: a free body's angular momentum about its
//! centre of mass evolves as it would under `D = a1 M` alone (kept, with
//! `a1 = 0`), up to the axes the guard leaves alone; bodies held by a fixed
//! vertex or an attachment are not free: their spin is not restored, but
//! the rigid rotation they can still perform (about a single holding point
//! or line: a pendulum, a door) is left undamped by step 1.

use crate::rigid::{RigidFit, RigidFreedom, SpinAtStart};
use crate::{DampingTargets, Point, StepContext};

/// Per-step state of the variant: each free body's spin at the start of the
/// step. Sized at the first step, reused after.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct SpinKeeper {
    spins: Vec<SpinAtStart>,
}

impl SpinKeeper {
    /// Records each free body's spin at `x_n`, `v_n` (scaled by what the
    /// mass term `a1` (1/s) leaves of it) and moves its `L_d` anchor with its
    /// rigid rotation.
    pub(crate) fn begin_step(
        &mut self,
        a1: f64,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &[Point],
        targets: DampingTargets<'_>,
    ) {
        let masses = step.base.masses;
        let h = step.base.h;
        // For a body held at a pivot or along a hinge, the rotation is fitted
        // to the motion the step predicts before internal forces act, as a
        // velocity `(y - x_n) / h`: it carries the angular impulse of external
        // forces about the pivot (gravity), so a pendulum's swing is followed
        // as it speeds up. A free body's spin needs no prediction (uniform
        // gravity exerts no torque about its centre of mass).
        let turnable = step.rigid_bodies.iter().any(|b| {
            matches!(
                b.freedom,
                RigidFreedom::Pivot { .. } | RigidFreedom::Hinge { .. }
            )
        });
        let predicted = &mut *targets.scratch;
        if turnable {
            for (u, y) in predicted
                .iter_mut()
                .zip(targets.inertial_displacement.iter())
            {
                *u = y / h;
            }
        }
        self.spins
            .resize(step.rigid_bodies.len(), SpinAtStart::ZERO);
        for (spin, rigid) in self.spins.iter_mut().zip(step.rigid_bodies) {
            let body = &rigid.vertices;
            let fit = RigidFit::of(body, masses, positions, velocities);
            let start_omega = fit.angular_velocity();
            *spin = SpinAtStart {
                angular_momentum: fit.angular_momentum * step.mass_damping_factor(a1),
                angular_speed: start_omega.norm(),
                kinetic_energy: body
                    .iter()
                    .map(|&i| 0.5 * masses[i] * velocities[i].norm_squared())
                    .sum(),
            };
            // The rigid rotation the body can perform: its spin for a free
            // body, about its pivot or hinge for a held one, none for a
            // clamped one.
            let predicted_fit = || RigidFit::of(body, masses, positions, predicted);
            let omega = match &rigid.freedom {
                RigidFreedom::Free => start_omega,
                RigidFreedom::Pivot { point } => {
                    predicted_fit().angular_velocity_about(point, None)
                }
                RigidFreedom::Hinge { point, axis } => {
                    predicted_fit().angular_velocity_about(point, Some(axis))
                }
                RigidFreedom::Held => continue,
            };
            let rotations: [nalgebra::Rotation3<f64>; 3] =
                std::array::from_fn(|k| nalgebra::Rotation3::new(omega * (h * (1.0 - k as f64))));
            for &i in body {
                let r = positions[i] - fit.centre;
                let mut along = Point::zeros();
                for (beta, rotation) in step.damping_stencil.iter().zip(&rotations) {
                    along += (rotation * r) * *beta;
                }
                targets.laplacian_anchor[i] += along;
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
    /// (`docs/design/damping.md`). Returns how many axes were left alone.
    pub(crate) fn end_step(
        &self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &mut [Point],
    ) -> usize {
        let mut axes_left = 0;
        for (rigid, start) in step.rigid_bodies.iter().zip(&self.spins) {
            if rigid.freedom != RigidFreedom::Free {
                // What holds it exerts a real torque: its spin is not its own.
                continue;
            }
            let body = &rigid.vertices;
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
