//! The a-posteriori error estimate of a step (docs/design/solver.md, "How
//! far from converged").
//!
//! The **relative error of a step** is `|x - x*|_M / |y - x*|_M`: the
//! distance from the positions `x` the step returns to the exact minimiser
//! `x*` of the step objective, over the distance from the inertial
//! prediction `y` to it, in the mass norm (the fraction of the step's
//! correction left undone).
//!
//! Every method measures, once per iteration, the local-global change
//! `c_k = |G(x_k) - x_k|_M` ([`super::iteration::StepProblem::record_residual`]).
//! A sequence whose error contracts by `rho` per iteration has the remaining
//! error `c_k (rho + rho^2 + ...) = c_k rho / (1 - rho)`. The observed
//! ratio `r = c_k / c_(k-1)` of plain PD is a mean of the modes' rates
//! weighted by their share of the change, while the error weighs a mode of
//! rate `l` by `1 / (1 - l)` more: the slow modes, which hold most of the
//! error, are under-represented in `r`, and the ratios are still rising
//! after 10 iterations (0.70 to 0.86 on the solver tests' beam, where the
//! rate that would give the true error lay between 0.85 and 0.93). So the
//! estimate takes
//!
//! `rho = sqrt(r_max)`, `r_max` the largest of the last [`RATIOS`] ratios of
//! the step, capped at [`MAX_RHO`] (0.9999):
//!
//! `1 - rho ~ (1 - r_max) / 2`, twice the factor `rho / (1 - rho)` near 1 (a
//! sequence that is already geometric is over-reported by
//! `(1 + rho) / rho`, about 2). Its estimated distance `a = c_K rho / (1 -
//! rho)` to `x*` becomes the relative error over the estimated `|y - x*|_M
//! ~ |x - y|_M + a` (the iterates move from `y` towards `x*`):
//!
//! `estimated_error = a / (|x - y|_M + a)`, at most 1.
//!
//! The same rule serves every method, with one more kind of ratio for the
//! accelerated ones. For local-global the ratios are the iteration's
//! observed contraction. The residual ratios of Anderson, L-BFGS and
//! Chebyshev are their own, accelerated convergence: they resolve the fast
//! modes within a few iterations, so their changes fall fast while the
//! error in the slow modes stays (with those ratios alone, Anderson's
//! estimate on the beam would be 0.23 to 0.52 of the true error). Their last
//! iterate is a plain one, `G(x_k)`, whose error in a mode of the map's
//! rate `l` is `l / (1 - l)` times that mode's part of the last change: the
//! rate that counts is the local-global map's on the modes still in error.
//! So each of these methods also reports, for every step `x_(k-1) -> x_k`
//! it takes, the map's contraction along it,
//!
//! `|G(x_k) - G(x_(k-1))|_M / |x_k - x_(k-1)|_M`
//!
//! ([`ErrorEstimate::note_step`], one pass over the vertices with what the
//! method keeps anyway), and the largest of the step joins the ratios. For
//! a plain step it is the ratio of the changes; for an accelerated one it
//! is about a mean of the map's rates over the modes the step moved along,
//! weighted by their share of it, and after the first iterations those are
//! mostly the slow modes the method has not resolved. Like plain PD's
//! observed ratio it under-weighs the slowest, and the square root covers
//! that the same way: on the beam these ratios reach 0.87 to 0.88 where
//! the rate that reproduces Anderson's true error is 0.94 (`1 - 0.88` is
//! twice `1 - 0.94`). Chebyshev also adds its estimate of the map's
//! spectral radius as one more ratio, and Anderson's rate reads every
//! residual ratio of the step, not only the last three. When the changes
//! stall or rise (a rejected extrapolation, a restart), the cap makes the
//! estimate large. Newton's residual ratios are its own (superlinear near
//! the end); its steps converge within a few iterations. A step with a
//! single iteration has no ratio and reports with the cap, `9999 c_1`:
//! nothing in it tells how fast the iteration converges.
//! `tests/accuracy_estimate.rs` measures the estimate against converged
//! steps (the figures are in docs/design/solver.md, "How far from
//! converged").

use pd_mesh::Point;

/// Ratios of successive changes the contraction estimate looks back over.
pub(crate) const RATIOS: usize = 3;

/// The largest contraction `rho` the estimate uses (`rho / (1 - rho)` =
/// 9999): changes that do not shrink are not evidence of convergence. Not
/// lower: stiff cloth converges at rates above 0.999 (the strip of
/// `tests/accuracy_estimate.rs` needs about 2,000 plain iterations for 1%),
/// and a cap at 0.99 reported such steps as converged 25 times too early.
pub(crate) const MAX_RHO: f64 = 0.9999;

