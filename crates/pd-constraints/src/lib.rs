//! Projective Dynamics constraints: the energy terms
//! `w/2 |G x - P(G x)|^2`, their local projections, energies and gradients,
//! and the assembly of the constant operators the global step needs.
//!
//! A [`Constraint`] describes one term; a [`ConstraintSet`] stores many of one
//! kind contiguously; the solver sees each set through the object-safe
//! [`ConstraintBlock`] trait, one virtual call per range of constraints. The
//! kinds are [`TetStrain`] (corotational strain, optionally strain-limited),
//! [`Spring`], [`Attachment`], and for cloth and shells [`TriangleStrain`],
//! [`PlateBending`] and [`Bending`], [`Area`] and [`Volume`]. The mathematics is in
//! `docs/design/constraints.md`.
//!
//! ```
//! use pd_constraints::{assembly, ConstraintBlock, ConstraintSet, Spring};
//! use pd_mesh::generators;
//!
//! // A chain of 3 springs; its Laplacian is the 1D stiffness matrix.
//! let chain = generators::chain(4, 3.0).unwrap();
//! let springs = ConstraintSet::new(
//!     chain.edges().iter().map(|&e| Spring::new(chain.vertices(), e, 2.0)).collect::<Result<Vec<_>, _>>().unwrap(),
//! );
//! let blocks: Vec<Box<dyn ConstraintBlock>> = vec![Box::new(springs)];
//! let l = assembly::laplacian(&blocks, 4, assembly::LaplacianKind::System);
//! assert_eq!(l.row(1).collect::<Vec<_>>(), vec![(0, -2.0), (1, 4.0), (2, -2.0)]);
//!
//! // At rest every spring is satisfied: zero energy.
//! assert_eq!(blocks[0].energy_range(chain.vertices(), 0..3), 0.0);
//! ```

mod area;
pub mod assembly;
mod attachment;
pub mod bending;
mod constraint;
#[cfg(target_arch = "x86_64")]
mod lane_rows;
pub mod material;
mod material_set;
pub mod plate_bending;
pub mod polar;
pub mod polar_batch;
mod set;
pub mod signed_svd;
mod spring;
mod stencil;
mod tet_hessian;
pub mod tet_strain;
mod triangle_frame;
mod triangle_strain;
mod unit_product;
mod volume;

pub use area::Area;
pub use attachment::Attachment;
pub use bending::Bending;
pub use constraint::Constraint;
pub use material::{Lame, MaterialKind};
pub use material_set::{MaterialSet, MaterialTet};
pub use pd_linalg::{CsrMatrix, Triplet};
pub use plate_bending::PlateBending;
pub use set::{ConstraintBlock, ConstraintSet, EnergyBound, MAX_ROWS};
pub use spring::Spring;
pub use stencil::{MAX_STENCIL, Stencil};
pub use tet_strain::TetStrain;
pub use triangle_strain::TriangleStrain;
pub use volume::Volume;

/// What can be wrong with a constraint's parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConstraintError {
    /// A stiffness is negative, NaN or infinite.
    #[error("stiffness must be finite and >= 0, got {stiffness}")]
    InvalidStiffness {
        /// The rejected value.
        stiffness: f64,
    },
    /// Strain limits outside `0 <= min <= 1 <= max`.
    #[error("strain limits must satisfy 0 <= min <= 1 <= max, got [{min}, {max}]")]
    InvalidStrainLimits {
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// A spring rest length is negative or not finite.
    #[error("rest length must be finite and >= 0, got {rest_length}")]
    InvalidRestLength {
        /// The rejected value.
        rest_length: f64,
    },
    /// An attachment target is not finite.
    #[error("attachment target of vertex {vertex} is not finite")]
    NonFiniteTarget {
        /// The attached vertex.
        vertex: usize,
    },
    /// A vertex index does not fit the kind's compact storage (tet strain
    /// stores 32-bit indices).
    #[error("vertex index {vertex} exceeds the largest storable index {max}")]
    VertexIndexTooLarge {
        /// The rejected index.
        vertex: usize,
        /// The largest index the kind stores.
        max: usize,
    },
    /// An element refers to a vertex beyond the rest positions given.
    #[error(
        "element with vertices {vertices:?} refers to vertex {vertex}, but there are {count} rest \
         positions"
    )]
    VertexOutOfRange {
        /// The element's vertices.
        vertices: Vec<usize>,
        /// The first index out of range.
        vertex: usize,
        /// How many rest positions there are.
        count: usize,
    },
    /// An element's rest shape is flat or inverted.
    #[error("element with vertices {vertices:?} has a flat or inverted rest shape")]
    DegenerateElement {
        /// Its vertices.
        vertices: Vec<usize>,
    },
    /// Young's modulus not finite and > 0.
    #[error("young must be finite and > 0 Pa, got {young}")]
    InvalidYoung {
        /// The rejected value, Pa.
        young: f64,
    },
    /// Poisson's ratio outside `[0, 0.5)`.
    #[error("poisson must be in [0, 0.5), got {poisson}")]
    InvalidPoisson {
        /// The rejected value.
        poisson: f64,
    },
    /// An edge shared by more than two triangles (bending needs a manifold
    /// surface).
    #[error("edge {edge:?} is shared by more than two triangles: {triangles:?}")]
    NonManifoldEdge {
        /// Its two vertices.
        edge: [usize; 2],
        /// The triangles (indices in the mesh) that share it.
        triangles: Vec<usize>,
    },
}
