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
//!
//! Three or more modes (Laplacian damping only) fit the Caughey series
//! `D = a1 M + a2 L_d + a3 L_d M^-1 L_d + ...`: mode `i` gets
//! `c_i = sum_k a_k Q_k,i` with the series quotients
//! `Q_k,i = phi_i^T L_d (M^-1 L_d)^(k-2) phi_i` (`Q_1 = 1`, `Q_2` the
//! Laplacian quotient), the same neglect of off-diagonal couplings as
//! above, so `p` ratios give a `p x p` system ([`RatioTarget::fit_series`]).
//! A `band` fits a three-term series by least squares to one ratio over the
//! modes in a frequency band. `D` is positive semi-definite exactly when the
//! polynomial `sum_k a_k s^(k-1)` is `>= 0` on the eigenvalues `s` of
//! `M^-1 L_d` ([`series_negative_at`]).

use crate::registry::Numbers;
use crate::{DampingError, HIGHER_SERIES_TERMS, MAX_SERIES_TERMS};

/// What a `[damping]` table asks for instead of `stiffness`.
#[derive(Debug, Clone, PartialEq)]
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
    /// `ratios` for three or more `modes` (up to [`MAX_SERIES_TERMS`]): the
    /// Caughey series `a1, ..., ap` is fitted (Laplacian damping only).
    Series {
        /// The elastic modes, 1-based, distinct.
        modes: Vec<usize>,
        /// Their damping ratios.
        ratios: Vec<f64>,
    },
    /// `ratio` as flat as a three-term series allows over the elastic modes
    /// whose frequencies lie in `band` (Laplacian damping only).
    Band {
        /// `[f_lo, f_hi]` in Hz, `0 <= f_lo < f_hi`.
        band: [f64; 2],
        /// The damping ratio asked for across the band.
        ratio: f64,
    },
}

/// The number of series terms a `band` fits (`a1 M + a2 L_d + a3 L_d M^-1
/// L_d`).
pub const BAND_TERMS: usize = 3;

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
    /// `a3, a4, ...` of a Caughey series (s^3, s^5, ...), zero for one or
    /// two ratios.
    pub series: [f64; HIGHER_SERIES_TERMS],
}

impl FittedCoefficients {
    /// `a1` and `a2` without series terms.
    pub fn pair(mass: f64, stiffness: f64) -> Self {
        Self {
            mass,
            stiffness,
            series: [0.0; HIGHER_SERIES_TERMS],
        }
    }

    /// The series terms `a3, ...` up to the last non-zero one (empty for
    /// one or two ratios).
    pub fn higher_terms(&self) -> &[f64] {
        let len = self
            .series
            .iter()
            .rposition(|a| *a != 0.0)
            .map_or(0, |j| j + 1);
        &self.series[..len]
    }

    /// All coefficients `[a1, a2, a3, ...]`.
    pub fn all(&self) -> Vec<f64> {
        let mut all = vec![self.mass, self.stiffness];
        all.extend_from_slice(self.higher_terms());
        all
    }
}

/// What a Caughey series fit needs besides [`ModalData`].
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesData {
    /// Per mode (lowest first, as the [`ModalData`]): the series quotients
    /// `[1, phi^T L_d phi, phi^T L_d M^-1 L_d phi, ...]` of the
    /// mass-normalised mode (1/s^(2k-2)), at least as many as terms fitted.
    pub quotients: Vec<Vec<f64>>,
    /// An upper bound of the eigenvalues of `M^-1 L_d` (1/s^2), over which
    /// the series polynomial must stay `>= 0`.
    pub spectrum_bound: f64,
}

/// The damping ratio a fitted series gives one mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AchievedRatio {
    /// The elastic mode, 1-based.
    pub mode: usize,
    /// Its angular frequency, rad/s.
    pub omega: f64,
    /// The damping ratio the series gives it (neglecting couplings).
    pub ratio: f64,
}

