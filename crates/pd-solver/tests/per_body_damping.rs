//! Per-body damping in the solver ([`PerBodyDamping`]): two bodies in one
//! simulation, one undamped and one damped, keep their own energy laws, and
//! a per-body model that gives every body the same coefficients steps bit
//! for bit as the global model.
//!
//! **Energy law.** With zero-rest-length springs every projection is 0, so
//! the energy is quadratic and each step is solved exactly (the global step
//! is the minimiser after one iteration). Implicit midpoint then gives,
//! body by body (the bodies share no constraint, so each body's equations
//! are its own), `E1 - E0 = -h v_mid^T D_b v_mid` (`prop_energy.rs`): exact
//! conservation for the undamped body, exactly that loss for the damped one
//! with `D_b = a1 M_b + a2 L_d,b`. The bound on round-off is
//! `prop_energy.rs`'s: the Cholesky backward error `u (|A| |x|)` per row
//! adds `h v . rho`, at most `n u h V |A| X`, and evaluating the energies
//! rounds by `n u` of their absolute sums; a factor 16 covers the constants.

use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, PerBodyDamping};
use pd_integrators::ImplicitMidpoint;
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation, SolverMethod, SolverSpec, State};

const STIFFNESS: f64 = 50.0;
const MASS: f64 = 0.02;
const U: f64 = f64::EPSILON / 2.0;

/// Two chains of 8 vertices with zero-rest-length springs, both ends of
/// each fixed, the second 1 m above the first.
fn model() -> Model {
    let mut model = Model::new();
    for b in 0..2 {
        let chain = generators::chain(8, 0.7).unwrap();
        let chain = chain.translated(Point::new(0.0, b as f64, 0.0));
        let body = model.add_body(chain, vec![MASS; 8]).unwrap();
        model
            .add_springs_with_rest_length(body, STIFFNESS, Some(0.0))
            .unwrap();
        model.fix_vertices(body, &[0, 7]).unwrap();
    }
    model
}

fn simulation(damping: Box<dyn Damping>, dt: f64) -> Simulation {
    let settings = Settings {
        dt,
        iterations: 3,
        gravity: Point::zeros(),
        ..Settings::default()
    };
    let mut sim = Simulation::new(model(), Box::new(ImplicitMidpoint), damping, settings).unwrap();
    let mut state = sim.state().clone();
    for (v, velocity) in state.velocities.iter_mut().enumerate() {
        let t = v as f64;
        *velocity = Point::new(0.3 * (1.3 * t).sin(), 0.2 * (0.7 * t).cos(), 0.1 * t.sin());
    }
    sim.set_state(state).unwrap();
    sim
}

/// Body `b`'s kinetic plus spring energy (J), with `x` and `v` of every
/// vertex.
fn body_energy(model: &Model, b: usize, x: &[Point], v: &[Point]) -> f64 {
    let body = &model.bodies()[b];
    let kinetic: f64 = body
        .vertices()
        .map(|i| 0.5 * model.masses()[i] * v[i].norm_squared())
        .sum();
    let springs: f64 = body
        .mesh
        .edges()
        .iter()
        .map(|e| 0.5 * STIFFNESS * (x[e[1] + body.offset] - x[e[0] + body.offset]).norm_squared())
        .sum();
    kinetic + springs
}

/// `v^T D_b v` for body `b` with `D_b = a1 M_b + a2 L_d,b` (W for `v` in
/// m/s: `h` times it is the step's loss in J).
fn body_form(model: &Model, b: usize, (a1, a2): (f64, f64), v: &[Point]) -> f64 {
    let body = &model.bodies()[b];
    let mass: f64 = body
        .vertices()
        .map(|i| model.masses()[i] * v[i].norm_squared())
        .sum();
    let laplacian: f64 = body
        .mesh
        .edges()
        .iter()
        .map(|e| STIFFNESS * (v[e[1] + body.offset] - v[e[0] + body.offset]).norm_squared())
        .sum();
    a1 * mass + a2 * laplacian
}

