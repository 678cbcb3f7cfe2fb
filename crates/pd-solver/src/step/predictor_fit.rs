//! The fitted predictor's bookkeeping (step/predictor.rs,
//! [`Predictor::Fitted`]): the history of corrections, its mass-weighted
//! Gram matrix, and the predicted start from the fitted recurrence
//! (step/fitted.rs).
//!
//! Nothing here allocates after the first fitted step: the corrections'
//! buffers are allocated together on the first step that stores one and
//! then cycle between the history and [`FitScratch`]'s spares, and the Gram
//! matrix is kept from step to step ([`GramCache`]), so each step computes
//! only the inner products of its new correction. The fit itself
//! ([`FitWorkspace::fit`]) still allocates a few small `k x k` matrices
//! (nalgebra's `SymmetricEigen` takes and returns heap matrices): see
//! `tests/no_allocation_in_step.rs`.

use pd_mesh::Point;

use super::fitted::FitWorkspace;
use super::ops::mass_dot;
use super::predictor::{Predictor, PredictorState};
use crate::Simulation;

/// The fitted predictor's buffers kept between steps, beside the
/// [`PredictorState`] (which a checkpoint stores; these it does not).
#[derive(Debug, Default)]
pub(crate) struct FitScratch {
    /// Correction buffers not in use (one point per vertex each).
    spares: Vec<Vec<Point>>,
    /// The inner products of the stored corrections.
    gram: GramCache,
    /// The Gram matrix of the stored corrections, `rows x rows` row-major,
    /// as [`FitWorkspace::fit`] takes it.
    compact: Vec<f64>,
    /// The fit's buffers; its coefficients those of the step's start.
    work: FitWorkspace,
}

/// The mass-weighted inner products `<c_p, c_q>_M` (kg m^2) of the stored
/// corrections (index 0 the newest), kept from step to step.
///
/// Same bits as recomputing them all ([`mass_gram`]): an entry `(p, q)`,
/// `p <= q`, is computed once, by [`mass_dot`] of the `p`-th and `q`-th
/// corrections in that order (the newer one first), when the newer one
/// arrives. When the next correction is stored, every correction moves one
/// place back (`c_p` becomes `c_{p+1}`) and the oldest may leave; the
/// vectors themselves never change while stored (a checkpoint restore or a
/// new state replaces them and calls [`GramCache::forget`]). So the entry
/// moves to `(p + 1, q + 1)`, still the inner product of the same two
/// vectors in the same order: the value [`mass_gram`] computes there, by
/// the same operations in the same order. Only the new row `(0, q)` is
/// computed (`rows` inner products instead of `rows (rows + 1) / 2`).
#[derive(Debug, Default, Clone)]
pub(crate) struct GramCache {
    /// The row length of `values`: the predictor's history length.
    stride: usize,
    /// `stride x stride`, row-major; entries `(p, q)` with
    /// `stale <= p <= q < rows` are valid.
    values: Vec<f64>,
    /// How many corrections the cache covers (the stored ones, at most
    /// `stride`).
    rows: usize,
    /// The leading rows not computed yet.
    stale: usize,
    /// Whether `rows` and the entries describe the stored corrections.
    known: bool,
}

impl GramCache {
    /// Forgets every entry (the stored corrections were replaced): the next
    /// [`GramCache::refresh`] computes them all.
    pub fn forget(&mut self) {
        self.known = false;
    }

    /// Brings the cache to the stored corrections of `state` (at most
    /// `stride`), computing the inner products of the rows that arrived
    /// since the last refresh. Returns the row count.
    pub fn refresh(&mut self, state: &PredictorState, masses: &[f64], stride: usize) -> usize {
        self.size(stride);
        let rows = state.correction_history().count().min(stride);
        if !self.known || rows != self.rows {
            (self.rows, self.stale, self.known) = (rows, rows, true);
        }
        for (p, a) in state.correction_history().enumerate().take(self.stale) {
            for (q, b) in state.correction_history().enumerate().take(rows).skip(p) {
                self.values[p * stride + q] = mass_dot(masses, a, b);
            }
        }
        self.stale = 0;
        rows
    }

