//! Where a step's iteration starts (docs/design/solver.md, "A better start: predictors").
//!
//! The converged step is `x_{n+1} = y + c_{n+1}`: the integrator's inertial
//! target `y` plus a correction `c` made of the elastic, damping and
//! attachment forces (for backward Euler `c = h^2 M^-1 f(x_{n+1})`; the
//! other integrators have the same form relative to their own `y`). By
//! default ([`Predictor::Inertial`]) every method starts at `y`. The
//! correction changes smoothly from step to step, so
//! [`Predictor::Extrapolated`] starts at `y + c_n`, the previous step's
//! correction (one stored vector per vertex, no extra work), which is
//! `O(h)` closer to the answer.
//!
//! The stored correction is used only when it belongs to a step of the
//! same kind: the same time step `h` and the same integrator coefficients
//! `(c1, c2, gamma)` (BDF-2's first step is backward Euler's and is not
//! followed by a step of the same kind), no contact (the contact forces are
//! warm-started separately and the start of their iteration is `y`), and
//! the same vertex count. Otherwise the step starts at `y`. Fixed vertices
//! always start (and stay) at their place. The correction is part of a
//! [`crate::Checkpoint`], so a resumed run continues bit for bit.
//!
//! The safeguard ([`keep_the_better_start`]): a predicted start is kept
//! only if the step objective is lower there than at `y` (two objective
//! evaluations a predicted step, the kept one's projections then serving
//! every method's first local step but Newton's). It does not make the predictor as stable
//! as the inertial start at large steps: docs/design/solver.md, "A better start: predictors".

use pd_mesh::Point;

use super::iteration::StepProblem;
use crate::{Simulation, SolverError};

/// Where each step's iteration starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Predictor {
    /// At the inertial target `y` (the default; every method's behaviour
    /// before the predictor existed).
    #[default]
    Inertial,
    /// At `y + c_n`, the inertial target plus the previous step's
    /// correction `x_n - y_{n-1}`, when the previous step was of the same
    /// kind (else at `y`).
    Extrapolated,
    /// At `y + 2 c_n - c_{n-1}`, the corrections' linear extrapolation,
    /// when the previous two steps were of the same kind (else as
    /// [`Predictor::Extrapolated`]).
    Linear,
    /// At `y + sum_j a_j c_{n+1-j}` (`j = 1..order`), the coefficients
    /// fitted to the last `equations` steps' corrections
    /// ([`super::fitted::fit_recurrence`]; over fewer steps, down to
    /// `order`, while the history grows); as [`Predictor::Linear`] until
    /// `2 order` corrections of the same kind are stored, or when
    /// the fit fails or leaves a relative residual above
    /// [`Predictor::FIT_RESIDUAL_LIMIT`].
    Fitted {
        /// `k`, the recurrence's number of terms (1 to 12).
        order: u8,
        /// `m >= k`, the number of past steps it is fitted to (up to 24).
        equations: u8,
    },
}

impl Predictor {
    /// Every predictor, in the order scenes list them.
    pub const ALL: [Predictor; 4] = [
        Predictor::Inertial,
        Predictor::Extrapolated,
        Predictor::Linear,
        Predictor::FITTED,
    ];

    /// [`Predictor::Fitted`] with its default order and equations.
    pub const FITTED: Predictor = Predictor::Fitted {
        order: 4,
        equations: 8,
    };

    /// The largest [`Predictor::Fitted`] order.
    pub const MAX_ORDER: u8 = 12;

    /// The largest [`Predictor::Fitted`] equation count.
    pub const MAX_EQUATIONS: u8 = 24;

    /// A fit whose relative residual is above this is not used (the step
    /// predicts linearly): the history is not a recurrence of that order.
    pub const FIT_RESIDUAL_LIMIT: f64 = 0.5;

    /// The name as scenes spell it (`inertial`).
    pub fn name(self) -> &'static str {
        match self {
            Predictor::Inertial => "inertial",
            Predictor::Extrapolated => "extrapolated",
            Predictor::Linear => "linear",
            Predictor::Fitted { .. } => "fitted",
        }
    }

    /// The predictor named `name`, if any ([`Predictor::FITTED`] for
    /// `fitted`).
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// How many corrections the predictor keeps (the newest included).
    pub(crate) fn history_len(self) -> usize {
        match self {
            Predictor::Inertial => 0,
            Predictor::Extrapolated => 1,
            Predictor::Linear => 2,
            Predictor::Fitted { order, equations } => usize::from(order) + usize::from(equations),
        }
    }
}

