//! Results are identical, bit for bit, with 1 thread and with 2: each
//! projection and right-hand-side row is computed independently of the
//! others, and nothing that steers the computation is a parallel reduction.

mod common;

use common::clamped_beam;
use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::Point;
use pd_solver::{Settings, Simulation};

fn run(threads: usize, tolerance: f64) -> (Vec<Point>, Vec<Point>, Vec<usize>, f64) {
    // 4 x 3 x 3 cells x 6 = 216 tets plus 1000+ springs: several chunks per
    // block, so both threads get work.
    let (mut model, body) = clamped_beam([8, 3, 3], [1.0, 0.3, 0.3], 3, 2e5);
    model.add_springs(body, 1e3).unwrap();
    let settings = Settings {
        dt: 0.01,
        iterations: 15,
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
    let iterations = sim.run(30).unwrap().iter().map(|s| s.iterations).collect();
    let elastic = sim.energies().elastic;
    (
        sim.state().positions.clone(),
        sim.state().velocities.clone(),
        iterations,
        elastic,
    )
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
