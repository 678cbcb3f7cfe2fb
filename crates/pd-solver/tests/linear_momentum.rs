//! With no gravity, no fixed vertices and only translation-invariant
//! constraints, the total linear momentum is unchanged by a step, for any
//! iteration count (docs/design/formulation.md, "Linear momentum": summing
//! the global equations, `1^T L = 0`
//! and `G_i 1 = 0` leave `sum M x = sum M y`, whatever the projections).

mod common;

use common::{U, jittered_box, laplacian_norm};
use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation, State};
use proptest::prelude::*;

fn settings(dt: f64, iterations: usize) -> Settings {
    Settings {
        dt,
        iterations,
        gravity: Point::zeros(),
        threads: 1,
        ..Settings::default()
    }
}

/// Runs `steps` steps from random velocities and checks the momentum after
/// each against the first.
///
/// Round-off bound: the velocity `(x_{n+1} - x_n)/h` of each vertex carries
/// an error of about `u |x| / h` from the cancellation, and the Cholesky
/// solve's backward error adds `u (m/h^2 + |L|) |x|` per equation, which
/// becomes `u h (m/h^2 + |L|) |x|` of momentum per vertex (`|L|` the
/// Laplacian's Gershgorin bound). Summed over `n` vertices and `steps` steps,
/// with a factor 16 for the constant of the solve's error bound.
fn check(
    model: Model,
    dt: f64,
    iterations: usize,
    velocities: Vec<Point>,
    steps: usize,
) -> Result<(), TestCaseError> {
    let n = model.num_vertices();
    let max_mass = model.masses().iter().copied().fold(0.0, f64::max);
    let stiffness = laplacian_norm(&model);
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings(dt, iterations),
    )
    .unwrap();
    let positions = sim.state().positions.clone();
    sim.set_state(State {
        positions,
        velocities,
    })
    .unwrap();
    let p0 = sim.linear_momentum();
    for step in 1..=steps {
        sim.step().unwrap();
        let extent = sim
            .state()
            .positions
            .iter()
            .map(|x| x.amax())
            .fold(0.0, f64::max);
        let tolerance = 16.0 * U * (n * step) as f64 * (max_mass / dt + dt * stiffness) * extent;
        let error = (sim.linear_momentum() - p0).amax();
        prop_assert!(
            error <= tolerance,
            "step {step}: momentum error {error:e} > {tolerance:e}"
        );
    }
    Ok(())
}

fn velocities(n: usize) -> impl Strategy<Value = Vec<Point>> {
    proptest::collection::vec((-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64), n)
        .prop_map(|v| v.into_iter().map(|(x, y, z)| Point::new(x, y, z)).collect())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, max_shrink_iters: 100, ..ProptestConfig::default() })]

    #[test]
    fn tet_body_keeps_momentum(
        seed in 0u64..1000,
        stiffness in 1e1..1e6f64,
        masses in proptest::collection::vec(0.01..10.0f64, 27),
        dt in 1e-3..0.1f64,
        iterations in 1usize..20,
        v in velocities(27),
    ) {
        let mesh = jittered_box([2, 2, 2], [1.0, 0.7, 0.4], 0.15, seed);
        let mut model = Model::new();
        let body = model.add_body(mesh, masses).unwrap();
        model.add_tet_strain(body, stiffness, None).unwrap();
        check(model, dt, iterations, v, 5)?;
    }

    #[test]
    fn chain_with_strain_limits_and_springs_keeps_momentum(
        points in 2usize..8,
        stiffness in 1e0..1e5f64,
        dt in 1e-3..0.1f64,
        iterations in 1usize..20,
        v in velocities(8),
    ) {
        let chain = generators::chain(points, 1.0).unwrap();
        let mut model = Model::new();
        let body = model.add_body(chain, vec![0.2; points]).unwrap();
        model.add_springs(body, stiffness).unwrap();
        // A second, strain-limited tet body in the same system.
        let tet = jittered_box([1, 1, 1], [0.3, 0.3, 0.3], 0.1, points as u64);
        let masses = tet.lumped_masses(500.0).unwrap();
        let second = model.add_body(tet.translated(Point::new(2.0, 0.0, 0.0)), masses).unwrap();
        model.add_tet_strain(second, stiffness, Some((0.9, 1.1))).unwrap();
        let n = model.num_vertices();
        check(model, dt, iterations, v[..n.min(8)].iter().copied().chain(std::iter::repeat(Point::new(0.5, -0.3, 0.1))).take(n).collect(), 5)?;
    }
}

#[test]
fn attachments_break_momentum_conservation() {
    // The control: an attachment is not translation invariant, so the same
    // check must see momentum change, or the test above could not fail.
    let chain = generators::chain(3, 1.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(chain, vec![1.0; 3]).unwrap();
    model.add_springs(body, 10.0).unwrap();
    model.add_attachments(body, &[0], 100.0).unwrap();
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings(0.01, 5),
    )
    .unwrap();
    sim.add_rigid_velocity(0, Point::new(1.0, 0.0, 0.0), Point::zeros())
        .unwrap();
    let p0 = sim.linear_momentum();
    sim.run(10).unwrap();
    assert!((sim.linear_momentum() - p0).norm() > 1e-3);
}
