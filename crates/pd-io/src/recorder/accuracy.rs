//! The `"accuracy"` object and the `"warnings"` of `summary.json`: how far a
//! run's steps were from converged and whether it created energy where it
//! should only dissipate, gathered row by row from what `metrics.csv`
//! holds (so that `pd resume` rebuilds it from the kept rows).
//!
//! Definitions (docs/guide/03-accuracy-and-solvers.md):
//!
//! - each step's `estimated_error` (`StepStats::estimated_error`): the
//!   estimated fraction of the step's correction `y -> x*` left undone;
//! - `energy_created_j`: the largest rise of the total energy (kinetic +
//!   elastic + gravitational) above its running minimum,
//!   `max_n (E_n - min_(m <= n) E_m)`, J. Gravity is the only external
//!   force, and its work is already in the total as potential energy, so
//!   in a setting that should only dissipate (backward Euler or BDF-2 with
//!   any damping, implicit midpoint with a damping model) the total never
//!   rises, and any rise is energy the steps created. `null` in other
//!   settings (undamped implicit midpoint conserves energy: its rises are
//!   round-off and exchange, not creation).

use pd_damping::{Damping, NoDamping};
use pd_integrators::registry::IntegratorKind;
use pd_solver::{Simulation, SolverMethod};
use serde_json::{Value, json};

use super::{MetricsRow, median};

/// The median estimated error above which a run is warned about.
pub const ERROR_WARNING: f64 = 0.1;

/// The energy created, as a fraction of the run's largest kinetic plus
/// elastic energy, above which a run is warned about.
pub const ENERGY_WARNING: f64 = 0.01;

/// The energy a run created in a setting that should only dissipate
/// (`energy_created_j` above), against its largest kinetic plus elastic
/// energy: what the energy warning of `summary.json` and the stability
/// maps' "energy created" heading both read
/// ([`AccuracyWatch::energy_created`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyCreated {
    /// The largest rise of the total energy above its running minimum, J.
    pub created: f64,
    /// The run's largest kinetic plus elastic energy so far, J.
    pub largest: f64,
}

impl EnergyCreated {
    /// The energy created as a fraction of the largest kinetic plus
    /// elastic energy (0 when none was created).
    pub fn fraction(&self) -> f64 {
        if self.created > 0.0 {
            self.created / self.largest
        } else {
            0.0
        }
    }

    /// Whether the energy created is above [`ENERGY_WARNING`] of the
    /// largest kinetic plus elastic energy: the run is warned about.
    pub fn warns(&self) -> bool {
        self.created > ENERGY_WARNING * self.largest
    }
}

/// What the rows so far say about the run's accuracy.
#[derive(Debug, Clone, Default)]
pub struct AccuracyWatch {
    /// Each step's estimated error (row 0, the initial state, excluded).
    errors: Vec<f64>,
    /// Each step's iterations.
    iterations: Vec<f64>,
    /// The running minimum of the total energy, J (NaN before row 0).
    minimum: Option<f64>,
    /// The largest rise of the total above its running minimum so far, J.
    created: f64,
    /// The largest kinetic plus elastic energy so far, J.
    largest: f64,
}

impl AccuracyWatch {
    /// Takes one row of `metrics.csv` (row 0 first).
    pub fn observe(&mut self, row: &MetricsRow) {
        if row.step > 0 {
            self.errors.push(row.estimated_error);
            self.iterations.push(row.iterations as f64);
        }
        let minimum = self.minimum.map_or(row.total, |m| m.min(row.total));
        self.minimum = Some(minimum);
        self.created = self.created.max(row.total - minimum);
        self.largest = self.largest.max(row.kinetic + row.elastic);
    }

    /// The watch of the rows kept by a resumed run.
    pub fn of_rows(rows: &[MetricsRow]) -> Self {
        let mut watch = Self::default();
        for row in rows {
            watch.observe(row);
        }
        watch
    }

    /// Whether `sim`'s integrator and damping should only dissipate.
    fn dissipative(sim: &Simulation) -> bool {
        match IntegratorKind::parse(sim.integrator_name()) {
            Some(IntegratorKind::BackwardEuler | IntegratorKind::Bdf2) => true,
            Some(IntegratorKind::ImplicitMidpoint) => sim.damping_name() != NoDamping.name(),
            _ => false,
        }
    }

    /// The largest estimated error of the steps so far (NaN before a step).
    fn largest_error(&self) -> f64 {
        self.errors.iter().copied().fold(f64::NAN, f64::max)
    }

    /// The energy created in a setting that should only dissipate, with
    /// the largest kinetic plus elastic energy it is measured against;
    /// `None` in other settings (undamped implicit midpoint) or before
    /// row 0. `sim`: the run the rows are of (its integrator and damping).
    pub fn energy_created(&self, sim: &Simulation) -> Option<EnergyCreated> {
        (Self::dissipative(sim) && self.minimum.is_some()).then_some(EnergyCreated {
            created: self.created,
            largest: self.largest,
        })
    }