/// A change at most this fraction of the step's displacement
/// (`|G(x) - x|_M <= ROUNDOFF |G(x) - x_n|_M`) is round-off, not evidence
/// of an error: the step counts as converged. A step of a rigid
/// translation (a body in free fall) has nothing to correct, and its
/// changes are round-off (relative 1e-16 to 1e-14 measured) that never
/// shrink, so the contraction rule alone read them as no convergence and
/// ran such steps to the cap. At this ratio the estimated distance, at
/// most `9999 c`, is below `1e-8` of the step's displacement.
pub(crate) const ROUNDOFF: f64 = 1e-12;

/// Iterations without a new smallest change after which a step with an
/// accuracy target stops, unconverged: the iteration no longer converges
/// (frictional contact can hold the relative residual at 1e-4 for
/// thousands of iterations), and running to the cap would only cost time.
/// Converging iterations set a new smallest change every few iterations,
/// even slow plain PD on stiff cloth (its changes fall steadily).
pub(crate) const STALL: usize = 200;

/// What a method keeps of its last two iterates, beside their residuals
/// `f = G(x) - x` ([`ErrorEstimate::note_step`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kept {
    /// The iterates `x`.
    Iterates,
    /// Their images `G(x)`.
    Images,
}

/// The running estimate of one step, fed the change of every iteration.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ErrorEstimate {
    /// The last change `c_k`, m kg^(1/2) (NaN before the first).
    last: f64,
    /// The last [`RATIOS`] ratios `c_k / c_{k-1}` (ring; NaN where empty).
    ratios: [f64; RATIOS],
    /// The next slot of `ratios`.
    next: usize,
    /// A method's own contraction estimate (0: none).
    known: f64,
    /// The largest ratio of the whole step (NaN: none yet).
    largest: f64,
    /// Whether the rate reads every ratio of the step, not the last few.
    whole_step: bool,
    /// The contraction carried from earlier steps (0: none; see
    /// [`ErrorEstimate::carrying`]).
    carried: f64,
    /// Whether this step's ratios are evidence of the local-global map's
    /// contraction, to carry to the next step (not for L-BFGS and Newton).
    carries: bool,
    /// Ratios recorded in this step.
    count: usize,
    /// Whether the last change was round-off ([`ROUNDOFF`]).
    at_roundoff: bool,
    /// The smallest change of the step, and the iterations since it.
    smallest: f64,
    since_smallest: usize,
}

impl Default for ErrorEstimate {
    fn default() -> Self {
        Self {
            last: f64::NAN,
            ratios: [f64::NAN; RATIOS],
            next: 0,
            known: 0.0,
            largest: f64::NAN,
            whole_step: false,
            carried: 0.0,
            carries: true,
            count: 0,
            at_roundoff: false,
            smallest: f64::INFINITY,
            since_smallest: 0,
        }
    }
}

impl ErrorEstimate {
    /// Takes the change of one iteration, `|G(x_k) - x_k|_M^2` (kg m^2).
    pub fn record(&mut self, change_squared: f64) {
        let change = change_squared.sqrt();
        if self.last > 0.0 && change.is_finite() {
            let ratio = change / self.last;
            self.ratios[self.next] = ratio;
            self.largest = self.largest.max(ratio);
            self.next = (self.next + 1) % RATIOS;
            self.count += 1;
        }
        self.last = change;
        if change < self.smallest {
            self.smallest = change;
            self.since_smallest = 0;
        } else {
            self.since_smallest += 1;
        }
    }

    /// Notes whether the last change (`change_squared`) is round-off of
    /// the step's displacement (`displacement_squared`), [`ROUNDOFF`].
    pub fn note_displacement(&mut self, change_squared: f64, displacement_squared: f64) {
        self.at_roundoff = change_squared <= ROUNDOFF * ROUNDOFF * displacement_squared;
    }

    /// Whether [`STALL`] iterations have passed without a new smallest
    /// change.
    pub fn stalled(&self) -> bool {
        self.since_smallest >= STALL
    }

    /// The estimate of a step that starts with the contraction `carried`
    /// observed in earlier steps ([`ErrorEstimate::carry_out`]; 0 for
    /// none). The rate of the local-global map is a property of the
    /// step's problem, which changes little from one step to the next,
    /// while a step's own first ratios are dominated by its fast modes: a
    /// step stopped after two or three iterations has seen none of the
    /// slow rate that holds most of its error (stiff cloth: ratios of 0.1
    /// at the second iteration where the map's rate is above 0.999).
    pub fn carrying(carried: f64) -> Self {
        Self {
            carried,
            ..Self::default()
        }
    }

