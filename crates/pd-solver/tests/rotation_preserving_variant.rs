//! What a user of the rotation-preserving Laplacian variant sees:
//! it damps the strain rate and leaves the rigid motion of free bodies alone,
//! exactly for each integrator; bodies held by attachments are not free; the
//! mass term `a1 M` still damps spin.

mod common;

use common::jittered_box;
use pd_damping::rigid::RigidFit;
use pd_damping::{Damping, LaplacianDamping, NoDamping};
use pd_integrators::{Bdf2, ImplicitMidpoint, Integrator};
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation};

fn spin_of(sim: &Simulation) -> Point {
    let s = sim.state();
    let all: Vec<usize> = (0..s.positions.len()).collect();
    RigidFit::of(&all, sim.model().masses(), &s.positions, &s.velocities).angular_momentum
}

/// A 0.3 x 0.1 x 0.1 m block (density 1000 kg/m^3, corotational strain
/// `stiffness` Pa) lying horizontally with its corner at the origin held by
/// an attachment of 1e7 N/m: released, it swings down about that corner
/// like a pendulum.
fn pendulum(damping: Box<dyn Damping>) -> Simulation {
    let mesh = generators::box_tets([0.3, 0.1, 0.1], [6, 2, 2]).unwrap();
    let corner = (0..mesh.num_vertices())
        .min_by(|&a, &b| {
            let (pa, pb) = (mesh.vertices()[a], mesh.vertices()[b]);
            (pa.x + pa.y + pa.z).total_cmp(&(pb.x + pb.y + pb.z))
        })
        .unwrap();
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e7, None).unwrap();
    model.add_attachments(body, &[corner], 1e7).unwrap();
    let settings = Settings {
        dt: 0.005,
        iterations: 30,
        ..Settings::default()
    };
    Simulation::new(model, Box::new(ImplicitMidpoint), damping, settings).unwrap()
}

fn centre_of_mass(sim: &Simulation) -> Point {
    let s = sim.state();
    let masses = sim.model().masses();
    let total: f64 = masses.iter().sum();
    s.positions
        .iter()
        .zip(masses)
        .map(|(x, m)| x * *m)
        .sum::<Point>()
        / total
}

/// Regression pin on a partial fix, not the property the variant is for.
/// Before the fix, a body held by an attachment counted as free: its spin
/// was reset every step and the block did not swing at all (its centre of
/// mass 0.317 m from the undamped one's after 0.6 s, the whole swing, as with
/// plain Laplacian damping). Now the `L_d` anchor follows the rotation the
/// step predicts about the pivot: measured gap 0.167 m at a2 = 0.01 s,
/// 0.096 m at 1e-3 s, 0.026 m at 1e-4 s. It is not zero because the stiff
/// damping term (`a2 / (2h) L_d` here outweighs the inertia) makes the body
/// follow the predicted, explicit rotation rather than the implicit one; the
/// exact remedy (damping `(I - P)^T L_d (I - P)` with `P` the projection on
/// the rigid rotations, a rank-3 update of the prefactored system) is noted
/// in docs/design/damping.md. The bound 0.6 x the plain model's gap fails on the
/// old code (ratio 1.0) and holds now (0.53).
#[test]
fn a_body_hanging_from_an_attachment_swings_more_freely_than_with_plain_laplacian() {
    let mut undamped = pendulum(Box::new(NoDamping));
    let mut variant = pendulum(Box::new(LaplacianDamping::new(0.01, 0.0, true).unwrap()));
    let mut plain = pendulum(Box::new(LaplacianDamping::new(0.01, 0.0, false).unwrap()));
    let start = centre_of_mass(&undamped);
    undamped.run(120).unwrap();
    variant.run(120).unwrap();
    plain.run(120).unwrap();
    let reference = centre_of_mass(&undamped);
    let swing = (reference - start).norm();
    assert!(swing > 0.3, "the undamped block swings: {swing} m");
    let gap = (centre_of_mass(&variant) - reference).norm();
    let plain_gap = (centre_of_mass(&plain) - reference).norm();
    assert!(
        gap <= 0.6 * plain_gap,
        "variant gap {gap:.3e} m against plain Laplacian {plain_gap:.3e} m"
    );
}

