//! The boundary surface of a mesh: what a renderer draws and what collision
//! handling tests against.

use std::collections::HashMap;

use crate::Mesh;

/// The four faces of a positively oriented tetrahedron `[a, b, c, d]`, as
/// positions in it, each ordered so that `(b - a) x (c - a)` points away from
/// the vertex opposite the face. Listed as: opposite `d`, `c`, `b`, `a`.
const OUTWARD_TET_FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

impl Mesh {
    /// The boundary surface as triangles.
    ///
    /// For a tetrahedral mesh, these are the tetrahedron faces that belong
    /// to exactly one tetrahedron, each ordered so that its normal
    /// `(b - a) x (c - a)` points out of its tetrahedron; they come in order
    /// of tetrahedron index, then of the face's opposite vertex (`d`, `c`,
    /// `b`, `a`). For a mesh without tetrahedra, its triangles as stored.
    ///
    /// Costs `O(T)` expected time and memory for `T` tetrahedra (one hash map
    /// of faces).
    ///
    /// ```
    /// use pd_mesh::{Mesh, Point};
    /// let vertices = vec![
    ///     Point::new(0.0, 0.0, 0.0),
    ///     Point::new(1.0, 0.0, 0.0),
    ///     Point::new(0.0, 1.0, 0.0),
    ///     Point::new(0.0, 0.0, 1.0),
    /// ];
    /// let tet = Mesh::from_tets(vertices, vec![[0, 1, 2, 3]]).unwrap();
    /// let surface = tet.surface_triangles();
    /// assert_eq!(surface.len(), 4);
    /// // The face on the plane z = 0 has its normal along -z.
    /// assert_eq!(surface[0], [0, 2, 1]);
    /// ```
    pub fn surface_triangles(&self) -> Vec<[usize; 3]> {
        if self.tets().is_empty() {
            return self.triangles().to_vec();
        }
        let outward_faces = |tet: &[usize; 4]| OUTWARD_TET_FACES.map(|face| face.map(|v| tet[v]));
        let face_key = |face: [usize; 3]| {
            let mut key = face;
            key.sort_unstable();
            key
        };
        let mut tets_per_face: HashMap<[usize; 3], usize> =
            HashMap::with_capacity(2 * self.tets().len());
        for face in self.tets().iter().flat_map(outward_faces) {
            *tets_per_face.entry(face_key(face)).or_default() += 1;
        }
        self.tets()
            .iter()
            .flat_map(outward_faces)
            .filter(|&face| tets_per_face[&face_key(face)] == 1)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use crate::{Mesh, Point, generators};

    fn unit_tet_vertices() -> Vec<Point> {
        vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
        ]
    }

    #[test]
    fn every_face_of_a_single_tet_points_away_from_its_opposite_vertex() {
        let vertices = unit_tet_vertices();
        let mesh = Mesh::from_tets(vertices.clone(), vec![[0, 1, 2, 3]]).unwrap();
        let surface = mesh.surface_triangles();
        assert_eq!(surface.len(), 4);
        for face in surface {
            let opposite = (0..4).find(|v| !face.contains(v)).unwrap();
            let [a, b, c] = face.map(|v| vertices[v]);
            let normal = (b - a).cross(&(c - a));
            assert!(normal.dot(&(vertices[opposite] - a)) < 0.0, "{face:?}");
        }
    }

    #[test]
    fn shared_face_of_two_tets_is_interior() {
        let mut vertices = unit_tet_vertices();
        vertices.push(Point::new(1.0, 1.0, 1.0));
        // Both tets contain face {1, 2, 3}; the second lies on its far side.
        let mesh = Mesh::from_tets(vertices, vec![[0, 1, 2, 3], [4, 1, 3, 2]]).unwrap();
        let surface = mesh.surface_triangles();
        assert_eq!(surface.len(), 6);
        assert!(surface.iter().all(|face| {
            let mut key = *face;
            key.sort_unstable();
            key != [1, 2, 3]
        }));
    }

    #[test]
    fn mesh_without_tets_returns_its_triangles() {
        let cloth = generators::cloth([1.0, 1.0], [2, 3]).unwrap();
        assert_eq!(cloth.surface_triangles(), cloth.triangles());
        let rope = generators::chain(4, 1.0).unwrap();
        assert!(rope.surface_triangles().is_empty());
    }
}