#[test]
fn undamped_body_keeps_its_energy_and_damped_body_loses_its_own_share() {
    let (a1, a2, dt) = (0.5, 0.02, 0.01);
    let per_body = PerBodyDamping::new(vec![
        Box::new(NoDamping),
        Box::new(LaplacianDamping::new(a2, a1, false).unwrap()),
    ])
    .unwrap();
    let mut sim = simulation(Box::new(per_body), dt);
    let n = sim.model().num_vertices() as f64;
    // |A|_inf <= m (1/h^2 + a1/h) + |L|_inf (1 + a2/h), |L|_inf = 4 k
    // (two springs per vertex, diagonal plus two off-diagonal entries).
    let matrix_bound = MASS * (1.0 / (dt * dt) + a1 / dt) + 4.0 * STIFFNESS * (1.0 + a2 / dt);
    let mut damped_loss = 0.0;
    for step in 1..=200 {
        let (x0, v0) = (
            sim.state().positions.clone(),
            sim.state().velocities.clone(),
        );
        sim.step().unwrap();
        let (x1, v1) = (&sim.state().positions, &sim.state().velocities);
        let v_mid: Vec<Point> = v0.iter().zip(v1).map(|(a, b)| (a + b) * 0.5).collect();
        let max = |p: &[Point]| p.iter().map(|q| q.amax()).fold(0.0, f64::max);
        let speed = max(&v0).max(max(v1));
        let extent = max(&x0).max(max(x1)) + dt * speed;
        for b in 0..2 {
            let before = body_energy(sim.model(), b, &x0, &v0);
            let after = body_energy(sim.model(), b, x1, v1);
            let loss = match b {
                0 => 0.0,
                _ => dt * body_form(sim.model(), b, (a1, a2), &v_mid),
            };
            let tolerance =
                16.0 * U * n * (n * dt * speed * matrix_bound * extent + before + after);
            assert!(
                (after - before + loss).abs() <= tolerance,
                "step {step}, body {b}: energy changed by {:e} J, predicted {:e} J \
                 (tolerance {tolerance:e})",
                after - before,
                -loss
            );
            if b == 1 {
                damped_loss += loss;
            }
        }
    }
    // The damped body did lose its vibration energy (the test above is
    // not vacuous): the rest state is the equilibrium (both ends fixed,
    // vertices evenly spaced), so the energy above it is the initial
    // kinetic energy; a1 = 0.5 1/s over 2 s alone removes 1 - e^-1 = 63%.
    let start = simulation(Box::new(NoDamping), dt);
    let kinetic: f64 = start.model().bodies()[1]
        .vertices()
        .map(|i| 0.5 * MASS * start.state().velocities[i].norm_squared())
        .sum();
    assert!(damped_loss > 0.5 * kinetic, "{damped_loss} of {kinetic}");
}

#[test]
fn the_same_coefficients_on_every_body_step_as_the_global_model() {
    let dt = 0.01;
    let laplacian = || LaplacianDamping::new(0.02, 0.5, false).unwrap();
    let per_body = PerBodyDamping::new(vec![Box::new(laplacian()), Box::new(laplacian())]).unwrap();
    let mut weighted = simulation(Box::new(per_body), dt);
    let mut global = simulation(Box::new(laplacian()), dt);
    weighted.run(30).unwrap();
    global.run(30).unwrap();
    let (a, b): (&State, &State) = (weighted.state(), global.state());
    assert_eq!(a, b);
    assert_eq!(weighted.damping_name(), "per-body");
}

