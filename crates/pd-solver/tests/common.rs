//! Helpers shared by the solver's integration tests.
#![allow(dead_code)]

use pd_constraints::assembly::{self, LaplacianKind};
use pd_damping::NoDamping;
use pd_integrators::{BackwardEuler, Bdf2, ImplicitMidpoint, Integrator};
use pd_mesh::{Mesh, Point, VertexSelection};
use pd_solver::contact::{Collider, ColliderShape};
use pd_solver::{BodyId, Model, Settings, Simulation, SolverMethod, SolverSpec};

/// The bits of every coordinate, for bit-for-bit comparisons.
pub fn bits(points: &[Point]) -> Vec<u64> {
    points
        .iter()
        .flat_map(|p| p.iter().map(|c| c.to_bits()))
        .collect()
}

/// The free block of the rotation-preserving damping's tests: a jittered
/// 0.4 x 0.2 x 0.1 m box of 4 x 2 x 2 cells, 500 kg/m^3, `tet-strain` 1e6
/// Pa (spun by the tests about an axis off its principal axes).
pub fn spinning_block_model() -> Model {
    let mesh = jittered_box([4, 2, 2], [0.4, 0.2, 0.1], 0.1, 5);
    let masses = mesh.lumped_masses(500.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e6, None).unwrap();
    model
}

/// Unit round-off of f64.
pub const U: f64 = f64::EPSILON / 2.0;

/// A box tet mesh with its rest positions perturbed by up to `jitter` of a
/// cell (deterministic in `seed`), so that tests do not depend on a regular
/// grid. Jitter below 0.2 cells keeps every tet positively oriented.
pub fn jittered_box(cells: [usize; 3], size: [f64; 3], jitter: f64, seed: u64) -> Mesh {
    let mesh = pd_mesh::generators::box_tets(size, cells).unwrap();
    let cell = Point::new(
        size[0] / cells[0] as f64,
        size[1] / cells[1] as f64,
        size[2] / cells[2] as f64,
    );
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    let vertices: Vec<Point> = mesh
        .vertices()
        .iter()
        .map(|p| p + Point::new(next() * cell.x, next() * cell.y, next() * cell.z) * jitter)
        .collect();
    Mesh::from_tets(vertices, mesh.tets().to_vec()).unwrap()
}

/// A cantilever: a jittered box beam (`jittered_box` with jitter 0.1) of
/// density 1000 kg/m^3 with corotational strain of `stiffness` Pa, and every
/// vertex with x <= 0.01 m fixed.
pub fn clamped_beam(
    cells: [usize; 3],
    size: [f64; 3],
    seed: u64,
    stiffness: f64,
) -> (Model, BodyId) {
    let mesh = jittered_box(cells, size, 0.1, seed);
    let clamp = VertexSelection::Box {
        min: [-1.0; 3],
        max: [0.01, 1.0, 1.0],
    }
    .resolve(&mesh)
    .unwrap();
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, stiffness, None).unwrap();
    model.fix_vertices(body, &clamp).unwrap();
    (model, body)
}

/// The solver tests' 1 x 0.2 x 0.2 m beam ([`clamped_beam`] of 10 x 2 x
/// 2 cells, seed 7, 1e6 Pa), undamped, stepped by `scheme` with `method`
/// (its default parameters) and `settings`.
pub fn method_beam(scheme: Scheme, method: SolverMethod, settings: Settings) -> Simulation {
    let (model, _) = clamped_beam([10, 2, 2], [1.0, 0.2, 0.2], 7, 1e6);
    let mut sim =
        Simulation::new(model, scheme.integrator(), Box::new(NoDamping), settings).unwrap();
    let spec = SolverSpec {
        method,
        ..SolverSpec::default()
    };
    sim.set_position_solver(spec.create().unwrap());
    sim
}

/// Largest absolute row sum of the system Laplacian (N/m): a bound on its
/// largest eigenvalue (Gershgorin), used to scale round-off tolerances.
pub fn laplacian_norm(model: &Model) -> f64 {
    let l = assembly::laplacian(
        &model.constraint_blocks(),
        model.num_vertices(),
        LaplacianKind::System,
    );
    (0..l.nrows())
        .map(|r| l.row(r).map(|(_, v)| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// The three integrators, as the tests iterate over them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scheme {
    /// `pd_integrators::BackwardEuler`.
    BackwardEuler,
    /// `pd_integrators::ImplicitMidpoint`.
    ImplicitMidpoint,
    /// `pd_integrators::Bdf2`.
    Bdf2,
}

/// Every integrator.
pub const SCHEMES: [Scheme; 3] = [
    Scheme::BackwardEuler,
    Scheme::ImplicitMidpoint,
    Scheme::Bdf2,
];

impl Scheme {
    /// A fresh integrator of this kind.
    pub fn integrator(self) -> Box<dyn Integrator> {
        match self {
            Self::BackwardEuler => Box::new(BackwardEuler),
            Self::ImplicitMidpoint => Box::new(ImplicitMidpoint),
            Self::Bdf2 => Box::new(Bdf2::new()),
        }
    }
}

/// The total linear momentum `sum m_i v_i` of a simulation's state, kg m/s.
pub fn momentum(sim: &Simulation) -> Point {
    let s = sim.state();
    (s.velocities.iter().zip(sim.model().masses()))
        .map(|(v, m)| v * *m)
        .sum()
}

/// Adds a cube of side `size` (m), `cells` per side, 1000 kg/m^3,
/// tet-strain stiffness `k` (Pa), its lowest face centred at `bottom`.
pub fn add_cube(model: &mut Model, size: f64, cells: usize, k: f64, bottom: Point) {
    let mesh = pd_mesh::generators::box_tets([size; 3], [cells; 3]).unwrap();
    let (lo, hi) = mesh.bounding_box().unwrap();
    let centre = (lo + hi) / 2.0;
    let offset = bottom - Point::new(centre.x, lo.y, centre.z);
    let mesh = mesh.translated(offset);
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, k, None).unwrap();
}

/// The contact tests' stack: a 0.2 m cube (3 cells, 1e5 Pa) whose lowest
/// face is `gap` (m) above the floor, and a 0.1 m cube (2 cells, 1e5 Pa)
/// 0.05 m above it, off-centre by 2 cm so that no vertex meets a vertex.
pub fn stacked_cubes(gap: f64) -> Model {
    let mut model = Model::new();
    add_cube(&mut model, 0.2, 3, 1e5, Point::new(0.0, gap, 0.0));
    add_cube(&mut model, 0.1, 2, 1e5, Point::new(0.02, 0.25, 0.01));
    model
}

/// The floor plane `y = 0` with Coulomb coefficient `friction`, no
/// restitution.
pub fn floor(friction: f64) -> Collider {
    Collider {
        shape: ColliderShape::Plane {
            point: Point::zeros(),
            normal: Point::y(),
        },
        friction,
        restitution: 0.0,
    }
}
