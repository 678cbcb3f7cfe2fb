//! Energy laws on quadratic, convex energies (zero-rest-length springs, hard
//! pins, attachments, gravity), over random small scenes, masses, stiffnesses, time steps
//! and damping models.
//!
//! With zero-rest-length springs every projection is 0 (`L0 d/|d|` with
//! `L0 = 0`), so the global step is the exact minimiser after any number of
//! iterations: each step is solved to convergence. Write `E` for the total
//! energy (kinetic + springs + gravity) and `f = -grad E_pot`, linear in `x`.
//!
//! - **Backward Euler** (`M (v1 - v0)/h = f(x1) - D v1`, `x1 = x0 + h v1`):
//!   for a quadratic potential
//!   `E_pot(x1) - E_pot(x0) = -f(x1).(x1 - x0) - 1/2 |x1 - x0|_L^2`, and
//!   `1/2|v1|_M^2 - 1/2|v0|_M^2 = v1^T M (v1 - v0) - 1/2 |v1 - v0|_M^2`, so
//!   `E1 - E0 = -h v1^T D v1 - 1/2 |v1 - v0|_M^2 - 1/2 |x1 - x0|_L^2 <= 0`
//!   for every PSD `D`. The explicit filters (ether drag, PBD) only lower
//!   the kinetic energy afterwards (`prop_velocity_filters.rs`), so energy
//!   never increases for every dissipative model. The rotation-preserving
//!   Laplacian variant is left out: it gives a free body back spin, which can
//!   add kinetic energy, and theory promises no sign.
//! - **Implicit midpoint** (`x1 - x0 = h v_mid`, `M (v1 - v0)/h =
//!   f(x_mid) - D v_mid`): for a quadratic potential
//!   `E_pot(x1) - E_pot(x0) = -f(x_mid).(x1 - x0)` exactly, and
//!   `1/2|v1|_M^2 - 1/2|v0|_M^2 = v_mid^T M (v1 - v0)`, so
//!   `E1 - E0 = -h v_mid^T D v_mid`: exact conservation without damping, and
//!   exactly that loss with a constant (or lagged, here constant) `D`.
//! - BDF-2 has no per-step energy guarantee; its law, G-stability, is
//!   checked in `prop_bdf2_stability.rs`.
//!
//! Round-off bound, per step: the computed `x1` satisfies the step's
//! equations up to a residual `rho` per row of about `u (|A| |x|)_i`
//! (Cholesky backward error), which adds `h v1 . rho` to the identities
//! above; with `|A|_inf <= m_max (1/h^2 + a1/h) + |L| (1 + a2/h)` that is at
//! most `n u h V |A| X` (`V`, `X` the largest velocity and position
//! coordinate). Evaluating the energies rounds each of `n` terms by `n u`
//! of their absolute sum. A factor 16 covers the constants of the bounds,
//! as in `damped_momentum.rs`.

mod common;
mod prop_common;

use common::{U, laplacian_norm};
use pd_integrators::{BackwardEuler, ImplicitMidpoint, Integrator};
use pd_mesh::Point;
use pd_solver::{Model, Simulation, State};
use prop_common::{DampingChoice, Material, Scene, config, damping, max_norm, scene, settings};
use proptest::prelude::*;

const STEPS: usize = 6;

/// One step's energies and the scales of its round-off bound.
struct StepRecord {
    before: f64,
    after: f64,
    /// `h v_mid^T D v_mid` in J (implicit midpoint's predicted loss).
    midpoint_loss: f64,
    tolerance: f64,
}

/// `v^T L_d v` for the springs of `model`'s bodies: `sum_e w |v_j - v_i|^2`.
fn spring_quadratic_form(model: &Model, stiffness: f64, v: &[Point]) -> f64 {
    model
        .bodies()
        .iter()
        .flat_map(|b| {
            b.mesh
                .edges()
                .iter()
                .map(move |e| (e[0] + b.offset, e[1] + b.offset))
        })
        .map(|(i, j)| stiffness * (v[j] - v[i]).norm_squared())
        .sum()
}

fn absolute_energy(sim: &Simulation) -> f64 {
    let e = sim.energies();
    e.kinetic.abs() + e.elastic.abs() + e.gravity.abs()
}

