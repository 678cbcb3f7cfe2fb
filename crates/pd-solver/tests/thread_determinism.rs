//! Results are identical, bit for bit, with 1 thread and with 2: each
//! projection and right-hand-side row is computed independently of the
//! others, and nothing that steers the computation is a parallel reduction.
//! A second beam checks the same on a mesh where the right-hand side `B p`
//! is scattered one range of free vertices per thread
//! (`projection_scatter/ranges.rs`).

mod common;

use common::clamped_beam;
use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::Point;
use pd_solver::{Model, Settings, Simulation};

/// A backward-Euler simulation of `model` under gravity, no damping.
fn simulation(model: Model, threads: usize, iterations: usize, tolerance: f64) -> Simulation {
    let settings = Settings {
        dt: 0.01,
        iterations,
        tolerance,
        threads,
        gravity: Point::new(0.0, -9.81, 0.0),
        ..Settings::default()
    };
    Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings,
    )
    .unwrap()
}

fn run(threads: usize, tolerance: f64) -> (Vec<Point>, Vec<Point>, Vec<usize>, f64) {
    // 4 x 3 x 3 cells x 6 = 216 tets plus 1000+ springs: several chunks per
    // block, so both threads get work.
    let (mut model, body) = clamped_beam([8, 3, 3], [1.0, 0.3, 0.3], 3, 2e5);
    model.add_springs(body, 1e3).unwrap();
    let mut sim = simulation(model, threads, 15, tolerance);
    let iterations = sim.run(30).unwrap().iter().map(|s| s.iterations).collect();
    let elastic = sim.energies().elastic;
    (
        sim.state().positions.clone(),
        sim.state().velocities.clone(),
        iterations,
        elastic,
    )
}

/// Final positions and velocities as bits, on a box numbered x fastest
/// with 12 cells along z, so that a cut between ranges crosses one or two
/// of the 12 layers of cells and few elements straddle two ranges (the
/// beam of `run` has 3 cells across, so a cut there crosses a large share
/// of its elements and `B p` keeps the row gather).
fn run_ranges(threads: usize) -> Vec<u64> {
    let (model, _) = clamped_beam([6, 3, 12], [0.5, 0.25, 1.0], 7, 2e5);
    let mut sim = simulation(model, threads, 10, 0.0);
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
fn one_and_two_threads_agree_bit_for_bit() {
    for tolerance in [0.0, 1e-4] {
        let one = run(1, tolerance);
        let two = run(2, tolerance);
        let bits = |v: &[Point]| {
            v.iter()
                .flat_map(|p| p.iter().map(|c| c.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            bits(&one.0),
            bits(&two.0),
            "positions differ (tolerance {tolerance})"
        );
        assert_eq!(
            bits(&one.1),
            bits(&two.1),
            "velocities differ (tolerance {tolerance})"
        );
        assert_eq!(one.2, two.2, "iteration counts differ");
        assert_eq!(one.3.to_bits(), two.3.to_bits(), "elastic energy differs");
    }
}

#[test]
fn the_ranges_give_the_bits_of_one_thread() {
    let one = run_ranges(1);
    assert_eq!(run_ranges(2), one, "2 threads");
    assert_eq!(run_ranges(3), one, "3 threads");
}
