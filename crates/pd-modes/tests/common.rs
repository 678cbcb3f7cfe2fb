//! The clamped tet beam of the modal tests (docs/design/validation.md,
//! sections 4 and 5): pd-solver's beam validations build the same one.

// Each test crate uses only some of these helpers.
#![allow(dead_code)]

use pd_mesh::{VertexSelection, generators};
use pd_solver::Model;

/// Density, kg/m^3.
pub const DENSITY: f64 = 1000.0;
/// The tet-strain stiffness, Pa. The corotational energy density is
/// `stiffness/2 |F - R|^2 = stiffness/2 |sym grad u|^2 + O(|grad u|^3)`,
/// i.e. linear elasticity with `mu = stiffness/2`, `lambda = 0`: Young's
/// modulus `E = 2 mu (1 + nu) = stiffness`, Poisson ratio 0.
pub const YOUNGS_MODULUS: f64 = 1.0e6;

/// A beam `size` with `cells`, regular Kuhn tets (no jitter: the
/// refinement study needs nested, similar meshes), density [`DENSITY`],
/// tet strain of [`YOUNGS_MODULUS`], the face x = 0 clamped (every vertex
/// on it fixed in x, y and z).
pub fn beam(size: [f64; 3], cells: [usize; 3]) -> Model {
    let mesh = generators::box_tets(size, cells).unwrap();
    let clamp = VertexSelection::Box {
        min: [-1.0; 3],
        max: [1e-9, size[1] + 1.0, size[2] + 1.0],
    }
    .resolve(&mesh)
    .unwrap();
    let masses = mesh.lumped_masses(DENSITY).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, YOUNGS_MODULUS, None).unwrap();
    model.fix_vertices(body, &clamp).unwrap();
    model
}