/// A fitted Caughey series and the ratios it gives.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesFit {
    /// The coefficients.
    pub coefficients: FittedCoefficients,
    /// The ratio of each mode the fit was asked about (the asked modes, or
    /// the band's).
    pub achieved: Vec<AchievedRatio>,
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
    /// The highest mode (1-based) the fit needs; 0 for a band, whose modes
    /// are those below its upper frequency.
    pub fn highest_mode(&self) -> usize {
        match self {
            Self::One { mode, .. } => *mode,
            Self::Two { modes, .. } => modes[0].max(modes[1]),
            Self::Series { modes, .. } => modes.iter().copied().max().unwrap_or(0),
            Self::Band { .. } => 0,
        }
    }

    /// Whether this is a Caughey series ([`RatioTarget::fit_series`]), not
    /// one or two ratios ([`RatioTarget::fit`]).
    pub fn is_series(&self) -> bool {
        matches!(self, Self::Series { .. } | Self::Band { .. })
    }

    /// The frequency band of a band target, Hz.
    pub fn band(&self) -> Option<[f64; 2]> {
        match self {
            Self::Band { band, .. } => Some(*band),
            _ => None,
        }
    }

    /// The Caughey series for `modes` (lowest first, with the series
    /// quotients of `series`, at least up to the highest mode asked, or
    /// every mode up to the band's upper frequency), for Laplacian damping.
    ///
    /// Ratios for `p` modes solve `sum_k a_k Q_k,i = 2 zeta_i omega_i`,
    /// with the columns scaled by powers of the largest `Q_2,i` (the
    /// unscaled system's entries span `q^(p-1)`). A band fits
    /// [`BAND_TERMS`] terms by least squares on the relative ratio error
    /// over its modes, keeping the best fit among the series made of a
    /// subset of the terms that passes the positivity test; it reports each
    /// band mode's ratio.
    ///
    /// # Errors
    /// [`DampingError::Conflict`] naming `modes` when a mode is missing or
    /// two modes' quotients make the system singular; `ratios` when the
    /// series is negative somewhere on `[0, spectrum_bound]` or for a
    /// computed mode (naming that mode: `D` would be indefinite); `band`
    /// when fewer than [`BAND_TERMS`] modes lie in the band; `ratio`/`ratios`
    /// for a target that is not a series.
    pub fn fit_series(
        &self,
        modes: &[ModalData],
        series: &SeriesData,
    ) -> Result<SeriesFit, DampingError> {
        let conflict =
            |parameter: &'static str, reason: String| DampingError::Conflict { parameter, reason };
        match self {
            Self::Series {
                modes: asked,
                ratios,
            } => {
                let p = asked.len();
                for &m in asked {
                    if m > modes.len() || series.quotients.get(m - 1).is_none_or(|q| q.len() < p) {
                        return Err(conflict(
                            "modes",
                            format!(
                                "asks for elastic mode {m}, but the scene has only {} (rigid \
                                 motions and zero-stiffness mechanisms are not elastic modes)",
                                modes.len()
                            ),
                        ));
                    }
                }
                let rows: Vec<Vec<f64>> = asked
                    .iter()
                    .map(|&m| series.quotients[m - 1][..p].to_vec())
                    .collect();
                let targets: Vec<f64> = asked
                    .iter()
                    .zip(ratios)
                    .map(|(&m, z)| 2.0 * z * modes[m - 1].omega)
                    .collect();
                let coefficients = scaled_least_squares(&rows, &targets).ok_or_else(|| {
                    conflict(
                        "modes",
                        format!(
                            "modes {asked:?} have (nearly) dependent series quotients: one \
                             series cannot give them these ratios; choose other modes"
                        ),
                    )
                })?;
                check_positive(&coefficients, modes, series)
                    .map_err(|why| conflict("ratios", why))?;
                Ok(SeriesFit {
                    achieved: achieved(&coefficients, asked, modes, series),
                    coefficients: to_fitted(&coefficients),
                })
            }
            Self::Band { band, ratio } => {
                let in_band: Vec<usize> = modes
                    .iter()
                    .enumerate()
                    .filter(|(_, m)| {
                        let f = m.omega / std::f64::consts::TAU;
                        f >= band[0] && f <= band[1]
                    })
                    .map(|(i, _)| i + 1)
                    .collect();
                if in_band.len() < BAND_TERMS {
                    return Err(conflict(
                        "band",
                        format!(
                            "holds {} elastic mode(s) ({in_band:?}) between {} and {} Hz; a \
                             {BAND_TERMS}-term series needs at least {BAND_TERMS}: widen the \
                             band or give ratio/ratios",
                            in_band.len(),
                            band[0],
                            band[1]
                        ),
                    ));
                }
                if let Some(&m) = in_band.iter().find(|&&m| {
                    series
                        .quotients
                        .get(m - 1)
                        .is_none_or(|q| q.len() < BAND_TERMS)
                }) {
                    return Err(conflict(
                        "band",
                        format!("mode {m} has no series quotients"),
                    ));
                }
                // Relative error of the ratio: row i divided by its target
                // 2 zeta omega_i (by 2 omega_i for zeta = 0).
                let weight =
                    |m: usize| 1.0 / (2.0 * ratio.max(f64::MIN_POSITIVE) * modes[m - 1].omega);
                let targets: Vec<f64> = in_band
                    .iter()
                    .map(|&m| 2.0 * ratio * modes[m - 1].omega * weight(m))
                    .collect();
                let mut best: Option<(f64, Vec<f64>)> = None;
                // Every non-empty subset of the terms, as a bit mask.
                for mask in 1..(1usize << BAND_TERMS) {
                    let terms: Vec<usize> =
                        (0..BAND_TERMS).filter(|k| mask >> k & 1 == 1).collect();
                    let rows: Vec<Vec<f64>> = in_band
                        .iter()
                        .map(|&m| {
                            terms
                                .iter()
                                .map(|&k| series.quotients[m - 1][k] * weight(m))
                                .collect()
                        })
                        .collect();
                    let Some(sub) = scaled_least_squares(&rows, &targets) else {
                        continue;
                    };
                    let mut full = vec![0.0; BAND_TERMS];
                    for (&k, a) in terms.iter().zip(&sub) {
                        full[k] = *a;
                    }
                    // Without a3 the model is plain Laplacian damping,
                    // whose a2 must not be negative.
                    if (full[2] == 0.0 && full[1] < 0.0)
                        || check_positive(&full, modes, series).is_err()
                    {
                        continue;
                    }
                    let residual: f64 = rows
                        .iter()
                        .zip(&targets)
                        .map(|(row, t)| {
                            (row.iter().zip(&sub).map(|(q, a)| q * a).sum::<f64>() - t).powi(2)
                        })
                        .sum();
                    if best.as_ref().is_none_or(|(r, _)| residual < *r) {
                        best = Some((residual, full));
                    }
                }
                // a1 alone is the weighted mean of non-negative targets,
                // which is positive everywhere: some subset always passes.
                let (_, coefficients) = best.ok_or_else(|| {
                    conflict("band", "no series passes the positivity test".into())
                })?;
                Ok(SeriesFit {
                    achieved: achieved(&coefficients, &in_band, modes, series),
                    coefficients: to_fitted(&coefficients),
                })
            }
            Self::One { .. } => Err(conflict(
                "ratio",
                "one ratio fits a1 and a2, not a series: use RatioTarget::fit".into(),
            )),
            Self::Two { .. } => Err(conflict(
                "ratios",
                "two ratios fit a1 and a2, not a series: use RatioTarget::fit".into(),
            )),
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
        match self {
            Self::Series { .. } | Self::Band { .. } => Err(DampingError::Conflict {
                parameter: "ratios",
                reason: "a Caughey series is fitted by RatioTarget::fit_series".into(),
            }),
            &Self::One { mode, ratio, mass } => {
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
                Ok(FittedCoefficients::pair(mass, stiffness))
            }
            &Self::Two { modes: m, ratios } => {
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
                Ok(FittedCoefficients::pair(mass, stiffness))
            }
        }
    }
}

