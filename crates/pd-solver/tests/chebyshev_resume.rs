//! Chebyshev with `rho = "auto"` carries its estimate from step to step
//! (step/chebyshev.rs); a checkpoint keeps it, so a resumed run continues
//! bit for bit, as with every other method.

mod common;

use common::{Scheme, bits, method_beam};
use pd_solver::{Checkpoint, Settings, Simulation, SolverMethod};

fn beam(scheme: Scheme) -> Simulation {
    let settings = Settings {
        dt: 0.01,
        iterations: 12,
        threads: 1,
        ..Settings::default()
    };
    method_beam(scheme, SolverMethod::Chebyshev, settings)
}

/// Resumed from a checkpoint after 4 steps, 3 more steps end where the
/// uninterrupted run does, bit for bit; without the saved estimate (the
/// next step then estimates afresh from 4 plain iterations) they do not,
/// so the test can fail.
#[test]
fn a_resumed_run_continues_bit_for_bit() {
    for scheme in [Scheme::BackwardEuler, Scheme::ImplicitMidpoint] {
        let mut straight = beam(scheme);
        straight.run(4).unwrap();
        let saved = straight.checkpoint();
        assert_eq!(saved.solver.len(), 1, "{scheme:?}: an estimate is saved");
        straight.run(3).unwrap();
        // A new simulation restored from `checkpoint`, 3 steps on.
        let resume = |checkpoint: &Checkpoint| {
            let mut sim = beam(scheme);
            sim.restore(checkpoint).unwrap();
            sim.run(3).unwrap();
            sim
        };

        let resumed = resume(&saved);
        assert_eq!(
            bits(&resumed.state().positions),
            bits(&straight.state().positions),
            "{scheme:?}"
        );
        assert_eq!(resumed.checkpoint(), straight.checkpoint(), "{scheme:?}");

        let forgetful = resume(&Checkpoint {
            solver: Vec::new(),
            ..saved.clone()
        });
        assert_ne!(
            bits(&forgetful.state().positions),
            bits(&straight.state().positions),
            "{scheme:?}: the estimate makes no difference"
        );
    }
}

/// A saved estimate outside (0, 0.999] (or more than one value) is refused
/// with an error naming it, and the simulation is unchanged.
#[test]
fn an_impossible_estimate_is_refused() {
    let mut sim = beam(Scheme::BackwardEuler);
    sim.run(2).unwrap();
    let mut saved = sim.checkpoint();
    let before = sim.checkpoint();
    for bad in [vec![1.5], vec![0.0], vec![0.5, 0.5]] {
        saved.solver = bad.clone();
        let error = sim.restore(&saved).unwrap_err().to_string();
        assert!(error.contains("solver"), "{bad:?}: {error}");
        assert_eq!(sim.checkpoint(), before, "{bad:?}: changed");
    }
}

/// A checkpoint whose time is negative or whose energy scale is not
/// positive (an edited or damaged one) is refused, naming the value, and
/// the simulation is unchanged: such a scale would make the divergence
/// check fire at the next step.
#[test]
fn a_negative_time_or_energy_scale_is_refused() {
    let mut sim = beam(Scheme::BackwardEuler);
    sim.run(2).unwrap();
    let before = sim.checkpoint();
    let mut early = before.clone();
    early.time = -5.0;
    let mut unscaled = before.clone();
    unscaled.energy_scale = -1.0;
    for (name, bad) in [("time", early), ("energy_scale", unscaled)] {
        let error = sim.restore(&bad).unwrap_err().to_string();
        assert!(error.contains(name), "{name}: {error}");
        assert_eq!(sim.checkpoint(), before, "{name}: changed");
    }
}