/// The previous step's correction, as a checkpoint stores it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PredictorState {
    /// `x_{n} - y_{n-1}` per vertex (m), zero at fixed vertices; empty
    /// when no step with [`Predictor::Extrapolated`] has been taken.
    pub correction: Vec<Point>,
    /// The step that produced it: `h` (s), `c1`, `c2` and `gamma` (1/s).
    pub key: [f64; 4],
    /// The correction of the step before, of the same kind, for
    /// [`Predictor::Linear`] (empty when there is none).
    pub previous: Vec<Point>,
    /// Older corrections of the same kind for [`Predictor::Fitted`],
    /// newest first (`c_{n-2}, c_{n-3}, ...`; empty for the others).
    pub history: Vec<Vec<Point>>,
}

impl PredictorState {
    /// Whether a correction is stored.
    pub fn is_empty(&self) -> bool {
        self.correction.is_empty()
    }
}

/// The key of a step: its `h` and integrator coefficients.
fn step_key(h: f64, c: pd_integrators::StepCoefficients) -> [f64; 4] {
    [h, c.c1, c.c2, c.gamma]
}

impl Simulation {
    /// Chooses where each step's iteration starts (default
    /// [`Predictor::Inertial`]). Forgets any stored correction, so the next
    /// step starts at `y`.
    pub fn set_predictor(&mut self, predictor: Predictor) {
        self.predictor = predictor;
        self.replace_predictor_state(PredictorState::default());
    }

    /// Where each step's iteration starts.
    pub fn predictor(&self) -> Predictor {
        self.predictor
    }

    /// Moves the step's starting displacement from `y - x_n` to
    /// `y + c_n - x_n` when the predictor and the stored correction allow
    /// it (called after the targets' phase). Returns the step's kind, for
    /// [`Simulation::record_correction`] (the integrator's coefficients
    /// change at its end, e.g. after BDF-2's first step).
    pub(crate) fn apply_predictor(&mut self) -> [f64; 4] {
        let h = self.settings.dt;
        let key = step_key(h, self.integrator.coefficients(h));
        self.scratch.predicted = false;
        let state = &self.predictor_state;
        if self.predictor == Predictor::Inertial
            || self.has_contact()
            || state.correction.len() != self.state.positions.len()
            || key.map(f64::to_bits) != state.key.map(f64::to_bits)
        {
            return key;
        }
        if let Predictor::Fitted { order, equations } = self.predictor
            && self.fit_corrections(order.into(), equations.into())
        {
            self.apply_fitted();
            return key;
        }
        let state = &self.predictor_state;
        let fixed = self.model.fixed();
        let dx = &mut self.scratch.iteration.displacement;
        let linear = self.predictor != Predictor::Extrapolated && !state.previous.is_empty();
        self.scratch.predicted = true;
        for (v, ((dx, c), &fixed)) in dx.iter_mut().zip(&state.correction).zip(fixed).enumerate() {
            if fixed {
                continue;
            }
            *dx += if linear {
                c * 2.0 - state.previous[v]
            } else {
                *c
            };
        }
        key
    }

    /// Stores the step's correction `x_{n+1} - y` (before contact's
    /// projection) for the next step, with the step's kind `key`; not with
    /// [`Predictor::Inertial`].
    pub(crate) fn record_correction(&mut self, key: [f64; 4]) {
        if self.predictor == Predictor::Inertial {
            return;
        }
        self.size_start_buffers();
        let state = &mut self.predictor_state;
        let same_kind = state.key.map(f64::to_bits) == key.map(f64::to_bits);
        if self.predictor == Predictor::Linear && same_kind && !state.correction.is_empty() {
            std::mem::swap(&mut state.previous, &mut state.correction);
        } else if matches!(self.predictor, Predictor::Fitted { .. }) {
            self.shift_fitted_history(same_kind);
        } else {
            state.previous.clear();
        }
        let fixed = self.model.fixed();
        let s = &self.scratch;
        let state = &mut self.predictor_state;
        if self.predictor == Predictor::Linear {
            // The buffer `previous` becomes `correction` at the next step of
            // the same kind: sized now (once), not then.
            let n = s.iteration.displacement.len();
            state
                .previous
                .reserve(n.saturating_sub(state.previous.len()));
        }
        let correction = &mut state.correction;
        correction.resize(s.iteration.displacement.len(), Point::zeros());
        for (((c, dx), y), &fixed) in correction
            .iter_mut()
            .zip(&s.iteration.displacement)
            .zip(&s.targets.inertial_displacement)
            .zip(fixed)
        {
            *c = if fixed { Point::zeros() } else { dx - y };
        }
        self.predictor_state.key = key;
    }

