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

#[test]
fn explore_slope() {
    let g = 9.81;
    for (theta_deg, mu) in [(30.0_f64, 0.3), (20.0, 0.5)] {
        let theta = theta_deg.to_radians();
        for (name, integrator) in integrators() {
            let settings = Settings {
                dt: 0.005,
                iterations: 20,
                gravity: Point::new(g * theta.sin(), -g * theta.cos(), 0.0),
                ..Settings::default()
            };
            let contact = ContactSettings {
                colliders: vec![floor(mu, 0.0)],
                thickness: 0.001,
            };
            let mut sim = simulation(
                cube(0.1, 2, 1e6, 0.001),
                integrator,
                Box::new(NoDamping),
                settings,
                contact,
            );
            let stats = sim.run(100).unwrap();
            let v0 = centre_velocity(&sim);
            let stats2 = sim.run(100).unwrap();
            let v1 = centre_velocity(&sim);
            let a = (v1.x - v0.x) / (100.0 * 0.005);
            let expected = (g * (theta.sin() - mu * theta.cos())).max(0.0);
            println!(
                "{theta_deg} {mu} {name}: a {a:.5} expected {expected:.5} vy {:.2e} contacts {} pen {:.2e} {:.2e}",
                v1.y,
                stats2.last().unwrap().contacts,
                stats2.last().unwrap().penetration,
                stats.iter().map(|s| s.penetration).fold(0.0, f64::max)
            );
        }
    }
}
