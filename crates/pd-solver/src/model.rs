//! The [`Model`]: bodies, masses, constraints and fixed vertices of a scene,
//! in one global vertex numbering.

use std::ops::Range;
use std::sync::Arc;

use pd_constraints::{Attachment, Constraint, ConstraintBlock, ConstraintSet, Spring, TetStrain};
use pd_mesh::{Mesh, Point};

use crate::SolverError;

mod fingerprint;
mod groups;
mod materials;
mod shells;

pub use groups::ConstraintGroup;
use groups::GroupStorage;

/// Index of a body in a [`Model`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BodyId(pub usize);

/// One body: its mesh and where its vertices sit in the global numbering.
#[derive(Debug, Clone)]
pub struct Body {
    /// The rest mesh, in the body's own vertex numbering.
    pub mesh: Mesh,
    /// Global index of the body's vertex 0.
    pub offset: usize,
}

/// The constraints sorted by their vertex indices (each stencil's indices
/// in ascending order, compared lexicographically), so that constraints
/// sharing vertices sit close together. The local step then reads nearby
/// positions one after the other, and the right-hand side's row of vertex
/// `v` gathers projections that sit close in memory: on the TetGen
/// armadillo, whose tets come in no such order, this takes the global step
/// from 60 to 44 ms per time step (docs/design/performance.md, "The right-hand side `B p`").
/// Generated meshes already come in this order. Only the storage order
/// changes, not any constraint; the sort is stable, so it is deterministic.
fn locality_order<C: Constraint>(mut constraints: Vec<C>) -> Vec<C> {
    constraints.sort_by_cached_key(|c| {
        let mut key = c.vertices().to_vec();
        key.sort_unstable();
        key
    });
    constraints
}

impl Body {
    /// The body's vertices in the global numbering.
    pub fn vertices(&self) -> Range<usize> {
        self.offset..self.offset + self.mesh.num_vertices()
    }
}

/// Everything that defines the mechanical system, independent of time
/// stepping: rest positions, lumped masses, constraints (one contiguous
/// vector per kind) and hard-fixed vertices. Only the kinds a scene uses
/// hold any constraint, and only those are iterated over.
///
/// ```
/// use pd_mesh::generators;
/// use pd_solver::Model;
///
/// let beam = generators::box_tets([1.0, 0.2, 0.2], [5, 1, 1]).unwrap();
/// let masses = beam.lumped_masses(1000.0).unwrap();
/// let mut model = Model::new();
/// let body = model.add_body(beam, masses).unwrap();
/// model.add_tet_strain(body, 1e5, None).unwrap();
/// model.fix_vertices(body, &[0, 6, 12, 18]).unwrap();
/// assert_eq!(model.num_vertices(), 24);
/// assert_eq!(model.num_constraints(), 30);
/// ```
#[derive(Debug, Default)]
pub struct Model {
    rest_positions: Vec<Point>,
    masses: Vec<f64>,
    fixed: Vec<bool>,
    bodies: Vec<Body>,
    /// Shared with the blocks handed to a simulation (no copy).
    tet_strain: Arc<Vec<TetStrain>>,
    springs: Arc<Vec<Spring>>,
    attachments: Arc<Vec<Attachment>>,
    /// Blocks of kinds defined elsewhere ([`Model::add_constraints`]).
    other: Vec<Box<dyn ConstraintBlock>>,
    /// One entry per `add_*` call, in order ([`Model::constraint_groups`]).
    groups: Vec<(ConstraintGroup, GroupStorage)>,
}

impl Clone for Model {
    fn clone(&self) -> Self {
        Self {
            rest_positions: self.rest_positions.clone(),
            masses: self.masses.clone(),
            fixed: self.fixed.clone(),
            bodies: self.bodies.clone(),
            tet_strain: self.tet_strain.clone(),
            springs: self.springs.clone(),
            attachments: self.attachments.clone(),
            other: self.other.iter().map(|b| b.boxed_clone()).collect(),
            groups: self.groups.clone(),
        }
    }
}

