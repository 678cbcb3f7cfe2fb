//! Which [`PositionSolver`] a step uses, as a scene's `[solver]` table
//! names it (docs/design/solver.md, "Iteration methods"): the method and its parameters,
//! checked by [`SolverSpec::validate`] and turned into a solver by
//! [`SolverSpec::create`].

use super::anderson::Anderson;
use super::chebyshev::Chebyshev;
use super::iteration::{LocalGlobal, PositionSolver};
use super::lbfgs::Lbfgs;
use super::newton::Newton;
use crate::SolverError;

/// The iteration method of a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SolverMethod {
    /// Plain local-global Projective Dynamics (the default).
    #[default]
    LocalGlobal,
    /// Anderson acceleration of the local-global fixed point with a
    /// merit-function safeguard (Peng et al. 2018).
    Anderson,
    /// Chebyshev semi-iterative acceleration (Wang 2015).
    Chebyshev,
    /// L-BFGS with the prefactored matrix as initial Hessian (Liu, Bouaziz
    /// and Kavan 2017), for PD energies and hyperelastic materials.
    Lbfgs,
    /// Newton's method with per-element PSD-projected Hessians and a line
    /// search on the step objective: the converged reference.
    Newton,
}

impl SolverMethod {
    /// Every method, in the order scenes list them.
    pub const ALL: [SolverMethod; 5] = [
        SolverMethod::LocalGlobal,
        SolverMethod::Anderson,
        SolverMethod::Chebyshev,
        SolverMethod::Lbfgs,
        SolverMethod::Newton,
    ];

    /// The name as scenes spell it (`local-global`).
    pub fn name(self) -> &'static str {
        match self {
            SolverMethod::LocalGlobal => "local-global",
            SolverMethod::Anderson => "anderson",
            SolverMethod::Chebyshev => "chebyshev",
            SolverMethod::Lbfgs => "lbfgs",
            SolverMethod::Newton => "newton",
        }
    }

    /// The method named `name`, if any.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }

    /// Whether the method only minimises Projective Dynamics' energies
    /// (local-global, anderson, chebyshev): hyperelastic materials
    /// (docs/design/materials.md) need `lbfgs` or `newton`.
    pub fn pd_only(self) -> bool {
        matches!(
            self,
            SolverMethod::LocalGlobal | SolverMethod::Anderson | SolverMethod::Chebyshev
        )
    }
}

/// Chebyshev's estimate of the local-global iteration's spectral radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpectralRadius {
    /// Given, in `(0, 1)`.
    Fixed(f64),
    /// Estimated from every step's iterates for the next (and within long
    /// steps), as the largest Ritz value of the local-global map's
    /// linearisation (`step/chebyshev.rs`, `step/ritz.rs`); lowered when
    /// the iteration oscillates.
    Auto,
}

impl SpectralRadius {
    /// Checks a fixed radius lies in `(0, 1)`.
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] naming `rho`.
    pub fn validate(self) -> Result<(), SolverError> {
        match self {
            SpectralRadius::Fixed(rho) if !(rho > 0.0 && rho < 1.0) => {
                Err(SolverError::InvalidSetting {
                    field: "rho",
                    reason: format!("must be in (0, 1) or \"auto\", got {rho}"),
                })
            }
            _ => Ok(()),
        }
    }
}

/// A step's iteration method and its parameters (the `[solver]` table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverSpec {
    /// The method.
    pub method: SolverMethod,
    /// History length of `anderson` (and `lbfgs`), 1 to [`SolverSpec::MAX_WINDOW`].
    pub window: usize,
    /// Chebyshev's spectral radius.
    pub rho: SpectralRadius,
    /// Plain iterations Chebyshev runs in each step before it accelerates,
    /// at least 2 (the first step with `rho = "auto"` runs at least 4,
    /// which give the first estimate).
    pub start: usize,
}

impl Default for SolverSpec {
    fn default() -> Self {
        Self {
            method: SolverMethod::LocalGlobal,
            window: 5,
            rho: SpectralRadius::Auto,
            start: 2,
        }
    }
}

impl SolverSpec {
    /// The largest `window` accepted (the least-squares problem of each
    /// Anderson iteration is `window x window`).
    pub const MAX_WINDOW: usize = 50;

    /// Checks every field.
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] naming the field (`method`, `window`,
    /// `rho`, `start`).
    pub fn validate(&self) -> Result<(), SolverError> {
        let bad = |field: &'static str, reason: String| {
            Err(SolverError::InvalidSetting { field, reason })
        };
        if !(1..=Self::MAX_WINDOW).contains(&self.window) {
            return bad(
                "window",
                format!(
                    "must be between 1 and {}, got {}",
                    Self::MAX_WINDOW,
                    self.window
                ),
            );
        }
        self.rho.validate()?;
        if self.start < 2 {
            return bad("start", format!("must be at least 2, got {}", self.start));
        }
        Ok(())
    }

    /// The solver this spec describes.
    ///
    /// # Errors
    /// As [`SolverSpec::validate`].
    pub fn create(&self) -> Result<Box<dyn PositionSolver>, SolverError> {
        self.validate()?;
        let solver: Box<dyn PositionSolver> = match self.method {
            SolverMethod::LocalGlobal => Box::new(LocalGlobal),
            SolverMethod::Lbfgs => Box::new(Lbfgs::new(self.window)),
            SolverMethod::Anderson => Box::new(Anderson::new(self.window)),
            SolverMethod::Chebyshev => Box::new(Chebyshev::new(self.rho, self.start)),
            SolverMethod::Newton => Box::new(Newton::default()),
        };
        Ok(solver)
    }
}
