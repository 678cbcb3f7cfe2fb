//! Which vertices move together: the bodies' vertex ranges, the connected
//! components of their mesh graphs, and the free bodies among them, as the
//! damping models see them ([`pd_damping::StepContext`]).

use std::ops::Range;

use pd_constraints::ConstraintBlock;
use pd_damping::rigid::{RigidBody, RigidFreedom};
use pd_mesh::Point;

use crate::Model;
use crate::energy::bounding_box;

/// Bodies, components and free bodies of a model, computed once.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Topology {
    /// Vertex ranges of the bodies, in scene order.
    pub bodies: Vec<Range<usize>>,
    /// Free vertices of each connected component of the mesh graphs (edges,
    /// which include those of tetrahedra and triangles).
    pub components: Vec<Vec<usize>>,
    /// Every component with its free vertices and what holds it: fixed
    /// vertices and the vertices of anchoring constraints (attachments, or
    /// any block whose constraints are not translation invariant), at their
    /// rest positions. Only free ones keep their spin physically.
    pub rigid_bodies: Vec<RigidBody>,
}

impl Topology {
    /// The topology of `model`, whose constraints are `blocks`.
    pub fn of(model: &Model, blocks: &[Box<dyn ConstraintBlock>]) -> Self {
        let n = model.num_vertices();
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut v: usize) -> usize {
            while parent[v] != v {
                parent[v] = parent[parent[v]];
                v = parent[v];
            }
            v
        }
        for body in model.bodies() {
            for e in body.mesh.edges() {
                let (a, b) = (
                    root(&mut parent, e[0] + body.offset),
                    root(&mut parent, e[1] + body.offset),
                );
                if a != b {
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        let mut anchored = vec![false; n];
        for block in blocks.iter().filter(|b| !b.translation_invariant()) {
            for i in 0..block.len() {
                for &v in &block.stencil(i) {
                    anchored[v] = true;
                }
            }
        }
        let mut index_of_root = vec![usize::MAX; n];
        // Per component: its free vertices and the rest positions that hold it.
        let mut all: Vec<(Vec<usize>, Vec<Point>)> = Vec::new();
        let rest = model.rest_positions();
        for v in 0..n {
            let r = root(&mut parent, v);
            if index_of_root[r] == usize::MAX {
                index_of_root[r] = all.len();
                all.push((Vec::new(), Vec::new()));
            }
            let (vertices, held) = &mut all[index_of_root[r]];
            if model.fixed()[v] || anchored[v] {
                held.push(rest[v]);
            }
            if !model.fixed()[v] {
                vertices.push(v);
            }
        }
        let rigid_bodies = all
            .into_iter()
            .filter(|(vertices, _)| !vertices.is_empty())
            .map(|(vertices, held)| {
                let points: Vec<Point> = vertices.iter().map(|&v| rest[v]).collect();
                let (lo, hi) = bounding_box(&points);
                let freedom = RigidFreedom::of_held_points(&held, (hi - lo).norm());
                RigidBody { vertices, freedom }
            })
            .collect::<Vec<_>>();
        let components = rigid_bodies.iter().map(|b| b.vertices.clone()).collect();
        Self {
            bodies: model.bodies().iter().map(|b| b.vertices()).collect(),
            components,
            rigid_bodies,
        }
    }
}

impl Model {
    /// Every connected component of the mesh graphs (edges, those of
    /// tetrahedra and triangles included) with its free vertices and the
    /// rigid motions it keeps, judged from what holds it at rest: fixed
    /// vertices and the vertices of the constraints among `blocks` that are
    /// not translation invariant (attachments). `blocks` are the model's
    /// constraints, as [`Model::constraint_blocks`] returns them. These are
    /// the rigid bodies the damping models see
    /// ([`pd_damping::StepContext`]); components without free vertices are
    /// left out.
    ///
    /// ```
    /// use pd_damping::rigid::RigidFreedom;
    /// use pd_mesh::generators;
    /// use pd_solver::Model;
    ///
    /// let mut model = Model::new();
    /// let body = model.add_body(generators::chain(3, 1.0).unwrap(), vec![1.0; 3]).unwrap();
    /// model.add_springs(body, 10.0).unwrap();
    /// let free = model.rigid_bodies(&model.constraint_blocks());
    /// assert_eq!(free.len(), 1);
    /// assert_eq!(free[0].freedom, RigidFreedom::Free);
    /// ```
    pub fn rigid_bodies(&self, blocks: &[Box<dyn ConstraintBlock>]) -> Vec<RigidBody> {
        Topology::of(self, blocks).rigid_bodies
    }
}
