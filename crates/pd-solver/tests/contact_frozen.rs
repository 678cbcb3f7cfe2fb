//! `Simulation::freeze_contact_forces`, the measurement aid of
//! docs/design/contact.md ("Contact's own cost"): frozen forces hold a resting
//! body up as a constant load, contact reports nothing while frozen, and
//! runs again once unfrozen.

mod common;

use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::{Point, generators};
use pd_solver::contact::ContactSettings;
use pd_solver::{Model, Settings, Simulation};

const DT: f64 = 0.01;
const G: f64 = 9.81;

/// A 0.1 m cube, 2 cells per side, 1000 kg/m^3, 1e5 Pa, resting on a
/// frictional floor after 150 steps (backward Euler damps it to rest).
fn resting_cube() -> Simulation {
    // The generated box spans [0, 0.1]^3: its lowest face is centred at
    // (0.05, 0, 0.05), so this lifts it by 2 mm and nothing else.
    let mut model = Model::new();
    common::add_cube(&mut model, 0.1, 2, 1e5, Point::new(0.05, 0.002, 0.05));
    let settings = Settings {
        dt: DT,
        iterations: 20,
        gravity: Point::new(0.0, -G, 0.0),
        ..Settings::default()
    };
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings,
    )
    .unwrap();
    sim.set_contact(ContactSettings {
        colliders: vec![common::floor(0.5)],
        thickness: 0.001,
    })
    .unwrap();
    sim.run(150).unwrap();
    sim
}

fn centre_height(sim: &Simulation) -> f64 {
    let p = &sim.state().positions;
    p.iter().map(|x| x.y).sum::<f64>() / p.len() as f64
}

#[test]
fn frozen_forces_hold_a_resting_body_and_contact_resumes() {
    let mut sim = resting_cube();
    let start = centre_height(&sim);
    assert!(sim.freeze_contact_forces(true));
    let steps = 10;
    for stats in sim.run(steps).unwrap() {
        assert_eq!(stats.contacts, 0, "frozen contact reports no contacts");
    }
    // Without the frozen load the cube falls freely: g t^2 / 2 = 49 mm over
    // 0.1 s (backward Euler's discrete fall is a little more). The frozen
    // forces balance the weight up to the last iteration's Uzawa residual
    // (measured: 7e-17 m moved, the cube being at rest): a drop below a
    // tenth of free fall shows they are applied.
    let free_fall = 0.5 * G * (steps as f64 * DT).powi(2);
    let drop = start - centre_height(&sim);
    assert!(
        drop.abs() < 0.1 * free_fall,
        "moved {drop:e} m against a free fall of {free_fall:e} m"
    );
    assert!(sim.freeze_contact_forces(false));
    let stats = sim.step().unwrap();
    assert!(stats.contacts > 0, "contact runs again once unfrozen");
}

#[test]
fn freezing_without_contact_does_nothing() {
    let mesh = generators::box_tets([0.1; 3], [1; 3]).unwrap();
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    model.add_body(mesh, masses).unwrap();
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap();
    assert!(!sim.freeze_contact_forces(true));
    assert!(sim.contact().is_none());
}
