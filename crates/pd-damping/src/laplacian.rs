//! Laplacian damping, the paper's model: `D = a2 L_d + a1 M`, constant, so it
//! is factored once with the rest of the global step.

use crate::error::non_negative;
use crate::rotation_preserving::SpinKeeper;
use crate::{
    Damping, DampingError, DampingMatrix, DampingReport, DampingTargets, Point, StepContext,
};

/// The name scenes, the command line and the registry use for this model.
pub const NAME: &str = "laplacian";

/// Laplacian damping `D = stiffness L_d + mass M` ("Laplacian-Rayleigh" when
/// `mass > 0`), `L_d` the damping Laplacian of the translation-invariant
/// constraints.
///
/// `L_d` damps rigid rotation too (`v^T L_d v > 0` for `v = omega x r`). With
/// `preserve_rotation` it leaves each free body's rigid rotation alone: the
/// damping anchor turns with the body, and the spin is given back at the end
/// of the step (`rotation_preserving.rs`, `docs/design/damping.md`).
///
/// ```
/// use pd_damping::{Damping, DampingMatrix, LaplacianDamping};
/// let damping = LaplacianDamping::new(0.01, 0.0, true)?;
/// assert_eq!(damping.name(), "laplacian");
/// assert!(damping.preserves_rotation());
/// assert_eq!(
///     damping.implicit_matrix(),
///     DampingMatrix { mass: 0.0, damping_laplacian: 0.01, lagged_stiffness: 0.0 }
/// );
/// # Ok::<(), pd_damping::DampingError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct LaplacianDamping {
    stiffness: f64,
    mass: f64,
    /// The rotation-preserving variant's state, when it is on.
    spin_keeper: Option<SpinKeeper>,
}

impl LaplacianDamping {
    /// Laplacian damping with coefficient `stiffness` (`a2`, in s) on the
    /// damping Laplacian and `mass` (`a1`, in 1/s) on the mass matrix;
    /// `preserve_rotation` asks the solver to give back the angular momentum
    /// the damping removes.
    ///
    /// # Errors
    /// [`DampingError::InvalidParameter`] naming `stiffness` or `mass` unless
    /// it is finite and `>= 0`.
    pub fn new(stiffness: f64, mass: f64, preserve_rotation: bool) -> Result<Self, DampingError> {
        Ok(Self {
            stiffness: non_negative("stiffness", stiffness)?,
            mass: non_negative("mass", mass)?,
            spin_keeper: preserve_rotation.then(SpinKeeper::default),
        })
    }
}

impl Damping for LaplacianDamping {
    fn name(&self) -> &'static str {
        NAME
    }

    fn implicit_matrix(&self) -> DampingMatrix {
        DampingMatrix {
            mass: self.mass,
            damping_laplacian: self.stiffness,
            lagged_stiffness: 0.0,
        }
    }

    fn preserves_rotation(&self) -> bool {
        self.spin_keeper.is_some()
    }

    fn begin_step(
        &mut self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &[Point],
        targets: DampingTargets<'_>,
    ) {
        if let Some(keeper) = &mut self.spin_keeper {
            keeper.begin_step(self.mass, step, positions, velocities, targets);
        }
    }

    fn end_step(
        &mut self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &mut [Point],
    ) -> DampingReport {
        let mut report = DampingReport::default();
        if let Some(keeper) = &self.spin_keeper {
            report.spin_axes_left = keeper.end_step(step, positions, velocities);
        }
        report
    }
}