    /// The contraction to carry to the next step: the largest ratio of
    /// this one when it recorded at least [`RATIOS`] ratios and its ratios
    /// are the local-global map's contraction, else `previous` (what it
    /// was given).
    pub fn carry_out(&self, previous: f64) -> f64 {
        // The map's contraction measured along the method's steps
        // (`note_step`, Chebyshev's spectral radius) is evidence too.
        let known = (self.known > 0.0).then_some(self.known);
        let own = (self.carries && self.count >= RATIOS && self.largest.is_finite())
            .then_some(self.largest);
        let carried = (self.carried > 0.0).then_some(self.carried);
        let evidence = if self.carries {
            // This step's own rate replaces the carried one.
            own.into_iter().chain(known).reduce(f64::max)
        } else {
            // L-BFGS and Newton see the map only along their steps: the
            // contraction measured by plain iterations is kept.
            carried.into_iter().chain(known).reduce(f64::max)
        };
        evidence.map_or(previous, |r| r.min(MAX_RHO * MAX_RHO))
    }

    /// Takes the largest ratio recorded so far in this step (plain
    /// local-global iterations run to measure it) as the carried
    /// contraction, for the rest of the step and the next steps.
    pub fn adopt_measured_contraction(&mut self) {
        if self.count >= RATIOS && self.largest.is_finite() {
            self.carried = self.carried.max(self.largest.min(MAX_RHO * MAX_RHO));
        }
    }

    /// Marks this step's ratios as the method's own convergence, not the
    /// local-global map's contraction (L-BFGS, Newton): they are not
    /// carried to the next step. The contraction carried into the step
    /// still counts: the change `c_K = |G(x_K) - x_K|_M` these methods
    /// record is the local-global map's at their last iterate, whose
    /// distance to `x*` that contraction bounds by `c_K / (1 - rho)`.
    pub fn own_convergence(&mut self) {
        self.carries = false;
    }

    /// Makes the rate read every ratio of the step, not only the last
    /// [`RATIOS`] (Anderson: its first ratios are plain PD's, its later
    /// ones its accelerated rate).
    pub fn look_back_over_step(&mut self) {
        self.whole_step = true;
    }

    /// Takes a method's own estimate `rho` of the local-global map's
    /// contraction (Chebyshev's spectral radius) as one more ratio, for
    /// this step.
    pub fn note_contraction(&mut self, rho: f64) {
        if rho.is_finite() && rho > 0.0 {
            self.known = self.known.max(rho);
        }
    }

    /// Takes the local-global map's contraction along the step from
    /// `x_(k-1)` to `x_k` of an iteration that is not plain PD's,
    /// `|G(x_k) - G(x_(k-1))|_M / |x_k - x_(k-1)|_M` (for a plain step, the
    /// ratio of its changes), as one more ratio for this step (see the
    /// module's documentation). `last` holds the method's last two iterates
    /// or their images, as `kept` says, newest first, and `residuals` their
    /// `f = G(x) - x`; one pass over the vertices.
    pub fn note_step(
        &mut self,
        masses: &[f64],
        kept: Kept,
        last: [&[Point]; 2],
        residuals: [&[Point]; 2],
    ) {
        let (mut moved, mut image) = (0.0, 0.0);
        let pairs = last[0].iter().zip(last[1]);
        let differences = residuals[0].iter().zip(residuals[1]);
        for ((m, (a, a_before)), (f, f_before)) in masses.iter().zip(pairs).zip(differences) {
            let (step, map) = match kept {
                Kept::Iterates => (a - a_before, a - a_before + (f - f_before)),
                Kept::Images => (a - a_before - (f - f_before), a - a_before),
            };
            moved += m * step.norm_squared();
            image += m * map.norm_squared();
        }
        self.note_contraction((image / moved).sqrt());
    }

    /// The contraction the estimate uses: the square root of the largest
    /// recent ratio (see the module's documentation), capped at
    /// [`MAX_RHO`] (the cap without a ratio).
    pub fn rho(&self) -> f64 {
        let largest = self
            .ratios
            .iter()
            .copied()
            .chain((self.known > 0.0).then_some(self.known))
            .chain((self.carried > 0.0).then_some(self.carried))
            .chain(self.whole_step.then_some(self.largest))
            .filter(|r| !r.is_nan())
            .reduce(f64::max);
        largest.map_or(MAX_RHO, |r| r.sqrt().min(MAX_RHO))
    }

