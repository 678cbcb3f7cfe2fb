//! Contact with static colliders (docs/contact.md): Coulomb sliding and
//! sticking, coming to rest, restitution, momentum, tunnelling, thread
//! determinism.

use pd_damping::{Damping, NoDamping};
use pd_integrators::{BackwardEuler, Bdf2, ImplicitMidpoint, Integrator};
use pd_mesh::{Point, generators};
use pd_solver::contact::{Collider, ColliderShape, ContactSettings};
use pd_solver::{Model, Settings, Simulation};

/// A cube of side `size` (m), `cells` per side, density 1000 kg/m^3,
/// tet-strain stiffness `k` (Pa), its lowest face at height `bottom`.
fn cube(size: f64, cells: usize, k: f64, bottom: f64) -> Model {
    let mesh = generators::box_tets([size; 3], [cells; 3]).unwrap();
    let low = mesh
        .vertices()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    let mesh = mesh.translated(Point::new(0.0, bottom - low, 0.0));
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, k, None).unwrap();
    model
}

fn floor(friction: f64, restitution: f64) -> Collider {
    Collider {
        shape: ColliderShape::Plane {
            point: Point::zeros(),
            normal: Point::y(),
        },
        friction,
        restitution,
    }
}

fn simulation(
    model: Model,
    integrator: Box<dyn Integrator>,
    damping: Box<dyn Damping>,
    settings: Settings,
    contact: ContactSettings,
) -> Simulation {
    let mut sim = Simulation::new(model, integrator, damping, settings).unwrap();
    sim.set_contact(contact).unwrap();
    sim
}

fn centre_velocity(sim: &Simulation) -> Point {
    let s = sim.state();
    s.velocities.iter().sum::<Point>() / s.velocities.len() as f64
}

fn integrators() -> Vec<(&'static str, Box<dyn Integrator>)> {
    vec![
        ("backward-euler", Box::new(BackwardEuler)),
        ("implicit-midpoint", Box::new(ImplicitMidpoint)),
        ("bdf2", Box::new(Bdf2::default())),
    ]
}

/// Side, cells per side, stiffness (Pa) and mass (kg) of the test cube.
const SIDE: f64 = 0.1;
const CELLS: usize = 2;
const MASS: f64 = 1000.0 * SIDE * SIDE * SIDE;

fn settings(dt: f64, iterations: usize, gravity: Point) -> Settings {
    Settings {
        dt,
        iterations,
        gravity,
        ..Settings::default()
    }
}

fn on_floor(friction: f64, restitution: f64, thickness: f64) -> ContactSettings {
    ContactSettings {
        colliders: vec![floor(friction, restitution)],
        thickness,
    }
}

/// The block's mean acceleration along the slope over `[0.5 s, 1 s]` on a
/// plane with gravity tilted by `theta`, and its mean displacement along
/// the slope over that interval.
fn slope(theta: f64, mu: f64, integrator: Box<dyn Integrator>) -> (f64, f64) {
    let (g, dt) = (9.81, 0.005);
    let gravity = Point::new(g * theta.sin(), -g * theta.cos(), 0.0);
    let thickness = 0.001;
    let mut sim = simulation(
        cube(SIDE, CELLS, 1e6, thickness),
        integrator,
        Box::new(NoDamping),
        settings(dt, 20, gravity),
        on_floor(mu, 0.0, thickness),
    );
    sim.run(100).unwrap();
    let (v0, x0) = (centre_velocity(&sim), centre(&sim));
    sim.run(100).unwrap();
    let (v1, x1) = (centre_velocity(&sim), centre(&sim));
    ((v1.x - v0.x) / 0.5, x1.x - x0.x)
}

fn centre(sim: &Simulation) -> Point {
    let s = sim.state();
    s.positions.iter().sum::<Point>() / s.positions.len() as f64
}

#[test]
fn a_block_slides_by_coulombs_law_and_sticks_below_the_friction_angle() {
    let g = 9.81;
    for (name, integrator) in integrators() {
        // tan 30 deg = 0.577 > 0.3: slides.
        let (theta, mu) = (30.0_f64.to_radians(), 0.3);
        let expected = g * (theta.sin() - mu * theta.cos());
        let (a, _) = slope(theta, mu, integrator);
        println!(
            "{name}: slide a {a} expected {expected} rel {:.2e}",
            (a / expected - 1.0).abs()
        );
    }
    for (name, integrator) in integrators() {
        // tan 20 deg = 0.364 < 0.5: sticks.
        let (a, moved) = slope(20.0_f64.to_radians(), 0.5, integrator);
        println!("{name}: stick a {a} moved {moved:e}");
    }
}

