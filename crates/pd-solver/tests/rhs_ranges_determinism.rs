//! Results are identical, bit for bit, on 1, 2 and 3 threads on a mesh
//! where the right-hand side `B p` is scattered one range of free vertices
//! per thread (`projection_scatter/ranges.rs`): a box numbered x fastest
//! with 12 cells along z, so that a cut between ranges crosses one or two of
//! the 12 layers of cells and few elements straddle two ranges (the
//! thread_determinism test's beam has 3 cells across, so a cut there
//! crosses a large share of its elements).

mod common;

use common::clamped_beam;
use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::Point;
use pd_solver::{Settings, Simulation};

fn run(threads: usize) -> Vec<u64> {
    let (model, _) = clamped_beam([6, 3, 12], [0.5, 0.25, 1.0], 7, 2e5);
    let settings = Settings {
        dt: 0.01,
        iterations: 10,
        tolerance: 0.0,
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
    sim.run(10).unwrap();
    let state = sim.state();
    state
        .positions
        .iter()
        .chain(&state.velocities)
        .flat_map(|p| p.iter().map(|c| c.to_bits()))
        .collect()
}

#[test]
fn the_ranges_give_the_bits_of_one_thread() {
    let one = run(1);
    assert_eq!(run(2), one, "2 threads");
    assert_eq!(run(3), one, "3 threads");
}
