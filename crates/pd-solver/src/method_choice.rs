//! Choosing the iteration method for an accuracy target by measurement
//! (docs/design/solver.md, "Choosing a method by measurement").
//!
//! With [`crate::Settings::accuracy`] set, every method stops each step at
//! the same estimated error, so the methods differ only in what that costs,
//! and the cost depends on the scene: stiff cloth needs thousands of plain
//! local-global iterations per step where L-BFGS needs about a hundred, a
//! soft solid converges in a few plain iterations, where the accelerated
//! methods' extra work per iteration does not pay. No rule over the scene's
//! description predicts this reliably, so
//! [`Simulation::choose_method`] measures it: from the simulation's current
//! state it runs [`PROBE_STEPS`] steps with each method that can run the
//! model, timing them, and keeps the fastest one that met the target on
//! every probe step. A method that has taken longer than the fastest so far
//! is stopped where it is (it cannot win). The simulation then returns to
//! the state it started from, with the chosen method: a run continues
//! exactly as one that named that method from the start would, bit for bit.
//!
//! The choice rests on measured time, so two runs of the same scene can
//! choose differently where two methods cost about the same (on another
//! machine, another thread count, or under load); each run reports its
//! choice, and naming the method (`[solver] method`) makes a run
//! reproducible bit for bit anywhere.

use std::time::{Duration, Instant};

use crate::{Simulation, SolverError, SolverMethod, SolverSpec};

/// Steps each candidate runs in the probe. The first one is not timed: it
/// holds what a method does once (Chebyshev estimating its `rho`, Newton's
/// symbolic analysis, L-BFGS's and Newton's first step by plain
/// local-global, which measures the contraction their error estimate
/// needs, step/estimate.rs); the others are, and the fastest total wins.
/// Few enough that probing costs a few percent of a run of some hundred
/// steps.
pub const PROBE_STEPS: usize = 3;

/// The order candidates are probed in. It decides no choice (a candidate
/// that takes longer than the fastest so far is stopped, so only the
/// fastest one can be kept whatever the order), only what probing costs:
/// the methods most often fastest for a target go first, so that the slow
/// ones are stopped early.
/// The probe steps that are timed.
const TIMED: usize = PROBE_STEPS - 1;

const PROBE_ORDER: [SolverMethod; 5] = [
    SolverMethod::Newton,
    SolverMethod::Anderson,
    SolverMethod::Lbfgs,
    SolverMethod::Chebyshev,
    SolverMethod::LocalGlobal,
];

/// How much longer than the fastest method's timed steps a candidate's
/// untimed first step may take before it is stopped: generous, since that
/// step holds one-time work.
const FIRST_STEP_ALLOWANCE: u32 = 10;

/// How one candidate fared in the probe.
#[derive(Debug, Clone, PartialEq)]
pub enum ProbeOutcome {
    /// It met the target on every probe step.
    Measured {
        /// Wall time of the timed probe steps (all but the first), s.
        seconds: f64,
        /// Iterations over the timed probe steps.
        iterations: usize,
    },
    /// It cannot run this model (the reason names what it cannot run).
    Excluded {
        /// Why, from the method's compatibility check.
        reason: String,
    },
    /// Stopped once it had taken longer than the fastest method so far.
    Slower {
        /// Wall time when it was stopped, s.
        seconds: f64,
    },
    /// A probe step ended at the iteration cap above the target.
    MissedTarget {
        /// The step's estimated relative error.
        estimated_error: f64,
        /// The cap (`Settings::iterations`).
        cap: usize,
    },
    /// A probe step failed (diverged, or a factorisation failed).
    Failed {
        /// The error.
        reason: String,
    },
}

/// One candidate of the probe.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeResult {
    /// The method.
    pub method: SolverMethod,
    /// How it fared.
    pub outcome: ProbeOutcome,
}

