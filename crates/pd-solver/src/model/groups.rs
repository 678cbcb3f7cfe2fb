//! Constraint groups: what each `add_*` call of a [`Model`] added, so that
//! a caller can name "body 0's second constraint group" (a scene's
//! `body[0].constraints[1]`) and read its stiffness and its constraints,
//! whatever block they were stored in.

use std::ops::Range;

use pd_constraints::{ConstraintBlock, ConstraintSet};

use super::{BodyId, Model};
use crate::SolverError;

/// One group of constraints: everything one `add_*` call of a [`Model`]
/// added (e.g. one tet-strain per tetrahedron of a body), in the order the
/// calls were made.
#[derive(Debug, Clone, PartialEq)]
pub struct ConstraintGroup {
    /// The body the group belongs to; `None` for
    /// [`Model::add_constraints`], whose stencils may span bodies.
    pub body: Option<usize>,
    /// The constraints' kind, as scenes spell it (`tet-strain`), or the
    /// material's name.
    pub kind: &'static str,
    /// The stiffness the group was built with (Pa, N/m, ...; Young's
    /// modulus for a material): every constraint's weight, and so the
    /// group's energy, is proportional to it. `None` for
    /// [`Model::add_constraints`].
    pub stiffness: Option<f64>,
    /// Number of constraints (0 when the call added none).
    pub len: usize,
}

/// Where a group's constraints are stored.
#[derive(Debug, Clone)]
pub(super) enum GroupStorage {
    TetStrain(Range<usize>),
    Springs(Range<usize>),
    Attachments(Range<usize>),
    /// The whole block `other[i]`.
    Other(usize),
    /// The call added no constraint.
    Empty,
}

impl Model {
    /// Records the group an `add_*` call just stored.
    pub(super) fn record_group(
        &mut self,
        body: Option<BodyId>,
        kind: &'static str,
        stiffness: Option<f64>,
        storage: GroupStorage,
    ) {
        let len = match &storage {
            GroupStorage::TetStrain(r)
            | GroupStorage::Springs(r)
            | GroupStorage::Attachments(r) => r.len(),
            GroupStorage::Other(i) => self.other[*i].len(),
            GroupStorage::Empty => 0,
        };
        let group = ConstraintGroup {
            body: body.map(|b| b.0),
            kind,
            stiffness,
            len,
        };
        self.groups.push((group, storage));
    }

    /// [`Model::add_constraints`] for one body's kind built with one
    /// stiffness: the group records both.
    pub(super) fn add_body_constraints<C: pd_constraints::Constraint>(
        &mut self,
        body: BodyId,
        stiffness: f64,
        constraints: Vec<C>,
    ) -> Result<usize, SolverError> {
        let count = self.add_constraints(constraints)?;
        if let Some((group, _)) = self.groups.last_mut() {
            group.body = Some(body.0);
            group.stiffness = Some(stiffness);
        }
        Ok(count)
    }

    /// Every constraint group, in the order the `add_*` calls were made
    /// (one per call, [`Model::fix_vertices`] excepted). A body's `j`-th
    /// group is the `j`-th with `body == Some(b)`: the scene's
    /// `body[b].constraints[j]`.
    pub fn constraint_groups(&self) -> Vec<ConstraintGroup> {
        self.groups.iter().map(|(g, _)| g.clone()).collect()
    }

    /// A block holding a copy of group `group`'s constraints only (`None`
    /// for a group out of range or one without constraints), for
    /// evaluating one group's energy, gradient or Hessian apart from the
    /// others (the gradient of a run with respect to the group's
    /// stiffness).
    #[doc(hidden)]
    pub fn constraint_group_block(&self, group: usize) -> Option<Box<dyn ConstraintBlock>> {
        let (_, storage) = self.groups.get(group)?;
        Some(match storage {
            GroupStorage::TetStrain(r) => {
                Box::new(ConstraintSet::new(self.tet_strain[r.clone()].to_vec()))
            }
            GroupStorage::Springs(r) => {
                Box::new(ConstraintSet::new(self.springs[r.clone()].to_vec()))
            }
            GroupStorage::Attachments(r) => {
                Box::new(ConstraintSet::new(self.attachments[r.clone()].to_vec()))
            }
            GroupStorage::Other(i) => self.other[*i].boxed_clone(),
            GroupStorage::Empty => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    use pd_mesh::generators;

    use super::*;

    /// Each call is one group, in call order, with its body, kind,
    /// stiffness and count; a group's block holds exactly its constraints.
    #[test]
    fn groups_follow_the_calls() {
        let beam = generators::box_tets([1.0, 0.2, 0.2], [2, 1, 1]).unwrap();
        let masses = beam.lumped_masses(1000.0).unwrap();
        let mut model = Model::new();
        let body = model.add_body(beam, masses).unwrap();
        let tets = model.add_tet_strain(body, 1e5, None).unwrap();
        let springs = model.add_springs(body, 30.0).unwrap();
        model.add_attachments(body, &[0, 1], 7.0).unwrap();
        let groups = model.constraint_groups();
        let kinds: Vec<_> = groups
            .iter()
            .map(|g| (g.body, g.kind, g.stiffness, g.len))
            .collect();
        assert_eq!(
            kinds,
            vec![
                (Some(0), "tet-strain", Some(1e5), tets),
                (Some(0), "spring", Some(30.0), springs),
                (Some(0), "attachment", Some(7.0), 2),
            ]
        );
        for (i, g) in groups.iter().enumerate() {
            assert_eq!(model.constraint_group_block(i).unwrap().len(), g.len);
        }
        assert!(model.constraint_group_block(3).is_none());
    }
}