    /// Sizes the cache for `stride` rows (forgetting it if that changes).
    fn size(&mut self, stride: usize) {
        if stride != self.stride || self.values.len() != stride * stride {
            self.stride = stride;
            self.values.clear();
            self.values.resize(stride * stride, 0.0);
            self.known = false;
        }
    }

    /// After a new correction was stored, `rows` corrections now (at most
    /// `stride`): after a restart (`restart`, the older ones forgotten) the
    /// cache holds the new row only; else every entry moves one row and one
    /// column on and row 0 is to be computed.
    pub fn after_store(&mut self, restart: bool, rows: usize) {
        if !self.known {
            return;
        }
        if restart {
            (self.rows, self.stale) = (rows, rows);
            return;
        }
        if !(rows == self.rows || rows == self.rows + 1) || rows > self.stride {
            // Not one shift of the covered rows: recompute.
            self.known = false;
            return;
        }
        let s = self.stride;
        // From the last row back, so that row p - 1 is read before it is
        // overwritten.
        for p in (1..rows).rev() {
            for q in p..rows {
                self.values[p * s + q] = self.values[(p - 1) * s + q - 1];
            }
        }
        self.rows = rows;
        self.stale = (self.stale + 1).min(rows);
    }

    /// The `rows x rows` Gram matrix, both triangles, into `out` (resized;
    /// within its capacity once reserved).
    fn write_full(&self, out: &mut Vec<f64>) {
        let (rows, s) = (self.rows, self.stride);
        out.clear();
        out.resize(rows * rows, 0.0);
        for p in 0..rows {
            for q in p..rows {
                let value = self.values[p * s + q];
                out[p * rows + q] = value;
                out[q * rows + p] = value;
            }
        }
    }
}

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
    /// buffer for the new correction. Buffers leave for `spares` and come
    /// from it (its capacity and the history's reserved by
    /// [`PredictorState::reserve_history`]), so that this allocates nothing.
    pub(crate) fn shift_history(
        &mut self,
        same_kind: bool,
        len: usize,
        spares: &mut Vec<Vec<Point>>,
    ) {
        if !same_kind || self.correction.is_empty() {
            spares.append(&mut self.history);
            if !self.previous.is_empty() {
                spares.push(std::mem::take(&mut self.previous));
            }
            if self.correction.is_empty() {
                self.correction = spares.pop().unwrap_or_default();
            }
            return;
        }
        // The oldest correction leaves when the history is full.
        if self.history.len() + 3 > len
            && let Some(oldest) = self.history.pop()
        {
            spares.push(oldest);
        }
        let previous = std::mem::take(&mut self.previous);
        if !previous.is_empty() && len > 2 {
            self.history.insert(0, previous);
        } else if !previous.is_empty() {
            spares.push(previous);
        }
        let spare = spares.pop().unwrap_or_default();
        self.previous = std::mem::replace(&mut self.correction, spare);
    }

    /// How many corrections are stored.
    fn stored(&self) -> usize {
        usize::from(!self.correction.is_empty())
            + usize::from(!self.previous.is_empty())
            + self.history.len()
    }

    /// Sizes the history and `spares` for `len` corrections of `n` points
    /// each: allocates the missing buffers at once (on the first fitted
    /// step; later only after a restore or a new state dropped some).
    fn reserve_history(&mut self, len: usize, n: usize, spares: &mut Vec<Vec<Point>>) {
        self.history.reserve(len.saturating_sub(self.history.len()));
        spares.reserve(len.saturating_sub(spares.len()));
        while self.stored() + spares.len() < len {
            spares.push(vec![Point::zeros(); n]);
        }
    }
}

