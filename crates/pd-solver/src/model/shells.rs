//! `Model::add_*` for the cloth and shell kinds: membrane strain, bending,
//! area and volume, with the input checks that name the offending triangle,
//! edge or tetrahedron.

use pd_constraints::{
    Area, Bending, Constraint, ConstraintError, PlateBending, TriangleStrain, Volume,
    bending::hinges, plate_bending::neighbours,
};
use pd_mesh::Point;

use super::{BodyId, Model};
use crate::SolverError;

impl Model {
    /// Adds a corotational membrane-strain constraint for every triangle of
    /// a body: `stiffness = E t` in N/m (Young's modulus times thickness,
    /// Poisson ratio 0), optional principal-stretch limits. Returns how
    /// many.
    ///
    /// # Errors
    /// A body without triangles, a zero-area triangle or an edge shared by
    /// more than two triangles (named by index), or invalid parameters.
    pub fn add_triangle_strain(
        &mut self,
        body: BodyId,
        stiffness: f64,
        limits: Option<(f64, f64)>,
    ) -> Result<usize, SolverError> {
        let new = self.per_triangle(body, TriangleStrain::KIND, |rest, t| {
            TriangleStrain::new(rest, t, stiffness, limits)
        })?;
        self.add_body_constraints(body, stiffness, new)
    }

    /// Adds an area-preservation constraint for every triangle of a body,
    /// `stiffness` in N/m. Returns how many.
    ///
    /// # Errors
    /// As [`Model::add_triangle_strain`].
    pub fn add_area(&mut self, body: BodyId, stiffness: f64) -> Result<usize, SolverError> {
        let new = self.per_triangle(body, Area::KIND, |rest, t| Area::new(rest, t, stiffness))?;
        self.add_body_constraints(body, stiffness, new)
    }

    /// Adds bending with flexural rigidity `stiffness = D` in N m to a body's
    /// triangles (open edges are free). If every interior edge is flat at
    /// rest (a flat sheet) this is one [`PlateBending`] per triangle, the
    /// quadratic plate energy with Poisson ratio 0; otherwise one curved
    /// [`Bending`] hinge per interior edge, which keeps the rest curvature
    /// magnitude (`docs/design/constraints.md`). Returns how many.
    ///
    /// # Errors
    /// As [`Model::add_triangle_strain`].
    pub fn add_bending(&mut self, body: BodyId, stiffness: f64) -> Result<usize, SolverError> {
        // Validates the triangles (degenerate, non-manifold) first.
        self.per_triangle(body, "bending", |rest, t| {
            TriangleStrain::new(rest, t, 0.0, None)
        })?;
        let b = self.body(body)?;
        let offset = b.offset;
        let to_solver = |source| SolverError::Constraint {
            body: body.0,
            source,
        };
        let triangles = b.mesh.triangles();
        let rest = &self.rest_positions;
        let curved = hinges(triangles)
            .map_err(to_solver)?
            .iter()
            .map(|h| Bending::new(rest, h.map(|v| v + offset), stiffness))
            .collect::<Result<Vec<_>, _>>()
            .map_err(to_solver)?;
        if curved.iter().any(|h| h.rest_magnitude() > 0.0) {
            return self.add_body_constraints(body, stiffness, curved);
        }
        let across = neighbours(triangles).map_err(to_solver)?;
        // A triangle without interior edges has no bending to measure.
        let flat = triangles
            .iter()
            .zip(&across)
            .filter(|(_, a)| a.iter().any(Option::is_some))
            .map(|(t, a)| {
                PlateBending::new(
                    rest,
                    t.map(|v| v + offset),
                    a.map(|o| o.map(|v| v + offset)),
                    stiffness,
                )
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(to_solver)?;
        self.add_body_constraints(body, stiffness, flat)
    }

    /// Adds a volume-preservation constraint for every tetrahedron of a
    /// body, `stiffness` in Pa (alongside or instead of tet strain). Returns
    /// how many.
    ///
    /// # Errors
    /// A body without tetrahedra, a flat or inverted tetrahedron (named by
    /// index), or invalid parameters.
    pub fn add_volume(&mut self, body: BodyId, stiffness: f64) -> Result<usize, SolverError> {
        let b = self.body(body)?;
        if b.mesh.tets().is_empty() {
            return Err(SolverError::InvalidModel {
                reason: format!("body {}: volume needs a tetrahedral mesh", body.0),
            });
        }
        let offset = b.offset;
        let rest = &self.rest_positions;
        let mut new = Vec::with_capacity(b.mesh.tets().len());
        for (i, t) in b.mesh.tets().iter().enumerate() {
            new.push(
                Volume::new(rest, t.map(|v| v + offset), stiffness)
                    .map_err(|e| element_error(body, "volume", "tetrahedron", i, &t[..], e))?,
            );
        }
        self.add_body_constraints(body, stiffness, new)
    }

    /// Builds one constraint per triangle of `body` with `build(rest,
    /// triangle)` (global vertex indices), after checking that the body has
    /// triangles and no edge shared by more than two.
    fn per_triangle<C>(
        &self,
        body: BodyId,
        kind: &str,
        build: impl Fn(&[Point], [usize; 3]) -> Result<C, ConstraintError>,
    ) -> Result<Vec<C>, SolverError> {
        let b = self.body(body)?;
        let triangles = b.mesh.triangles();
        if triangles.is_empty() {
            return Err(SolverError::InvalidModel {
                reason: format!("body {}: {kind} needs a triangle mesh", body.0),
            });
        }
        if let Err(ConstraintError::NonManifoldEdge { edge, triangles }) = hinges(triangles) {
            return Err(SolverError::InvalidModel {
                reason: format!(
                    "body {}: {kind}: edge {edge:?} is shared by more than two triangles \
                     {triangles:?} (non-manifold)",
                    body.0
                ),
            });
        }
        let offset = b.offset;
        triangles
            .iter()
            .enumerate()
            .map(|(i, t)| {
                build(&self.rest_positions, t.map(|v| v + offset))
                    .map_err(|e| element_error(body, kind, "triangle", i, &t[..], e))
            })
            .collect()
    }
}

/// Names element `index` (vertices in the body's numbering) for a
/// degenerate rest shape; other errors pass through with the body.
fn element_error(
    body: BodyId,
    kind: &str,
    element: &str,
    index: usize,
    vertices: &[usize],
    error: ConstraintError,
) -> SolverError {
    match error {
        ConstraintError::DegenerateElement { .. } => SolverError::InvalidModel {
            reason: format!(
                "body {}: {kind}: {element} {index} (vertices {vertices:?}) has a degenerate \
                 (zero-area, flat or inverted) rest shape",
                body.0
            ),
        },
        source => SolverError::Constraint {
            body: body.0,
            source,
        },
    }
}
