//! Position-based-dynamics damping (Mueller et al. 2007, "Position Based
//! Dynamics", section 3.5): pull the velocities of each connected component
//! towards their best rigid motion.

use crate::error::unit_interval;
use crate::rigid::RigidFit;
use crate::{Damping, DampingContext, DampingError, Point};

/// The name scenes, the command line and the registry use for this model.
pub const NAME: &str = "pbd";

/// PBD damping with factor `k`: per connected component, with the rigid fit
/// `v_cm + omega x r_i` of [`RigidFit`],
/// `v_i <- v_i + k (v_cm + omega x r_i - v_i)`.
///
/// It keeps each component's linear momentum and angular momentum, leaves a
/// rigid motion unchanged, and scales the rest of the velocity field by
/// `1 - k`, so the kinetic energy becomes `KE_rigid + (1 - k)^2 KE_deform`.
/// Singular inertia (a single vertex, two vertices, a chain) is handled by
/// the pseudo-inverse, see [`crate::rigid`].
///
/// Reads the components from [`DampingContext::components`], which must not
/// hold fixed vertices; vertices in no component are not touched.
///
/// ```
/// use pd_damping::{Damping, PbdDamping};
/// let pbd = PbdDamping::new(0.1)?;
/// assert_eq!(pbd.name(), "pbd");
/// assert_eq!(pbd.factor(), 0.1);
/// assert!(pbd.implicit_matrix().is_zero());
/// # Ok::<(), pd_damping::DampingError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PbdDamping {
    factor: f64,
}

impl PbdDamping {
    /// PBD damping removing the fraction `factor` (dimensionless, in `[0, 1]`)
    /// of the non-rigid velocity after each step; 1 makes every component
    /// move rigidly.
    ///
    /// # Errors
    /// [`DampingError::InvalidParameter`] naming `factor` unless it lies in
    /// `[0, 1]`.
    pub fn new(factor: f64) -> Result<Self, DampingError> {
        let factor = unit_interval("factor", factor)?;
        Ok(Self { factor })
    }

    /// The factor `k` (dimensionless).
    pub fn factor(&self) -> f64 {
        self.factor
    }
}

impl Damping for PbdDamping {
    fn name(&self) -> &'static str {
        NAME
    }

    /// Cost: two passes over each component plus one 3 x 3 eigendecomposition
    /// per component; no allocation.
    fn filter_velocities(
        &self,
        context: &DampingContext<'_>,
        positions: &[Point],
        velocities: &mut [Point],
    ) {
        if self.factor == 0.0 {
            return;
        }
        for component in context.components {
            let rigid = RigidFit::of(component, context.masses, positions, velocities).motion();
            for &vertex in component {
                let velocity = &mut velocities[vertex];
                *velocity += self.factor * (rigid.velocity_at(&positions[vertex]) - *velocity);
            }
        }
    }
}
