//! The accuracy mode (`Settings::accuracy`) and the choice of the method by
//! measurement (`Simulation::choose_method`): a chosen method runs exactly
//! as a run naming it; every method's accuracy-mode steps keep momentum
//! and give the same bits on 1 and 2 threads.

mod common;

use common::{Scheme, bits, clamped_beam, floor, method_beam, momentum};
use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::Point;
use pd_solver::{ProbeOutcome, Settings, Simulation, SolverMethod, SolverSpec, contact};

fn accuracy_settings(threads: usize) -> Settings {
    Settings {
        dt: 0.01,
        iterations: 10_000,
        accuracy: 0.01,
        threads,
        ..Settings::default()
    }
}

/// The solver tests' beam under implicit midpoint (no damping) with an
/// accuracy target of 1%, stepped by `method`.
fn beam(method: SolverMethod, threads: usize) -> Simulation {
    method_beam(Scheme::ImplicitMidpoint, method, accuracy_settings(threads))
}

#[test]
fn a_chosen_method_runs_as_a_run_that_names_it() {
    let mut chosen = beam(SolverMethod::LocalGlobal, 1);
    let choice = chosen.choose_method().unwrap();
    assert_eq!(chosen.steps(), 0);
    assert_eq!(chosen.time(), 0.0);
    assert_eq!(chosen.position_solver_name(), choice.chosen.name());
    assert_eq!(chosen.method_choice(), Some(&choice));
    assert_eq!(choice.candidates.len(), SolverMethod::ALL.len());
    // The beam is plain PD: every method can run it, and the chosen one
    // was measured meeting the target.
    assert!(choice.measured(), "{}", choice.describe());
    assert!(
        choice
            .candidates
            .iter()
            .all(|c| !matches!(c.outcome, ProbeOutcome::Excluded { .. })),
        "{}",
        choice.describe()
    );
    let mut named = beam(choice.chosen, 1);
    for step in 0..20 {
        let (a, b) = (chosen.step().unwrap(), named.step().unwrap());
        assert_eq!(a.iterations, b.iterations, "step {step}");
        assert!(a.converged, "step {step} missed the target");
    }
    assert_eq!(
        bits(&chosen.state().positions),
        bits(&named.state().positions)
    );
    assert_eq!(
        bits(&chosen.state().velocities),
        bits(&named.state().velocities)
    );
}

#[test]
fn choosing_needs_a_target() {
    let settings = Settings {
        accuracy: 0.0,
        ..accuracy_settings(1)
    };
    let mut sim = method_beam(Scheme::BackwardEuler, SolverMethod::LocalGlobal, settings);
    let err = sim.choose_method().unwrap_err().to_string();
    assert!(err.contains("accuracy"), "{err}");
}

#[test]
fn methods_that_cannot_run_contact_are_excluded_with_the_reason() {
    let (model, _) = clamped_beam([6, 2, 2], [0.6, 0.2, 0.2], 3, 1e5);
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        accuracy_settings(1),
    )
    .unwrap();
    sim.set_contact(contact::ContactSettings {
        colliders: vec![floor(0.5)],
        thickness: 0.0,
    })
    .unwrap();
    let choice = sim.choose_method().unwrap();
    assert_eq!(choice.chosen, SolverMethod::LocalGlobal);
    for c in &choice.candidates {
        let excluded =
            matches!(&c.outcome, ProbeOutcome::Excluded { reason } if reason.contains("collider"));
        // Only local-global handles contact (docs/design/contact.md).
        assert_eq!(
            excluded,
            c.method != SolverMethod::LocalGlobal,
            "{}",
            c.describe()
        );
    }
}

/// A free beam (nothing fixed, no gravity) spinning and moving: its linear
/// momentum stays what it was, with every method stopped by the accuracy
/// target. Each iterate of every method is a combination of local-global
/// updates (or, for Newton, of solves with a translation-invariant
/// Hessian), none of which changes the momentum; the tolerance is
/// round-off: 1e-12 of the momentum scale `sum m |v|`, some 100 ulps of
/// sums over 99 vertices.
#[test]
fn every_method_keeps_momentum_in_accuracy_mode() {
    for method in SolverMethod::ALL {
        let (mut model, _) = clamped_beam([10, 2, 2], [1.0, 0.2, 0.2], 7, 1e6);
        let mesh = model.bodies()[0].mesh.clone();
        let masses = model.masses().to_vec();
        model = {
            let mut free = pd_solver::Model::new();
            let body = free.add_body(mesh, masses).unwrap();
            free.add_tet_strain(body, 1e6, None).unwrap();
            free
        };
        let settings = Settings {
            gravity: Point::zeros(),
            ..accuracy_settings(1)
        };
        let mut sim = Simulation::new(
            model,
            Scheme::ImplicitMidpoint.integrator(),
            Box::new(NoDamping),
            settings,
        )
        .unwrap();
        let spec = SolverSpec {
            method,
            ..SolverSpec::default()
        };
        sim.set_position_solver(spec.create().unwrap());
        sim.add_rigid_velocity(0, Point::new(0.3, -0.2, 0.1), Point::new(0.5, 2.0, -1.0))
            .unwrap();
        let start = momentum(&sim);
        let scale: f64 = (sim.state().velocities.iter().zip(sim.model().masses()))
            .map(|(v, m)| v.norm() * m)
            .sum();
        for _ in 0..10 {
            assert!(sim.step().unwrap().converged, "{}", method.name());
        }
        let drift = (momentum(&sim) - start).norm();
        assert!(
            drift <= 1e-12 * scale,
            "{}: drift {drift:e} of {scale:e}",
            method.name()
        );
    }
}

#[test]
fn every_method_gives_the_same_bits_on_one_and_two_threads_in_accuracy_mode() {
    for method in SolverMethod::ALL {
        let run = |threads| {
            let mut sim = beam(method, threads);
            let iterations: Vec<usize> = sim.run(8).unwrap().iter().map(|s| s.iterations).collect();
            (
                bits(&sim.state().positions),
                bits(&sim.state().velocities),
                iterations,
            )
        };
        assert_eq!(run(1), run(2), "{}", method.name());
    }
}

/// A checkpoint keeps the contraction the estimate carries: a restored
/// simulation stops its steps where the saved one does, bit for bit.
#[test]
fn a_restored_accuracy_run_continues_bit_for_bit() {
    for method in SolverMethod::ALL {
        let mut a = beam(method, 1);
        a.run(4).unwrap();
        let saved = a.checkpoint();
        assert!(saved.contraction > 0.0, "{}", method.name());
        a.run(5).unwrap();
        let mut b = beam(method, 1);
        b.restore(&saved).unwrap();
        b.run(5).unwrap();
        assert_eq!(
            bits(&a.state().positions),
            bits(&b.state().positions),
            "{}",
            method.name()
        );
    }
}