impl Model {
    /// An empty model.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a body with one mass (kg) per vertex.
    ///
    /// # Errors
    /// A mass count that differs from the vertex count, or a mass that is
    /// negative or not finite.
    pub fn add_body(&mut self, mesh: Mesh, masses: Vec<f64>) -> Result<BodyId, SolverError> {
        let body = self.bodies.len();
        if masses.len() != mesh.num_vertices() {
            return Err(SolverError::InvalidModel {
                reason: format!(
                    "body {body}: {} masses for {} vertices",
                    masses.len(),
                    mesh.num_vertices()
                ),
            });
        }
        if let Some(vertex) = masses.iter().position(|m| !(m.is_finite() && *m >= 0.0)) {
            return Err(SolverError::InvalidModel {
                reason: format!(
                    "body {body}: vertex {vertex} has mass {}; masses must be finite and >= 0",
                    masses[vertex]
                ),
            });
        }
        let offset = self.rest_positions.len();
        self.rest_positions.extend_from_slice(mesh.vertices());
        self.masses.extend_from_slice(&masses);
        self.fixed.resize(self.rest_positions.len(), false);
        self.bodies.push(Body { mesh, offset });
        Ok(BodyId(body))
    }

    /// Adds a corotational strain constraint for every tetrahedron of a body
    /// (stiffness in Pa, optional stretch limits). Returns how many.
    ///
    /// # Errors
    /// A body without tetrahedra, or invalid parameters.
    pub fn add_tet_strain(
        &mut self,
        body: BodyId,
        stiffness: f64,
        limits: Option<(f64, f64)>,
    ) -> Result<usize, SolverError> {
        let b = self.body(body)?;
        if b.mesh.tets().is_empty() {
            return Err(SolverError::InvalidModel {
                reason: format!("body {}: tet-strain needs a tetrahedral mesh", body.0),
            });
        }
        let offset = b.offset;
        let rest = &self.rest_positions;
        let new = b
            .mesh
            .tets()
            .iter()
            .map(|t| TetStrain::new(rest, t.map(|v| v + offset), stiffness, limits))
            .collect::<Result<Vec<_>, _>>()
            .map(locality_order);
        let start = self.tet_strain.len();
        let count = Self::append(body, new, &mut self.tet_strain)?;
        self.record_group(
            Some(body),
            TetStrain::KIND,
            Some(stiffness),
            GroupStorage::TetStrain(start..start + count),
        );
        Ok(count)
    }

    /// Adds a spring along every edge of a body (stiffness in N/m, rest
    /// length the rest distance). Returns how many.
    ///
    /// # Errors
    /// A body without edges, or invalid parameters.
    pub fn add_springs(&mut self, body: BodyId, stiffness: f64) -> Result<usize, SolverError> {
        self.add_springs_with_rest_length(body, stiffness, None)
    }

    /// Like [`Model::add_springs`] with one rest length in m for every edge
    /// (`Some(0.0)`: zero-rest-length springs, whose energy is quadratic and
    /// convex); `None` takes each edge's rest distance. Returns how many.
    ///
    /// # Errors
    /// A body without edges, or invalid parameters.
    pub fn add_springs_with_rest_length(
        &mut self,
        body: BodyId,
        stiffness: f64,
        rest_length: Option<f64>,
    ) -> Result<usize, SolverError> {
        let b = self.body(body)?;
        if b.mesh.edges().is_empty() {
            return Err(SolverError::InvalidModel {
                reason: format!("body {}: spring constraints need edges", body.0),
            });
        }
        let offset = b.offset;
        let rest = &self.rest_positions;
        let new = b
            .mesh
            .edges()
            .iter()
            .map(|e| Spring::with_rest_length(rest, e.map(|v| v + offset), stiffness, rest_length))
            .collect::<Result<Vec<_>, _>>();
        let start = self.springs.len();
        let count = Self::append(body, new, &mut self.springs)?;
        self.record_group(
            Some(body),
            Spring::KIND,
            Some(stiffness),
            GroupStorage::Springs(start..start + count),
        );
        Ok(count)
    }

