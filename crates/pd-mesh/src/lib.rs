//! Meshes for Projective Dynamics: tetrahedral meshes, triangle meshes and
//! edge (spring) graphs, their rest geometry, lumped masses, boundary
//! surfaces, vertex selections and generators.
//!
//! This crate owns geometry only. It knows nothing of constraints, solvers
//! or files; a [`Mesh`] is validated once, when it is built, so code that
//! receives one may rely on its invariants.
//!
//! ```
//! use pd_mesh::{generators, VertexSelection};
//!
//! // A 1 m x 0.2 m x 0.2 m beam of 10 x 2 x 2 cubes, 6 tetrahedra each.
//! let beam = generators::box_tets([1.0, 0.2, 0.2], [10, 2, 2]).unwrap();
//! assert_eq!(beam.num_vertices(), 11 * 3 * 3);
//! assert_eq!(beam.tets().len(), 10 * 2 * 2 * 6);
//!
//! // Lumped masses from a density in kg/m^3 add up to rho * volume.
//! let total: f64 = beam.lumped_masses(1000.0).unwrap().iter().sum();
//! assert!((total - 1000.0 * 0.04).abs() < 1e-9);
//!
//! // The clamped end of a cantilever: every vertex with x <= 0.
//! let clamp = VertexSelection::Box { min: [-1.0, -1.0, -1.0], max: [1e-9, 1.0, 1.0] };
//! assert_eq!(clamp.resolve(&beam).unwrap().len(), 9);
//! ```

mod error;
pub mod generators;
mod mesh;
mod selection;
mod surface;

pub use error::MeshError;
pub use mesh::{ElementKind, Mesh, Point, tet_volume};
pub use selection::VertexSelection;
