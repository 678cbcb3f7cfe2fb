//! Projective Dynamics with Laplacian damping: deformable bodies (tet
//! solids, cloth, spring networks) stepped by a parallel local step and a
//! prefactored sparse global solve. This crate is the front door: it
//! re-exports the workspace's crates by concern, gathers what a program
//! needs in [`prelude`], builds a simulation with
//! [`Simulation::builder`](prelude::Simulation::builder), and loads a scene
//! file in one call ([`load_scene`]). The crates below stay usable on their
//! own: [`mesh`] (geometry), [`linalg`] (sparse Cholesky, SIMD dispatch),
//! [`constraints`] (the PD energy terms), [`integrators`], [`damping`] (each
//! damping model a trait implementation), [`solver`] (the model and the
//! time step), [`contact`] (colliders, contact between and within bodies),
//! [`modes`] (modal analysis), [`adjoint`] (gradients of a loss on a run) and, with the default `scenes` feature, [`io`] (scene files, mesh readers, frame
//! writers). A program that needs no contact depends on `pd-solver` with
//! `default-features = false, features = ["metis"]` and compiles none of it.
//!
//! A clamped beam with Laplacian damping:
//!
//! ```
//! use pd::prelude::*;
//!
//! let beam = generators::box_tets([1.0, 0.1, 0.1], [10, 1, 1])?;
//! let clamp = VertexSelection::Box { min: [-1.0; 3], max: [1e-9, 1.0, 1.0] }.resolve(&beam)?;
//! let masses = beam.lumped_masses(1000.0)?;
//! let mut model = Model::new();
//! let body = model.add_body(beam, masses)?;
//! model.add_tet_strain(body, 1e6, None)?;
//! model.fix_vertices(body, &clamp)?;
//! let mut sim = Simulation::builder(model)
//!     .integrator(ImplicitMidpoint)
//!     .damping(LaplacianDamping::new(0.003, 0.0, false)?)
//!     .dt(0.01)
//!     .build()?;
//! sim.run(20)?;
//! assert!(sim.state().positions.iter().all(|p| p.iter().all(|c| c.is_finite())));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub use pd_adjoint as adjoint;
pub use pd_constraints as constraints;
pub use pd_contact as contact;
pub use pd_damping as damping;
pub use pd_integrators as integrators;
#[cfg(feature = "scenes")]
pub use pd_io as io;
pub use pd_linalg as linalg;
pub use pd_mesh as mesh;
pub use pd_modes as modes;
pub use pd_solver as solver;

/// What most programs need, in one `use pd::prelude::*;`.
pub mod prelude {
    pub use pd_constraints::{Constraint, ConstraintSet};
    pub use pd_damping::registry::DampingSpec;
    pub use pd_damping::{
        Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged,
    };
    pub use pd_integrators::{BackwardEuler, Bdf2, ImplicitMidpoint, Integrator};
    pub use pd_mesh::{Mesh, Point, VertexSelection, generators};
    pub use pd_solver::contact::{Collider, ColliderShape, ContactSettings};
    pub use pd_solver::{
        BodyId, Energies, Model, PositionSolver, Settings, Simulation, SimulationBuilder,
        SolverError, SolverMethod, SolverSpec, State,
    };

    #[cfg(feature = "scenes")]
    pub use crate::load_scene;
    #[cfg(feature = "scenes")]
    pub use pd_io::scene::Scene;
}

/// Loads a scene file (TOML or JSON, by extension; `docs/reference/scene-format.md`)
/// and builds its simulation, at the scene's initial state.
///
/// # Errors
/// A file that cannot be read or parsed, or a scene that cannot be built;
/// each error names the file and the field.
#[cfg(feature = "scenes")]
pub fn load_scene(path: impl AsRef<std::path::Path>) -> pd_io::Result<pd_solver::Simulation> {
    pd_io::scene::Scene::load(path.as_ref())?.build()
}