#[test]
fn an_explicit_model_acts_on_its_own_body_only() {
    let dt = 0.01;
    let drag = || EtherDrag::rate(2.0).unwrap();
    let per_body = PerBodyDamping::new(vec![Box::new(NoDamping), Box::new(drag())]).unwrap();
    let mut mixed = simulation(Box::new(per_body), dt);
    let mut undamped = simulation(Box::new(NoDamping), dt);
    let mut dragged = simulation(Box::new(drag()), dt);
    for sim in [&mut mixed, &mut undamped, &mut dragged] {
        sim.run(50).unwrap();
    }
    let bodies: Vec<_> = mixed
        .model()
        .bodies()
        .iter()
        .map(|b| b.vertices())
        .collect();
    // Each body's equations are its own (no shared constraint, zero-length
    // springs: the solve is exact), so body 0 moves as in the undamped run
    // and body 1 as in the all-dragged run. The global solves differ only
    // in the other block's right-hand side, which the block-diagonal
    // factor keeps apart; 1e-12 m leaves room for the elimination order's
    // round-off (positions ~1 m, u ~ 1e-16, 50 steps).
    for (b, reference) in [(0, &undamped), (1, &dragged)] {
        for v in bodies[b].clone() {
            let (x, y) = (mixed.state().positions[v], reference.state().positions[v]);
            assert!((x - y).norm() <= 1e-12, "body {b} vertex {v}: {x} vs {y}");
        }
    }
    // And the drag did act: body 1 differs from the undamped run.
    let v = bodies[1].start + 3;
    assert!((mixed.state().positions[v] - undamped.state().positions[v]).norm() > 1e-4);
}

#[test]
fn pbd_acts_on_its_own_body_with_renumbered_components() {
    let dt = 0.01;
    let pbd = || PbdDamping::new(0.3).unwrap();
    let per_body = PerBodyDamping::new(vec![Box::new(NoDamping), Box::new(pbd())]).unwrap();
    let mut mixed = simulation(Box::new(per_body), dt);
    let mut undamped = simulation(Box::new(NoDamping), dt);
    let mut filtered = simulation(Box::new(pbd()), dt);
    for sim in [&mut mixed, &mut undamped, &mut filtered] {
        sim.run(50).unwrap();
    }
    let bodies: Vec<_> = mixed
        .model()
        .bodies()
        .iter()
        .map(|b| b.vertices())
        .collect();
    // As for ether drag above: body 1's component (its six free vertices,
    // numbered from 0 in its own view) is filtered as in the all-PBD run,
    // body 0 moves as in the undamped run.
    for (b, reference) in [(0, &undamped), (1, &filtered)] {
        for v in bodies[b].clone() {
            let (x, y) = (mixed.state().positions[v], reference.state().positions[v]);
            assert!((x - y).norm() <= 1e-12, "body {b} vertex {v}: {x} vs {y}");
        }
    }
    let v = bodies[1].start + 3;
    assert!((mixed.state().positions[v] - undamped.state().positions[v]).norm() > 1e-4);
}

#[test]
fn every_method_but_newton_takes_per_body_coefficients() {
    let dt = 0.01;
    let mixed = || {
        PerBodyDamping::new(vec![
            Box::new(NoDamping),
            Box::new(LaplacianDamping::new(0.02, 0.5, false).unwrap()),
        ])
        .unwrap()
    };
    let spec = |method| SolverSpec {
        method,
        ..SolverSpec::default()
    };
    let mut reference = simulation(Box::new(mixed()), dt);
    reference.run(20).unwrap();
    // Zero-rest-length springs: every method reaches the step's exact
    // minimiser (the fixed point of the weighted local-global map), so they
    // agree with local-global to round-off (1e-12 m on positions of order
    // 1 m after 20 steps). This checks that each runs with per-body
    // weights and lands on the weighted solution; L-BFGS's weighted product
    // with A only steers its directions, which with an exact first
    // iteration this scene does not exercise.
    for method in [
        SolverMethod::Anderson,
        SolverMethod::Chebyshev,
        SolverMethod::Lbfgs,
    ] {
        let mut sim = simulation(Box::new(mixed()), dt);
        sim.set_position_solver(spec(method).create().unwrap());
        sim.run(20).unwrap();
        for (v, (x, y)) in sim
            .state()
            .positions
            .iter()
            .zip(&reference.state().positions)
            .enumerate()
        {
            assert!((x - y).norm() <= 1e-12, "{method:?} vertex {v}: {x} vs {y}");
        }
    }
    let mut newton = simulation(Box::new(mixed()), dt);
    newton.set_position_solver(spec(SolverMethod::Newton).create().unwrap());
    let early = newton.check_position_solver().unwrap_err().to_string();
    let error = newton.step().unwrap_err().to_string();
    assert_eq!(early, error);
    assert!(error.contains("per-body"), "{error}");
}

