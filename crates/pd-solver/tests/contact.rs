//! Contact with static colliders (docs/design/contact.md): Coulomb sliding and
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
        // tan 30 deg = 0.577 > mu = 0.3: slides at g (sin - mu cos).
        let (theta, mu) = (30.0_f64.to_radians(), 0.3);
        let expected = g * (theta.sin() - mu * theta.cos());
        let (a, _) = slope(theta, mu, integrator);
        // Measured relative errors: backward Euler 5e-10, BDF-2 7e-9,
        // implicit midpoint 6.7e-4. Midpoint does not damp the elastic
        // vibration the initial loading excites, which modulates the normal
        // force (and so the friction) around its mean; 1% bounds it.
        assert!(
            (a / expected - 1.0).abs() < 1e-2,
            "{name}: a = {a} m/s^2, expected {expected}"
        );
    }
    for (name, integrator) in integrators() {
        // tan 20 deg = 0.364 < mu = 0.5: sticks.
        let (a, moved) = slope(20.0_f64.to_radians(), 0.5, integrator);
        // Without friction it would slide 0.5 g sin(20 deg) (1 - 0.25) = 1.26 m
        // over this interval. Measured: backward Euler 2e-13 m, BDF-2
        // 5e-10 m, implicit midpoint 2.7e-6 m (its undamped elastic vibration
        // again): below 1e-5 m, i.e. 1e-5 of the frictionless slide.
        assert!(moved.abs() < 1e-5, "{name}: crept {moved} m (a = {a})");
    }
}

/// Drops the cube from `height` (m) onto the floor with backward Euler;
/// returns the last step's penetration, the largest penetration after the
/// first 0.5 s, the kinetic energy at the end, and the drop's potential energy.
fn drop(
    integrator: Box<dyn Integrator>,
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
        integrator,
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
    let thickness = 0.001;
    for name in ["backward-euler", "implicit-midpoint", "bdf2"] {
        for damped in [false, true] {
            let integrator = integrators()
                .into_iter()
                .find(|(n, _)| *n == name)
                .unwrap()
                .1;
            let damping: Box<dyn Damping> = if damped {
                Box::new(LaplacianDamping::new(0.01, 0.0, false).unwrap())
            } else {
                Box::new(NoDamping)
            };
            let (_, late, kinetic, potential, sim) = drop(integrator, damping, 0.2, 1);
            let low = sim
                .state()
                .positions
                .iter()
                .map(|p| p.y)
                .fold(f64::INFINITY, f64::min);
            // Every vertex ends at or above the thickened floor (the final
            // projection guarantees it, up to the round-off of one addition).
            assert!(
                low >= thickness - 1e-15,
                "{name} {damped}: lowest vertex {low}"
            );
            // What the iterations themselves leave, after the landing (from
            // 0.5 s): measured at most 1.4e-7 m (BDF-2 undamped); bound 1% of
            // the thickness.
            assert!(late < 1e-5, "{name} {damped}: penetration {late} m");
            // At rest after 2 s: measured kinetic / drop potential energy
            // 3e-27 (backward Euler), 2.2e-5 (BDF-2 undamped), 8.8e-7
            // (midpoint damped). Undamped implicit midpoint keeps 2.7e-3: the
            // elastic vibration of the landing, which it conserves by design
            // (no numerical damping), not contact jitter; its bound is 1e-2.
            let bound = if name == "implicit-midpoint" && !damped {
                1e-2
            } else {
                1e-4
            };
            assert!(
                kinetic < bound * potential,
                "{name} {damped}: kinetic {kinetic} J of {potential} J"
            );
        }
    }
}

/// Drops a stiff cube (1e10 Pa: its contact lasts one step) flat from
/// `height` onto a floor of restitution `e` with backward Euler
/// (`dt` = 1 ms); returns the highest its bottom gets after the bounce.
fn bounce(height: f64, e: f64) -> f64 {
    let g = 9.81;
    let mut sim = simulation(
        cube(SIDE, CELLS, 1e10, height),
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings(0.001, 20, Point::new(0.0, -g, 0.0)),
        on_floor(0.0, e, 0.0),
    );
    let mut landed = false;
    let mut peak = 0.0_f64;
    for _ in 0..600 {
        landed |= sim.step().unwrap().contacts > 0;
        if landed {
            peak = peak.max(centre(&sim).y - SIDE / 2.0);
        }
    }
    assert!(landed);
    peak
}