    /// Adds constraints of any kind, including one defined outside this
    /// workspace (a type implementing [`Constraint`]), stored contiguously
    /// as one block. Their stencils are global vertex indices (a body's
    /// vertex `v` is `model.bodies()[b].offset + v`). A kind whose
    /// constraints are not translation invariant acts as an anchor (like
    /// attachments). Returns how many were added.
    ///
    /// # Errors
    /// A vertex out of range, naming the constraint.
    ///
    /// ```
    /// use pd_constraints::Spring;
    /// use pd_mesh::generators;
    /// use pd_solver::Model;
    ///
    /// let chain = generators::chain(3, 1.0).unwrap();
    /// let mut model = Model::new();
    /// model.add_body(chain, vec![0.1; 3]).unwrap();
    /// // One extra spring from the first to the last vertex.
    /// let spring = Spring::new(model.rest_positions(), [0, 2], 10.0).unwrap();
    /// assert_eq!(model.add_constraints(vec![spring]).unwrap(), 1);
    /// assert_eq!(model.num_constraints(), 1);
    /// ```
    pub fn add_constraints<C: Constraint>(
        &mut self,
        constraints: Vec<C>,
    ) -> Result<usize, SolverError> {
        let n = self.num_vertices();
        for (i, c) in constraints.iter().enumerate() {
            if let Some(&v) = c.vertices().iter().find(|&&v| v >= n) {
                return Err(SolverError::InvalidModel {
                    reason: format!(
                        "{} constraint {i}: vertex {v} is out of range: the model has {n} vertices",
                        C::KIND
                    ),
                });
            }
        }
        let count = constraints.len();
        let storage = if count > 0 {
            self.other.push(Box::new(ConstraintSet::new(constraints)));
            GroupStorage::Other(self.other.len() - 1)
        } else {
            GroupStorage::Empty
        };
        self.record_group(None, C::KIND, None, storage);
        Ok(count)
    }

    /// Appends freshly built constraints of one body, or names the body in
    /// the error; returns how many were added.
    fn append<C: Clone>(
        body: BodyId,
        new: Result<Vec<C>, pd_constraints::ConstraintError>,
        to: &mut Arc<Vec<C>>,
    ) -> Result<usize, SolverError> {
        let new = new.map_err(|source| SolverError::Constraint {
            body: body.0,
            source,
        })?;
        let count = new.len();
        Arc::make_mut(to).extend(new);
        Ok(count)
    }

    /// Softly attaches the given vertices of a body (its own numbering) to
    /// their rest positions with `stiffness` in N/m.
    ///
    /// # Errors
    /// A vertex out of range or invalid parameters.
    pub fn add_attachments(
        &mut self,
        body: BodyId,
        vertices: &[usize],
        stiffness: f64,
    ) -> Result<(), SolverError> {
        let range = self.body_vertices(body, vertices)?;
        let start = self.attachments.len();
        for &v in vertices {
            let global = range.start + v;
            let attachment = Attachment::new(global, self.rest_positions[global], stiffness)
                .map_err(|source| SolverError::Constraint {
                    body: body.0,
                    source,
                })?;
            Arc::make_mut(&mut self.attachments).push(attachment);
        }
        self.record_group(
            Some(body),
            Attachment::KIND,
            Some(stiffness),
            GroupStorage::Attachments(start..self.attachments.len()),
        );
        Ok(())
    }

    /// Removes the given vertices of a body (its own numbering) from the
    /// unknowns: they stay at their positions, with zero velocity.
    ///
    /// # Errors
    /// A vertex out of range.
    pub fn fix_vertices(&mut self, body: BodyId, vertices: &[usize]) -> Result<(), SolverError> {
        let range = self.body_vertices(body, vertices)?;
        for &v in vertices {
            self.fixed[range.start + v] = true;
        }
        Ok(())
    }