/// Runs [`STEPS`] steps and records each step's energy change.
#[allow(clippy::too_many_arguments)]
fn run(
    scene: &Scene,
    integrator: Box<dyn Integrator>,
    choice: DampingChoice,
    pinned: bool,
    attached: bool,
    gravity: bool,
    dt: f64,
    iterations: usize,
) -> Result<Vec<StepRecord>, TestCaseError> {
    let mut model = scene.model(Material::ZeroLengthSprings, pinned);
    if attached {
        // The first body's last vertex, softly held at its rest position: a
        // zero-rest-length spring to a fixed point, quadratic and convex.
        let last = model.bodies()[0].vertices().len() - 1;
        model
            .add_attachments(pd_solver::BodyId(0), &[last], 0.5 * scene.stiffness)
            .unwrap();
    }
    let n = model.num_vertices();
    let max_mass = model.masses().iter().copied().fold(0.0, f64::max);
    let laplacian = laplacian_norm(&model);
    let damping = choice.create();
    let d = damping.implicit_matrix();
    let matrix_bound = max_mass * (1.0 / (dt * dt) + d.mass / dt)
        + laplacian * (1.0 + (d.damping_laplacian + d.lagged_stiffness) / dt);
    let mut sim = Simulation::new(
        model,
        integrator,
        damping,
        settings(dt, iterations, gravity),
    )
    .unwrap();
    let positions = sim.state().positions.clone();
    sim.set_state(State {
        positions,
        velocities: scene.initial_velocities(n),
    })
    .unwrap();
    let masses = sim.model().masses().to_vec();
    let mut records = Vec::new();
    for step in 1..=STEPS {
        let before = sim.energies().total();
        let absolute_before = absolute_energy(&sim);
        let x0 = sim.state().positions.clone();
        let v0 = sim.state().velocities.clone();
        sim.step()
            .map_err(|e| TestCaseError::fail(format!("step {step}: {e}")))?;
        let after = sim.energies().total();
        let v1 = &sim.state().velocities;
        let v_mid: Vec<Point> = v0.iter().zip(v1).map(|(a, b)| (a + b) * 0.5).collect();
        let mass_form: f64 = masses
            .iter()
            .zip(&v_mid)
            .map(|(m, v)| m * v.norm_squared())
            .sum();
        let midpoint_loss = dt
            * (d.mass * mass_form
                + (d.damping_laplacian + d.lagged_stiffness)
                    * spring_quadratic_form(sim.model(), scene.stiffness, &v_mid));
        let speed = max_norm(&v0).max(max_norm(v1));
        let extent = max_norm(&x0).max(max_norm(&sim.state().positions)) + dt * speed;
        let tolerance = 16.0
            * U
            * n as f64
            * (n as f64 * dt * speed * matrix_bound * extent
                + absolute_before
                + absolute_energy(&sim));
        records.push(StepRecord {
            before,
            after,
            midpoint_loss,
            tolerance,
        });
    }
    Ok(records)
}

fn dissipative_damping() -> impl Strategy<Value = DampingChoice> {
    damping(1.0).prop_filter("the rotation-preserving variant has no energy sign", |c| {
        !matches!(
            c,
            DampingChoice::Laplacian {
                preserve_rotation: true,
                ..
            }
        )
    })
}

fn matrix_damping() -> impl Strategy<Value = DampingChoice> {
    damping(1.0).prop_filter("only matrix models have the exact midpoint balance", |c| {
        c.is_matrix_only()
    })
}

proptest! {
    #![proptest_config(config(24))]

    #[test]
    fn backward_euler_never_increases_energy(
        scene in scene(1e0..1e4, 3.0),
        choice in dissipative_damping(),
        pinned: bool,
        attached: bool,
        gravity: bool,
        dt in 1e-4..0.1f64,
        iterations in 1usize..=4,
    ) {
        let records = run(&scene, Box::new(BackwardEuler), choice, pinned, attached, gravity, dt, iterations)?;
        for (step, r) in records.iter().enumerate() {
            prop_assert!(
                r.after <= r.before + r.tolerance,
                "step {}: energy rose from {:e} to {:e} J (by {:e} > {:e})",
                step + 1, r.before, r.after, r.after - r.before, r.tolerance
            );
        }
    }

    #[test]
    fn implicit_midpoint_loses_exactly_the_damping_work(
        scene in scene(1e0..1e4, 3.0),
        choice in matrix_damping(),
        pinned: bool,
        attached: bool,
        gravity: bool,
        dt in 1e-4..0.1f64,
        iterations in 1usize..=4,
    ) {
        let records = run(&scene, Box::new(ImplicitMidpoint), choice, pinned, attached, gravity, dt, iterations)?;
        for (step, r) in records.iter().enumerate() {
            let change = r.after - r.before;
            prop_assert!(
                (change + r.midpoint_loss).abs() <= r.tolerance,
                "step {}: energy changed by {:e} J, predicted {:e} J (tolerance {:e})",
                step + 1, change, -r.midpoint_loss, r.tolerance
            );
        }
    }
}

fn control_scene() -> Scene {
    Scene {
        shape: prop_common::Shape::Box { cells: [2, 1, 1] },
        seed: 5,
        stiffness: 500.0,
        masses: (0..27).map(|i| 0.2 + 0.05 * i as f64).collect(),
        velocities: (0..27)
            .map(|i| {
                let t = i as f64;
                Point::new((0.9 * t).sin(), (1.7 * t).cos(), 0.3 - 0.02 * t)
            })
            .collect(),
    }
}

#[test]
fn controls_fail_the_same_checks() {
    // Backward Euler loses energy numerically (about h omega / 2 per unit
    // time and mode): the exact-balance check must fail for it, and it
    // must pass for implicit midpoint on the same scene.
    let scene = control_scene();
    let balance_error = |integrator: Box<dyn Integrator>| -> f64 {
        let records = run(
            &scene,
            integrator,
            DampingChoice::None,
            false,
            false,
            true,
            0.02,
            1,
        )
        .unwrap();
        records
            .iter()
            .map(|r| (r.after - r.before).abs() / r.tolerance)
            .fold(0.0, f64::max)
    };
    assert!(balance_error(Box::new(ImplicitMidpoint)) <= 1.0);
    assert!(balance_error(Box::new(BackwardEuler)) > 1e3);
    // Predicting no loss under Laplacian damping fails for implicit midpoint.
    let damped = DampingChoice::Laplacian {
        stiffness: 0.05,
        mass: 0.0,
        preserve_rotation: false,
    };
    let records = run(
        &scene,
        Box::new(ImplicitMidpoint),
        damped,
        false,
        false,
        true,
        0.02,
        1,
    )
    .unwrap();
    assert!(
        records
            .iter()
            .any(|r| (r.after - r.before).abs() > 1e3 * r.tolerance)
    );
    assert!(
        records
            .iter()
            .all(|r| (r.after - r.before + r.midpoint_loss).abs() <= r.tolerance)
    );
}
