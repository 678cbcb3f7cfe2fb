//! Ether drag: every velocity decays towards zero, as if the body moved
//! through a viscous medium at rest.

use crate::error::{non_negative, unit_interval};
use crate::{Damping, DampingContext, DampingError, DampingMatrix, Point};

/// The name scenes, the command line and the registry use for this model.
pub const NAME: &str = "ether-drag";

/// Ether drag, in one of three forms:
/// - [`EtherDrag::factor`]: explicit, `v <- (1 - k) v` after each step (the
///   effect per second depends on `h`);
/// - [`EtherDrag::rate`]: explicit, `v <- exp(-c h) v` after each step, the
///   exact decay of `dv/dt = -c v` over the step, so the effect does not
///   depend on `h`;
/// - [`EtherDrag::implicit`]: no filter; the damping matrix `D = c M` enters
///   the global step.
///
/// Fixed vertices are never touched (their velocity stays 0).
///
/// ```
/// use pd_damping::{Damping, EtherDrag};
/// let drag = EtherDrag::rate(0.5)?;
/// assert_eq!(drag.name(), "ether-drag");
/// assert_eq!(drag.velocity_scale(2.0), (-1.0f64).exp());
/// assert!(drag.implicit_matrix().is_zero());
/// assert_eq!(EtherDrag::implicit(0.5)?.implicit_matrix().mass, 0.5);
/// # Ok::<(), pd_damping::DampingError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EtherDrag {
    form: Form,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Form {
    Factor(f64),
    Rate(f64),
    Implicit(f64),
}

impl EtherDrag {
    /// Explicit drag removing the fraction `factor` (dimensionless, in
    /// `[0, 1]`) of every velocity after each step.
    ///
    /// # Errors
    /// [`DampingError::InvalidParameter`] naming `factor` unless it lies in
    /// `[0, 1]`.
    pub fn factor(factor: f64) -> Result<Self, DampingError> {
        let factor = unit_interval("factor", factor)?;
        Ok(Self {
            form: Form::Factor(factor),
        })
    }

    /// Explicit drag with decay rate `rate` in 1/s: `v <- exp(-rate h) v`.
    ///
    /// # Errors
    /// [`DampingError::InvalidParameter`] naming `rate` unless it is finite
    /// and `>= 0`.
    pub fn rate(rate: f64) -> Result<Self, DampingError> {
        let rate = non_negative("rate", rate)?;
        Ok(Self {
            form: Form::Rate(rate),
        })
    }

    /// Implicit drag with rate `rate` in 1/s: the damping matrix `D = rate M`
    /// inside the global step (`a1` of [`DampingMatrix::mass`]).
    ///
    /// # Errors
    /// [`DampingError::InvalidParameter`] naming `rate` unless it is finite
    /// and `>= 0`.
    pub fn implicit(rate: f64) -> Result<Self, DampingError> {
        let rate = non_negative("rate", rate)?;
        Ok(Self {
            form: Form::Implicit(rate),
        })
    }

    /// The dimensionless factor the filter multiplies every free velocity by
    /// after a step of `h` seconds: `1 - k`, `exp(-c h)`, or 1 for the
    /// implicit form (no filter).
    pub fn velocity_scale(&self, h: f64) -> f64 {
        match self.form {
            Form::Factor(factor) => 1.0 - factor,
            Form::Rate(rate) => (-rate * h).exp(),
            Form::Implicit(_) => 1.0,
        }
    }
}

impl Damping for EtherDrag {
    fn name(&self) -> &'static str {
        NAME
    }

    fn implicit_matrix(&self) -> DampingMatrix {
        match self.form {
            Form::Implicit(rate) => DampingMatrix {
                mass: rate,
                ..DampingMatrix::default()
            },
            Form::Factor(_) | Form::Rate(_) => DampingMatrix::default(),
        }
    }

    fn filter_velocities(
        &self,
        context: &DampingContext<'_>,
        _positions: &[Point],
        velocities: &mut [Point],
    ) {
        let scale = self.velocity_scale(context.h);
        if scale == 1.0 {
            return;
        }
        for (vertex, velocity) in velocities.iter_mut().enumerate() {
            if !context.fixed.get(vertex).copied().unwrap_or(false) {
                *velocity *= scale;
            }
        }
    }
}
