//! Which vertices move together: the bodies' vertex ranges, the connected
//! components of their mesh graphs, and the free bodies among them, as the
//! damping models see them ([`pd_damping::StepContext`]).

use std::ops::Range;

use crate::Model;

/// Bodies, components and free bodies of a model, computed once.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Topology {
    /// Vertex ranges of the bodies, in scene order.
    pub bodies: Vec<Range<usize>>,
    /// Free vertices of each connected component of the mesh graphs (edges,
    /// which include those of tetrahedra and triangles).
    pub components: Vec<Vec<usize>>,
    /// The components without any fixed vertex: free rigid bodies.
    pub free_bodies: Vec<Vec<usize>>,
}

impl Topology {
    /// The topology of `model`.
    pub fn of(model: &Model) -> Self {
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
        let mut index_of_root = vec![usize::MAX; n];
        let mut all: Vec<(Vec<usize>, bool)> = Vec::new();
        for v in 0..n {
            let r = root(&mut parent, v);
            if index_of_root[r] == usize::MAX {
                index_of_root[r] = all.len();
                all.push((Vec::new(), false));
            }
            let (vertices, held) = &mut all[index_of_root[r]];
            if model.fixed()[v] {
                *held = true;
            } else {
                vertices.push(v);
            }
        }
        let free_bodies = all
            .iter()
            .filter(|(vertices, held)| !held && !vertices.is_empty())
            .map(|(vertices, _)| vertices.clone())
            .collect();
        let components = all
            .into_iter()
            .map(|(vertices, _)| vertices)
            .filter(|vertices| !vertices.is_empty())
            .collect();
        Self {
            bodies: model.bodies().iter().map(|b| b.vertices()).collect(),
            components,
            free_bodies,
        }
    }
}
