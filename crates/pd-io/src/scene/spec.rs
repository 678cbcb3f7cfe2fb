//! The typed scene: what a valid scene file means, in SI units, before
//! anything is built from it. [`super::validate`] makes it from the raw serde
//! image; [`Scene::build`](super::Scene::build) turns it into a simulation.

use std::path::PathBuf;

use pd_damping::registry::DampingSpec;
use pd_mesh::{Mesh, Point, VertexSelection};
use pd_solver::Settings;

/// Integrators a scene can name: the key of `pd_integrators::registry`.
pub use pd_integrators::registry::IntegratorKind;

/// Where a body's mesh comes from.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum MeshSource {
    /// `generator = "box"`: a tet mesh of `cells` cubes filling `size` (m).
    Box {
        /// Extent in m.
        size: [f64; 3],
        /// Cubes per axis.
        cells: [usize; 3],
    },
    /// `generator = "chain"`: `points` vertices over `length` m, springs between.
    Chain {
        /// Number of vertices.
        points: usize,
        /// Length in m.
        length: f64,
    },
    /// `generator = "cloth"`: a triangle grid in the x-z plane.
    Cloth {
        /// Extent in m (x, z).
        size: [f64; 2],
        /// Cells per axis (x, z).
        cells: [usize; 2],
    },
    /// `generator = "ball"`: a tet ball centred at the origin, the cube grid
    /// mapped radially onto the sphere ([`pd_mesh::generators::ball`]).
    Ball {
        /// Radius in m.
        radius: f64,
        /// Cells across the diameter (>= 2).
        cells: usize,
    },
    /// `file = "..."`: a TetGen `.node`/`.ele` pair (path resolved against the
    /// scene file's folder).
    TetGen(PathBuf),
    /// `file = "....face"`: a TetGen `.node`/`.face` pair read as a triangle
    /// surface (cloth).
    TetGenSurface(PathBuf),
    /// `file = "....msh"`: a Gmsh 4.1 ASCII mesh (tetrahedra, else triangles).
    Gmsh(PathBuf),
    /// `file = "....obj"`: a Wavefront OBJ surface (faces) or line network.
    Obj(PathBuf),
    /// `file = "....mesh"`: a Medit mesh (tetrahedra, else triangles).
    Medit(PathBuf),
    /// A mesh a program made in memory (no scene key): the Python package's
    /// `Model.add_body` puts its arrays here, so that the rest of the body is
    /// validated and built as a scene's.
    Given(Mesh),
}

/// How a body's masses are given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MassSpec {
    /// Density: kg/m^3 for tet meshes, kg/m^2 for triangle meshes, kg/m for
    /// edge graphs.
    Density(f64),
    /// The same mass for every vertex, kg.
    VertexMass(f64),
}

/// One constraint entry of a body.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum ConstraintSpec {
    /// `tet-strain`: stiffness in Pa, optional stretch limits.
    TetStrain {
        /// Pa.
        stiffness: f64,
        /// `[min, max]` principal stretches.
        limits: Option<(f64, f64)>,
    },
    /// `spring` along every edge: stiffness in N/m.
    Spring {
        /// N/m.
        stiffness: f64,
    },
    /// `triangle-strain` on every triangle: `E t` in N/m, optional stretch
    /// limits.
    TriangleStrain {
        /// N/m.
        stiffness: f64,
        /// `[min, max]` principal stretches.
        limits: Option<(f64, f64)>,
    },
    /// `bending` on every interior edge: flexural rigidity `D` in N m.
    Bending {
        /// N m.
        stiffness: f64,
    },
    /// `area` preservation of every triangle: N/m.
    Area {
        /// N/m.
        stiffness: f64,
    },
    /// `volume` preservation of every tetrahedron: Pa.
    Volume {
        /// Pa.
        stiffness: f64,
    },
    /// A hyperelastic material on every tetrahedron (`neo-hookean`, `stvk`,
    /// `corotated`; docs/design/materials.md).
    Material {
        /// The law.
        kind: pd_constraints::MaterialKind,
        /// Young's modulus, Pa.
        young: f64,
        /// Poisson's ratio, in `[0, 0.5)`.
        poisson: f64,
    },
    /// `attachment` of selected vertices to their rest positions: N/m.
    Attachment {
        /// N/m.
        stiffness: f64,
        /// Which vertices.
        selection: VertexSelection,
    },
}