/// `a` as [`FittedCoefficients`] (`a1`, `a2`, then the series terms).
fn to_fitted(a: &[f64]) -> FittedCoefficients {
    let mut fitted = FittedCoefficients::pair(a[0], a.get(1).copied().unwrap_or(0.0));
    for (s, x) in fitted.series.iter_mut().zip(a.iter().skip(2)) {
        *s = *x;
    }
    fitted
}

/// The ratio of each of `asked` (1-based) under the series `a`.
fn achieved(
    a: &[f64],
    asked: &[usize],
    modes: &[ModalData],
    series: &SeriesData,
) -> Vec<AchievedRatio> {
    asked
        .iter()
        .map(|&mode| {
            let omega = modes[mode - 1].omega;
            let c: f64 = a
                .iter()
                .zip(&series.quotients[mode - 1])
                .map(|(a, q)| a * q)
                .sum();
            AchievedRatio {
                mode,
                omega,
                ratio: c / (2.0 * omega),
            }
        })
        .collect()
}

/// The positivity test of a fitted series `a`: every computed mode's modal
/// damping `sum_k a_k Q_k,i` is `>= 0`, and so is the polynomial on
/// `[0, spectrum_bound]` ([`series_negative_at`]). The error says which
/// mode cannot be met.
fn check_positive(a: &[f64], modes: &[ModalData], series: &SeriesData) -> Result<(), String> {
    for (i, (mode, q)) in modes.iter().zip(&series.quotients).enumerate() {
        let terms = a.iter().zip(q).map(|(a, q)| a * q);
        let scale: f64 = terms.clone().map(f64::abs).sum();
        let c: f64 = terms.sum();
        // Round-off of the sum: a few units in the last place of its terms.
        if c < -1e-12 * scale {
            return Err(format!(
                "the fitted series {a:?} gives mode {} the damping ratio {:e} < 0: D would be \
                 indefinite (it would add energy to that mode); choose other ratios or modes",
                i + 1,
                c / (2.0 * mode.omega)
            ));
        }
    }
    if let Some(s) = series_negative_at(a, series.spectrum_bound) {
        let nearest = series
            .quotients
            .iter()
            .enumerate()
            .filter_map(|(i, q)| q.get(1).map(|q| (i + 1, *q)))
            .min_by(|x, y| {
                let distance = |q: f64| {
                    (q.max(f64::MIN_POSITIVE) / s.max(f64::MIN_POSITIVE))
                        .ln()
                        .abs()
                };
                distance(x.1).total_cmp(&distance(y.1))
            });
        let highest = series
            .quotients
            .iter()
            .filter_map(|q| q.get(1))
            .fold(0.0_f64, |m, q| m.max(*q));
        let where_ = match nearest {
            Some(_) if s > highest => format!(
                "above the highest computed mode ({} of them; mode {} and up cannot be met)",
                modes.len(),
                modes.len() + 1
            ),
            Some((mode, _)) => format!("near mode {mode}, which cannot be met"),
            None => "where no mode was computed".into(),
        };
        return Err(format!(
            "the fitted series {a:?} is negative at s = {s:e} 1/s^2 of the spectrum of M^-1 L_d \
             [0, {:e}] ({where_}): D would be indefinite; choose other ratios or modes",
            series.spectrum_bound
        ));
    }
    Ok(())
}