impl Simulation {
    /// The fitted predictor's part of [`Simulation::record_correction`]:
    /// shifts the history (or restarts it when the step is not of the same
    /// kind) and moves the Gram cache along; the caller then writes the new
    /// correction into `correction`.
    pub(crate) fn shift_fitted_history(&mut self, same_kind: bool) {
        let len = self.predictor.history_len();
        let n = self.state.positions.len();
        let state = &mut self.predictor_state;
        let fit = &mut self.scratch.fit;
        let restart = !same_kind || state.correction.is_empty();
        state.reserve_history(len, n, &mut fit.spares);
        fit.gram.size(len);
        fit.compact
            .reserve((len * len).saturating_sub(fit.compact.len()));
        state.shift_history(same_kind, len, &mut fit.spares);
        // The new correction is stored next: count it.
        let rows = (state.stored() + usize::from(state.correction.is_empty())).min(len);
        fit.gram.after_store(restart, rows);
    }

    /// Replaces the predictor's stored corrections (a checkpoint's, or none
    /// for a new state) and forgets their cached inner products.
    pub(crate) fn replace_predictor_state(&mut self, state: PredictorState) {
        self.predictor_state = state;
        self.scratch.fit.gram.forget();
    }

    /// Fits the recurrence to the stored corrections and returns whether
    /// the step starts from it: if at least `2 order` are stored (fitted
    /// over `order` to `equations` steps as the history grows) and the fit
    /// is good ([`Predictor::FIT_RESIDUAL_LIMIT`]); the coefficients are
    /// then in the scratch's workspace, for [`Simulation::apply_fitted`].
    pub(crate) fn fit_corrections(&mut self, order: usize, equations: usize) -> bool {
        let fit = &mut self.scratch.fit;
        let stride = order + equations;
        let rows = fit
            .gram
            .refresh(&self.predictor_state, self.model.masses(), stride);
        // Until the history is full, fit fewer equations (at least `order`).
        let equations = rows.saturating_sub(order).min(equations);
        if equations < order {
            return false;
        }
        fit.gram.write_full(&mut fit.compact);
        fit.work
            .fit(&fit.compact, order, equations)
            .is_some_and(|residual| residual <= Predictor::FIT_RESIDUAL_LIMIT)
    }

    /// Moves the step's start from `y` to `y + sum_j a_j c_{n+1-j}`
    /// (fixed vertices stay), `a` from the last [`Simulation::fit_corrections`].
    pub(crate) fn apply_fitted(&mut self) {
        let fixed = self.model.fixed();
        let coefficients = self.scratch.fit.work.coefficients();
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

/// `<c_p, c_q>_M` for every pair of `history`, row-major (kg m^2): each
/// entry computed afresh ([`GramCache`] keeps them from step to step with
/// the same bits).
#[cfg(test)]
pub(crate) fn mass_gram(history: &[&[Point]], masses: &[f64]) -> Vec<f64> {
    let len = history.len();
    let mut gram = vec![0.0; len * len];
    for p in 0..len {
        for q in p..len {
            let dot = mass_dot(masses, history[p], history[q]);
            gram[p * len + q] = dot;
            gram[q * len + p] = dot;
        }
    }
    gram
}

#[cfg(test)]
mod tests {
    use pd_damping::NoDamping;
    use pd_integrators::{Bdf2, ImplicitMidpoint};
    use pd_mesh::{Point, generators};

    use super::{GramCache, mass_gram};
    use crate::{Model, Predictor, PredictorState, Settings, Simulation};

    /// `cache` (refreshed on a copy, so that its own laziness is kept)
    /// against every inner product computed afresh, bit for bit.
    fn assert_cache_is_fresh(cache: &GramCache, state: &PredictorState, masses: &[f64]) {
        let stride = cache.stride;
        let history: Vec<&[Point]> = state.correction_history().take(stride).collect();
        let full = mass_gram(&history, masses);
        let mut copy = cache.clone();
        copy.refresh(state, masses, stride);
        let mut cached = Vec::new();
        copy.write_full(&mut cached);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&cached), bits(&full), "{} rows", history.len());
    }

