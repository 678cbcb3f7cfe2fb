//! The rotation-preserving damping keeps reference lever arms from step to
//! step (mapped by each step's fitted linear map, rebuilt when the body has
//! deformed away from them), so a checkpoint must carry them: a restored
//! run continues bit for bit, and one restored without them does not.

mod common;

use common::{bits, spinning_block_model};
use pd_damping::LaplacianDamping;
use pd_integrators::ImplicitMidpoint;
use pd_mesh::Point;
use pd_solver::{Checkpoint, RotationState, Settings, Simulation};

/// A free block (1e6 Pa) spun about an axis off its principal axes, no
/// gravity, damped by the rotation-preserving Laplacian damping: its arms
/// stay a linear map of the first step's, so later steps map that
/// reference rather than rebuild it.
fn spinning_block() -> Simulation {
    spinning_block_on(1)
}

/// [`spinning_block`] with the local step on `threads` threads.
fn spinning_block_on(threads: usize) -> Simulation {
    let model = spinning_block_model();
    let settings = Settings {
        dt: 0.005,
        iterations: 10,
        gravity: Point::zeros(),
        threads,
        ..Settings::default()
    };
    let damping = Box::new(LaplacianDamping::new(0.01, 0.0, true).unwrap());
    let mut sim = Simulation::new(model, Box::new(ImplicitMidpoint), damping, settings).unwrap();
    sim.add_rigid_velocity(0, Point::new(0.5, 0.2, 0.0), Point::new(0.5, 1.0, 4.0))
        .unwrap();
    sim
}

fn resumed(saved: &Checkpoint, steps: usize) -> Simulation {
    let mut sim = spinning_block();
    sim.restore(saved).unwrap();
    sim.run(steps).unwrap();
    sim
}

#[test]
fn a_restored_run_continues_bit_for_bit_and_needs_the_reference_arms() {
    let mut straight = spinning_block();
    straight.run(5).unwrap();
    let saved = straight.checkpoint();
    straight.run(5).unwrap();
    assert_eq!(
        saved.rotation.arms.len(),
        straight.model().num_vertices(),
        "every vertex of the free block is projected"
    );

    let again = resumed(&saved, 5);
    assert_eq!(
        bits(&again.state().positions),
        bits(&straight.state().positions)
    );
    assert_eq!(
        bits(&again.state().velocities),
        bits(&straight.state().velocities)
    );
    assert_eq!(again.checkpoint(), straight.checkpoint());

    // Without the arms the next step rebuilds its reference from its own
    // arms, which the straight run (still turning the arms of an earlier
    // step) does not.
    let forgetful = resumed(
        &Checkpoint {
            rotation: RotationState::default(),
            ..saved.clone()
        },
        5,
    );
    assert_ne!(
        bits(&forgetful.state().positions),
        bits(&straight.state().positions),
        "the reference arms make no difference"
    );
}

/// The projection is built in one fixed order whatever the thread count.
#[test]
fn two_threads_give_the_same_bits() {
    let mut one = spinning_block_on(1);
    let mut two = spinning_block_on(2);
    one.run(10).unwrap();
    two.run(10).unwrap();
    assert_eq!(bits(&one.state().positions), bits(&two.state().positions));
    assert_eq!(bits(&one.state().velocities), bits(&two.state().velocities));
}

/// Arms of the wrong count, a short key or a non-finite value are refused
/// with an error naming `rotation`, and the simulation is unchanged.
#[test]
fn impossible_reference_arms_are_refused() {
    let mut sim = spinning_block();
    sim.run(2).unwrap();
    let saved = sim.checkpoint();
    let before = sim.checkpoint();
    let mut short = saved.clone();
    short.rotation.arms.pop();
    let mut key = saved.clone();
    key.rotation.key.pop();
    let mut nan = saved.clone();
    nan.rotation.arms[3].y = f64::NAN;
    for bad in [short, key, nan] {
        let error = sim.restore(&bad).unwrap_err().to_string();
        assert!(error.contains("rotation"), "{error}");
        assert_eq!(sim.checkpoint(), before);
    }
}
