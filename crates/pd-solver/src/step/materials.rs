//! The energy-element seam: what the objective-judging methods (`lbfgs`,
//! `newton`) add for hyperelastic materials (`docs/design/materials.md`).
//!
//! A material block ([`pd_constraints::MaterialSet`]) projects to the
//! identity, so one local-global iteration `G` from `x` gives
//! `w = G(x) - x = -A^{-1} grad g_PD(x)`, the PD part of the gradient only.
//! The step objective's full gradient is
//! `grad g = grad g_PD + c1 c2 grad E_mat(x_n + c2 dx)` (the material
//! energies enter the objective as `c1 E_mat(x_n + c2 dx)`), so
//! [`MaterialGradient::correct`] turns `w` into
//! `w' = -A^{-1} grad g = w - A^{-1} (c1 c2 grad E_mat)` with one more
//! prefactored solve. With `w'` in place of `w`, L-BFGS's and Newton's
//! identities (`grad g = -A w'`) hold for the full objective. The energies
//! themselves (objective, divergence check, reports) and Newton's Hessian
//! need nothing here: they come from the blocks.

use std::time::Instant;

use pd_mesh::Point;

use super::iteration::StepProblem;
use crate::{Simulation, SolverError};

/// Scratch of the material correction, sized on first use.
#[derive(Debug, Clone, Default)]
pub(crate) struct MaterialGradient {
    q: Vec<Point>,
    gradient: Vec<Point>,
    rhs: Vec<Point>,
}

impl MaterialGradient {
    /// Whether `step`'s model has energy elements.
    pub fn present(step: &StepProblem<'_>) -> bool {
        step.local.blocks().iter().any(|b| b.is_energy_element())
    }

    /// `update -= A^{-1} (c1 c2 grad E_mat(x_n + c2 iterate))`: turns the
    /// local-global update from `iterate` into `-A^{-1} grad g` (module
    /// documentation). Counts the solve's time as global time. The caller
    /// checks [`MaterialGradient::present`] first.
    pub fn correct(&mut self, step: &mut StepProblem<'_>, iterate: &[Point], update: &mut [Point]) {
        let t0 = Instant::now();
        let n = step.positions.len();
        let free = step.global.free().len();
        if self.q.len() != n || self.rhs.len() != free {
            self.q = vec![Point::zeros(); n];
            self.gradient = vec![Point::zeros(); n];
            self.rhs = vec![Point::zeros(); free];
        }
        let c = step.coefficients;
        for ((q, x_n), dx) in self.q.iter_mut().zip(step.positions).zip(iterate) {
            *q = x_n + dx * c.c2;
        }
        self.gradient.iter_mut().for_each(|g| *g = Point::zeros());
        for block in step.local.blocks().iter().filter(|b| b.is_energy_element()) {
            block.add_gradient(&self.q, &mut self.gradient);
        }
        let scale = c.c1 * c.c2;
        for (r, &v) in self.rhs.iter_mut().zip(step.global.free()) {
            *r = self.gradient[v] * scale;
        }
        step.global.solve(&self.rhs);
        for (f, &v) in step.global.free().iter().enumerate() {
            update[v] -= step.global.solution(f);
        }
        step.stats.global_seconds += t0.elapsed().as_secs_f64();
    }
}

impl Simulation {
    /// `Unsupported` if the model has hyperelastic materials and the position
    /// solver cannot run them ([`crate::PositionSolver::handles_materials`]);
    /// the state is left untouched.
    pub(crate) fn check_solver_handles_materials(&self) -> Result<(), SolverError> {
        if self.position_solver.handles_materials()
            || !self.local.blocks().iter().any(|b| b.is_energy_element())
        {
            return Ok(());
        }
        Err(SolverError::Unsupported {
            what: format!(
                "the {} position solver with hyperelastic materials (neo-hookean, stvk, \
                 corotated): it only minimises Projective Dynamics' quadratic energies and would \
                 ignore their forces; use lbfgs or newton (docs/design/materials.md)",
                self.position_solver.name()
            ),
        })
    }
}