/// A point `s` of `[0, bound]` where the series polynomial
/// `p(s) = sum_k a_k s^(k-1)` (`a = [a1, a2, ...]`) is negative, or `None`
/// when it is `>= 0` there (to round-off: `-1e-12` of the sum of its terms'
/// magnitudes).
///
/// `D = M^(1/2) p(S) M^(1/2)` with `S = M^(-1/2) L_d M^(-1/2)`, so `D` is
/// positive semi-definite exactly when `p >= 0` on the eigenvalues of
/// `M^-1 L_d`, which lie in `[0, bound]` for a Gershgorin bound. The test
/// evaluates `p` at both ends, at the real critical points for up to four
/// terms (exact there), and on 4,096 uniform plus 241 logarithmically
/// spaced points (down to `1e-12 bound`).
///
/// ```
/// use pd_damping::ratio::series_negative_at;
/// // 1 - 2 s + s^2 = (1 - s)^2 >= 0; 1 - 3 s + s^2 < 0 near s = 1.5.
/// assert_eq!(series_negative_at(&[1.0, -2.0, 1.0], 10.0), None);
/// assert!(series_negative_at(&[1.0, -3.0, 1.0], 10.0).is_some());
/// ```
pub fn series_negative_at(a: &[f64], bound: f64) -> Option<f64> {
    if a.is_empty() {
        return None;
    }
    let bound = bound.max(0.0);
    // Scaled coefficients b_k = a_k bound^(k-1), polynomial in t = s / bound.
    let b: Vec<f64> = a
        .iter()
        .enumerate()
        .map(|(k, a)| a * bound.powi(k as i32))
        .collect();
    let negative = |t: f64| {
        let (mut value, mut scale) = (0.0, 0.0);
        for c in b.iter().rev() {
            value = value * t + c;
            scale = scale * t + c.abs();
        }
        value < -1e-12 * scale
    };
    let mut points: Vec<f64> = vec![0.0, 1.0];
    // Critical points: roots of p'(t) = b2 + 2 b3 t + 3 b4 t^2.
    match b.len() {
        3 if b[2] != 0.0 => points.push(-b[1] / (2.0 * b[2])),
        4 => {
            let (qa, qb, qc) = (3.0 * b[3], 2.0 * b[2], b[1]);
            if qa == 0.0 {
                if qb != 0.0 {
                    points.push(-qc / qb);
                }
            } else {
                let disc = qb * qb - 4.0 * qa * qc;
                if disc >= 0.0 {
                    points.push((-qb + disc.sqrt()) / (2.0 * qa));
                    points.push((-qb - disc.sqrt()) / (2.0 * qa));
                }
            }
        }
        _ => {}
    }
    points.extend((1..4096).map(|i| i as f64 / 4096.0));
    points.extend((0..=240).map(|i| 10f64.powf(-12.0 + i as f64 * 0.05)));
    points
        .into_iter()
        .filter(|t| (0.0..=1.0).contains(t))
        .find(|&t| negative(t))
        .map(|t| t * bound)
}

