//! Lagged Rayleigh damping `D_n = a1 M + a2 K(x_n)`: the classical baseline,
//! with the elastic Hessian taken at the start of each step.

use crate::error::non_negative;
use crate::{Damping, DampingError, DampingMatrix};

/// The name scenes, the command line and the registry use for this model.
pub const NAME: &str = "rayleigh-lagged";

/// Lagged Rayleigh damping `D_n = mass M + stiffness K(x_n)`, `K(x_n)` the
/// elastic Hessian at the start of the step, projected to PSD per element.
/// The solver assembles `K(x_n)` and refactors the 3n x 3n system every step
/// ([`DampingMatrix::is_lagged`]).
///
/// ```
/// use pd_damping::{Damping, DampingMatrix, RayleighLagged};
/// let damping = RayleighLagged::new(0.01, 0.1)?;
/// assert_eq!(damping.name(), "rayleigh-lagged");
/// assert_eq!(
///     damping.implicit_matrix(),
///     DampingMatrix { mass: 0.1, damping_laplacian: 0.0, lagged_stiffness: 0.01, ..Default::default() }
/// );
/// # Ok::<(), pd_damping::DampingError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayleighLagged {
    mass: f64,
    stiffness: f64,
}

impl RayleighLagged {
    /// Lagged Rayleigh damping with coefficient `stiffness` (`a2`, in s) on
    /// the lagged Hessian and `mass` (`a1`, in 1/s) on the mass matrix: the
    /// same argument order as [`crate::LaplacianDamping::new`].
    ///
    /// # Errors
    /// [`DampingError::InvalidParameter`] naming `mass` or `stiffness` unless
    /// it is finite and `>= 0`.
    pub fn new(stiffness: f64, mass: f64) -> Result<Self, DampingError> {
        Ok(Self {
            mass: non_negative("mass", mass)?,
            stiffness: non_negative("stiffness", stiffness)?,
        })
    }
}

impl Damping for RayleighLagged {
    fn name(&self) -> &'static str {
        NAME
    }

    fn implicit_matrix(&self) -> DampingMatrix {
        DampingMatrix {
            mass: self.mass,
            damping_laplacian: 0.0,
            lagged_stiffness: self.stiffness,
            ..DampingMatrix::default()
        }
    }
}
