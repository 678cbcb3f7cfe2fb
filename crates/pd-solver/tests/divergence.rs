//! A run that blows up stops with `SolverError::Diverged`, naming the step
//! and the cause, and leaves the state at the last good step. Backward Euler
//! with PD is unconditionally stable, so the blow-ups are made by test
//! integrators that break the physics on purpose.

use pd_damping::NoDamping;
use pd_integrators::{BackwardEuler, Integrator, Point, StepCoefficients, StepTargets};
use pd_mesh::generators;
use pd_solver::{Model, Settings, Simulation, SolverError};

/// Backward Euler whose velocity update doubles the velocity: the kinetic
/// energy grows fourfold per step.
#[derive(Debug)]
struct EnergyPump;

impl Integrator for EnergyPump {
    fn name(&self) -> &'static str {
        "energy-pump"
    }
    fn coefficients(&self, h: f64) -> StepCoefficients {
        BackwardEuler.coefficients(h)
    }
    fn prepare(&self, h: f64, x: &[Point], v: &[Point], a: Point, t: &mut StepTargets) {
        BackwardEuler.prepare(h, x, v, a, t);
    }
    fn finish(&mut self, h: f64, x0: &[Point], v0: &[Point], x: &[Point], v: &mut [Point]) {
        BackwardEuler.finish(h, x0, v0, x, v);
        v.iter_mut().for_each(|v| *v *= 2.0);
    }
}

/// Backward Euler that puts a NaN into vertex 2's inertial target at step 3.
#[derive(Debug, Default)]
struct NanAtStepThree {
    steps: usize,
}

impl Integrator for NanAtStepThree {
    fn name(&self) -> &'static str {
        "nan"
    }
    fn coefficients(&self, h: f64) -> StepCoefficients {
        BackwardEuler.coefficients(h)
    }
    fn prepare(&self, h: f64, x: &[Point], v: &[Point], a: Point, t: &mut StepTargets) {
        BackwardEuler.prepare(h, x, v, a, t);
        if self.steps == 2 {
            t.inertial_displacement[2].y = f64::NAN;
        }
    }
    fn finish(&mut self, h: f64, x0: &[Point], v0: &[Point], x: &[Point], v: &mut [Point]) {
        BackwardEuler.finish(h, x0, v0, x, v);
        self.steps += 1;
    }
}

fn chain_model() -> Model {
    let chain = generators::chain(5, 1.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(chain, vec![0.1; 5]).unwrap();
    model.add_springs(body, 100.0).unwrap();
    model.fix_vertices(body, &[0]).unwrap();
    model
}

#[test]
fn energy_blow_up_stops_the_run_at_the_step_it_happens() {
    let mut sim = Simulation::new(
        chain_model(),
        Box::new(EnergyPump),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap();
    let mut last_good = None;
    let error = loop {
        match sim.step() {
            Ok(_) => last_good = Some(sim.state().clone()),
            Err(e) => break e,
        }
        assert!(
            sim.steps() < 200,
            "a fourfold energy growth per step must be caught"
        );
    };
    let SolverError::Diverged { step, reason, .. } = &error else {
        panic!("expected Diverged, got {error}");
    };
    assert!(reason.contains("energy"), "{reason}");
    assert_eq!(*step, sim.steps() + 1, "the error names the failing step");
    assert_eq!(
        Some(sim.state()),
        last_good.as_ref(),
        "the state stays at the last good step"
    );
    assert!(
        error.to_string().contains(&format!("step {step}")),
        "{error}"
    );
}

#[test]
fn non_finite_position_is_reported_with_its_vertex() {
    let mut sim = Simulation::new(
        chain_model(),
        Box::new(NanAtStepThree::default()),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap();
    sim.run(2).unwrap();
    let error = sim.step().unwrap_err();
    let message = error.to_string();
    assert!(
        message.contains("step 3") && message.contains("not finite"),
        "{message}"
    );
    assert!(
        sim.state()
            .positions
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite()))
    );
    assert_eq!(sim.steps(), 2);
}

#[test]
fn invalid_settings_are_rejected_by_name() {
    for (settings, field) in [
        (
            Settings {
                dt: 0.0,
                ..Settings::default()
            },
            "dt",
        ),
        (
            Settings {
                dt: -0.01,
                ..Settings::default()
            },
            "dt",
        ),
        (
            Settings {
                dt: f64::NAN,
                ..Settings::default()
            },
            "dt",
        ),
        (
            Settings {
                iterations: 0,
                ..Settings::default()
            },
            "iterations",
        ),
        (
            Settings {
                tolerance: -1.0,
                ..Settings::default()
            },
            "tolerance",
        ),
        (
            Settings {
                gravity: Point::new(0.0, f64::INFINITY, 0.0),
                ..Settings::default()
            },
            "gravity",
        ),
        (
            // Finite, but beyond Settings::MAX_GRAVITY.
            Settings {
                gravity: Point::new(0.0, -1e300, 0.0),
                ..Settings::default()
            },
            "gravity",
        ),
    ] {
        let error = Simulation::new(
            chain_model(),
            Box::new(BackwardEuler),
            Box::new(NoDamping),
            settings,
        )
        .unwrap_err();
        assert!(
            matches!(&error, SolverError::InvalidSetting { field: f, .. } if *f == field),
            "{error}"
        );
    }
}

#[test]
fn model_errors_name_the_problem() {
    let chain = generators::chain(3, 1.0).unwrap();
    let mut model = Model::new();
    assert!(
        model.add_body(chain.clone(), vec![1.0; 2]).is_err(),
        "mass count mismatch"
    );
    assert!(
        model.add_body(chain.clone(), vec![1.0, -1.0, 1.0]).is_err(),
        "negative mass"
    );
    let body = model.add_body(chain, vec![1.0, 0.0, 1.0]).unwrap();
    assert!(model.add_springs(body, -5.0).is_err(), "negative stiffness");
    assert!(
        model.add_tet_strain(body, 5.0, None).is_err(),
        "no tets in a chain"
    );
    assert!(
        model.fix_vertices(body, &[3]).is_err(),
        "vertex out of range"
    );
    model.add_springs(body, 5.0).unwrap();
    let error = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap_err();
    assert!(
        error.to_string().contains("vertex 1"),
        "a massless free vertex is named: {error}"
    );
}