/// Least squares `rows a ~= targets` (`rows`: one equation per row, at most
/// [`MAX_SERIES_TERMS`] unknowns, at least as many rows), the columns
/// scaled to unit largest entry first (a series' columns span powers of the
/// quotients); Householder QR. `None` when the scaled matrix is
/// rank-deficient to `1e-12` of its largest pivot.
// The Householder updates read and write `a[i][j]` by row and column.
#[allow(clippy::needless_range_loop)]
fn scaled_least_squares(rows: &[Vec<f64>], targets: &[f64]) -> Option<Vec<f64>> {
    let m = rows.len();
    let n = rows.first()?.len();
    if n == 0 || n > MAX_SERIES_TERMS || m < n {
        return None;
    }
    let scale: Vec<f64> = (0..n)
        .map(|k| rows.iter().fold(0.0_f64, |s, r| s.max(r[k].abs())))
        .collect();
    if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return None;
    }
    let mut a: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| r.iter().zip(&scale).map(|(x, s)| x / s).collect())
        .collect();
    let mut y = targets.to_vec();
    let mut diagonal = vec![0.0; n];
    for k in 0..n {
        let norm = (k..m).map(|i| a[i][k] * a[i][k]).sum::<f64>().sqrt();
        if norm == 0.0 {
            return None;
        }
        let alpha = if a[k][k] > 0.0 { -norm } else { norm };
        let mut v: Vec<f64> = (k..m).map(|i| a[i][k]).collect();
        v[0] -= alpha;
        let vv: f64 = v.iter().map(|x| x * x).sum();
        diagonal[k] = alpha;
        if vv > 0.0 {
            for j in k + 1..n {
                let dot: f64 = (k..m).map(|i| v[i - k] * a[i][j]).sum::<f64>() * 2.0 / vv;
                for i in k..m {
                    a[i][j] -= dot * v[i - k];
                }
            }
            let dot: f64 = (k..m).map(|i| v[i - k] * y[i]).sum::<f64>() * 2.0 / vv;
            for i in k..m {
                y[i] -= dot * v[i - k];
            }
        }
    }
    let largest = diagonal.iter().fold(0.0_f64, |s, d| s.max(d.abs()));
    if diagonal.iter().any(|d| d.abs() <= 1e-12 * largest) {
        return None;
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let sum: f64 = (k + 1..n).map(|j| a[k][j] * x[j]).sum();
        x[k] = (y[k] - sum) / diagonal[k];
    }
    let solution: Vec<f64> = x.iter().zip(&scale).map(|(x, s)| x / s).collect();
    solution.iter().all(|x| x.is_finite()).then_some(solution)
}

