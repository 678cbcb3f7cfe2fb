//! The divergence check watches the elastic energy too: a run
//! whose mesh tangles while its velocities stay moderate must stop with an
//! error naming the step and the most strained element, not complete.
//!
//! The scene is the one a user reported: a 1 x 0.2 x 0.2 m box of 10 x 2 x 2
//! cells, density 1 kg/m^3, corotational strain 1e12 Pa, `dt = 0.5 s`,
//! implicit midpoint with 2 iterations, no damping, thrown at 1000 m/s and
//! spun at 500 rad/s. Before the check covered elastic energy this run
//! completed while its elastic energy climbed from 0 to 1.9e12 J in four
//! steps (the body starts with about 2e4 J).

use pd_damping::NoDamping;
use pd_integrators::ImplicitMidpoint;
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation, SolverError};

fn thrown_stiff_box() -> Simulation {
    let mesh = generators::box_tets([1.0, 0.2, 0.2], [10, 2, 2]).unwrap();
    let masses = mesh.lumped_masses(1.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e12, None).unwrap();
    let settings = Settings {
        dt: 0.5,
        iterations: 2,
        ..Settings::default()
    };
    let mut sim = Simulation::new(
        model,
        Box::new(ImplicitMidpoint),
        Box::new(NoDamping),
        settings,
    )
    .unwrap();
    sim.add_rigid_velocity(0, Point::new(1000.0, 0.0, 0.0), Point::new(0.0, 0.0, 500.0))
        .unwrap();
    sim
}

#[test]
fn a_tangling_mesh_stops_the_run_naming_step_and_element() {
    let mut sim = thrown_stiff_box();
    let initial = sim.energies().total();
    let limit = initial + sim.settings().divergence_energy_factor * sim.energy_scale();
    for _ in 0..20 {
        match sim.step() {
            Ok(_) => {
                // A step that passed the check must really be below its
                // bound: the exact energy, projection included.
                let total = sim.energies().total();
                assert!(
                    total <= limit,
                    "step {} completed with total energy {total:e} J above the divergence \
                     bound {limit:e} J",
                    sim.steps()
                );
            }
            Err(SolverError::Diverged { step, reason, .. }) => {
                assert_eq!(step, sim.steps() + 1, "the error names the failing step");
                assert!(reason.contains("elastic"), "{reason}");
                assert!(reason.contains("tet-strain constraint"), "{reason}");
                assert!(reason.contains("vertices ["), "{reason}");
                return;
            }
            Err(other) => panic!("unexpected error {other}"),
        }
    }
    // Twenty steps of 0.5 s at 1e12 Pa with two iterations: if the run never
    // diverged, its energy stayed below the bound at every step (checked
    // above), which is the other acceptable outcome.
}

#[test]
fn the_bound_never_stops_a_sane_run() {
    // A soft beam sagging under gravity with one iteration per step: the
    // projections of the last local step are far from those of the final
    // positions, so the elastic bound is loose; the exact fallback must keep
    // the run going.
    let mesh = generators::box_tets([1.0, 0.2, 0.2], [10, 2, 2]).unwrap();
    let clamp: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&v| mesh.vertices()[v].x < 1e-9)
        .collect();
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e5, None).unwrap();
    model.fix_vertices(body, &clamp).unwrap();
    let settings = Settings {
        dt: 0.02,
        iterations: 1,
        ..Settings::default()
    };
    let mut sim = Simulation::new(
        model,
        Box::new(ImplicitMidpoint),
        Box::new(NoDamping),
        settings,
    )
    .unwrap();
    sim.run(100).unwrap();
}