#[test]
fn a_stiff_body_bounces_to_e_squared_h() {
    // The bounce starts where the impact step began, up to v_in dt = 2 mm
    // above the floor, and backward Euler's discrete parabola misses the
    // apex by up to v dt (1-2 mm): 3-4 mm of the 50 mm of e^2 h, so 8%.
    // Measured: +1.5% (e = 0.5), -0.2% (e = 1).
    let (h, e) = (0.2, 0.5);
    let peak = bounce(h, e);
    assert!((peak / (e * e * h) - 1.0).abs() < 0.08, "peak {peak} m");
    // e = 1 must not gain energy: at most h plus the same 4 mm; and it
    // bounces back to h within the same 8%.
    let elastic = bounce(h, 1.0);
    assert!(
        elastic < h + 0.004 && elastic > 0.92 * h,
        "peak {elastic} m"
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
    // Hits the floor obliquely, bounces elastically off it, slides along it.
    sim.add_rigid_velocity(0, Point::new(1.0, -0.5, 0.3), Point::zeros())
        .unwrap();
    let p0 = sim.linear_momentum();
    let mut touched = false;
    for _ in 0..100 {
        touched |= sim.step().unwrap().contacts > 0;
    }
    let p1 = sim.linear_momentum();
    assert!(touched);
    assert!(p1.y > 0.0, "the normal momentum reverses: {p1:?}");
    // Frictionless contact forces are normal (along y): x and z momenta
    // change only by round-off, measured 5e-14 relative over 100 steps.
    for axis in [0, 2] {
        assert!(
            (p1[axis] - p0[axis]).abs() < 1e-12 * p0.norm(),
            "{p0:?} -> {p1:?}"
        );
    }
}

#[test]
fn a_fast_body_does_not_tunnel_through_a_thin_wall() {
    // A 1 cm wall, the cube moving 0.1 m to 2 m per step (10-200 m/s at
    // dt = 10 ms): the speeds docs/design/contact.md states.
    let thickness = 0.001;
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
                thickness,
            },
        );
        sim.add_rigid_velocity(0, Point::new(speed, 0.0, 0.0), Point::zeros())
            .unwrap();
        let mut touched = false;
        for step in 0..50 {
            touched |= sim.step().unwrap().contacts > 0;
            let front = sim
                .state()
                .positions
                .iter()
                .map(|p| p.x)
                .fold(f64::NEG_INFINITY, f64::max);
            // Never past the thickened near face (round-off of one addition).
            assert!(
                front <= 0.5 - thickness + 1e-15,
                "{speed} m/s, step {step}: x = {front}"
            );
        }
        assert!(touched, "{speed} m/s");
    }
}

#[test]
fn contact_is_bit_identical_for_one_and_two_threads() {
    let one = drop(Box::new(BackwardEuler), Box::new(NoDamping), 0.2, 1).4;
    let two = drop(Box::new(BackwardEuler), Box::new(NoDamping), 0.2, 2).4;
    assert_eq!(one.state().positions, two.state().positions);
    assert_eq!(one.state().velocities, two.state().velocities);
}

