//! BDF-2's energy law: G-stability (Dahlquist 1978), over random small
//! scenes, masses, stiffnesses, time steps, attachments and implicit damping
//! models.
//!
//! BDF-2 has no per-step energy guarantee: the energy of one state can
//! rise. What it has is a norm over *pairs* of consecutive states that never
//! rises on a dissipative linear system. Write the scheme on `Y = (x, v)` as
//! `3/2 Y_{n+1} - 2 Y_n + 1/2 Y_{n-1} = h F(Y_{n+1})` with
//! `F(x, v) = (v, M^-1 (f(x) - D v))` (`docs/design/integrators.md`:
//! BDF-2 applies the same formula to positions and velocities, and its
//! damping velocity is the BDF velocity). With the energy inner product
//! `<Y, Z> = x^T L z_x + v^T M z_v`, `L` the Hessian of a quadratic
//! potential (zero-rest-length springs and attachments, gravity: affine
//! forces), the difference `d` of two trajectories of the same scene obeys
//! `<F(Y) - F(Z), Y - Z> = dv^T L dx - dv^T (L dx + D dv) = -dv^T D dv <= 0`.
//! The algebraic identity, for any symmetric bilinear form,
//!
//! `<3/2 a - 2 b + 1/2 c, a> = G(a, b) - G(b, c) + 1/4 |a - 2b + c|^2`,
//! `G(a, b) = 5/4 |a|^2 - <a, b> + 1/4 |b|^2`,
//!
//! with `a, b, c = d_{n+1}, d_n, d_{n-1}` then gives
//! `G(d_{n+1}, d_n) = G(d_n, d_{n-1}) - 1/4 |d_{n+1} - 2 d_n + d_{n-1}|^2
//! - h dv_{n+1}^T D dv_{n+1} <= G(d_n, d_{n-1})`
//! from the second step on (the first is BDF-2's backward-Euler start), for
//! every PSD `D`: the G-norm of the difference never rises. Zero-rest-length
//! springs have zero projections, so every step is solved exactly at any
//! iteration count. The velocity filters (explicit ether drag, PBD) are not
//! a matrix `D` and are left out, as is the rotation-preserving variant.
//!
//! Round-off bound, per step, as in `prop_energy.rs`: each run's step is
//! solved to a residual of about `u (|A| |x|)` per row, which moves `G` by
//! at most `n u h V |A| X` (`V`, `X` the largest velocity and position
//! coordinate of either run), and evaluating `G`'s sums rounds each of `n`
//! terms by `n u` of their absolute sum; a factor 16 covers the constants.
//!
//! The check fails on a scheme that is not BDF-2: with the velocity history
//! of the inertial target weighted `8.2 v_n - 2 v_{n-1}` instead of
//! `8 v_n - 2 v_{n-1}` (a 2.5% error in one coefficient), the first cases
//! find a G-norm that rises (by 0.75 against a tolerance of 1.5e-10).

mod common;
mod prop_common;

use common::{U, laplacian_norm};
use pd_integrators::Bdf2;
use pd_mesh::Point;
use pd_solver::{BodyId, Model, Simulation, State};
use prop_common::{DampingChoice, Material, Scene, config, damping, max_norm, scene, settings};
use proptest::prelude::*;

const STEPS: usize = 8;
const ATTACHMENT_STIFFNESS: f64 = 50.0;

/// The scene's model, with the last vertex of the first body softly
/// attached to its rest position when `attached`.
fn model(scene: &Scene, pinned: bool, attached: bool) -> Model {
    let mut model = scene.model(Material::ZeroLengthSprings, pinned);
    if attached {
        let last = model.bodies()[0].vertices().len() - 1;
        model
            .add_attachments(BodyId(0), &[last], ATTACHMENT_STIFFNESS)
            .unwrap();
    }
    model
}

/// `x^T L y` for the zero-rest-length springs of `stiffness` and the
/// attachment (`attached`) of `model`, and the same form with absolute
/// values (a scale for its round-off).
fn stiffness_form(
    model: &Model,
    stiffness: f64,
    attached: bool,
    x: &[Point],
    y: &[Point],
) -> (f64, f64) {
    let (mut form, mut scale) = (0.0, 0.0);
    for body in model.bodies() {
        for e in body.mesh.edges() {
            let (i, j) = (e[0] + body.offset, e[1] + body.offset);
            let term = stiffness * (x[j] - x[i]).dot(&(y[j] - y[i]));
            form += term;
            scale += term.abs();
        }
    }
    if attached {
        let last = model.bodies()[0].vertices().end - 1;
        let term = ATTACHMENT_STIFFNESS * x[last].dot(&y[last]);
        form += term;
        scale += term.abs();
    }
    (form, scale)
}

