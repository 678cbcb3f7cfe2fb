//! Building blocks the accelerated and converged methods add to
//! [`StepProblem`]: access to the displacement, mass-weighted inner
//! products, and the residual bookkeeping every method shares.

use pd_mesh::Point;

use super::iteration::StepProblem;

/// `sum_v m_v a_v . b_v` (kg m^2 for displacements), summed sequentially so
/// that it does not depend on the thread count.
pub(crate) fn mass_dot(masses: &[f64], a: &[Point], b: &[Point]) -> f64 {
    masses
        .iter()
        .zip(a)
        .zip(b)
        .map(|((m, a), b)| m * a.dot(b))
        .sum()
}

/// `out = a - b`, per vertex.
pub(crate) fn difference(a: &[Point], b: &[Point], out: &mut [Point]) {
    for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
        *o = a - b;
    }
}

impl<'a> StepProblem<'a> {
    /// The current displacement `x - x_n` per vertex (m), to overwrite. It
    /// must stay zero at fixed vertices; every linear combination of
    /// displacements the step produced does.
    pub fn displacement_mut(&mut self) -> &mut [Point] {
        &mut self.buffers.displacement
    }

    /// The lumped vertex masses, kg.
    pub fn masses(&self) -> &'a [f64] {
        self.masses
    }

    /// Records the step's residual, the mass-norm ratio
    /// `|G(x) - x|_M / |G(x) - x_n|_M` of one local-global map `G` from `x`
    /// (given squared, kg m^2: `change_squared`, `displacement_squared`), in
    /// [`crate::StepStats::relative_change`], and whether it meets the
    /// tolerance (always `false` with tolerance 0). Unlike
    /// [`StepProblem::converged`], it records the residual without a
    /// tolerance too.
    pub fn record_residual(&mut self, change_squared: f64, displacement_squared: f64) -> bool {
        let ratio = (change_squared / displacement_squared).sqrt();
        // 0/0: a step that does not move at all has converged.
        self.stats.relative_change = if ratio.is_nan() && change_squared == 0.0 {
            0.0
        } else {
            ratio
        };
        let tolerance = self.settings.tolerance;
        if tolerance > 0.0 && change_squared <= tolerance.powi(2) * displacement_squared {
            self.stats.converged = true;
        }
        self.stats.converged
    }
}