    /// Total number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.rest_positions.len()
    }

    /// Total number of constraints of every kind.
    pub fn num_constraints(&self) -> usize {
        self.tet_strain.len()
            + self.springs.len()
            + self.attachments.len()
            + self.other.iter().map(|b| b.len()).sum::<usize>()
    }

    /// Rest positions (m), global numbering.
    pub fn rest_positions(&self) -> &[Point] {
        &self.rest_positions
    }

    /// Lumped masses (kg), global numbering.
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Whether each vertex is hard-fixed.
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }

    /// The mass-weighted distance `|a - b|_M` between two sets of
    /// positions (or displacements) over the free vertices (m kg^(1/2)):
    /// the norm a step's relative error is measured in
    /// ([`crate::StepStats::estimated_error`]).
    ///
    /// ```
    /// use pd_mesh::{Point, generators};
    /// use pd_solver::Model;
    ///
    /// let mut model = Model::new();
    /// let body = model.add_body(generators::chain(3, 1.0).unwrap(), vec![4.0; 3]).unwrap();
    /// model.fix_vertices(body, &[0]).unwrap();
    /// let a = vec![Point::zeros(); 3];
    /// let b = vec![Point::new(5.0, 0.0, 0.0), Point::new(1.0, 0.0, 0.0), Point::zeros()];
    /// assert_eq!(model.mass_distance(&a, &b), 2.0); // the fixed vertex 0 is left out
    /// ```
    pub fn mass_distance(&self, a: &[Point], b: &[Point]) -> f64 {
        (self.masses.iter().zip(&self.fixed))
            .zip(a.iter().zip(b))
            .filter(|((_, fixed), _)| !**fixed)
            .map(|((m, _), (a, b))| m * (a - b).norm_squared())
            .sum::<f64>()
            .sqrt()
    }

    /// The bodies, in the order they were added.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Checks that every free (not fixed) vertex has a positive mass, as
    /// the global matrix's mass term needs; a vertex that no element
    /// touches gets no mass from a density.
    ///
    /// # Errors
    /// [`SolverError::InvalidModel`] for the first free vertex without
    /// mass, named by its body, its index in the body's mesh and its index
    /// in the model.
    ///
    /// ```
    /// use pd_mesh::generators;
    /// use pd_solver::Model;
    ///
    /// let mut model = Model::new();
    /// for masses in [vec![1.0; 3], vec![1.0, 0.0, 1.0]] {
    ///     model.add_body(generators::chain(3, 1.0).unwrap(), masses).unwrap();
    /// }
    /// let message = model.check_free_masses().unwrap_err().to_string();
    /// assert!(message.contains("body 1 vertex 1 (vertex 4 of the model)"));
    /// ```
    pub fn check_free_masses(&self) -> Result<(), SolverError> {
        for (b, body) in self.bodies.iter().enumerate() {
            for (local, v) in body.vertices().enumerate() {
                let mass = self.masses[v];
                if !self.fixed[v] && !(mass > 0.0) {
                    return Err(SolverError::InvalidModel {
                        reason: format!(
                            "body {b} vertex {local} (vertex {v} of the model) is free but has \
                             mass {mass}: every free vertex needs a positive mass (is it \
                             touched by no element?)"
                        ),
                    });
                }
            }
        }
        Ok(())
    }

    /// The constraint sets that hold at least one constraint, one block per
    /// kind.
    pub fn constraint_blocks(&self) -> Vec<Box<dyn ConstraintBlock>> {
        let mut blocks: Vec<Box<dyn ConstraintBlock>> = Vec::new();
        if !self.tet_strain.is_empty() {
            blocks.push(Box::new(ConstraintSet::shared(self.tet_strain.clone())));
        }
        if !self.springs.is_empty() {
            blocks.push(Box::new(ConstraintSet::shared(self.springs.clone())));
        }
        if !self.attachments.is_empty() {
            blocks.push(Box::new(ConstraintSet::shared(self.attachments.clone())));
        }
        blocks.extend(self.other.iter().map(|b| b.boxed_clone()));
        blocks
    }

    fn body(&self, body: BodyId) -> Result<&Body, SolverError> {
        self.bodies
            .get(body.0)
            .ok_or_else(|| SolverError::InvalidModel {
                reason: format!("there is no body {}", body.0),
            })
    }

    fn body_vertices(&self, body: BodyId, vertices: &[usize]) -> Result<Range<usize>, SolverError> {
        let range = self.body(body)?.vertices();
        if let Some(&v) = vertices.iter().find(|&&v| v >= range.len()) {
            return Err(SolverError::InvalidModel {
                reason: format!(
                    "body {}: vertex {v} is out of range: the body has {} vertices",
                    body.0,
                    range.len()
                ),
            });
        }
        Ok(range)
    }
}
