//! Damping by ratio: the coefficients `(a1, a2)` of `D = a1 M + a2 Q` (`Q`
//! the damping Laplacian `L_d` for Laplacian damping, the stiffness `K` at
//! rest for lagged Rayleigh damping) that give chosen elastic modes chosen
//! damping ratios.
//!
//! For a mass-normalised mode `phi` (`phi^T M phi = 1`) of angular frequency
//! `omega`, `D` gives the modal equation `q'' + c q' + omega^2 q = 0` with
//! `c = a1 + a2 phi^T Q phi` (the off-diagonal couplings `phi_i^T D phi_j`
//! are neglected: exact when `Q` shares the modes, as `K` does and `L_d`
//! does on a spring chain), hence the damping ratio `zeta = c / (2 omega)`.
//! With `Q = K`, `phi^T K phi = omega^2` and `a2 = 2 zeta / omega`
//! (Rayleigh). With `Q = L_d` the quotient `phi^T L_d phi` is not `omega^2`:
//! for bending it is much larger (`L_d` treats every element as if it were
//! stretched), so `a2 = 2 zeta omega / (phi^T L_d phi)` (`docs/design/damping.md`).
//!
//! One mode: `a2 = (2 zeta omega - a1) / (phi^T Q phi)` with `a1` the given
//! `mass` (default 0). Two modes: the 2 x 2 system
//! `a1 + a2 q_i = 2 zeta_i omega_i`.

use crate::DampingError;

/// What a `[damping]` table asks for instead of `stiffness`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RatioTarget {
    /// `ratio` for `mode` (1 = lowest), with the given `mass` (`a1`, 1/s).
    One {
        /// The elastic mode, 1-based.
        mode: usize,
        /// The damping ratio (1 = critical).
        ratio: f64,
        /// `a1` in 1/s, kept as given.
        mass: f64,
    },
    /// `ratios` for `modes`: `a1` and `a2` are both fitted.
    Two {
        /// The elastic modes, 1-based, distinct.
        modes: [usize; 2],
        /// Their damping ratios.
        ratios: [f64; 2],
    },
}

/// What a ratio needs to know of one elastic mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModalData {
    /// Angular frequency `omega` in rad/s.
    pub omega: f64,
    /// `phi^T L_d phi` of the mass-normalised mode, in 1/s^2.
    pub laplacian_quotient: f64,
}

/// The fitted coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FittedCoefficients {
    /// `a1` in 1/s.
    pub mass: f64,
    /// `a2` in s.
    pub stiffness: f64,
}

/// Which matrix a model's `stiffness` multiplies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quotient {
    /// The damping Laplacian `L_d` (Laplacian damping).
    Laplacian,
    /// The elastic stiffness `K` (lagged Rayleigh damping; at rest
    /// `phi^T K phi = omega^2`).
    Stiffness,
}

impl Quotient {
    /// `phi^T Q phi` of `mode`, 1/s^2.
    pub fn of(self, mode: &ModalData) -> f64 {
        match self {
            Self::Laplacian => mode.laplacian_quotient,
            Self::Stiffness => mode.omega * mode.omega,
        }
    }
}

impl RatioTarget {
    /// The highest mode (1-based) the fit needs.
    pub fn highest_mode(&self) -> usize {
        match *self {
            Self::One { mode, .. } => mode,
            Self::Two { modes, .. } => modes[0].max(modes[1]),
        }
    }

    /// The coefficients for `modes` (lowest first, as many as
    /// [`RatioTarget::highest_mode`] or fewer).
    ///
    /// # Errors
    /// [`DampingError::Conflict`] naming `mode`/`modes` when the scene has
    /// fewer elastic modes, or `ratio`/`ratios` when the fit needs a negative
    /// coefficient (or two modes with equal quotients and different ratios).
    pub fn fit(
        &self,
        quotient: Quotient,
        modes: &[ModalData],
    ) -> Result<FittedCoefficients, DampingError> {
        let get = |parameter: &'static str, index: usize| {
            modes.get(index - 1).ok_or_else(|| DampingError::Conflict {
                parameter,
                reason: format!(
                    "asks for elastic mode {index}, but the scene has only {} (rigid motions \
                     and zero-stiffness mechanisms are not elastic modes)",
                    modes.len()
                ),
            })
        };
        let negative = |parameter: &'static str, what: String| DampingError::Conflict {
            parameter,
            reason: format!(
                "the fit needs {what} < 0, which would add energy; choose other ratios or modes"
            ),
        };
        match *self {
            Self::One { mode, ratio, mass } => {
                let data = get("mode", mode)?;
                let stiffness = (2.0 * ratio * data.omega - mass) / quotient.of(data);
                if !stiffness.is_finite() {
                    return Err(DampingError::Conflict {
                        parameter: "ratio",
                        reason: format!(
                            "ratio {ratio} of mode {mode} needs a stiffness a2 beyond the largest \
                             number ({stiffness:e} s); choose a smaller ratio"
                        ),
                    });
                }
                if stiffness < 0.0 {
                    return Err(negative(
                        "ratio",
                        format!(
                            "stiffness a2 = {stiffness:e} s (mass a1 = {mass} 1/s is too large)"
                        ),
                    ));
                }
                Ok(FittedCoefficients { mass, stiffness })
            }
            Self::Two { modes: m, ratios } => {
                let (a, b) = (get("modes", m[0])?, get("modes", m[1])?);
                let (qa, qb) = (quotient.of(a), quotient.of(b));
                let (ra, rb) = (2.0 * ratios[0] * a.omega, 2.0 * ratios[1] * b.omega);
                // a1 + a2 q_i = r_i.
                let stiffness = (rb - ra) / (qb - qa);
                let mass = ra - stiffness * qa;
                if !stiffness.is_finite() || !mass.is_finite() {
                    return Err(DampingError::Conflict {
                        parameter: "modes",
                        reason: format!(
                            "modes {} and {} have the same quotient phi^T D phi: one \
                             coefficient pair cannot give them different ratios",
                            m[0], m[1]
                        ),
                    });
                }
                if stiffness < 0.0 {
                    return Err(negative(
                        "ratios",
                        format!("stiffness a2 = {stiffness:e} s"),
                    ));
                }
                if mass < 0.0 {
                    return Err(negative("ratios", format!("mass a1 = {mass:e} 1/s")));
                }
                Ok(FittedCoefficients { mass, stiffness })
            }
        }
    }
}