    /// Sizes the buffers of [`keep_the_better_start`] (first used in the
    /// first predicted step, which may come several steps after the first:
    /// BDF-2's third) in the first step that stores a correction, so that
    /// no later step allocates. Their contents are scratch.
    fn size_start_buffers(&mut self) {
        let chunks = self.local.num_chunks();
        let s = &mut self.scratch;
        let b = &mut s.iteration;
        if b.partials.len() != chunks {
            b.partials = vec![pd_constraints::EnergyBound::default(); chunks];
        }
        let rows = b.projections.len();
        b.spare_projections
            .reserve(rows.saturating_sub(b.spare_projections.len()));
        let n = b.displacement.len();
        s.predicted_start
            .reserve(n.saturating_sub(s.predicted_start.len()));
    }

    /// Checks a checkpoint's stored correction against this simulation
    /// (`n` vertices): empty, or `n` finite points and a finite key.
    pub(crate) fn check_predictor_state(
        state: &PredictorState,
        n: usize,
    ) -> Result<(), SolverError> {
        let invalid = |reason: String| Err(SolverError::InvalidState { reason });
        if state.is_empty() {
            return Ok(());
        }
        let older = state.history.iter().map(|h| ("history", h, [n, n]));
        if !state.history.is_empty() && state.previous.len() != n {
            return invalid("predictor history without a previous correction".into());
        }
        for (name, values, lengths) in [
            ("correction", &state.correction, [n, n]),
            ("previous", &state.previous, [0, n]),
        ]
        .into_iter()
        .chain(older)
        {
            if !lengths.contains(&values.len()) {
                return invalid(format!(
                    "predictor {name} has {} points for {n} vertices",
                    values.len()
                ));
            }
            if let Some(v) = values.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                return invalid(format!("predictor {name} of vertex {v} is not finite"));
            }
        }
        if !state.key.iter().all(|k| k.is_finite()) {
            return invalid("predictor key is not finite".into());
        }
        Ok(())
    }
}

/// Keeps the step's predicted start only if the step objective is lower
/// there than at the inertial target `y` (fixed vertices at zero); else
/// the step starts at `y` and `step.predicted` becomes `false`. `saved` is
/// scratch (resized to the vertex count). Two objective evaluations, each
/// with its own projection pass: the kept start's projections stay in the
/// step's buffer and its objective in `step.start_objective`, so that the
/// method's first local step does not project there again
/// ([`StepProblem::take_start_projections`]). The values are those of
/// [`StepProblem::objective`] bit for bit (the energy summed from the same
/// projections in the same order), so the choice is the same.
pub(crate) fn keep_the_better_start(step: &mut StepProblem<'_>, saved: &mut Vec<Point>) {
    let chunks = step.local_chunks();
    let b = &mut *step.buffers;
    if b.partials.len() != chunks {
        b.partials = vec![pd_constraints::EnergyBound::default(); chunks];
    }
    saved.clear();
    saved.extend_from_slice(&b.displacement);
    step.start_at_y();
    let mut partials = std::mem::take(&mut step.buffers.partials);
    let at_y = step.project_with_objective(&mut partials);
    let b = &mut *step.buffers;
    b.spare_projections
        .resize(b.projections.len(), Point::zeros());
    std::mem::swap(&mut b.projections, &mut b.spare_projections);
    b.displacement.copy_from_slice(saved);
    let predicted = step.project_with_objective(&mut partials);
    step.buffers.partials = partials;
    // Not `<=`: a NaN predicted objective falls back to y.
    if predicted < at_y {
        step.start_objective = Some(predicted);
    } else {
        step.start_at_y();
        let b = &mut *step.buffers;
        std::mem::swap(&mut b.projections, &mut b.spare_projections);
        step.predicted = false;
        step.start_objective = Some(at_y);
    }
}

impl StepProblem<'_> {
    /// Sets the displacement to the inertial target's (zero at fixed
    /// vertices).
    fn start_at_y(&mut self) {
        let inertial = &self.targets.inertial_displacement;
        let dx = &mut self.buffers.displacement;
        dx.iter_mut().for_each(|d| *d = Point::zeros());
        for &v in self.global.free() {
            dx[v] = inertial[v];
        }
    }
}
