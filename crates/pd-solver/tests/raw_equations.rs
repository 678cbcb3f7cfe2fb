//! After a solve run to convergence, each integrator's own discrete
//! equations of motion hold, assembled directly from forces (per-constraint
//! gradients, `D v` from the assembled damping matrices), not from the step
//! objective:
//!
//! - backward Euler: `M (v1 - v0)/h = f(x1) + M g - D v1`
//! - implicit midpoint: `M (v1 - v0)/h = f((x0 + x1)/2) + M g - D (v0 + v1)/2`
//! - BDF-2: `M (3 v1 - 4 v0 + v_{-1})/(2h) = f(x1) + M g - D v1`
//!
//! with `D = a1 M + a2 L_d + a3 K(x0)` for every implicit damping model.
//!
//! Predicted residual: the equations above are `grad g / s` for the step
//! objective `g` (`s = 1` for backward Euler, `1/2` for implicit midpoint,
//! `4/9` for BDF-2, docs/design/integrators.md). After the last local step at `x^K`,
//! `grad g(x^K) = A (x^K - x^{K+1})`, and with a linear convergence rate
//! below 1, `|x^K - x^{K+1}| <= |x^K - x^{K-1}|`, which the solver reports as
//! `relative_change * |x^K - x_n|_M`. So
//! `|r|_2 <= |A|_inf relative_change |x1 - x0|_M / (s sqrt(m_min))`.

mod common;

use common::{Scheme, clamped_beam};
use pd_constraints::assembly::{self, LaplacianKind};
use pd_constraints::{ConstraintBlock, CsrMatrix};
use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, RayleighLagged};
use pd_mesh::Point;
use pd_solver::{Model, Settings, Simulation, State};

/// (model, a1, a2 of L_d, a3 of K).
fn models() -> Vec<(Box<dyn Damping>, [f64; 3])> {
    vec![
        (Box::new(NoDamping), [0.0; 3]),
        (Box::new(EtherDrag::implicit(2.0).unwrap()), [2.0, 0.0, 0.0]),
        (
            Box::new(LaplacianDamping::new(0.02, 0.0, false).unwrap()),
            [0.0, 0.02, 0.0],
        ),
        (
            Box::new(LaplacianDamping::new(0.02, 1.0, false).unwrap()),
            [1.0, 0.02, 0.0],
        ),
        (
            Box::new(RayleighLagged::new(0.02, 0.5).unwrap()),
            [0.5, 0.0, 0.02],
        ),
    ]
}

fn model() -> Model {
    clamped_beam([3, 1, 1], [0.6, 0.2, 0.2], 5, 2e4).0
}

