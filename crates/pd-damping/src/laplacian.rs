//! Laplacian damping, the paper's model: `D = a2 L_d + a1 M`, constant, so it
//! is factored once with the rest of the global step.

use crate::error::non_negative;
use crate::{Damping, DampingError, DampingMatrix, HIGHER_SERIES_TERMS};

/// The name scenes, the command line and the registry use for this model.
pub const NAME: &str = "laplacian";

/// Laplacian damping `D = stiffness L_d + mass M` ("Laplacian-Rayleigh" when
/// `mass > 0`), `L_d` the damping Laplacian of the translation-invariant
/// constraints.
///
/// `L_d` damps rigid rotation too (`v^T L_d v > 0` for `v = omega x r`). With
/// `preserve_rotation` the step damps `(I - P)^T L_d (I - P)` instead, `P`
/// the mass-orthogonal projection on the rigid rotations each body may
/// perform (about its centre of mass when free, about its pivot or hinge
/// when held there): the rigid rotation then feels no damping force and no
/// torque (the solver builds `P` each step, `docs/design/damping.md`).
///
/// ```
/// use pd_damping::{Damping, DampingMatrix, LaplacianDamping};
/// let damping = LaplacianDamping::new(0.01, 0.0, true)?;
/// assert_eq!(damping.name(), "laplacian");
/// assert!(damping.preserves_rotation());
/// assert_eq!(
///     damping.implicit_matrix(),
///     DampingMatrix { mass: 0.0, damping_laplacian: 0.01, ..DampingMatrix::default() }
/// );
/// # Ok::<(), pd_damping::DampingError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct LaplacianDamping {
    stiffness: f64,
    mass: f64,
    /// `a3, a4, ...` of the Caughey series, zero without one.
    series: [f64; HIGHER_SERIES_TERMS],
    /// Whether the rigid rotations are projected out of the `L_d` term.
    preserve_rotation: bool,
}

impl LaplacianDamping {
    /// Laplacian damping with coefficient `stiffness` (`a2`, in s) on the
    /// damping Laplacian and `mass` (`a1`, in 1/s) on the mass matrix;
    /// `preserve_rotation` asks the solver to leave the bodies' rigid
    /// rotations out of the `L_d` term.
    ///
    /// # Errors
    /// [`DampingError::InvalidParameter`] naming `stiffness` or `mass` unless
    /// it is finite and `>= 0`.
    pub fn new(stiffness: f64, mass: f64, preserve_rotation: bool) -> Result<Self, DampingError> {
        Ok(Self {
            stiffness: non_negative("stiffness", stiffness)?,
            mass: non_negative("mass", mass)?,
            series: [0.0; HIGHER_SERIES_TERMS],
            preserve_rotation,
        })
    }

    /// Caughey series damping `D = mass M + stiffness L_d + higher[0] L_d
    /// M^-1 L_d + higher[1] L_d (M^-1 L_d)^2 + ...` (`a1`, `a2`, `a3`, ...;
    /// `docs/design/damping.md`, "Caughey series"); an empty `higher` is
    /// [`LaplacianDamping::new`].
    ///
    /// With series terms, `stiffness` and the higher terms may be negative:
    /// what must hold is that the polynomial `sum_k a_k s^(k-1)` is `>= 0`
    /// over the spectrum of `M^-1 L_d`, which the solver checks when it
    /// builds the global step (`mass`, its value at `s = 0`, stays `>= 0`).
    ///
    /// ```
    /// use pd_damping::{Damping, LaplacianDamping};
    /// let damping = LaplacianDamping::with_series(0.01, 0.1, false, &[1e-6])?;
    /// assert_eq!(damping.implicit_matrix().series_coefficients(), vec![0.1, 0.01, 1e-6]);
    /// # Ok::<(), pd_damping::DampingError>(())
    /// ```
    ///
    /// # Errors
    /// As [`LaplacianDamping::new`] without series. With series:
    /// [`DampingError::InvalidParameter`] naming `series` for a non-finite
    /// term or more than [`HIGHER_SERIES_TERMS`] terms, `stiffness` for a
    /// non-finite value, `mass` for a negative one; and
    /// [`DampingError::Conflict`] naming `preserve_rotation`, which does not
    /// combine with the series.
    pub fn with_series(
        stiffness: f64,
        mass: f64,
        preserve_rotation: bool,
        higher: &[f64],
    ) -> Result<Self, DampingError> {
        if higher.iter().all(|a| *a == 0.0) {
            return Self::new(stiffness, mass, preserve_rotation);
        }
        if higher.len() > HIGHER_SERIES_TERMS {
            return Err(DampingError::InvalidParameter {
                parameter: "series",
                value: higher.len() as f64,
                requirement: "at most 6 terms (a3 to a8)",
            });
        }
        if let Some(bad) = higher.iter().find(|a| !a.is_finite()) {
            return Err(DampingError::InvalidParameter {
                parameter: "series",
                value: *bad,
                requirement: "finite coefficients",
            });
        }
        if !stiffness.is_finite() {
            return Err(DampingError::InvalidParameter {
                parameter: "stiffness",
                value: stiffness,
                requirement: "finite",
            });
        }
        if preserve_rotation {
            return Err(DampingError::Conflict {
                parameter: "preserve_rotation",
                reason: "is not available with a Caughey series (three or more ratios, a \
                         band, or series): only the a2 L_d term is projected"
                    .into(),
            });
        }
        let mut series = [0.0; HIGHER_SERIES_TERMS];
        series[..higher.len()].copy_from_slice(higher);
        Ok(Self {
            stiffness,
            mass: non_negative("mass", mass)?,
            series,
            preserve_rotation: false,
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
            series: self.series,
        }
    }

    fn preserves_rotation(&self) -> bool {
        self.preserve_rotation
    }
}