#[test]
fn a_body_rests_on_a_box_and_on_a_sphere() {
    let thickness = 0.001;
    // A box whose top face is at y = 0, wider than the cube; a sphere of
    // radius 1 m whose top is at y = 0 under the cube's centre.
    let shapes = [
        ColliderShape::Box {
            min: Point::new(-1.0, -0.5, -1.0),
            max: Point::new(1.0, 0.0, 1.0),
        },
        ColliderShape::Sphere {
            center: Point::new(SIDE / 2.0, -1.0, SIDE / 2.0),
            radius: 1.0,
        },
    ];
    for shape in shapes {
        let collider = Collider {
            shape: shape.clone(),
            friction: 0.8,
            restitution: 0.0,
        };
        let mut sim = simulation(
            cube(SIDE, CELLS, 1e5, 0.1),
            Box::new(BackwardEuler),
            Box::new(NoDamping),
            settings(0.005, 20, Point::new(0.0, -9.81, 0.0)),
            ContactSettings {
                colliders: vec![collider],
                thickness,
            },
        );
        let stats = sim.run(600).unwrap();
        let last = stats.last().unwrap();
        assert!(last.contacts > 0, "{shape:?}");
        // As on the plane: what the iterations leave is below 1% of the
        // thickness, and the body is at rest after 3 s: kinetic energy below
        // 1e-6 J, of a drop worth 0.1 J (measured on the sphere, where the
        // cube rocks a while: 3e-8 J).
        assert!(last.penetration < 1e-5, "{shape:?}: {}", last.penetration);
        assert!(
            sim.energies().kinetic < 1e-6,
            "{shape:?}: {:?}",
            sim.energies()
        );
        // Nothing inside the thickened collider after the final projection.
        let (min_gap, _) = sim
            .state()
            .positions
            .iter()
            .fold((f64::INFINITY, 0), |acc, p| {
                let gap = match &shape {
                    ColliderShape::Box { .. } => p.y,
                    _ => (p - Point::new(SIDE / 2.0, -1.0, SIDE / 2.0)).norm() - 1.0,
                };
                (acc.0.min(gap), 0)
            });
        assert!(min_gap >= thickness - 1e-12, "{shape:?}: gap {min_gap}");
    }
}

/// A position solver that judges iterates by the step objective (which has
/// no contact term) is refused when colliders are on, with an error that
/// names it, and the state is left untouched; local-global steps.
#[test]
fn objective_judging_solvers_are_refused_with_colliders() {
    let make = || {
        simulation(
            cube(0.1, 2, 1e5, 0.0),
            Box::new(BackwardEuler),
            Box::new(NoDamping),
            settings(0.01, 10, Point::new(0.0, -9.81, 0.0)),
            on_floor(0.3, 0.0, 1e-3),
        )
    };
    let mut sim = make();
    let before = sim.state().positions.clone();
    sim.set_position_solver(Box::new(pd_solver::Anderson::new(5)));
    let e = sim.step().unwrap_err().to_string();
    assert!(e.contains("anderson") && e.contains("local-global"), "{e}");
    assert_eq!(sim.state().positions, before);
    assert!(make().step().is_ok());
}

/// A plane normal whose length overflows or underflows `f64` is still
/// made a unit vector (it used to become the zero vector, or be called
/// one); the zero vector is refused.
#[test]
fn a_plane_normal_of_extreme_entries_is_made_unit() {
    // A resting cube and one plane through the origin with `normal`.
    let set = |normal: Point| {
        let mut sim = Simulation::new(
            cube(0.1, 1, 1e4, 0.5),
            Box::new(BackwardEuler),
            Box::new(NoDamping),
            Settings::default(),
        )
        .unwrap();
        let point = Point::zeros();
        let plane = Collider {
            shape: ColliderShape::Plane { point, normal },
            friction: 0.0,
            restitution: 0.0,
        };
        let contact = ContactSettings {
            colliders: vec![plane],
            thickness: 0.0,
        };
        sim.set_contact(contact).map(|()| sim)
    };
    for (normal, expected) in [
        (
            Point::new(0.0, 1e300, 1e300),
            Point::new(0.0, 1.0, 1.0).normalize(),
        ),
        (Point::new(0.0, 1e-320, 0.0), Point::y()),
        (Point::new(0.0, 2.0, 0.0), Point::y()),
    ] {
        let sim = set(normal).unwrap();
        let ColliderShape::Plane { normal: n, .. } = &sim.contact().unwrap().colliders[0].shape
        else {
            panic!("not a plane");
        };
        // One rounding in each division and in the square root: ulps.
        assert!((n - expected).norm() < 4.0 * f64::EPSILON, "{normal}: {n}");
    }
    let error = set(Point::zeros()).unwrap_err().to_string();
    assert!(error.contains("zero vector"), "{error}");
}