/// A validated body.
#[derive(Debug, Clone, PartialEq)]
pub struct BodySpec {
    /// Name (defaults to `body0`, `body1`, ...).
    pub name: String,
    /// The mesh.
    pub mesh: MeshSource,
    /// The masses.
    pub mass: MassSpec,
    /// The constraints, in order.
    pub constraints: Vec<ConstraintSpec>,
    /// Hard-fixed vertices.
    pub fixed: Option<VertexSelection>,
    /// An initial-state file (resolved path).
    pub initial_state: Option<PathBuf>,
    /// Initial linear velocity (m/s).
    pub initial_velocity: Point,
    /// Initial angular velocity about the body's centre of mass (rad/s).
    pub angular_velocity: Point,
    /// Offset added to the mesh's rest positions (m).
    pub translate: Point,
    /// This body's own damping (`[[body]] damping = { ... }`), overriding
    /// the scene's `[damping]` for it; `None` uses `[damping]`.
    pub damping: Option<DampingSpec>,
}

/// Frame file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameFormat {
    /// Legacy VTK unstructured grid (`.vtk`), for ParaView.
    Vtk,
    /// Wavefront OBJ surface (`.obj`), for Blender.
    Obj,
    /// VTK XML unstructured grid (`.vtu`) with velocity and strain fields,
    /// plus the `frames.pvd` series, for ParaView.
    Vtu,
    /// PLY surface (`.ply`), for Blender, Houdini and MeshLab.
    Ply,
}

impl FrameFormat {
    /// Every format, in the order messages list them.
    pub const ALL: [FrameFormat; 4] = [Self::Vtk, Self::Vtu, Self::Obj, Self::Ply];

    /// The name scenes use in `output.formats`, which is also the frame
    /// files' extension.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vtk => "vtk",
            Self::Obj => "obj",
            Self::Vtu => "vtu",
            Self::Ply => "ply",
        }
    }

    /// The format a scene name stands for.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }
}

/// The `[output]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputSpec {
    /// Write a frame every `every` steps; 0 writes none.
    pub every: usize,
    /// Frame formats.
    pub formats: Vec<FrameFormat>,
    /// Vertices (global numbering) recorded every step in `probes.csv`.
    pub probes: Vec<usize>,
}

impl OutputSpec {
    /// Steps between frames as written: `every`, or 0 (no frames) when no
    /// format is asked for.
    pub fn frame_every(&self) -> usize {
        if self.formats.is_empty() {
            0
        } else {
            self.every
        }
    }
}

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The file it was read from (for messages and relative paths).
    pub source: PathBuf,
    /// Number of steps to run.
    pub steps: usize,
    /// Time-stepping settings.
    pub settings: Settings,
    /// The integrator.
    pub integrator: IntegratorKind,
    /// The damping model.
    pub damping: DampingSpec,
    /// The bodies.
    pub bodies: Vec<BodySpec>,
    /// What to write.
    pub output: OutputSpec,
    /// The iteration method (`[solver]`; local-global by default).
    pub solver: pd_solver::SolverSpec,
    /// Whether [`Scene::build`] chooses the iteration method by measurement
    /// ([`pd_solver::Simulation::choose_method`]): the scene sets
    /// `accuracy` and `[solver]` names no method. `solver.method` is then
    /// only the fallback.
    pub choose_method: bool,
    /// Where each step's iteration starts (`[solver] predictor`; inertial
    /// by default).
    pub predictor: pd_solver::Predictor,
    /// Contact with colliders (`[[collider]]`, `[contact]`); `None` when
    /// the scene names no collider.
    pub contact: Option<pd_solver::contact::ContactSettings>,
    /// Contact between bodies (`[contact] bodies = true`), on top of
    /// `contact` (which then holds its thickness).
    pub body_contact: Option<pd_solver::contact::BodyContactSettings>,
    /// Which surface pairs `body_contact` admits (`bodies`, `self`).
    pub surface_pairs: pd_solver::contact::SurfacePairs,
}