    /// The estimated distance `|x - x*|_M` (m kg^(1/2)) to the step's
    /// solution: `c_K rho / (1 - rho)`; 0 for a step that does not move, NaN
    /// before the first iteration.
    pub fn absolute(&self) -> f64 {
        if self.last == 0.0 {
            return 0.0;
        }
        let rho = self.rho();
        self.last * rho / (1.0 - rho)
    }

    /// The relative error for a step whose result lies `distance` (m
    /// kg^(1/2)) from the inertial prediction `y`: `a / (distance + a)`
    /// with `a` = [`ErrorEstimate::absolute`], the estimated error over the
    /// estimated `|y - x*|_M` (the iterates move from `y` towards `x*`, so
    /// the distance still to go adds to the distance gone); 0 when the
    /// estimate is 0, at most 1.
    pub fn relative(&self, distance: f64) -> f64 {
        let absolute = self.absolute();
        if absolute == 0.0 || self.at_roundoff {
            0.0
        } else {
            absolute / (distance + absolute)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A geometric sequence of changes `c_k = r^k`: the remaining error is
    /// `r^(K+1) / (1 - r)`, and the estimate, with `rho = sqrt(r)`, over-
    /// reports it by `(1 + sqrt(r)) / sqrt(r)` (2.12 for `r = 0.8`), the
    /// price of the margin for the slow modes.
    #[test]
    fn geometric_changes_are_over_reported_by_the_margin() {
        let r: f64 = 0.8;
        let mut e = ErrorEstimate::default();
        for k in 0..10 {
            e.record(r.powi(2 * k));
        }
        let exact = r.powi(10) / (1.0 - r);
        let margin = (1.0 + r.sqrt()) / r.sqrt();
        // The ratios are r up to round-off of the powers (a few ulps).
        assert!((e.absolute() - margin * exact).abs() <= 1e-12 * exact);
        let a = e.absolute();
        assert!((e.relative(2.0) - a / (2.0 + a)).abs() <= 1e-15);
    }

    /// A linear map `G(x) = s + l (x - s)` contracts every step by `l`,
    /// whichever of its iterates or images a method keeps; the contraction
    /// joins the ratios.
    #[test]
    fn a_step_of_a_linear_map_contracts_by_its_rate() {
        let l: f64 = 0.9;
        let fixed = [Point::new(1.0, 2.0, 3.0), Point::new(-1.0, 0.5, 0.0)];
        let map = |x: &[Point]| -> Vec<Point> {
            x.iter().zip(&fixed).map(|(x, s)| s + (x - s) * l).collect()
        };
        let residual =
            |x: &[Point]| -> Vec<Point> { map(x).iter().zip(x).map(|(g, x)| g - x).collect() };
        let before = [Point::new(0.3, -0.2, 0.1), Point::new(2.0, 1.0, -1.0)];
        let after = [Point::new(0.5, 0.1, -0.4), Point::new(1.0, 0.0, 0.7)];
        let (f, f_before) = (residual(&after), residual(&before));
        let (g, g_before) = (map(&after), map(&before));
        let masses = [2.0, 0.5];
        for (kept, last) in [
            (Kept::Iterates, [&after[..], &before[..]]),
            (Kept::Images, [&g[..], &g_before[..]]),
        ] {
            let mut e = ErrorEstimate::default();
            e.note_step(&masses, kept, last, [&f, &f_before]);
            assert!((e.rho() - l.sqrt()).abs() < 1e-12, "{kept:?}: {}", e.rho());
        }
    }

    /// The largest of the recent ratios counts, an older one does not, and
    /// growing changes hit the cap.
    #[test]
    fn the_largest_recent_ratio_counts_and_the_cap_holds() {
        let mut e = ErrorEstimate::default();
        for c in [1.0, 0.9, 0.1, 0.05, 0.025, 0.0125] {
            e.record(f64::powi(c, 2));
        }
        // 0.9 is older than the last three ratios (0.5, 0.5, 0.5).
        assert!((e.rho() - 0.5f64.sqrt()).abs() < 1e-12, "{}", e.rho());
        e.record(1.0);
        assert_eq!(e.rho(), MAX_RHO);
        let mut single = ErrorEstimate::default();
        single.record(4.0);
        assert_eq!(single.rho(), MAX_RHO);
        let mut still = ErrorEstimate::default();
        still.record(0.0);
        assert_eq!(still.absolute(), 0.0);
        assert_eq!(still.relative(0.0), 0.0);
        // A step that returns y unconverged: the whole correction is left.
        assert_eq!(single.relative(0.0), 1.0);
    }
}