/// Drops the cube from `height` (m) onto the floor with backward Euler;
/// returns the last step's penetration, the largest penetration after the
/// first 0.5 s, the kinetic energy at the end, and the drop's potential energy.
fn drop(
    damping: Box<dyn Damping>,
    height: f64,
    threads: usize,
) -> (f64, f64, f64, f64, Simulation) {
    let g = 9.81;
    let thickness = 0.001;
    let mut settings = settings(0.005, 20, Point::new(0.0, -g, 0.0));
    settings.threads = threads;
    let mut sim = simulation(
        cube(SIDE, CELLS, 1e5, height),
        Box::new(BackwardEuler),
        damping,
        settings,
        on_floor(0.5, 0.0, thickness),
    );
    let stats = sim.run(400).unwrap();
    let late = stats[100..]
        .iter()
        .map(|s| s.penetration)
        .fold(0.0, f64::max);
    let kinetic = sim.energies().kinetic;
    (
        stats.last().unwrap().penetration,
        late,
        kinetic,
        MASS * g * height,
        sim,
    )
}

#[test]
fn a_dropped_body_comes_to_rest_on_the_floor() {
    use pd_damping::LaplacianDamping;
    for (name, damping) in [
        ("none", Box::new(NoDamping) as Box<dyn Damping>),
        (
            "laplacian",
            Box::new(LaplacianDamping::new(0.01, 0.0, false).unwrap()),
        ),
    ] {
        let (last, late, kinetic, potential, _) = drop(damping, 0.2, 1);
        println!(
            "{name}: pen last {last:e} late {late:e} ke/pe {:e}",
            kinetic / potential
        );
    }
}

#[test]
fn a_stiff_body_bounces_to_e_squared_h() {
    let (g, h, e) = (9.81, 0.2, 0.5);
    let thickness = 0.0;
    let mut sim = simulation(
        cube(SIDE, CELLS, 1e8, h),
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings(0.001, 20, Point::new(0.0, -g, 0.0)),
        on_floor(0.0, e, thickness),
    );
    let bottom = |sim: &Simulation| {
        sim.state()
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min)
    };
    let mut landed = false;
    let mut peak = 0.0_f64;
    for _ in 0..600 {
        let stats = sim.step().unwrap();
        if stats.contacts > 0 {
            landed = true;
        }
        if landed && stats.contacts == 0 {
            peak = peak.max(bottom(&sim));
        }
    }
    println!(
        "bounce peak {peak} expected {} rel {:e}",
        e * e * h,
        peak / (e * e * h) - 1.0
    );
}

#[test]
fn frictionless_contact_keeps_tangential_momentum() {
    let thickness = 0.001;
    let mut sim = simulation(
        cube(SIDE, CELLS, 1e5, 0.01),
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings(0.005, 20, Point::zeros()),
        on_floor(0.0, 0.0, thickness),
    );
    let v = Point::new(1.0, -0.5, 0.3);
    sim.add_rigid_velocity(0, v, Point::zeros());
    let p0 = sim.linear_momentum();
    let stats = sim.run(100).unwrap();
    let p1 = sim.linear_momentum();
    println!(
        "p0 {p0:?} p1 {p1:?} contacts {}",
        stats.last().unwrap().contacts
    );
}

#[test]
fn a_fast_body_does_not_tunnel_through_a_thin_wall() {
    for speed in [10.0, 50.0, 200.0] {
        let wall = Collider {
            shape: ColliderShape::Box {
                min: Point::new(0.5, -1.0, -1.0),
                max: Point::new(0.51, 1.0, 1.0),
            },
            friction: 0.0,
            restitution: 0.0,
        };
        let mut sim = simulation(
            cube(SIDE, CELLS, 1e5, 0.0),
            Box::new(BackwardEuler),
            Box::new(NoDamping),
            settings(0.01, 20, Point::zeros()),
            ContactSettings {
                colliders: vec![wall],
                thickness: 0.001,
            },
        );
        sim.add_rigid_velocity(0, Point::new(speed, 0.0, 0.0), Point::zeros());
        let mut deepest = f64::NEG_INFINITY;
        let mut pen = 0.0_f64;
        for _ in 0..50 {
            let s = sim.step().unwrap();
            pen = pen.max(s.penetration);
            deepest = deepest.max(
                sim.state()
                    .positions
                    .iter()
                    .map(|p| p.x)
                    .fold(f64::NEG_INFINITY, f64::max),
            );
        }
        println!("speed {speed}: furthest x {deepest} pen {pen}");
    }
}

#[test]
fn contact_is_bit_identical_for_one_and_two_threads() {
    let one = drop(Box::new(NoDamping), 0.2, 1).4;
    let two = drop(Box::new(NoDamping), 0.2, 2).4;
    assert_eq!(one.state().positions, two.state().positions);
    assert_eq!(one.state().velocities, two.state().velocities);
}