    /// A synthetic history: corrections stored one by one (restarting
    /// sometimes), the cache refreshed only every third store, so that
    /// several new rows wait at once, and checked against a full
    /// recomputation after every store, through wrap-around.
    #[test]
    fn cached_gram_equals_full_recomputation_for_any_store_pattern() {
        let n = 17;
        let masses: Vec<f64> = (0..n).map(|v| 0.5 + 0.1 * (v % 4) as f64).collect();
        for len in [2, 3, 7, 12] {
            let mut state = PredictorState::default();
            let mut cache = GramCache::default();
            let mut spares = Vec::new();
            for step in 0..40_usize {
                let same_kind = step % 17 != 5;
                let restart = !same_kind || state.correction.is_empty();
                state.reserve_history(len, n, &mut spares);
                state.shift_history(same_kind, len, &mut spares);
                state.correction.resize(n, Point::zeros());
                for (v, c) in state.correction.iter_mut().enumerate() {
                    let t = (step * 31 + v * 7) as f64;
                    *c = Point::new((0.37 * t).sin(), (0.11 * t).cos(), 1e-3 * t);
                }
                cache.after_store(restart, state.stored().min(len));
                if step % 3 == 0 {
                    cache.refresh(&state, &masses, len);
                }
                if cache.stride == len {
                    assert_cache_is_fresh(&cache, &state, &masses);
                }
                assert!(state.stored() <= len);
            }
        }
    }

    /// A 4 x 1 x 1 beam clamped at one end, sagging under gravity.
    fn beam(integrator: Box<dyn pd_integrators::Integrator>) -> Simulation {
        let mesh = generators::box_tets([0.4, 0.1, 0.1], [4, 1, 1]).unwrap();
        let n = mesh.vertices().len();
        let mut model = Model::new();
        let body = model.add_body(mesh, vec![0.05; n]).unwrap();
        model.add_tet_strain(body, 2e4, None).unwrap();
        model.fix_vertices(body, &[0, 1, 2, 3]).unwrap();
        let settings = Settings {
            dt: 0.01,
            iterations: 3,
            ..Settings::default()
        };
        Simulation::new(model, integrator, Box::new(NoDamping), settings).unwrap()
    }

    /// Whole steps with the cache against steps that recompute every inner
    /// product (the cache forgotten before each step): the same state bit
    /// for bit, through BDF-2's restart after its first step, the history's
    /// wrap-around, a checkpoint restore, an order change and a new state;
    /// and the cache equals a full recomputation after every step.
    #[test]
    fn cached_gram_steps_equal_recomputed_steps() {
        for integrator in [0, 1] {
            let make = || -> Simulation {
                if integrator == 0 {
                    beam(Box::new(Bdf2::new()))
                } else {
                    beam(Box::new(ImplicitMidpoint))
                }
            };
            let (mut cached, mut fresh) = (make(), make());
            let fitted = Predictor::Fitted {
                order: 2,
                equations: 3,
            };
            let mut saved = None;
            for step in 0..70 {
                if step == 0 || step == 40 {
                    let predictor = if step == 0 { fitted } else { Predictor::FITTED };
                    cached.set_predictor(predictor);
                    fresh.set_predictor(predictor);
                }
                if step == 12 {
                    saved = Some(cached.checkpoint());
                }
                if step == 25 {
                    let saved = saved.as_ref().expect("saved at step 12");
                    cached.restore(saved).unwrap();
                    fresh.restore(saved).unwrap();
                }
                if step == 55 {
                    let state = cached.state().clone();
                    cached.set_state(state.clone()).unwrap();
                    fresh.set_state(state).unwrap();
                }
                fresh.scratch.fit.gram.forget();
                cached.step().unwrap();
                fresh.step().unwrap();
                let bits = |s: &Simulation| -> Vec<u64> {
                    let state = s.state();
                    (state.positions.iter().chain(&state.velocities))
                        .flat_map(|p| p.iter().map(|c| c.to_bits()).collect::<Vec<_>>())
                        .collect()
                };
                assert_eq!(bits(&cached), bits(&fresh), "step {step}");
                let masses = cached.model.masses();
                assert_cache_is_fresh(&cached.scratch.fit.gram, &cached.predictor_state, masses);
            }
            // The fit is used (else the test compares little).
            assert_eq!(cached.scratch.fit.gram.rows, 12);
            assert!(cached.fit_corrections(4, 8));
        }
    }
}