impl ProbeResult {
    /// One line for a log: the method and how it fared.
    pub fn describe(&self) -> String {
        let name = self.method.name();
        match &self.outcome {
            ProbeOutcome::Measured {
                seconds,
                iterations,
            } => format!(
                "{name}: {:.3} ms a step, {:.1} iterations a step",
                seconds * 1e3 / TIMED as f64,
                *iterations as f64 / TIMED as f64
            ),
            ProbeOutcome::Excluded { reason } => {
                format!("{name}: cannot run this scene ({reason})")
            }
            ProbeOutcome::Slower { seconds } => format!(
                "{name}: stopped after {:.3} ms, slower than the fastest",
                seconds * 1e3
            ),
            ProbeOutcome::MissedTarget {
                estimated_error,
                cap,
            } => format!(
                "{name}: missed the target within the cap of {cap} iterations (estimated \
                 error {estimated_error:.3e})"
            ),
            ProbeOutcome::Failed { reason } => format!("{name}: failed ({reason})"),
        }
    }
}

/// What [`Simulation::choose_method`] measured and chose.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodChoice {
    /// The method the simulation now uses.
    pub chosen: SolverMethod,
    /// The accuracy target the probe ran to.
    pub target: f64,
    /// Every candidate, in the order probed.
    pub candidates: Vec<ProbeResult>,
}

impl MethodChoice {
    /// Whether some candidate met the target on every probe step (when
    /// none did, the choice is plain local-global, the default).
    pub fn measured(&self) -> bool {
        self.candidates
            .iter()
            .any(|c| matches!(c.outcome, ProbeOutcome::Measured { .. }))
    }

    /// One paragraph for a log: the choice and every candidate's result.
    pub fn describe(&self) -> String {
        let lines: Vec<String> = self.candidates.iter().map(ProbeResult::describe).collect();
        let how = if self.measured() {
            "the fastest to reach it"
        } else {
            "no method reached it in the probe; the default"
        };
        format!(
            "method for accuracy = {}: {} ({how}; probe of {PROBE_STEPS} steps, the last {TIMED} timed: {})",
            self.target,
            self.chosen.name(),
            lines.join("; ")
        )
    }
}

