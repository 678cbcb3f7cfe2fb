//! What a user of the rotation-preserving Laplacian variant sees (issue 13):
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

fn kinetic(sim: &Simulation) -> f64 {
    sim.energies().kinetic
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

/// Regression pin on a partial fix, not the property the issue asks for.
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
/// in docs/damping.md. The bound 0.6 x the plain model's gap fails on the
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
    sim.add_rigid_velocity(0, Point::zeros(), Point::new(0.0, 0.0, 4.0));
    sim
}

/// BDF-2: the `L_d` anchor follows the rigid rotation through BDF-2's own
/// damping velocity `x - (4 x_n - x_{n-1}) / 3` (the integrator's damping
/// stencil), so a rigidly spinning stiff block (1e9 Pa: centrifugal strain
/// near 1e-8) feels almost no damping. Before, with the one-step shift
/// `R(omega / gamma)`, it ended with 2.2% more kinetic energy than without
/// damping (issue 13). What remains is stated, not hidden: the restoration
/// keeps the spin exactly (to round-off), while undamped BDF-2 loses 0.20% of
/// it in 100 steps by its own numerical damping of the rotation, so the
/// variant keeps that much more spin, 0.4% more rotational energy, and
/// measured 0.69% more kinetic energy in all. The bound 1% sits between the
/// measured residual and the old 2.2%.
#[test]
fn bdf2_rigid_spin_is_kept_and_barely_damped() {
    let mut none = spinning_block(Box::new(Bdf2::new()), Box::new(NoDamping), 1e9);
    let mut variant = spinning_block(
        Box::new(Bdf2::new()),
        Box::new(LaplacianDamping::new(0.01, 0.0, true).unwrap()),
        1e9,
    );
    let j0 = spin_of(&variant).z;
    none.run(100).unwrap();
    variant.run(100).unwrap();
    // Restored exactly each step: round-off of 100 rigid fits (1e-14 each).
    assert!((spin_of(&variant).z / j0 - 1.0).abs() < 1e-11);
    let excess = kinetic(&variant) / kinetic(&none) - 1.0;
    assert!(excess.abs() < 0.01, "kinetic energy excess {excess:.3e}");
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
