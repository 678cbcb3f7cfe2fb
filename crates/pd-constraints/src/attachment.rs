//! Soft attachment of a vertex to a target point: `w/2 |x - t|^2`.

use pd_mesh::Point;

use crate::{Constraint, ConstraintError, tet_strain::check_stiffness};

/// Pulls one vertex towards a fixed target point with weight `stiffness`
/// (N/m). `G = [1]` and the projection is the target. Not translation
/// invariant: it exerts a net force, so it is in the system Laplacian but
/// never in the damping Laplacian. (Hard-fixed vertices are not attachments:
/// the solver removes them from the unknowns.)
#[derive(Debug, Clone, PartialEq)]
pub struct Attachment {
    vertex: [usize; 1],
    weight: f64,
    target: Point,
}

impl Attachment {
    /// Attaches `vertex` to `target` (metres).
    ///
    /// # Errors
    /// A negative or non-finite stiffness, or a non-finite target.
    pub fn new(vertex: usize, target: Point, stiffness: f64) -> Result<Self, ConstraintError> {
        check_stiffness(stiffness)?;
        if !target.iter().all(|c| c.is_finite()) {
            return Err(ConstraintError::NonFiniteTarget { vertex });
        }
        Ok(Self {
            vertex: [vertex],
            weight: stiffness,
            target,
        })
    }

    /// The target point.
    pub fn target(&self) -> Point {
        self.target
    }
}

impl Constraint for Attachment {
    const STENCIL: usize = 1;
    const ROWS: usize = 1;
    const TRANSLATION_INVARIANT: bool = false;
    const KIND: &'static str = "attachment";

    type Vertices<'a> = &'a [usize];

    fn vertices(&self) -> &[usize] {
        &self.vertex
    }

    fn weight(&self) -> f64 {
        self.weight
    }

    fn operator(&self, _row: usize, _column: usize) -> f64 {
        1.0
    }

    fn project(&self, _gx: &[Point], out: &mut [Point]) {
        out[0] = self.target;
    }

    /// The projection is the target whatever the positions: copied
    /// without gathering `G q` (the default computes it for each
    /// constraint and discards it). The same bits.
    fn project_many(constraints: &[Self], _q: &[Point], out: &mut [Point]) {
        for (c, p) in constraints.iter().zip(out) {
            *p = c.target;
        }
    }

    fn gx_hessian(&self, _gx: &[Point], _project_psd: bool, out: &mut [f64]) {
        // E = w/2 |x - t|^2: Hessian w I, already positive definite.
        for a in 0..3 {
            for b in 0..3 {
                out[3 * a + b] = if a == b { self.weight } else { 0.0 };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `project_many` (the targets without `G q`) and the energies give
    /// the one-at-a-time bits.
    #[test]
    fn batched_projection_is_bit_identical() {
        let q: Vec<Point> = (0..7)
            .map(|i| Point::new(i as f64, 0.5 * i as f64, -1.0 / (i + 1) as f64))
            .collect();
        let constraints: Vec<Attachment> = (0..7)
            .map(|i| {
                let target = Point::new(0.1 * i as f64, 2.0, 3.0 - i as f64);
                Attachment::new((i * 3) % 7, target, 1.0 + i as f64).unwrap()
            })
            .collect();
        crate::lane_rows::test_support::assert_all_bit_identical(&constraints, &q);
    }
}
