//! The step objective (docs/design/formulation.md, "The step objective"),
//! the merit function of a step:
//!
//! `g(x) = 1/(2h^2) |x - y|_M^2 + c1 E(x_n + c2 dx)
//!   + 1/2 c1 c2 gamma (x - x_hat)^T D (x - x_hat)`, `dx = x - x_n`,
//!
//! with `D = a1 M + a2 L_d + a3 K(x_n)` plus the Caughey series' terms
//! `a_(j+3) L_d (M^-1 L_d)^(j+1)` (the `L_d` terms measured from their
//! own anchor, which a damping model may move). Fixed vertices sit at `x_n`,
//! where `x - x_hat` vanishes, so `L_d`'s rows of the free vertices suffice;
//! their inertia term is a constant of the step.

use pd_mesh::Point;

use super::iteration::StepProblem;
use crate::local::LocalStep;

/// `g(x_n + dx)` in J for the problem's current displacement.
pub(crate) fn step_objective(problem: &mut StepProblem<'_>) -> f64 {
    objective_with(problem, |local, q, _| local.energy(q))
}

/// `g(x_n + dx)` with the elastic energy `E(q)` given by `elastic(local, q,
/// projections)` (which may overwrite the problem's projections, e.g. to
/// project at `q` and sum the energy from them).
pub(crate) fn objective_with(
    problem: &mut StepProblem<'_>,
    elastic: impl FnOnce(&LocalStep, &[Point], &mut [Point]) -> f64,
) -> f64 {
    let c = problem.coefficients;
    let d = problem.damping;
    let h = problem.h;
    let x_n = problem.positions;
    let targets = problem.targets;
    let masses = problem.masses;
    let b = &mut *problem.buffers;
    let dx = &b.displacement;
    let [offset, laplacian_offset, product] = &mut b.scratch;
    let laplacian_anchor = problem.laplacian_anchor;
    let mut inertia = 0.0;
    let mut mass_form = 0.0;
    // Per-body damping scales the a1 M term per vertex (weights.rs).
    let weights = problem.global.damping_weights().map(|w| &w.mass);
    let mass_weight = |v: usize| weights.map_or(1.0, |w| w[v]);
    for v in 0..x_n.len() {
        b.q[v] = x_n[v] + dx[v] * c.c2;
        offset[v] = dx[v] - targets.anchor_displacement[v];
        laplacian_offset[v] = dx[v] - laplacian_anchor[v];
        inertia += masses[v] * (dx[v] - targets.inertial_displacement[v]).norm_squared();
        mass_form += masses[v] * offset[v].norm_squared() * mass_weight(v);
    }
    let laplacian_form = if d.damping_laplacian != 0.0 {
        // Rotation-preserving damping measures (I - P)(x - x_hat) instead.
        problem.global.project_rotations(laplacian_offset);
        problem.global.damping_laplacian_form(laplacian_offset)
    } else {
        0.0
    };
    let blocks = problem.local.blocks();
    let series_form = if d.has_series() {
        problem.global.series_form(laplacian_offset, &d.series)
    } else {
        0.0
    };
    let lagged_form = problem
        .global
        .lagged_stiffness_form(blocks, offset, product);
    let damping_form = d.mass * mass_form
        + d.damping_laplacian * laplacian_form
        + d.lagged_stiffness * lagged_form
        + series_form;
    let elastic = elastic(problem.local, &b.q, &mut b.projections);
    inertia / (2.0 * h * h) + c.c1 * elastic + 0.5 * c.c1 * c.c2 * c.gamma * damping_form
}