/// Reads a ratio target from the parameters `ratio`, `mode`, `ratios`,
/// `modes`, `band`, `series`, `stiffness`, `mass` as given (`None` where
/// absent); `Ok(None)` when the coefficients are given as `stiffness`, or
/// when neither `stiffness` nor a ratio is given (the model's build then
/// reports the missing `stiffness`).
///
/// # Errors
/// [`DampingError::Conflict`] for `stiffness` with `ratio`/`ratios`/`band`,
/// both `ratio` and `ratios`, `mode` without `ratio`, `modes` without
/// `ratios` or the other way round, lists of different lengths, fewer than
/// two ratios, `band` without `ratio` or with `mode`, `series` with a ratio,
/// or a non-zero `mass` with `ratios` or `band`;
/// [`DampingError::InvalidParameter`] for a negative or non-finite ratio, a
/// mode that is not a whole number >= 1, or a band that is not
/// `0 <= f_lo < f_hi`, finite.
pub(crate) fn target(
    given: impl Fn(&str) -> Option<f64>,
    list: impl Fn(&str) -> Option<Numbers>,
) -> Result<Option<RatioTarget>, DampingError> {
    let conflict = |parameter: &'static str, reason: &str| DampingError::Conflict {
        parameter,
        reason: reason.into(),
    };
    let (ratio, ratios, band) = (given("ratio"), list("ratios"), list("band"));
    if given("stiffness").is_some() {
        return match (ratio, ratios, band) {
            (None, None, None) if given("mode").is_none() && list("modes").is_none() => Ok(None),
            (None, None, None) => Err(conflict(
                "mode",
                "only goes with ratio/ratios, not with stiffness",
            )),
            _ => Err(conflict(
                "stiffness",
                "give either stiffness (s) or ratio/ratios/band (dimensionless), not both",
            )),
        };
    }
    if (ratio.is_some() || ratios.is_some()) && list("series").is_some() {
        return Err(conflict(
            "series",
            "is fitted from ratio/ratios/band; leave it out (or give stiffness instead)",
        ));
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
    if let Some(band) = band {
        let band = band.as_slice();
        if ratio.is_none() {
            return Err(conflict(
                "band",
                "goes with ratio, the damping ratio asked across the band",
            ));
        }
        if ratios.is_some() || list("modes").is_some() || given("mode").is_some() {
            return Err(conflict(
                "band",
                "chooses its modes by frequency: leave out mode, modes and ratios",
            ));
        }
        if given("mass").is_some_and(|m| m != 0.0) {
            return Err(conflict("mass", "is fitted from band; leave it out"));
        }
        let [lo, hi] = <[f64; 2]>::try_from(band)
            .map_err(|_| conflict("band", "takes two frequencies in Hz, [f_lo, f_hi]"))?;
        if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo < hi) {
            return Err(DampingError::InvalidParameter {
                parameter: "band",
                value: if lo.is_finite() && lo >= 0.0 { hi } else { lo },
                requirement: "[f_lo, f_hi] in Hz with 0 <= f_lo < f_hi, finite",
            });
        }
        return Ok(Some(RatioTarget::Band {
            band: [lo, hi],
            ratio: ratio_value("ratio", ratio.unwrap_or(0.0))?,
        }));
    }
    match (ratio, ratios) {
        // Neither: `stiffness` is missing, which the model's build reports.
        (None, None) if given("mode").is_none() && list("modes").is_none() => Ok(None),
        (None, None) => Err(conflict(
            "mode",
            "only goes with ratio (and modes with ratios), which is missing",
        )),
        (Some(_), Some(_)) => Err(conflict("ratio", "give either ratio or ratios, not both")),
        (Some(ratio), None) => {
            if list("modes").is_some() {
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
            let modes = list("modes").ok_or_else(|| {
                conflict(
                    "modes",
                    "is required with ratios: the modes (1 = lowest) they are for",
                )
            })?;
            if given("mass").is_some_and(|m| m != 0.0) {
                return Err(conflict("mass", "is fitted from ratios; leave it out"));
            }
            let (ratios, modes) = (ratios.as_slice(), modes.as_slice());
            if ratios.len() < 2 {
                return Err(conflict(
                    "ratios",
                    "needs two or more damping ratios (one ratio is given as ratio)",
                ));
            }
            if modes.len() != ratios.len() {
                return Err(conflict(
                    "modes",
                    "must name as many modes as ratios gives ratios",
                ));
            }
            let modes = modes
                .iter()
                .map(|&m| mode_value("modes", m))
                .collect::<Result<Vec<_>, _>>()?;
            let ratios = ratios
                .iter()
                .map(|&z| ratio_value("ratios", z))
                .collect::<Result<Vec<_>, _>>()?;
            for (i, m) in modes.iter().enumerate() {
                if modes[..i].contains(m) {
                    return Err(conflict("modes", "must name different modes"));
                }
            }
            Ok(Some(if modes.len() == 2 {
                RatioTarget::Two {
                    modes: [modes[0], modes[1]],
                    ratios: [ratios[0], ratios[1]],
                }
            } else {
                RatioTarget::Series { modes, ratios }
            }))
        }
    }
}