/// Reads a ratio target from the parameters `ratio`, `mode`, `ratios`,
/// `modes`, `stiffness`, `mass` as given (`None` where absent); `Ok(None)`
/// when the coefficients are given as `stiffness`, or when neither
/// `stiffness` nor a ratio is given (the model's build then reports the
/// missing `stiffness`).
///
/// # Errors
/// [`DampingError::Conflict`] for `stiffness` with `ratio`/`ratios`, both
/// `ratio` and `ratios`, `mode` without `ratio`, `modes` without `ratios` or
/// the other way round, or a non-zero `mass` with `ratios`;
/// [`DampingError::InvalidParameter`] for a
/// negative or non-finite ratio, or a mode that is not a whole number >= 1.
pub(crate) fn target(
    given: impl Fn(&str) -> Option<f64>,
    pair: impl Fn(&str) -> Option<[f64; 2]>,
) -> Result<Option<RatioTarget>, DampingError> {
    let conflict = |parameter: &'static str, reason: &str| DampingError::Conflict {
        parameter,
        reason: reason.into(),
    };
    let (ratio, ratios) = (given("ratio"), pair("ratios"));
    if given("stiffness").is_some() {
        return match (ratio, ratios) {
            (None, None) if given("mode").is_none() && pair("modes").is_none() => Ok(None),
            (None, None) => Err(conflict(
                "mode",
                "only goes with ratio/ratios, not with stiffness",
            )),
            _ => Err(conflict(
                "stiffness",
                "give either stiffness (s) or ratio/ratios (dimensionless), not both",
            )),
        };
    }
    let ratio_value = |name: &'static str, value: f64| {
        if value.is_finite() && value >= 0.0 {
            Ok(value)
        } else {
            Err(DampingError::InvalidParameter {
                parameter: name,
                value,
                requirement: "a finite damping ratio >= 0",
            })
        }
    };
    let mode_value = |name: &'static str, value: f64| {
        if value >= 1.0 && value.fract() == 0.0 && value <= 1e6 {
            Ok(value as usize)
        } else {
            Err(DampingError::InvalidParameter {
                parameter: name,
                value,
                requirement: "a whole number >= 1 (1 = the lowest elastic mode)",
            })
        }
    };
    match (ratio, ratios) {
        // Neither: `stiffness` is missing, which the model's build reports.
        (None, None) if given("mode").is_none() && pair("modes").is_none() => Ok(None),
        (None, None) => Err(conflict(
            "mode",
            "only goes with ratio (and modes with ratios), which is missing",
        )),
        (Some(_), Some(_)) => Err(conflict("ratio", "give either ratio or ratios, not both")),
        (Some(ratio), None) => {
            if pair("modes").is_some() {
                return Err(conflict("modes", "goes with ratios; with ratio use mode"));
            }
            Ok(Some(RatioTarget::One {
                mode: given("mode").map_or(Ok(1), |m| mode_value("mode", m))?,
                ratio: ratio_value("ratio", ratio)?,
                mass: crate::error::non_negative("mass", given("mass").unwrap_or(0.0))?,
            }))
        }
        (None, Some(ratios)) => {
            if given("mode").is_some() {
                return Err(conflict("mode", "goes with ratio; with ratios use modes"));
            }
            let modes = pair("modes").ok_or_else(|| {
                conflict(
                    "modes",
                    "is required with ratios: the two modes (1 = lowest) they are for",
                )
            })?;
            if given("mass").is_some_and(|m| m != 0.0) {
                return Err(conflict("mass", "is fitted from ratios; leave it out"));
            }
            let modes = [
                mode_value("modes", modes[0])?,
                mode_value("modes", modes[1])?,
            ];
            if modes[0] == modes[1] {
                return Err(conflict("modes", "must name two different modes"));
            }
            Ok(Some(RatioTarget::Two {
                modes,
                ratios: [
                    ratio_value("ratios", ratios[0])?,
                    ratio_value("ratios", ratios[1])?,
                ],
            }))
        }
    }
}
