//! Per-body damping coefficients in the one constant global matrix
//! (`pd_damping::PerBodyDamping`, docs/design/damping.md "Per-body damping").
//!
//! Body `b` asks for `D_b = a1_b M_b + a2_b L_d,b`. The damping model
//! reports the largest of each coefficient, `a1` and `a2`
//! ([`pd_damping::Damping::implicit_matrix`]); every vertex gets the weights
//! `w1 = a1_b / a1` and `w2 = a2_b / a2` of its body, so that
//! `D = a1 W1 M + a2 W2 L_d`. `W2 L_d` is symmetric because `L_d` is block
//! diagonal over the bodies (no constraint joins two bodies; a coupling
//! between bodies of different `w2` is refused here), so the global matrix
//! stays one constant symmetric positive definite matrix, factored once.
//!
//! With every weight 1 each product below is the unweighted one times 1.0,
//! which is exact: a per-body model giving every body the same coefficients
//! steps bit for bit as the global one.

use std::ops::Range;

use pd_damping::DampingMatrix;

use crate::SolverError;
use crate::global::{GlobalSystem, MatrixCoefficients, combine};

/// The per-vertex weights of a per-body damping model and the weighted
/// matrix parts.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DampingWeights {
    /// `w1` of every vertex (dimensionless).
    pub mass: Vec<f64>,
    /// `w2` of every vertex (dimensionless).
    pub laplacian: Vec<f64>,
    /// Per pattern slot: the entry of `W2 L_d`.
    damping_part: Vec<f64>,
    /// Per pattern slot: `(w1 - 1) m` on the diagonal, else 0.
    mass_excess: Vec<f64>,
}

/// `numerator / reference`, 0 when the reference is 0 (then the numerator
/// is 0 too: the reference is the largest).
fn ratio(numerator: f64, reference: f64) -> f64 {
    if reference > 0.0 {
        numerator / reference
    } else {
        0.0
    }
}

impl DampingWeights {
    /// The weights of `per_body` (one implicit matrix per body in
    /// `bodies`, vertex ranges) relative to `reference`, over `system`.
    ///
    /// # Errors
    /// [`SolverError::InvalidModel`] when the counts differ, a body has a
    /// lagged term, or a constraint joins two bodies with different
    /// Laplacian coefficients.
    pub fn new(
        system: &GlobalSystem,
        per_body: &[DampingMatrix],
        reference: DampingMatrix,
        bodies: &[Range<usize>],
    ) -> Result<Self, SolverError> {
        if per_body.len() != bodies.len() {
            return Err(SolverError::InvalidModel {
                reason: format!(
                    "the damping model has coefficients for {} bodies, the model has {}",
                    per_body.len(),
                    bodies.len()
                ),
            });
        }
        if per_body.iter().any(DampingMatrix::is_lagged) {
            return Err(SolverError::InvalidModel {
                reason: "a lagged damping term cannot be given per body".into(),
            });
        }
        let n = system.free_index.len();
        let (mut mass, mut laplacian) = (vec![0.0; n], vec![0.0; n]);
        for (range, d) in bodies.iter().zip(per_body) {
            let (w1, w2) = (
                ratio(d.mass, reference.mass),
                ratio(d.damping_laplacian, reference.damping_laplacian),
            );
            mass[range.clone()].fill(w1);
            laplacian[range.clone()].fill(w2);
        }
        let pattern = &system.pattern;
        let mut damping_part = system.damping_part.clone();
        let mut mass_excess = vec![0.0; damping_part.len()];
        for col in 0..pattern.n {
            let (vc, start) = (system.free[col], pattern.col_ptr[col]);
            for slot in start..pattern.col_ptr[col + 1] {
                let vr = system.free[pattern.row_idx[slot]];
                if damping_part[slot] != 0.0 && laplacian[vr] != laplacian[vc] {
                    return Err(SolverError::InvalidModel {
                        reason: format!(
                            "vertices {vr} and {vc} share a constraint but their bodies have \
                             different damping Laplacian coefficients: give coupled bodies \
                             the same damping"
                        ),
                    });
                }
                damping_part[slot] *= laplacian[vr];
                if vr == vc {
                    mass_excess[slot] = (mass[vr] - 1.0) * system.mass_part[slot];
                }
            }
        }
        Ok(Self {
            mass,
            laplacian,
            damping_part,
            mass_excess,
        })
    }
}

/// [`combine`] of a system's `parts` (mass, `L_sys`, `L_d` per pattern
/// slot) for `coefficients`, with the weighted damping Laplacian and mass
/// term when the system has per-body `weights`.
pub(crate) fn combine_weighted(
    values: &mut [f64],
    coefficients: MatrixCoefficients,
    parts: [&[f64]; 3],
    weights: Option<&DampingWeights>,
) {
    let Some(weights) = weights else {
        combine(values, coefficients, parts);
        return;
    };
    combine(
        values,
        coefficients,
        [parts[0], parts[1], &weights.damping_part],
    );
    // (1/h^2 + c a1) M + c a1 (W1 - 1) M = M / h^2 + c a1 W1 M.
    for (value, excess) in values.iter_mut().zip(&weights.mass_excess) {
        *value += coefficients.mass_damping * excess;
    }
}