/// A free block spinning at 3 rad/s about z (no gravity), corotational
/// strain `stiffness` Pa.
fn spinning_block(
    integrator: Box<dyn Integrator>,
    damping: Box<dyn Damping>,
    stiffness: f64,
) -> Simulation {
    let mesh = jittered_box([4, 2, 2], [0.4, 0.2, 0.2], 0.1, 5);
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, stiffness, None).unwrap();
    let settings = Settings {
        dt: 0.01,
        iterations: 50,
        tolerance: 1e-10,
        gravity: Point::zeros(),
        ..Settings::default()
    };
    let mut sim = Simulation::new(model, integrator, damping, settings).unwrap();
    sim.add_rigid_velocity(0, Point::zeros(), Point::new(0.0, 0.0, 4.0))
        .unwrap();
    sim
}

/// BDF-2: the variant moves the `L_d` anchor by the damping
/// velocity BDF-2 itself gives a rigid rotation (`x - (4 x_n - x_{n-1}) / 3`
/// on the rotating trajectory, the integrator's damping stencil). The old
/// shift, the rotation over `1 / gamma`, is exact for one-step methods only:
/// under BDF-2 it misses a centripetal term `(4/9) (h omega)^2 r` every step,
/// and on this stiff spinning block (1e9 Pa, h omega = 0.04) the damping
/// then strained the body to 18.4 J of elastic energy, seven times its
/// kinetic energy, total energy +726% after 1 s. Measured now: elastic
/// 6.1e-4 J, total +0.21%. What remains is stated: the restoration keeps the
/// spin exactly, including the 0.20% that undamped BDF-2 loses to its own
/// numerical damping of the rotation, so the energy ends slightly above the
/// start. Bounds: elastic below 1e-3 of the kinetic energy (measured 2.4e-4,
/// old 7.3), total energy within 0.5% of the start (measured +0.21%).
#[test]
fn bdf2_spin_is_kept_without_straining_the_body() {
    let mut variant = spinning_block(
        Box::new(Bdf2::new()),
        Box::new(LaplacianDamping::new(0.01, 0.0, true).unwrap()),
        1e9,
    );
    let j0 = spin_of(&variant).z;
    let e0 = variant.energies().total();
    variant.run(100).unwrap();
    // Restored every step: round-off of 100 rigid fits (1e-14 each).
    assert!((spin_of(&variant).z / j0 - 1.0).abs() < 1e-11);
    let energies = variant.energies();
    assert!(
        energies.elastic < 1e-3 * energies.kinetic,
        "elastic {:.3e} J, kinetic {:.3e} J",
        energies.elastic,
        energies.kinetic
    );
    let drift = energies.total() / e0 - 1.0;
    assert!(drift.abs() < 0.005, "energy drift {drift:.3e}");
}

#[test]
fn the_mass_term_still_damps_spin() {
    let a1 = 0.5;
    let mut variant = spinning_block(
        Box::new(ImplicitMidpoint),
        Box::new(LaplacianDamping::new(0.01, a1, true).unwrap()),
        1e7,
    );
    let j0 = spin_of(&variant).z;
    let steps = 50;
    variant.run(steps).unwrap();
    let h = 0.01;
    let factor: f64 = (1.0 - a1 * h / 2.0) / (1.0 + a1 * h / 2.0);
    let predicted = j0 * factor.powi(steps as i32);
    // Implicit midpoint solved to 1e-10 conserves the spin of a free body
    // up to the mass term, whose exact recurrence is `(1 - a1 h/2) / (1 +
    // a1 h/2)` per step (StepContext::mass_damping_factor). 1e-6 relative
    // leaves four orders for 50 steps of solver residual; measured 1e-8.
    // Before the fix the restoration gave back what a1 took: J stayed J0,
    // 28% above the prediction.
    let spin = spin_of(&variant).z;
    assert!(
        (spin / predicted - 1.0).abs() < 1e-6,
        "spin {spin:.9e}, predicted {predicted:.9e}"
    );
}

