//! The divergence check (docs/design/solver.md): a step whose result is not
//! finite, or whose total energy (kinetic + gravitational + elastic) exceeds
//! the initial total by more than `Settings::divergence_energy_factor` times
//! the system's energy scale, stops the run with [`SolverError::Diverged`]
//! naming the step, the time and the vertex or constraint that went wrong;
//! the state stays at the last good step.
//!
//! The elastic energy comes first as an upper bound from the last local
//! step's projections (`LocalStep::energy_bound`: no projection pass); only
//! when the bound puts the total over the limit is the exact energy computed
//! (one projection pass), so a loose bound never stops a sane run and a
//! sane step pays a fraction of a local step for the check.

use pd_constraints::EnergyBound;
use pd_mesh::Point;

use crate::SolverError;
use crate::energy::{bounding_box, first_non_finite, gravity_energy, kinetic_energy};
use crate::local::LocalStep;

/// The reference energy and scale the check compares with, and its factor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DivergenceCheck {
    /// The total energy at the start (or the last `set_state`), J.
    pub reference: f64,
    /// The energy scale, J ([`DivergenceCheck::reset`]).
    pub scale: f64,
    /// `Settings::divergence_energy_factor`.
    pub factor: f64,
}

impl DivergenceCheck {
    /// A check with factor `factor` and no reference yet.
    pub fn new(factor: f64) -> Self {
        Self {
            reference: 0.0,
            scale: 0.0,
            factor,
        }
    }

    /// Sets the reference to the total energy `total` (J) of the state at
    /// `positions`, and the scale to the sum of its `kinetic` and `elastic`
    /// energy, the work gravity does over the body's size, and the kinetic
    /// energy of moving the whole mass by its size in one second.
    pub fn reset(
        &mut self,
        total: f64,
        kinetic_plus_elastic: f64,
        masses: &[f64],
        positions: &[Point],
        gravity: Point,
    ) {
        let total_mass: f64 = masses.iter().sum();
        let (lo, hi) = bounding_box(positions);
        let size = (hi - lo).norm();
        self.reference = total;
        self.scale = kinetic_plus_elastic
            + total_mass * gravity.norm() * size
            + 0.5 * total_mass * size * size;
        if !(self.scale > 0.0) {
            self.scale = f64::MIN_POSITIVE;
        }
    }

    /// Checks the new state of step `step` (ending at `time`, s), whose
    /// elastic energy is at most `elastic.0` (J, the bound of
    /// `LocalStep::energy_bound`, with the index of its block); `local`
    /// computes the exact energy if the bound is not enough.
    pub fn check(
        &self,
        step: usize,
        time: f64,
        state: StepState<'_>,
        elastic: (EnergyBound, usize),
        local: &LocalStep,
    ) -> Result<(), SolverError> {
        let StepState {
            masses,
            positions,
            velocities,
            gravity,
        } = state;
        if let Some(v) = first_non_finite(velocities) {
            return Err(SolverError::Diverged {
                step,
                time,
                reason: format!("velocity of vertex {v} is not finite"),
            });
        }
        let motion =
            kinetic_energy(masses, velocities) + gravity_energy(masses, positions, gravity);
        let limit = self.reference + self.factor * self.scale;
        let (bound, block) = elastic;
        // A non-finite energy is divergence even when the bound itself
        // overflowed (an enormous gravity makes the scale infinite).
        if (motion + bound.total).is_finite() && motion + bound.total <= limit {
            return Ok(());
        }
        let exact = if bound.total.is_finite() {
            local.energy(positions)
        } else {
            bound.total
        };
        let energy = motion + exact;
        if energy.is_finite() && energy <= limit {
            return Ok(());
        }
        let culprit = match local.blocks().get(block) {
            Some(worst) => format!(
                "; the most strained element is {} constraint {} (vertices {:?}), elastic energy \
                 up to {:.6e} J",
                worst.kind(),
                bound.worst,
                worst.stencil(bound.worst),
                bound.worst_energy
            ),
            None => String::new(),
        };
        Err(SolverError::Diverged {
            step,
            time,
            reason: format!(
                "total energy {energy:.6e} J (kinetic + gravitational {motion:.6e} J, elastic \
                 {exact:.6e} J) exceeds the bound {limit:.6e} J (initial energy {:.6e} J plus {} \
                 x the energy scale {:.6e} J){culprit}",
                self.reference, self.factor, self.scale
            ),
        })
    }
}

/// The new state a step is checked at: masses (kg), positions (m),
/// velocities (m/s) and gravity (m/s^2).
#[derive(Debug, Clone, Copy)]
pub(crate) struct StepState<'a> {
    pub masses: &'a [f64],
    pub positions: &'a [Point],
    pub velocities: &'a [Point],
    pub gravity: Point,
}