/// `D v` for `D = a1 M + a2 L_d + a3 K(x0)` (K: PSD-projected Hessians of the
/// translation-invariant constraints at x0), on every vertex.
fn damping_force(
    blocks: &[Box<dyn ConstraintBlock>],
    l_d: &CsrMatrix,
    masses: &[f64],
    x0: &[Point],
    v: &[Point],
    [a1, a2, a3]: [f64; 3],
) -> Vec<Point> {
    let mut out = vec![Point::zeros(); v.len()];
    l_d.mul_points(v, &mut out);
    for ((o, vi), m) in out.iter_mut().zip(v).zip(masses) {
        *o = *o * a2 + vi * (a1 * m);
    }
    if a3 != 0.0 {
        for block in blocks.iter().filter(|b| b.translation_invariant()) {
            let len = block.hessian_len();
            let size = 3 * block.stencil(0).len();
            let mut h = vec![0.0; block.len() * len];
            block.hessian_range(x0, 0, true, &mut h);
            for c in 0..block.len() {
                let stencil = block.stencil(c);
                for (k, &u) in stencil.iter().enumerate() {
                    for (l, &w) in stencil.iter().enumerate() {
                        for a in 0..3 {
                            for b in 0..3 {
                                out[u][a] +=
                                    a3 * h[c * len + (3 * k + a) * size + 3 * l + b] * v[w][b];
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

#[test]
fn converged_steps_satisfy_each_integrators_equations() {
    let gravity = Point::new(0.0, -9.81, 0.0);
    for scheme in [
        Scheme::BackwardEuler,
        Scheme::ImplicitMidpoint,
        Scheme::Bdf2,
    ] {
        for (damping, coefficients) in models() {
            let model = model();
            let blocks = model.constraint_blocks();
            let l_d = assembly::laplacian(&blocks, model.num_vertices(), LaplacianKind::Damping);
            let masses = model.masses().to_vec();
            let fixed = model.fixed().to_vec();
            let min_mass = masses.iter().copied().fold(f64::INFINITY, f64::min);
            let name = damping.name();
            let dt = 0.005;
            let settings = Settings {
                dt,
                iterations: 20_000,
                tolerance: 1e-9,
                gravity,
                ..Settings::default()
            };
            let mut sim = Simulation::new(model, scheme.integrator(), damping, settings).unwrap();
            // Start bent and moving, so every force is active.
            let positions: Vec<Point> = sim
                .state()
                .positions
                .iter()
                .zip(&fixed)
                .map(|(p, &f)| {
                    if f {
                        *p
                    } else {
                        p + Point::new(0.0, 0.3 * p.x * p.x, 0.05 * p.x)
                    }
                })
                .collect();
            let velocities: Vec<Point> = positions
                .iter()
                .zip(&fixed)
                .map(|(p, &f)| {
                    if f {
                        Point::zeros()
                    } else {
                        Point::new(0.0, -p.x, 0.2 * p.x)
                    }
                })
                .collect();
            sim.set_state(State {
                positions,
                velocities,
            })
            .unwrap();

            let mut previous_velocities: Option<Vec<Point>> = None;
            for step in 1..=4 {
                let a = sim.global_matrix().unwrap();
                let norm = (0..a.nrows())
                    .map(|r| a.row(r).map(|(_, v)| v.abs()).sum::<f64>())
                    .fold(0.0, f64::max);
                let State {
                    positions: x0,
                    velocities: v0,
                } = sim.state().clone();
                let stats = sim.step().unwrap();
                assert!(
                    stats.converged,
                    "{scheme:?} + {name}: step {step} did not converge"
                );
                let State {
                    positions: x1,
                    velocities: v1,
                } = sim.state().clone();

                let bdf2_proper = scheme == Scheme::Bdf2 && previous_velocities.is_some();
                let (force_at, damped_velocity, scale): (Vec<Point>, Vec<Point>, f64) = match scheme
                {
                    Scheme::ImplicitMidpoint => (
                        x0.iter().zip(&x1).map(|(a, b)| (a + b) * 0.5).collect(),
                        v0.iter().zip(&v1).map(|(a, b)| (a + b) * 0.5).collect(),
                        0.5,
                    ),
                    _ => (
                        x1.clone(),
                        v1.clone(),
                        if bdf2_proper { 4.0 / 9.0 } else { 1.0 },
                    ),
                };
                let mut gradient = vec![Point::zeros(); x1.len()];
                for block in &blocks {
                    block.add_gradient(&force_at, &mut gradient);
                }
                let d_v =
                    damping_force(&blocks, &l_d, &masses, &x0, &damped_velocity, coefficients);
                let mut residual2 = 0.0;
                let mut displacement2 = 0.0;
                for i in (0..x1.len()).filter(|&i| !fixed[i]) {
                    let inertia = if bdf2_proper {
                        let v_old = previous_velocities.as_ref().unwrap()[i];
                        (v1[i] * 3.0 - v0[i] * 4.0 + v_old) * (masses[i] / (2.0 * dt))
                    } else {
                        (v1[i] - v0[i]) * (masses[i] / dt)
                    };
                    let r = inertia - (-gradient[i] + gravity * masses[i] - d_v[i]);
                    residual2 += r.norm_squared();
                    displacement2 += masses[i] * (x1[i] - x0[i]).norm_squared();
                }
                let predicted =
                    norm * stats.relative_change * displacement2.sqrt() / (scale * min_mass.sqrt());
                let residual = residual2.sqrt();
                assert!(
                    residual <= predicted,
                    "{scheme:?} + {name}, step {step}: residual {residual:e} > predicted {predicted:e} \
                     ({} iterations, relative change {:e})",
                    stats.iterations,
                    stats.relative_change
                );
                previous_velocities = Some(v0);
            }
        }
    }
}
