//! Checkpoint and resume with contact between surfaces (docs/design/contact.md,
//! "Checkpoints"): a run of `N` steps and a run of `N / 2` steps,
//! checkpoint, a fresh simulation restored from it and `N / 2` more steps
//! end bit for bit alike (positions, velocities, integrator history and
//! the active contacts with their forces), with self-contact of a cloth
//! folding onto itself and with contact between bodies (with and without
//! self-contact). Each test also restores the checkpoint with its contacts
//! left out and requires a different end: the contacts it carries matter,
//! so the comparison can fail.

mod common;

use common::{floor, stacked_cubes};
use pd_damping::NoDamping;
use pd_integrators::{BackwardEuler, Bdf2, Integrator};
use pd_mesh::{Point, generators};
use pd_solver::contact::{BodyContactSettings, ContactCheckpoint, ContactSettings, SurfacePairs};
use pd_solver::{Checkpoint, Model, Settings, Simulation};

/// Runs `build()` for `n` steps straight, and for `n / 2` steps,
/// checkpoint, restore into a fresh `build()`, `n - n / 2` steps; requires
/// the two ends to be identical bit for bit, and returns the checkpoint.
/// Also resumes from the checkpoint without its contacts and requires a
/// different end.
fn resumes_bit_for_bit(build: impl Fn() -> Simulation, n: usize) -> Checkpoint {
    let mut straight = build();
    straight.run(n).unwrap();

    let mut first = build();
    first.run(n / 2).unwrap();
    let saved = first.checkpoint();
    let mut resumed = build();
    resumed.restore(&saved).unwrap();
    resumed.run(n - n / 2).unwrap();

    assert_eq!(resumed.state().positions, straight.state().positions);
    assert_eq!(resumed.state().velocities, straight.state().velocities);
    assert_eq!(resumed.time().to_bits(), straight.time().to_bits());
    // The whole checkpoint: steps, history, divergence reference and the
    // active contacts with their warm-started forces and normals.
    assert_eq!(resumed.checkpoint(), straight.checkpoint());

    // Not vacuous: the same resume without the contacts ends elsewhere.
    let mut forgetful = build();
    forgetful
        .restore(&Checkpoint {
            contact: ContactCheckpoint::default(),
            ..saved.clone()
        })
        .unwrap();
    forgetful.run(n - n / 2).unwrap();
    assert_ne!(forgetful.state().positions, straight.state().positions);
    saved
}

/// Both scenes' settings: 5 ms steps, 20 iterations, gravity, one thread.
fn settings() -> Settings {
    Settings {
        dt: 0.005,
        iterations: 20,
        gravity: Point::new(0.0, -9.81, 0.0),
        threads: 1,
        ..Settings::default()
    }
}

/// A 0.6 m cotton-like sheet (16 x 16 cells; 0.2 kg/m^2, membrane 5e3
/// N/m, bending 1e-4 N m) lying in the xz plane, its left half fixed,
/// its right half thrown up and over the left about the middle line (15
/// rad/s, 4.5 m/s at the edge); gravity lays it onto the fixed half. Self-contact only, 2 mm
/// thickness, backward Euler, 20 iterations, 5 ms steps.
fn folding_sheet() -> Simulation {
    let mesh = generators::cloth([0.6, 0.6], [16, 16])
        .unwrap()
        .translated(Point::new(-0.3, 0.0, -0.3));
    let rest = mesh.vertices().to_vec();
    let masses = mesh.lumped_masses(0.2).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_triangle_strain(body, 5.0e3, None).unwrap();
    model.add_bending(body, 1.0e-4).unwrap();
    let fixed: Vec<usize> = (0..rest.len()).filter(|&v| rest[v].x < -1e-9).collect();
    model.fix_vertices(body, &fixed).unwrap();
    let settings = settings();
    let mut sim = Simulation::new(
        model,
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings,
    )
    .unwrap();
    sim.set_contact(ContactSettings {
        colliders: Vec::new(),
        thickness: 0.002,
    })
    .unwrap();
    let pairs = SurfacePairs {
        between_bodies: false,
        self_contact: true,
    };
    sim.set_surface_contact(BodyContactSettings { friction: 0.3 }, pairs)
        .unwrap();
    // A rotation about the middle line (the z axis): up, then over.
    let velocities = rest
        .iter()
        .map(|p| {
            if p.x > 1e-9 {
                Point::new(-p.y, p.x, 0.0) * 15.0
            } else {
                Point::zeros()
            }
        })
        .collect();
    sim.set_state(pd_solver::State {
        positions: rest,
        velocities,
    })
    .unwrap();
    sim
}

#[test]
fn a_cloth_folding_onto_itself_resumes_bit_for_bit() {
    let saved = resumes_bit_for_bit(folding_sheet, 120);
    // The checkpoint falls while the fold presses onto the fixed half.
    println!(
        "self-contact pairs at the checkpoint: {}",
        saved.contact.pairs.len()
    );
    assert!(!saved.contact.pairs.is_empty());
}

/// A 0.1 m cube (2 cells, 1e5 Pa) dropped 5 cm onto a 0.2 m cube (3
/// cells) resting on the floor, 2 cm off-centre (`contact_bodies.rs`),
/// BDF-2 (a history to carry), `pairs` between the surfaces.
fn stack(pairs: SurfacePairs) -> Simulation {
    let model = stacked_cubes(0.001);
    let settings = settings();
    let integrator: Box<dyn Integrator> = Box::new(Bdf2::new());
    let mut sim = Simulation::new(model, integrator, Box::new(NoDamping), settings).unwrap();
    sim.set_contact(ContactSettings {
        colliders: vec![floor(0.5)],
        thickness: 0.001,
    })
    .unwrap();
    sim.set_surface_contact(BodyContactSettings { friction: 0.5 }, pairs)
        .unwrap();
    sim
}

#[test]
fn stacked_bodies_resume_bit_for_bit_with_and_without_self_contact() {
    for self_contact in [false, true] {
        let pairs = SurfacePairs {
            between_bodies: true,
            self_contact,
        };
        // The top lands at about step 20; step 30 is mid-settling.
        let saved = resumes_bit_for_bit(|| stack(pairs), 60);
        println!(
            "self = {self_contact}: {} pairs, {} collider contacts at the checkpoint",
            saved.contact.pairs.len(),
            saved.contact.colliders.len()
        );
        assert!(!saved.contact.pairs.is_empty());
        assert!(!saved.contact.colliders.is_empty());
    }
}
