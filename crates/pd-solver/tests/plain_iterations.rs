//! `LocalGlobal` writes the next local step's `q = x_n + c2 dx` in the
//! global step's tail and skips the `q` pass of later iterations
//! (step/tail.rs); on more threads another thread writes it and stays
//! awake. This must not change a bit: the same steps through the public
//! seam (`StepProblem::local_global_iteration` in a loop, which computes
//! `q` before every projection) must end in the same state, with the same
//! iteration counts and the same objective trace, on 1 and 2 threads, with
//! and without a tolerance that stops iterations early.

mod common;

use common::clamped_beam;
use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::Point;
use pd_solver::{PositionSolver, Settings, Simulation, SolverError, StepProblem};

/// Plain local-global iterations through the public seam only: the loop
/// `LocalGlobal` ran before its `q` moved into the tail.
#[derive(Debug)]
struct SeamLoop;

impl PositionSolver for SeamLoop {
    fn name(&self) -> &'static str {
        "seam-loop"
    }

    fn find_positions(&mut self, step: &mut StepProblem<'_>) -> Result<(), SolverError> {
        step.record_objective();
        for _ in 0..step.iterations() {
            let change = step.local_global_iteration();
            step.record_objective();
            if step.converged(change) {
                break;
            }
        }
        Ok(())
    }
}

/// Bits of the final positions and velocities, the iteration count of each
/// step and the bits of the last step's objective trace (empty when not
/// recorded).
type Outcome = (Vec<u64>, Vec<usize>, Vec<u64>);

/// The objective trace evaluates the objective after every iteration,
/// which writes `q` itself; without it the tail's `q` is what the next
/// local step uses, so both are run.
fn run(threads: usize, tolerance: f64, seam: bool, record: bool) -> Outcome {
    // 8 x 3 x 3 cells: 432 tets, two chunks of the local step, fixed
    // vertices at x = 0 (whose `q` the tail does not write).
    let (model, _) = clamped_beam([8, 3, 3], [1.0, 0.3, 0.3], 5, 2e5);
    let settings = Settings {
        dt: 0.01,
        iterations: 12,
        tolerance,
        threads,
        gravity: Point::new(0.0, -9.81, 0.0),
        ..Settings::default()
    };
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings,
    )
    .unwrap();
    if seam {
        sim.set_position_solver(Box::new(SeamLoop));
    }
    sim.record_objective(record);
    let iterations = sim.run(15).unwrap().iter().map(|s| s.iterations).collect();
    let state = sim.state();
    let bits = state
        .positions
        .iter()
        .chain(&state.velocities)
        .flat_map(|p| p.iter().map(|c| c.to_bits()))
        .collect();
    let trace = sim
        .objective_trace()
        .unwrap_or_default()
        .iter()
        .map(|g| g.to_bits())
        .collect();
    (bits, iterations, trace)
}

#[test]
fn local_global_is_the_seam_loop_bit_for_bit() {
    for (tolerance, record) in [(0.0, false), (1e-3, false), (0.0, true), (1e-3, true)] {
        let case = format!("tolerance {tolerance}, objective trace {record}");
        let reference = run(1, tolerance, true, record);
        // A tolerance that never stops early would not test the early exit.
        if tolerance > 0.0 {
            assert!(
                reference.1.iter().any(|&k| k < 12),
                "{case}: no step stopped early: {:?}",
                reference.1
            );
        }
        for threads in [1, 2] {
            let plain = run(threads, tolerance, false, record);
            assert_eq!(
                plain.1, reference.1,
                "{case}, {threads} thread(s): iterations"
            );
            assert!(
                plain.0 == reference.0,
                "{case}, {threads} thread(s): state differs"
            );
            assert!(
                plain.2 == reference.2,
                "{case}, {threads} thread(s): objective trace differs"
            );
        }
    }
}