/// A clamped tet beam (body 0) next to a free spinning tet cube (body 1,
/// so that its vertices and its rigid body are renumbered in its own view),
/// no gravity, with `damping`.
fn spinning_pair(damping: Box<dyn Damping>) -> Simulation {
    let mut model = Model::new();
    let beam = generators::box_tets([1.0, 0.1, 0.1], [5, 1, 1])
        .unwrap()
        .translated(Point::new(0.0, 1.0, 0.0));
    let masses = beam.lumped_masses(1000.0).unwrap();
    let body = model.add_body(beam, masses).unwrap();
    model.add_tet_strain(body, 1e6, None).unwrap();
    model.fix_vertices(body, &[0, 1, 2, 3]).unwrap();
    let cube = generators::box_tets([0.2, 0.2, 0.2], [2, 2, 2]).unwrap();
    let masses = cube.lumped_masses(1000.0).unwrap();
    let body = model.add_body(cube, masses).unwrap();
    model.add_tet_strain(body, 1e5, None).unwrap();
    let settings = Settings {
        dt: 0.01,
        iterations: 10,
        gravity: Point::zeros(),
        ..Settings::default()
    };
    let mut sim = Simulation::new(model, Box::new(ImplicitMidpoint), damping, settings).unwrap();
    sim.add_rigid_velocity(1, Point::zeros(), Point::new(0.0, 0.0, 3.0))
        .unwrap();
    sim
}

/// The cube's spin about z (rad/s): `sum m (r x v)_z / sum m |r_xy|^2`
/// about its centre of mass.
fn cube_spin(sim: &Simulation) -> f64 {
    let cube = sim.model().bodies()[1].vertices();
    let (x, v, m) = (
        &sim.state().positions,
        &sim.state().velocities,
        sim.model().masses(),
    );
    let total: f64 = cube.clone().map(|i| m[i]).sum();
    let centre = cube.clone().map(|i| x[i] * m[i]).sum::<Point>() / total;
    let (mut momentum, mut inertia) = (0.0, 0.0);
    for i in cube {
        let r = x[i] - centre;
        momentum += m[i] * r.cross(&v[i]).z;
        inertia += m[i] * (r.x * r.x + r.y * r.y);
    }
    momentum / inertia
}

#[test]
fn the_rotation_preserving_variant_works_on_its_own_body() {
    let keep = |preserve| LaplacianDamping::new(0.01, 0.0, preserve).unwrap();
    let per_body = PerBodyDamping::new(vec![Box::new(NoDamping), Box::new(keep(true))]).unwrap();
    let mut mixed = spinning_pair(Box::new(per_body));
    let mut global = spinning_pair(Box::new(keep(true)));
    let mut plain = spinning_pair(Box::new(keep(false)));
    for sim in [&mut mixed, &mut global, &mut plain] {
        sim.run(30).unwrap();
    }
    // The cube sees the same model in both runs (its free rigid body
    // renumbered in its own view), and the bodies share no equation; the
    // global solves differ only in the other block, so the cube agrees to
    // the elimination's round-off (1e-12 m on a 0.2 m body).
    for v in mixed.model().bodies()[1].vertices() {
        let (x, y) = (mixed.state().positions[v], global.state().positions[v]);
        assert!((x - y).norm() <= 1e-12, "vertex {v}: {x} vs {y}");
    }
    // And its spin is the variant's, not plain Laplacian damping's.
    let (kept, lost) = (cube_spin(&mixed), cube_spin(&plain));
    println!("spin: kept {kept}, plain Laplacian {lost} rad/s");
    // The variant keeps the 3 rad/s spin up to the cube's change of inertia
    // as it stretches (measured 2.969); plain Laplacian damping at this a2
    // stops it (measured 2e-8). 10% tells the two apart with room.
    assert!(
        (kept - 3.0).abs() < 0.3 && lost.abs() < 0.3,
        "{kept}, {lost}"
    );
}
