//! The PD objective never increases from one local-global iteration to the
//! next, for every integrator and damping model, over random scenes
//! (nonconvex corotational strain and rest-length springs, or zero-length
//! springs), pins, gravity, masses, velocities, time steps and iteration
//! counts.
//!
//! Why (docs/design/formulation.md, "The objective never increases"):
//! with projections `p` the step minimises the
//! surrogate `G(x, p) = 1/(2h^2)|x - y|_M^2 + c1 sum w/2 |G_i (c2 x + z) -
//! p_i|^2 + Phi(x)`, and `g(x) = min_p G(x, p)` over the constraint sets.
//! The local step picks that minimising `p_k` at `x_k`, so
//! `g(x_k) = G(x_k, p_k)`; the global step minimises `G(., p_k)` exactly,
//! so `G(x_{k+1}, p_k) <= G(x_k, p_k)`; and `g(x_{k+1}) <= G(x_{k+1}, p_k)`.
//! This holds for nonconvex constraint sets too, and for every damping
//! term, which only adds the fixed PSD quadratic `Phi` (a lagged `K(x_n)`
//! is fixed within the step; the explicit filters act after it).
//!
//! The objective is recorded by the solver (`Simulation::record_objective`),
//! from the formula of docs/design/formulation.md, "The step objective",
//! rather than from the right-hand
//! side the step assembles, so a mismatch between the two would show as an
//! increase.
//!
//! Round-off: `x - y` is a difference of absolute positions, so the inertia
//! term `m/(2h^2)|x - y|^2` rounds by about `m/h^2 |x - y| u |x|` per
//! vertex, the same for `Phi`'s `x - x_hat` with weight `c1 c2 gamma |D|`;
//! the energies and sums round by `n u` of their (non-negative) totals, and
//! the global solve's error `delta` raises `G` only to second order (it is
//! at its minimum). A factor 64 covers the constants.

mod common;
mod prop_common;

use common::{SCHEMES, U, laplacian_norm};
use pd_mesh::Point;
use pd_solver::{Simulation, State};
use prop_common::{DampingChoice, Material, Scene, config, damping, max_norm, scene, settings};
use proptest::prelude::*;

const STEPS: usize = 4;

/// Runs `STEPS` steps recording the objective; returns the largest
/// increase between successive iterations over its tolerance.
#[allow(clippy::too_many_arguments)]
fn worst_increase(
    scene: &Scene,
    material: Material,
    scheme: common::Scheme,
    choice: DampingChoice,
    pinned: bool,
    gravity: bool,
    dt: f64,
    iterations: usize,
) -> Result<f64, TestCaseError> {
    let model = scene.model(material, pinned);
    let n = model.num_vertices();
    let laplacian = laplacian_norm(&model);
    let damping = choice.create();
    let d = damping.implicit_matrix();
    let mut sim = Simulation::new(
        model,
        scheme.integrator(),
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
    sim.record_objective(true);
    let max_mass = sim.model().masses().iter().copied().fold(0.0, f64::max);
    let mut worst = 0.0f64;
    for step in 1..=STEPS {
        let x0 = max_norm(&sim.state().positions);
        let v0 = max_norm(&sim.state().velocities);
        sim.step()
            .map_err(|e| TestCaseError::fail(format!("{scheme:?} step {step}: {e}")))?;
        let trace = sim.objective_trace().unwrap();
        prop_assert_eq!(trace.len(), iterations + 1);
        // Scale of the differences of positions: |x| and |x - y| are below
        // the extent of the step's positions plus what the step moved.
        let extent = x0.max(max_norm(&sim.state().positions)) + dt * (v0 + 10.0);
        let spread = 2.0 * extent;
        let weight = max_mass * (1.0 / (dt * dt) + d.mass / dt)
            + laplacian * (1.0 + (d.damping_laplacian + d.lagged_stiffness) / dt);
        for pair in trace.windows(2) {
            let tolerance = 64.0 * U * n as f64 * (pair[0].abs() + weight * spread * extent);
            worst = worst.max((pair[1] - pair[0]) / tolerance);
        }
    }
    Ok(worst)
}

fn material() -> impl Strategy<Value = Material> {
    prop_oneof![Just(Material::Elastic), Just(Material::ZeroLengthSprings)]
}

proptest! {
    #![proptest_config(config(24))]

    #[test]
    fn objective_never_increases_between_iterations(
        scene in scene(1e1..1e5, 2.0),
        material in material(),
        choice in damping(0.1),
        pinned: bool,
        gravity: bool,
        dt in 1e-3..0.05f64,
        iterations in 1usize..=12,
    ) {
        for scheme in SCHEMES {
            let ratio = worst_increase(&scene, material, scheme, choice, pinned, gravity, dt, iterations)?;
            prop_assert!(ratio <= 1.0, "{scheme:?}: an increase {ratio} times its tolerance");
        }
    }
}

#[test]
fn trace_is_off_by_default_and_decreases_visibly() {
    let scene = Scene {
        shape: prop_common::Shape::Box { cells: [2, 1, 1] },
        seed: 4,
        stiffness: 1e4,
        masses: vec![0.5; 27],
        velocities: (0..27)
            .map(|i| Point::new(0.0, -(i as f64) * 0.3, 0.1))
            .collect(),
    };
    let model = scene.model(Material::Elastic, true);
    let mut sim = Simulation::new(
        model,
        common::Scheme::BackwardEuler.integrator(),
        DampingChoice::None.create(),
        settings(0.02, 10, true),
    )
    .unwrap();
    sim.step().unwrap();
    assert!(sim.objective_trace().is_none());
    sim.record_objective(true);
    sim.step().unwrap();
    // The control: the trace falls by far more than the tolerance, so the
    // check compares real changes, not round-off.
    let trace = sim.objective_trace().unwrap();
    assert!(trace[0] - trace[10] > 1e-6 * trace[0], "{trace:?}");
}
