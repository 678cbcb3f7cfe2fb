//! Springs: `w/2 (|x1 - x0| - L0)^2`.

use pd_mesh::Point;

use crate::tet_strain::{check_stiffness, check_vertices};
use crate::{Constraint, ConstraintError};

/// A spring between two vertices with rest length `L0` and weight
/// `stiffness` (N/m). `G = [-1, 1]`, so `G x` is the edge vector `d`, and the
/// projection is `L0 d / |d|`: the nearest vector of the rest length. A
/// zero-rest-length spring has a quadratic, convex energy.
#[derive(Debug, Clone, PartialEq)]
pub struct Spring {
    vertices: [usize; 2],
    weight: f64,
    rest_length: f64,
    rest_direction: Point,
}

impl Spring {
    /// Builds the spring along `edge` from rest positions.
    ///
    /// # Errors
    /// A negative or non-finite stiffness.
    pub fn new(rest: &[Point], edge: [usize; 2], stiffness: f64) -> Result<Self, ConstraintError> {
        Self::with_rest_length(rest, edge, stiffness, None)
    }

    /// Like [`Spring::new`] with an explicit rest length in metres (e.g. 0
    /// for a zero-rest-length spring); `None` takes the rest distance.
    ///
    /// # Errors
    /// A negative or non-finite stiffness or rest length.
    pub fn with_rest_length(
        rest: &[Point],
        edge: [usize; 2],
        stiffness: f64,
        rest_length: Option<f64>,
    ) -> Result<Self, ConstraintError> {
        check_vertices(rest, &edge)?;
        check_stiffness(stiffness)?;
        let d = rest[edge[1]] - rest[edge[0]];
        let rest_length = rest_length.unwrap_or_else(|| d.norm());
        if !(rest_length.is_finite() && rest_length >= 0.0) {
            return Err(ConstraintError::InvalidRestLength { rest_length });
        }
        let rest_direction = d.try_normalize(0.0).unwrap_or_else(Point::x);
        Ok(Self {
            vertices: edge,
            weight: stiffness,
            rest_length,
            rest_direction,
        })
    }

    /// Rest length in metres.
    pub fn rest_length(&self) -> f64 {
        self.rest_length
    }
}

impl Constraint for Spring {
    const STENCIL: usize = 2;
    const ROWS: usize = 1;
    const TRANSLATION_INVARIANT: bool = true;
    const KIND: &'static str = "spring";

    type Vertices<'a> = &'a [usize];

    fn vertices(&self) -> &[usize] {
        &self.vertices
    }

    fn weight(&self) -> f64 {
        self.weight
    }

    fn operator(&self, _row: usize, column: usize) -> f64 {
        if column == 0 { -1.0 } else { 1.0 }
    }

    fn project(&self, gx: &[Point], out: &mut [Point]) {
        // A collapsed spring has no direction: any is equally close, so take
        // the rest direction (deterministic, and it pushes the ends apart).
        let direction = gx[0].try_normalize(0.0).unwrap_or(self.rest_direction);
        out[0] = direction * self.rest_length;
    }

    fn gx_hessian(&self, gx: &[Point], project_psd: bool, out: &mut [f64]) {
        // E(d) = w/2 (|d| - L0)^2: Hessian w [d^ d^T + (1 - L0/|d|)(I - d^ d^T)].
        // The transverse eigenvalue is negative for a compressed spring.
        let length = gx[0].norm();
        let direction = gx[0].try_normalize(0.0).unwrap_or(self.rest_direction);
        let mut transverse = if length > 0.0 {
            1.0 - self.rest_length / length
        } else if self.rest_length == 0.0 {
            1.0
        } else {
            f64::NEG_INFINITY
        };
        if project_psd {
            transverse = transverse.max(0.0);
        }
        for a in 0..3 {
            for b in 0..3 {
                let along = direction[a] * direction[b];
                let identity = if a == b { 1.0 } else { 0.0 };
                out[3 * a + b] = self.weight * (along + transverse * (identity - along));
            }
        }
    }
}