    /// The warnings of the run, each a sentence that names the measured
    /// figure and what to change; empty when none applies.
    pub fn warnings(&self, sim: &Simulation) -> Vec<String> {
        let mut warnings = Vec::new();
        let target = sim.settings().accuracy;
        // A faster method is worth naming only to a run of plain PD; a run
        // that already uses a method gets the iteration budget's advice.
        let method = if sim.position_solver_name() == SolverMethod::LocalGlobal.name() {
            "use a faster [solver] method (chebyshev, lbfgs)"
        } else {
            "raise `iterations` in [simulation]"
        };
        let remedy = if target > 0.0 {
            format!(
                "raise `iterations` in [simulation] (the cap, now {}, of `accuracy = {target}`) \
                 or use a faster [solver] method (chebyshev, lbfgs)",
                sim.settings().iterations
            )
        } else {
            format!(
                "set `accuracy = 0.01` in [simulation] (each step then iterates until its \
                 estimated error is 1%), or {method}"
            )
        };
        let error = median(&self.errors);
        if error > ERROR_WARNING {
            warnings.push(format!(
                "steps are far from converged: the median step leaves an estimated {:.0}% of its \
                 correction undone (estimated error {error:.3}, largest {:.3}, {} {} iterations \
                 a step); {remedy}",
                error * 100.0,
                self.largest_error(),
                median(&self.iterations),
                sim.position_solver_name(),
            ));
        }
        if let Some(energy) = self.energy_created(sim)
            && energy.warns()
        {
            // Every step met its target: more iterations would not change
            // the trajectory, the time step would.
            let cause = if target > 0.0 && self.largest_error() <= target {
                let dt = sim.settings().dt;
                let (why, other) = if IntegratorKind::parse(sim.integrator_name())
                    == Some(IntegratorKind::ImplicitMidpoint)
                {
                    (
                        " (implicit midpoint conserves only quadratic energies)".to_string(),
                        format!(" or use `integrator = \"{}\"`", IntegratorKind::Bdf2.name()),
                    )
                } else {
                    (String::new(), String::new())
                };
                format!(
                    "every step met `accuracy = {target}` (largest estimated error {:.3}), so \
                     the energy is the time step's{why}: halve `dt` (now {dt} s){other}",
                    self.largest_error()
                )
            } else {
                format!("the steps are not converged enough; {remedy}")
            };
            warnings.push(format!(
                "the run created {:.3e} J of energy ({:.1}% of its largest kinetic plus \
                 elastic energy, {:.3e} J) where {} with damping `{}` should only dissipate: \
                 {cause}",
                energy.created,
                100.0 * energy.fraction(),
                energy.largest,
                sim.integrator_name(),
                sim.damping_name(),
            ));
        }
        warnings
    }

    /// The `"accuracy"` object of `summary.json`.
    pub fn summary(&self, sim: &Simulation) -> Value {
        let target = sim.settings().accuracy;
        let number = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
        json!({
            "target": (target > 0.0).then_some(target),
            "estimated_error_median": number(median(&self.errors)),
            "estimated_error_max": number(self.largest_error()),
            "energy_created_j": self.energy_created(sim).map(|e| e.created),
            "largest_kinetic_plus_elastic_j": self.largest,
            "method": sim.position_solver_name(),
            // How each candidate fared when the method was chosen by
            // measurement (null when the scene named it).
            "method_probe": sim.method_choice().map(|choice| {
                choice.candidates.iter().map(|c| c.describe()).collect::<Vec<_>>()
            }),
            "iterations_median": number(median(&self.iterations)),
        })
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::scene::{Scene, Syntax};

    /// A damped implicit-midpoint cube, with `accuracy` in [simulation]
    /// when given.
    fn cube(accuracy: Option<f64>) -> Simulation {
        let target = accuracy.map_or(String::new(), |a| format!("accuracy = {a}\n"));
        let text = format!(
            "[simulation]\ndt = 0.01\nsteps = 2\nintegrator = \"implicit-midpoint\"\n{target}\n\
             [damping]\nmodel = \"laplacian\"\nratio = 0.05\n\n[[body]]\n\
             mesh = {{ generator = \"box\", size = [0.1, 0.1, 0.1], cells = [1, 1, 1] }}\n\
             density = 1000.0\nconstraints = [ {{ kind = \"tet-strain\", stiffness = 1.0e5 }} ]\n"
        );
        Scene::parse(&text, Syntax::Toml, Path::new("cube.toml"))
            .unwrap()
            .build()
            .unwrap()
    }

    /// Rows whose total energy rises by 5 J of 100 J (5%) after step 1,
    /// each step with `error` as its estimated error.
    fn watch(error: f64) -> AccuracyWatch {
        let mut watch = AccuracyWatch::default();
        for (step, total) in [(0, 0.0), (1, -10.0), (2, -5.0)] {
            watch.observe(&MetricsRow {
                step,
                kinetic: 100.0,
                total,
                iterations: 20,
                estimated_error: if step == 0 { 0.0 } else { error },
                ..MetricsRow::default()
            });
        }
        watch
    }

    /// Energy created by a run whose every step met its accuracy target is
    /// the time step's: the warning says so and names `dt`, not iterations.
    /// Where a step missed the target, it names the iteration budget.
    #[test]
    fn the_energy_warning_names_the_cause() {
        let met = watch(0.005).warnings(&cube(Some(0.01)));
        assert_eq!(met.len(), 1, "{met:?}");
        assert!(
            met[0].contains("5.000e0 J") && met[0].contains("the energy is the time step's"),
            "{met:?}"
        );
        assert!(
            met[0].contains("halve `dt` (now 0.01 s)") && met[0].contains("bdf2"),
            "{met:?}"
        );
        assert!(!met[0].contains("not converged"), "{met:?}");
        let missed = watch(0.05).warnings(&cube(Some(0.01)));
        assert!(missed[0].contains("not converged enough"), "{missed:?}");
        let fixed = watch(0.05).warnings(&cube(None));
        assert!(
            fixed[0].contains("not converged enough") && fixed[0].contains("accuracy = 0.01"),
            "{fixed:?}"
        );
    }
}
