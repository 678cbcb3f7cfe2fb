//! Determinism over random scenes, damping models, integrators, tolerances,
//! pins and gravity:
//!
//! - 1 and 2 threads give identical results, bit for bit: every projection
//!   and right-hand-side row is computed independently of the others, and
//!   no parallel reduction steers the computation (`thread_determinism.rs`
//!   checks one fixed beam; this checks random cases).
//! - A run resumed from an initial-state file written mid-run (pd-io's
//!   `write_state`, `read_state`, then `Simulation::set_state`) ends in the
//!   same state, bit for bit, as the uninterrupted run: the file keeps every
//!   `f64` exactly, and backward Euler and implicit midpoint need nothing
//!   but positions and velocities. BDF-2 also needs the previous step, which
//!   a state file does not hold (`set_state` restarts it with a backward
//!   Euler step); resuming BDF-2 exactly is the checkpoint's job, not the
//!   state file's.

mod common;
mod prop_common;

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use common::{Scheme, bits, jittered_box};
use pd_io::state::{read_state, write_state};
use pd_mesh::Point;
use pd_solver::{Model, Settings, Simulation, State};
use prop_common::{DampingChoice, config, damping, points};
use proptest::prelude::*;

/// A random scene large enough that two threads split the work: a jittered
/// box of up to 6 x 3 x 2 cells (216 tets) with strain, springs on its
/// edges, and random masses and velocities.
#[derive(Debug, Clone)]
struct Case {
    cells: [usize; 3],
    seed: u64,
    stiffness: f64,
    density: f64,
    velocities: Vec<Point>,
    choice: DampingChoice,
    pinned: bool,
    tolerance: f64,
    dt: f64,
    iterations: usize,
}

impl Case {
    fn model(&self) -> Model {
        let mesh = jittered_box(self.cells, [1.2, 0.6, 0.4], 0.15, self.seed);
        let masses = mesh.lumped_masses(self.density).unwrap();
        let mut model = Model::new();
        let body = model.add_body(mesh, masses).unwrap();
        model.add_tet_strain(body, self.stiffness, None).unwrap();
        model.add_springs(body, self.stiffness * 0.01).unwrap();
        if self.pinned {
            model.fix_vertices(body, &[0, 1]).unwrap();
        }
        model
    }

    fn simulation(&self, scheme: Scheme, threads: usize) -> Simulation {
        let model = self.model();
        let n = model.num_vertices();
        let settings = Settings {
            dt: self.dt,
            iterations: self.iterations,
            tolerance: self.tolerance,
            threads,
            ..Settings::default()
        };
        let mut sim =
            Simulation::new(model, scheme.integrator(), self.choice.create(), settings).unwrap();
        let positions = sim.state().positions.clone();
        let velocities = self.velocities.iter().cycle().take(n).copied().collect();
        sim.set_state(State {
            positions,
            velocities,
        })
        .unwrap();
        sim
    }
}

fn case() -> impl Strategy<Value = Case> {
    (
        (1usize..=6, 1usize..=3, 1usize..=2),
        0u64..1000,
        1e3..1e6f64,
        1e2..1e4f64,
        points(17, 1.0),
        damping(0.05),
        any::<bool>(),
        prop_oneof![Just(0.0), Just(1e-4)],
        1e-3..0.02f64,
        1usize..=12,
    )
        .prop_map(
            |(
                cells,
                seed,
                stiffness,
                density,
                velocities,
                choice,
                pinned,
                tolerance,
                dt,
                iterations,
            )| {
                Case {
                    cells: [cells.0, cells.1, cells.2],
                    seed,
                    stiffness,
                    density,
                    velocities,
                    choice,
                    pinned,
                    tolerance,
                    dt,
                    iterations,
                }
            },
        )
}

fn scheme() -> impl Strategy<Value = Scheme> {
    prop_oneof![
        Just(Scheme::BackwardEuler),
        Just(Scheme::ImplicitMidpoint),
        Just(Scheme::Bdf2)
    ]
}

const STEPS: usize = 6;

/// A fresh path for a state file under Cargo's per-test temporary folder.
fn state_path() -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("prop_determinism");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(format!(
        "state-{}-{}.json",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ))
}

proptest! {
    #![proptest_config(config(12))]

    #[test]
    fn one_and_two_threads_agree_bit_for_bit(case in case(), scheme in scheme()) {
        let mut one = case.simulation(scheme, 1);
        let mut two = case.simulation(scheme, 2);
        for step in 1..=STEPS {
            let a = one.step().map_err(|e| TestCaseError::fail(format!("1 thread, step {step}: {e}")))?;
            let b = two.step().map_err(|e| TestCaseError::fail(format!("2 threads, step {step}: {e}")))?;
            prop_assert_eq!(a.iterations, b.iterations, "step {}", step);
            prop_assert_eq!(a.relative_change.to_bits(), b.relative_change.to_bits(), "step {}", step);
            prop_assert_eq!(bits(&one.state().positions), bits(&two.state().positions), "step {}", step);
            prop_assert_eq!(bits(&one.state().velocities), bits(&two.state().velocities), "step {}", step);
        }
        prop_assert_eq!(one.energies().elastic.to_bits(), two.energies().elastic.to_bits());
    }

    #[test]
    fn a_run_resumed_from_a_state_file_matches_the_uninterrupted_run(
        case in case(),
        scheme in prop_oneof![Just(Scheme::BackwardEuler), Just(Scheme::ImplicitMidpoint)],
        split in 1usize..STEPS,
    ) {
        let mut whole = case.simulation(scheme, 1);
        whole.run(STEPS).map_err(|e| TestCaseError::fail(e.to_string()))?;

        let mut first = case.simulation(scheme, 1);
        first.run(split).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let path = state_path();
        write_state(&path, &first.state().positions, &first.state().velocities).unwrap();
        let file = read_state(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let mut resumed = case.simulation(scheme, 1);
        resumed
            .set_state(State {
                positions: file.positions_as_points(),
                velocities: file.velocities_as_points(),
            })
            .unwrap();
        resumed.run(STEPS - split).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(bits(&whole.state().positions), bits(&resumed.state().positions));
        prop_assert_eq!(bits(&whole.state().velocities), bits(&resumed.state().velocities));
    }
}

#[test]
fn bdf2_resumed_from_a_state_file_restarts_its_history() {
    // The control, and the documented limit: BDF-2 resumed from a state file
    // takes a backward Euler start-up step, so it leaves the uninterrupted
    // run (by far more than round-off).
    let case = Case {
        cells: [3, 1, 1],
        seed: 2,
        stiffness: 1e5,
        density: 1e3,
        velocities: (0..17)
            .map(|i| Point::new(0.1 * i as f64, 0.2, -0.05 * i as f64))
            .collect(),
        choice: DampingChoice::None,
        pinned: true,
        tolerance: 0.0,
        dt: 0.01,
        iterations: 5,
    };
    let mut whole = case.simulation(Scheme::Bdf2, 1);
    whole.run(STEPS).unwrap();
    let mut first = case.simulation(Scheme::Bdf2, 1);
    first.run(3).unwrap();
    let mut resumed = case.simulation(Scheme::Bdf2, 1);
    resumed.set_state(first.state().clone()).unwrap();
    resumed.run(STEPS - 3).unwrap();
    let difference = whole
        .state()
        .positions
        .iter()
        .zip(&resumed.state().positions)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(difference > 1e-9, "{difference:e}");
}
