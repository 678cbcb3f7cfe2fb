//! The fitted predictor's bookkeeping (step/predictor.rs,
//! [`Predictor::Fitted`]): the history of corrections, its mass-weighted
//! Gram matrix, and the predicted start from the fitted recurrence
//! (step/fitted.rs).

use pd_mesh::Point;

use super::fitted::fit_recurrence;
use super::predictor::{Predictor, PredictorState};
use crate::Simulation;

impl PredictorState {
    /// The stored corrections, newest first: `c_n`, `c_{n-1}`, ... (m per
    /// vertex).
    pub fn correction_history(&self) -> impl Iterator<Item = &[Point]> {
        let previous = (!self.previous.is_empty()).then_some(self.previous.as_slice());
        std::iter::once(self.correction.as_slice())
            .filter(|c| !c.is_empty())
            .chain(previous)
            .chain(self.history.iter().map(Vec::as_slice))
    }

    /// Before a new correction is stored: moves `c_n` to `previous` and
    /// `previous` to the front of `history`, keeping `len` corrections in
    /// all (the new one included), when the new step is of the same kind
    /// as the stored ones; else forgets them. `correction` is then a spare
    /// buffer for the new correction.
    pub(crate) fn shift_history(&mut self, same_kind: bool, len: usize) {
        if !same_kind || self.correction.is_empty() {
            self.previous.clear();
            self.history.clear();
            return;
        }
        let spare = if self.history.len() + 3 > len {
            self.history.pop().unwrap_or_default()
        } else {
            Vec::new()
        };
        let previous = std::mem::take(&mut self.previous);
        if !previous.is_empty() && len > 2 {
            self.history.insert(0, previous);
        }
        self.previous = std::mem::replace(&mut self.correction, spare);
    }
}

impl Simulation {
    /// The fitted recurrence's coefficients for the stored corrections, if
    /// at least `2 order` are stored (fitted over `order` to `equations`
    /// steps as the history grows) and the fit is good
    /// ([`Predictor::FIT_RESIDUAL_LIMIT`]).
    pub(crate) fn fit_corrections(&self, order: usize, equations: usize) -> Option<Vec<f64>> {
        let state = &self.predictor_state;
        let history: Vec<&[Point]> = state.correction_history().take(order + equations).collect();
        // Until the history is full, fit fewer equations (at least `order`).
        let equations = history.len().saturating_sub(order).min(equations);
        if equations < order {
            return None;
        }
        let gram = mass_gram(&history, self.model.masses());
        let fit = fit_recurrence(&gram, order, equations)?;
        (fit.relative_residual <= Predictor::FIT_RESIDUAL_LIMIT).then_some(fit.coefficients)
    }

    /// Moves the step's start from `y` to `y + sum_j a_j c_{n+1-j}`
    /// (fixed vertices stay).
    pub(crate) fn apply_fitted(&mut self, coefficients: &[f64]) {
        let fixed = self.model.fixed();
        let dx = &mut self.scratch.iteration.displacement;
        self.scratch.predicted = true;
        for (a, c) in coefficients
            .iter()
            .zip(self.predictor_state.correction_history())
        {
            for ((dx, c), &fixed) in dx.iter_mut().zip(c).zip(fixed) {
                if !fixed {
                    *dx += c * *a;
                }
            }
        }
    }
}

/// `<c_p, c_q>_M = sum_v m_v c_p[v] . c_q[v]` for every pair of `history`,
/// row-major (kg m^2).
pub(crate) fn mass_gram(history: &[&[Point]], masses: &[f64]) -> Vec<f64> {
    let len = history.len();
    let mut gram = vec![0.0; len * len];
    for p in 0..len {
        for q in p..len {
            let dot: f64 = (history[p].iter().zip(history[q]).zip(masses))
                .map(|((a, b), m)| m * a.dot(b))
                .sum();
            gram[p * len + q] = dot;
            gram[q * len + p] = dot;
        }
    }
    gram
}