impl Simulation {
    /// Chooses the iteration method for the accuracy target by measurement
    /// (see the module documentation): probes every method that can run
    /// the model for [`PROBE_STEPS`] steps from the current state, keeps
    /// the fastest that met the target, and returns to the current state
    /// with it. The methods are probed with their default parameters
    /// ([`SolverSpec::default`]). The result is also kept, for
    /// [`Simulation::method_choice`].
    ///
    /// ```
    /// use pd_damping::NoDamping;
    /// use pd_integrators::BackwardEuler;
    /// use pd_mesh::generators;
    /// use pd_solver::{Model, Settings, Simulation};
    ///
    /// let beam = generators::box_tets([1.0, 0.1, 0.1], [10, 1, 1]).unwrap();
    /// let masses = beam.lumped_masses(1000.0).unwrap();
    /// let mut model = Model::new();
    /// let body = model.add_body(beam, masses).unwrap();
    /// model.add_tet_strain(body, 1e6, None).unwrap();
    /// model.fix_vertices(body, &[0, 1, 2, 3]).unwrap();
    /// let settings = Settings { accuracy: 0.01, iterations: 10_000, ..Settings::default() };
    /// let mut sim = Simulation::new(model, Box::new(BackwardEuler), Box::new(NoDamping), settings).unwrap();
    /// let choice = sim.choose_method().unwrap();
    /// assert_eq!(sim.position_solver_name(), choice.chosen.name());
    /// assert_eq!(sim.steps(), 0); // back where it started
    /// ```
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] naming `accuracy` when no target is
    /// set. Errors of the probe steps are not errors of the choice: they
    /// exclude the method (see [`ProbeOutcome::Failed`]).
    pub fn choose_method(&mut self) -> Result<MethodChoice, SolverError> {
        let target = self.settings.accuracy;
        if target <= 0.0 {
            return Err(SolverError::InvalidSetting {
                field: "accuracy",
                reason: "the method is chosen for an accuracy target; none is set".into(),
            });
        }
        let start = self.checkpoint();
        if let Err(e) = self.restore(&start) {
            // A state the simulation cannot return to (a non-finite
            // energy scale, say) is not probed: the method stays plain
            // local-global, and the first step reports the problem.
            self.use_method(SolverMethod::LocalGlobal)?;
            let reason = format!("not probed: {e}");
            let candidates = PROBE_ORDER
                .iter()
                .map(|&method| ProbeResult {
                    method,
                    outcome: ProbeOutcome::Failed {
                        reason: reason.clone(),
                    },
                })
                .collect();
            let choice = MethodChoice {
                chosen: SolverMethod::LocalGlobal,
                target,
                candidates,
            };
            self.method_choice = Some(choice.clone());
            return Ok(choice);
        }
        let mut candidates = Vec::with_capacity(PROBE_ORDER.len());
        let mut fastest: Option<(SolverMethod, Duration)> = None;
        for method in PROBE_ORDER {
            let outcome = self.probe(method, &start, fastest.map(|(_, d)| d));
            if let ProbeOutcome::Measured { seconds, .. } = outcome {
                let elapsed = Duration::from_secs_f64(seconds);
                if fastest.is_none_or(|(_, best)| elapsed < best) {
                    fastest = Some((method, elapsed));
                }
            }
            candidates.push(ProbeResult { method, outcome });
        }
        let chosen = fastest.map_or(SolverMethod::LocalGlobal, |(m, _)| m);
        self.use_method(chosen)?;
        self.restore(&start)?;
        let choice = MethodChoice {
            chosen,
            target,
            candidates,
        };
        self.method_choice = Some(choice.clone());
        Ok(choice)
    }

    /// The last [`Simulation::choose_method`]'s result, if any.
    pub fn method_choice(&self) -> Option<&MethodChoice> {
        self.method_choice.as_ref()
    }

    /// Replaces the position solver by `method` with default parameters.
    fn use_method(&mut self, method: SolverMethod) -> Result<(), SolverError> {
        let spec = SolverSpec {
            method,
            ..SolverSpec::default()
        };
        self.set_position_solver(spec.create()?);
        Ok(())
    }

    /// Runs [`PROBE_STEPS`] steps with `method` from `start`, stopping
    /// once they take longer than `limit`; the state is left wherever the
    /// probe ended (the caller restores it).
    fn probe(
        &mut self,
        method: SolverMethod,
        start: &crate::Checkpoint,
        limit: Option<Duration>,
    ) -> ProbeOutcome {
        if let Err(e) = self.use_method(method) {
            return ProbeOutcome::Failed {
                reason: e.to_string(),
            };
        }
        if let Err(e) = self.check_position_solver() {
            return ProbeOutcome::Excluded {
                reason: e.to_string(),
            };
        }
        // The method's own carried state starts afresh, as it would in a
        // run that named it.
        if let Err(e) = self.restore(start) {
            return ProbeOutcome::Failed {
                reason: e.to_string(),
            };
        }
        let mut began = Instant::now();
        self.probe_deadline = limit.map(|limit| began + limit * FIRST_STEP_ALLOWANCE);
        let mut iterations = 0;
        let mut outcome = None;
        for k in 0..PROBE_STEPS {
            if k == PROBE_STEPS - TIMED {
                // The clock starts after the untimed first step.
                began = Instant::now();
                self.probe_deadline = limit.map(|limit| began + limit);
            }
            match self.step() {
                Ok(stats) if stats.converged => {
                    if k >= PROBE_STEPS - TIMED {
                        iterations += stats.iterations;
                    }
                }
                Ok(stats) => {
                    let seconds = began.elapsed().as_secs_f64();
                    let stopped = self.probe_deadline.is_some_and(|d| Instant::now() >= d);
                    outcome = Some(if stopped {
                        ProbeOutcome::Slower { seconds }
                    } else {
                        ProbeOutcome::MissedTarget {
                            estimated_error: stats.estimated_error,
                            cap: self.settings.iterations,
                        }
                    });
                    break;
                }
                Err(e) => {
                    outcome = Some(ProbeOutcome::Failed {
                        reason: e.to_string(),
                    });
                    break;
                }
            }
        }
        self.probe_deadline = None;
        let seconds = began.elapsed().as_secs_f64();
        outcome.unwrap_or(match limit {
            // Met the target on every step, but only after the fastest had
            // finished: it cannot be kept either.
            Some(limit) if seconds >= limit.as_secs_f64() => ProbeOutcome::Slower { seconds },
            _ => ProbeOutcome::Measured {
                seconds,
                iterations,
            },
        })
    }
}
