//! Anderson acceleration of the local-global fixed point (Peng, Deng, Zhang
//! and Liu 2018, "Anderson acceleration for geometry optimization and
//! physics simulation"), with their merit-function safeguard.
//!
//! One local-global iteration is a map `G` whose fixed point is the step's
//! solution. With the residual `f_k = G(x_k) - x_k` and the last `m`
//! differences `dF_j = f_{j+1} - f_j`, `dG_j = G(x_{j+1}) - G(x_j)`, the
//! accelerated iterate is
//!
//! `x_AA = G(x_k) - sum_j theta_j dG_j`, `theta = argmin |f_k - sum_j theta_j dF_j|_M`
//!
//! (mass-weighted least squares, solved by its normal equations with a tiny
//! Tikhonov term). The safeguard: `x_AA` is accepted only if the step
//! objective (inertia + elastic + the integrator's damping potential,
//! [`StepProblem::objective`]) is lower there than at `x_k` (and, in the
//! budget's last two accelerated iterations, lower than at the plain
//! iterate `G(x_k)`: see [`ENDGAME`]); otherwise the plain iterate `G(x_k)`
//! is taken and the history restarts. Every local-global iteration lowers the objective,
//! so the method never raises it. The last iteration of the budget ends on
//! a plain iterate `G(x_k)`.
//!
//! With implicit midpoint, a step that took an accelerated iterate ends with
//! the end-of-step check of `step/ray.rs` (its end point must not lie past
//! the objective's minimum along the step's ray, or the energy grows).
//!
//! Cost per iteration: one local-global iteration. The objective of a trial
//! point is summed from the local step's projections there (the energy is
//! `sum w/2 |G q - P(G q)|^2`), and an accepted point's projections serve
//! its global step, so only a rejection costs an extra projection pass.

use pd_constraints::EnergyBound;
use pd_mesh::Point;

use super::estimate::Kept;
use super::iteration::{PositionSolver, StepProblem};
use super::ops::{difference, mass_dot};
use super::ray::RayCheck;
use crate::SolverError;

/// In the budget's last `ENDGAME - 1` accelerated iterations, a trial must
/// beat the plain iterate `G(x_k)` itself (one extra objective evaluation),
/// not just `x_k`: with the weaker test alone, an extrapolated point
/// followed by only one or two plain iterations ended above plain PD on 16
/// of 1,800 random cases (by up to 25%, budgets of 3 and 4); with this
/// test on the last one or two, on none (`tests/prop_anderson_merit.rs`'
/// scenes, 600 cases x 3 integrators).
const ENDGAME: usize = 3;

/// Anderson-accelerated local-global iteration with history `window`.
#[derive(Debug, Clone)]
pub struct Anderson {
    window: usize,
    /// Ring of the last `window` residual differences `dF`.
    residual_differences: Vec<Vec<Point>>,
    /// Ring of the matching map differences `dG`.
    map_differences: Vec<Vec<Point>>,
    /// The accepted iterate `x_k`.
    iterate: Vec<Point>,
    /// `G(x_k)` and `G(x_{k-1})`.
    map: [Vec<Point>; 2],
    /// `f_k` and `f_{k-1}`.
    residual: [Vec<Point>; 2],
    /// Normal equations (`window^2`) and right-hand side / solution.
    gram: Vec<f64>,
    theta: Vec<f64>,
    /// Per-chunk scratch of the objective's energy sum.
    partials: Vec<EnergyBound>,
    /// The projections at the plain iterate `G(x_k)` while a trial is
    /// evaluated (in the endgame, where the bar evaluated them).
    plain_projections: Vec<Point>,
    /// The end-of-step check of implicit midpoint (step/ray.rs).
    ray: RayCheck,
}