/// Deformation energy: elastic plus the kinetic energy of the velocities
/// minus their rigid fit (J).
fn deformation_energy(sim: &Simulation) -> f64 {
    let s = sim.state();
    let all: Vec<usize> = (0..s.positions.len()).collect();
    let masses = sim.model().masses();
    let motion = RigidFit::of(&all, masses, &s.positions, &s.velocities).motion();
    let kinetic: f64 = all
        .iter()
        .map(|&i| {
            0.5 * masses[i] * (s.velocities[i] - motion.velocity_at(&s.positions[i])).norm_squared()
        })
        .sum();
    kinetic + sim.energies().elastic
}

/// A free block (1e6 Pa, no gravity, implicit midpoint solved to 1e-10)
/// released from a 2% stretch along x, spinning about z at `spin` rad/s.
fn vibrating_block(damping: Box<dyn Damping>, spin: f64) -> Simulation {
    let mesh = jittered_box([4, 2, 2], [0.4, 0.2, 0.2], 0.1, 9);
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e6, None).unwrap();
    let settings = Settings {
        dt: 0.002,
        iterations: 100,
        tolerance: 1e-10,
        gravity: Point::zeros(),
        ..Settings::default()
    };
    let mut sim = Simulation::new(model, Box::new(ImplicitMidpoint), damping, settings).unwrap();
    let mut state = sim.state().clone();
    for x in &mut state.positions {
        x.x *= 1.02;
    }
    sim.set_state(state).unwrap();
    sim.add_rigid_velocity(0, Point::zeros(), Point::new(0.0, 0.0, spin))
        .unwrap();
    sim
}

/// What a user sees: a spinning, vibrating body keeps its spin
/// while its vibration decays as plain Laplacian damping makes a body that
/// does not spin decay. The spin (2 rad/s) is slow against the block's
/// lowest vibration (about 2 kHz), so the rotating frame's Coriolis and
/// centrifugal terms change the vibration by a relative amount of order
/// `spin / omega_vib` and `(spin / omega_vib)^2`, below 1e-3; the decay over
/// 0.2 s (the deformation energy falls by a factor of 15) must then agree
/// within 5%, a margin for the mode mixing the spin's coupling of x and y
/// causes (measured: 0.0659 against 0.0681, 3.2% apart).
#[test]
fn a_spinning_vibrating_body_keeps_its_spin_and_its_vibration_decays_as_without_spin() {
    let a2 = 2e-4;
    let mut variant = vibrating_block(Box::new(LaplacianDamping::new(a2, 0.0, true).unwrap()), 2.0);
    let mut still = vibrating_block(
        Box::new(LaplacianDamping::new(a2, 0.0, false).unwrap()),
        0.0,
    );
    let (j0, d0, s0) = (
        spin_of(&variant).z,
        deformation_energy(&variant),
        deformation_energy(&still),
    );
    variant.run(100).unwrap();
    still.run(100).unwrap();
    let kept = spin_of(&variant).z / j0;
    let (decay_spinning, decay_still) = (
        deformation_energy(&variant) / d0,
        deformation_energy(&still) / s0,
    );
    // Converged implicit midpoint keeps a free body's spin; the restoration
    // gives back what L_d took: round-off of 100 rigid fits.
    assert!((kept - 1.0).abs() < 1e-9, "spin kept {kept}");
    assert!(
        decay_still < 0.1,
        "plain Laplacian damping damps: {decay_still}"
    );
    assert!(
        (decay_spinning / decay_still - 1.0).abs() < 0.05,
        "decay with spin {decay_spinning:.4e}, without {decay_still:.4e}"
    );
}
