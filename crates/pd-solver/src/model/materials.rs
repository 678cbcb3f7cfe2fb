//! `Model::add_material`: hyperelastic tetrahedra (`neo-hookean`, `stvk`,
//! `corotated`; `docs/design/materials.md`), stored as one
//! [`pd_constraints::MaterialSet`] energy-element block per call.

use pd_constraints::{ConstraintBlock, MaterialKind, MaterialSet, MaterialTet};

use super::{BodyId, Model};
use crate::SolverError;

impl Model {
    /// Makes every tetrahedron of a body a hyperelastic element of law
    /// `kind` with Young's modulus `young` (Pa) and Poisson's ratio
    /// `poisson` (in `[0, 0.5)`). Returns how many. Only the `lbfgs` and
    /// `newton` position solvers run a model with materials
    /// ([`crate::PositionSolver::handles_materials`]).
    ///
    /// # Errors
    /// A body without tetrahedra, a flat or inverted rest tetrahedron (named
    /// by index), or invalid `young` / `poisson`.
    pub fn add_material(
        &mut self,
        body: BodyId,
        kind: MaterialKind,
        young: f64,
        poisson: f64,
    ) -> Result<usize, SolverError> {
        let b = self.body(body)?;
        if b.mesh.tets().is_empty() {
            return Err(SolverError::InvalidModel {
                reason: format!("body {}: {} needs a tetrahedral mesh", body.0, kind.name()),
            });
        }
        let offset = b.offset;
        let mut tets = Vec::with_capacity(b.mesh.tets().len());
        for (i, t) in b.mesh.tets().iter().enumerate() {
            let tet =
                MaterialTet::new(&self.rest_positions, t.map(|v| v + offset)).map_err(|e| {
                    SolverError::InvalidModel {
                        reason: format!(
                            "body {}: {}: tetrahedron {i} {t:?}: {e}",
                            body.0,
                            kind.name()
                        ),
                    }
                })?;
            tets.push(tet);
        }
        let set = MaterialSet::new(kind, young, poisson, tets).map_err(|source| {
            SolverError::Constraint {
                body: body.0,
                source,
            }
        })?;
        let count = set.len();
        self.other.push(Box::new(set));
        self.record_group(
            Some(body),
            kind.name(),
            Some(young),
            super::GroupStorage::Other(self.other.len() - 1),
        );
        Ok(count)
    }

    /// Whether any block is a hyperelastic material (an energy element).
    pub fn has_materials(&self) -> bool {
        self.other.iter().any(|b| b.is_energy_element())
    }
}