impl Anderson {
    /// A solver keeping the last `window` differences, taken into
    /// `1..=`[`SolverSpec::MAX_WINDOW`](super::method::SolverSpec::MAX_WINDOW)
    /// (its least-squares problem is `window x window`; a scene's `window`
    /// outside that range is an error).
    pub fn new(window: usize) -> Self {
        let window = window.clamp(1, super::method::SolverSpec::MAX_WINDOW);
        Self {
            window,
            residual_differences: vec![Vec::new(); window],
            map_differences: vec![Vec::new(); window],
            iterate: Vec::new(),
            map: [Vec::new(), Vec::new()],
            residual: [Vec::new(), Vec::new()],
            gram: vec![0.0; window * window],
            theta: vec![0.0; window],
            partials: Vec::new(),
            plain_projections: Vec::new(),
            ray: RayCheck::default(),
        }
    }

    /// Sizes the buffers for `n` vertices and `chunks` local-step chunks
    /// (allocates only when they change).
    fn size(&mut self, n: usize, chunks: usize) {
        if self.partials.len() != chunks {
            self.partials = vec![EnergyBound::default(); chunks];
        }
        if self.iterate.len() == n {
            return;
        }
        let zero = vec![Point::zeros(); n];
        for v in self
            .residual_differences
            .iter_mut()
            .chain(&mut self.map_differences)
            .chain(&mut self.map)
            .chain(&mut self.residual)
        {
            v.clone_from(&zero);
        }
        self.iterate = zero;
    }

    /// Swaps the step's projections with `plain_projections` (sized to
    /// them on first use).
    fn swap_projections(&mut self, step: &mut StepProblem<'_>) {
        let projections = &mut step.buffers.projections;
        self.plain_projections
            .resize(projections.len(), Point::zeros());
        std::mem::swap(projections, &mut self.plain_projections);
    }

    /// Solves the mass-weighted least squares over the `len` stored
    /// differences (ring slots `0..len`) for the current residual
    /// `residual[0]`, into `theta`. Returns `false` if the normal equations
    /// are singular to working precision.
    fn least_squares(&mut self, masses: &[f64], len: usize) -> bool {
        let m = len;
        let mut trace = 0.0;
        for i in 0..m {
            for j in 0..=i {
                let v = mass_dot(
                    masses,
                    &self.residual_differences[i],
                    &self.residual_differences[j],
                );
                self.gram[i * m + j] = v;
                self.gram[j * m + i] = v;
            }
            trace += self.gram[i * m + i];
            self.theta[i] = mass_dot(masses, &self.residual_differences[i], &self.residual[0]);
        }
        if !(trace > 0.0 && trace.is_finite()) {
            return false;
        }
        // Tikhonov regularisation at 1e-12 of the mean eigenvalue: keeps
        // nearly collinear histories solvable without changing theta where
        // the history is well conditioned.
        let regularisation = 1e-12 * trace / m as f64;
        for i in 0..m {
            self.gram[i * m + i] += regularisation;
        }
        cholesky_solve(&mut self.gram[..m * m], &mut self.theta[..m])
    }
}

/// Solves `a x = b` in place (`a` m x m symmetric positive definite,
/// row-major, overwritten by its factor; `b` becomes `x`). Returns `false`
/// on a non-positive pivot.
fn cholesky_solve(a: &mut [f64], b: &mut [f64]) -> bool {
    let m = b.len();
    for j in 0..m {
        let mut d = a[j * m + j];
        for k in 0..j {
            d -= a[j * m + k] * a[j * m + k];
        }
        if !(d > 0.0) {
            return false;
        }
        let d = d.sqrt();
        a[j * m + j] = d;
        for i in j + 1..m {
            let mut s = a[i * m + j];
            for k in 0..j {
                s -= a[i * m + k] * a[j * m + k];
            }
            a[i * m + j] = s / d;
        }
    }
    for i in 0..m {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * m + k] * b[k];
        }
        b[i] = s / a[i * m + i];
    }
    for i in (0..m).rev() {
        let mut s = b[i];
        for k in i + 1..m {
            s -= a[k * m + i] * b[k];
        }
        b[i] = s / a[i * m + i];
    }
    b.iter().all(|x| x.is_finite())
}

