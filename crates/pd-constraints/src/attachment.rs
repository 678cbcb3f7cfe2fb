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

    fn gx_hessian(&self, _gx: &[Point], _project_psd: bool, out: &mut [f64]) {
        // E = w/2 |x - t|^2: Hessian w I, already positive definite.
        for a in 0..3 {
            for b in 0..3 {
                out[3 * a + b] = if a == b { self.weight } else { 0.0 };
            }
        }
    }
}