/// `<a, b>` of the energy inner product, and its absolute scale, for state
/// differences `a = (ax, av)`, `b = (bx, bv)`.
fn inner(
    model: &Model,
    stiffness: f64,
    attached: bool,
    a: (&[Point], &[Point]),
    b: (&[Point], &[Point]),
) -> (f64, f64) {
    let (potential, potential_scale) = stiffness_form(model, stiffness, attached, a.0, b.0);
    let (mut kinetic, mut kinetic_scale) = (0.0, 0.0);
    for ((m, va), vb) in model.masses().iter().zip(a.1).zip(b.1) {
        let term = m * va.dot(vb);
        kinetic += term;
        kinetic_scale += term.abs();
    }
    (potential + kinetic, potential_scale + kinetic_scale)
}

/// `G(a, b) = 5/4 <a, a> - <a, b> + 1/4 <b, b>` and its absolute scale.
fn g_norm(
    model: &Model,
    stiffness: f64,
    attached: bool,
    a: (&[Point], &[Point]),
    b: (&[Point], &[Point]),
) -> (f64, f64) {
    let (aa, saa) = inner(model, stiffness, attached, a, a);
    let (ab, sab) = inner(model, stiffness, attached, a, b);
    let (bb, sbb) = inner(model, stiffness, attached, b, b);
    (1.25 * aa - ab + 0.25 * bb, 1.25 * saa + sab + 0.25 * sbb)
}

fn difference(a: &[Point], b: &[Point]) -> Vec<Point> {
    a.iter().zip(b).map(|(p, q)| p - q).collect()
}

/// The G-norms of the two runs' difference, one per step from the second
/// on, with each step's round-off tolerance.
#[allow(clippy::too_many_arguments)]
fn g_norms(
    scene: &Scene,
    other_velocities: &[Point],
    choice: DampingChoice,
    pinned: bool,
    attached: bool,
    gravity: bool,
    dt: f64,
    iterations: usize,
) -> Result<Vec<(f64, f64)>, TestCaseError> {
    let reference = model(scene, pinned, attached);
    let n = reference.num_vertices();
    let max_mass = reference.masses().iter().copied().fold(0.0, f64::max);
    let d = choice.create().implicit_matrix();
    let matrix_bound = max_mass * (1.0 / (dt * dt) + d.mass / dt)
        + laplacian_norm(&reference) * (1.0 + (d.damping_laplacian + d.lagged_stiffness) / dt);
    let start = |velocities: Vec<Point>| {
        let mut sim = Simulation::new(
            model(scene, pinned, attached),
            Box::new(Bdf2::default()),
            choice.create(),
            settings(dt, iterations, gravity),
        )
        .unwrap();
        let positions = sim.state().positions.clone();
        sim.set_state(State {
            positions,
            velocities,
        })
        .unwrap();
        sim
    };
    let mut runs = [
        start(scene.initial_velocities(n)),
        start(other_velocities[..n].to_vec()),
    ];
    let state_difference = |runs: &[Simulation; 2]| {
        (
            difference(&runs[0].state().positions, &runs[1].state().positions),
            difference(&runs[0].state().velocities, &runs[1].state().velocities),
        )
    };
    let mut previous = state_difference(&runs);
    let mut norms = Vec::new();
    for step in 1..=STEPS {
        for run in &mut runs {
            run.step()
                .map_err(|e| TestCaseError::fail(format!("step {step}: {e}")))?;
        }
        let current = state_difference(&runs);
        let (g, scale) = g_norm(
            &reference,
            scene.stiffness,
            attached,
            (&current.0, &current.1),
            (&previous.0, &previous.1),
        );
        let speed = runs
            .iter()
            .map(|r| max_norm(&r.state().velocities))
            .fold(0.0, f64::max);
        let extent = runs
            .iter()
            .map(|r| max_norm(&r.state().positions))
            .fold(0.0, f64::max);
        let tolerance =
            16.0 * U * n as f64 * (n as f64 * dt * speed * matrix_bound * extent + scale);
        if step >= 2 {
            norms.push((g, tolerance));
        }
        previous = current;
    }
    Ok(norms)
}

fn matrix_damping() -> impl Strategy<Value = DampingChoice> {
    damping(1.0).prop_filter("G-stability needs a matrix D", |c| c.is_matrix_only())
}

proptest! {
    #![proptest_config(config(64))]

    #[test]
    fn bdf2_never_raises_the_g_norm_of_a_difference(
        scene in scene(1e0..1e4, 3.0),
        other in prop_common::points(prop_common::MAX_VERTICES, 3.0),
        choice in matrix_damping(),
        pinned: bool,
        attached: bool,
        gravity: bool,
        dt in 1e-4..0.1f64,
        iterations in 1usize..=3,
    ) {
        let norms = g_norms(&scene, &other, choice, pinned, attached, gravity, dt, iterations)?;
        for (k, pair) in norms.windows(2).enumerate() {
            let ((before, _), (after, tolerance)) = (pair[0], pair[1]);
            prop_assert!(
                after <= before + tolerance,
                "step {}: G rose from {:e} to {:e} (by {:e} > {:e})",
                k + 3, before, after, after - before, tolerance
            );
        }
    }
}