impl PositionSolver for Anderson {
    fn name(&self) -> &'static str {
        "anderson"
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        self.size(step.displacement().len(), step.local_chunks());
        step.estimate.look_back_over_step();
        step.record_objective();
        // The first iteration judges no trial, so its start needs only its
        // projections (kept from the predictor's safeguard when it ran);
        // later local steps give the objective too, and an accepted trial
        // point's projections serve the next global step.
        let mut merit = match step.take_start_projections() {
            Some(value) => value,
            None => {
                step.project_here();
                f64::NAN
            }
        };
        let check = RayCheck::applies(step);
        // Whether an accelerated iterate was taken (else the step is plain
        // PD's and needs no end-of-step check).
        let mut accelerated = step.predicted;
        // Differences stored so far (at most `window`), and the ring slot
        // of the next one.
        let (mut stored, mut next) = (0usize, 0usize);
        let mut have_previous = false;
        let iterations = step.iterations();
        for k in 0..iterations {
            self.iterate.copy_from_slice(step.displacement());
            step.global_half();
            self.map.swap(0, 1);
            self.residual.swap(0, 1);
            self.map[0].copy_from_slice(step.displacement());
            difference(&self.map[0], &self.iterate, &mut self.residual[0]);
            let masses = step.masses();
            let change = mass_dot(masses, &self.residual[0], &self.residual[0]);
            let size = mass_dot(masses, &self.map[0], &self.map[0]);
            if k > 0 {
                // The map's contraction along the step (step/estimate.rs).
                let images = [&self.map[0][..], &self.map[1]];
                let residuals = [&self.residual[0][..], &self.residual[1]];
                (step.estimate).note_step(masses, Kept::Images, images, residuals);
            }
            let converged = step.record_residual(change, size);
            if converged || k + 1 == iterations {
                if check && accelerated && !converged {
                    self.ray.finish(step, &mut self.partials);
                }
                step.record_objective();
                break;
            }
            if have_previous {
                difference(
                    &self.residual[0],
                    &self.residual[1],
                    &mut self.residual_differences[next],
                );
                difference(&self.map[0], &self.map[1], &mut self.map_differences[next]);
                next = (next + 1) % self.window;
                stored = (stored + 1).min(self.window);
            }
            have_previous = true;
            // The bar a trial must clear: g(x_k), or near the end of the
            // budget g(G(x_k)) (see ENDGAME).
            // The endgame's evaluation at G(x_k) keeps its projections in
            // `plain_projections`: a rejection then needs no projection pass.
            let endgame = stored > 0 && k + ENDGAME >= iterations;
            let bar = if endgame {
                let value = step.project_with_objective(&mut self.partials);
                self.swap_projections(step);
                value
            } else {
                merit
            };
            let accepted = stored > 0 && self.least_squares(masses, stored) && {
                let dx = step.displacement_mut();
                for (j, &t) in self.theta[..stored].iter().enumerate() {
                    for (x, d) in dx.iter_mut().zip(&self.map_differences[j]) {
                        *x -= d * t;
                    }
                }
                let trial = step.project_with_objective(&mut self.partials);
                // Not `<=`: a NaN trial is rejected.
                if trial < bar {
                    merit = trial;
                    accelerated = true;
                    true
                } else {
                    false
                }
            };
            if !accepted {
                // The plain iterate G(x_k); the history restarts from it.
                step.displacement_mut().copy_from_slice(&self.map[0]);
                merit = if endgame {
                    self.swap_projections(step);
                    bar
                } else {
                    step.project_with_objective(&mut self.partials)
                };
                if stored > 0 {
                    stored = 0;
                    next = 0;
                    have_previous = false;
                }
            }
            step.record_objective();
        }
        Ok(())
    }
}
