//! An undeformed body translating uniformly, with no gravity, keeps
//! translating: every projection of a rigidly moved rest shape is exact, so
//! each step lands on `x_n + h v` and the velocity stays `v`.

mod common;

use common::{U, jittered_box, laplacian_norm};
use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation};

fn run_translation(model: Model, velocity: Point, steps: usize) {
    let settings = Settings {
        dt: 0.01,
        iterations: 3,
        gravity: Point::zeros(),
        ..Settings::default()
    };
    let rest = model.rest_positions().to_vec();
    let n = model.num_vertices() as f64;
    let min_mass = model.masses().iter().copied().fold(f64::INFINITY, f64::min);
    // Condition number bound of A = M/h^2 + L: 1 + h^2 |L| / m_min.
    let condition = 1.0 + settings.dt * settings.dt * laplacian_norm(&model) / min_mass;
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings,
    )
    .unwrap();
    sim.add_rigid_velocity(0, velocity, Point::zeros()).unwrap();
    sim.run(steps).unwrap();
    let t = sim.time();
    for (v, (x, x0)) in sim.state().positions.iter().zip(&rest).enumerate() {
        let expected = x0 + velocity * t;
        // Per step, the Cholesky solve's forward error is at most about
        // 4 n u cond(A) |x| (Higham, Accuracy and Stability, Thm 10.4), with
        // |x| <= 1 + |v| t here; it accumulates linearly over the steps.
        let tolerance = 4.0 * n * U * condition * steps as f64 * (1.0 + velocity.norm() * t);
        assert!(
            (x - expected).amax() <= tolerance,
            "vertex {v}: {x} vs {expected}"
        );
        let u = sim.state().velocities[v];
        // The velocity is a difference of two such positions divided by h.
        assert!(
            (u - velocity).amax() <= 2.0 * tolerance / 0.01,
            "vertex {v}: velocity {u}"
        );
    }
}

#[test]
fn tet_body_translates_exactly() {
    let mesh = jittered_box([3, 2, 2], [1.0, 0.5, 0.5], 0.15, 7);
    let masses = mesh.lumped_masses(800.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e5, None).unwrap();
    run_translation(model, Point::new(1.5, -0.5, 2.0), 50);
}

#[test]
fn spring_chain_translates_exactly() {
    let chain = generators::chain(6, 2.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(chain, vec![0.3; 6]).unwrap();
    model.add_springs(body, 1e3).unwrap();
    run_translation(model, Point::new(-0.7, 0.2, 0.0), 50);
}
