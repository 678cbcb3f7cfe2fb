//! Strategies and helpers shared by the property tests (`prop_*.rs`): random
//! small scenes (jittered tet boxes, spring chains, both at once), random
//! masses, velocities and damping models.
//!
//! Case counts are modest so that `cargo test` stays fast; the `proptest!`
//! macro applies the `PROPTEST_CASES` environment variable on top of the
//! count written here, so `PROPTEST_CASES=2000 cargo test -p pd-solver --test
//! prop_energy` is a long run (docs/design/properties.md).
#![allow(dead_code)]

use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged};
use pd_mesh::{Mesh, Point, generators};
use pd_solver::{Model, Settings};
use proptest::prelude::*;

use crate::common::jittered_box;

/// The config of every property test: `cases` by default (raised by
/// `PROPTEST_CASES`), and a bounded shrink so a failure reports quickly.
pub fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        max_shrink_iters: 200,
        ..ProptestConfig::default()
    }
}

/// The shape of a random scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A jittered tet box of `cells` cells (6 tets per cell).
    Box {
        /// Cells along x, y, z.
        cells: [usize; 3],
    },
    /// A straight chain of `points` vertices (1 m long), whose inertia is
    /// singular at rest.
    Chain {
        /// Vertices.
        points: usize,
    },
    /// A chain and a one-cell tet box 2 m away: two bodies.
    ChainAndCube {
        /// Vertices of the chain.
        points: usize,
    },
    /// A 1 m x 0.7 m cloth of `cells` quads (two triangles each), flat for
    /// an even seed and with a rest shape bent out of plane by up to 0.1 m
    /// for an odd one (so both plate and curved bending occur).
    Cloth {
        /// Quads along x and z.
        cells: [usize; 2],
    },
}

/// Which energy the scene's edges or tets carry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// Zero-rest-length springs on every edge: a quadratic, convex energy.
    ZeroLengthSprings,
    /// Corotational tet strain and volume preservation (`0.5 x stiffness`)
    /// on boxes, rest-length springs on chains,
    /// triangle strain, bending (`D = 1e-3 m^2 x stiffness`) and area
    /// (`0.1 x stiffness`) on cloth: rotation-invariant, nonconvex.
    Elastic,
}

/// A random scene: shape, rest-shape seed, stiffness, per-vertex masses and
/// initial velocities (the vectors are long enough for every shape; extra
/// entries are ignored).
#[derive(Debug, Clone)]
pub struct Scene {
    /// Shape.
    pub shape: Shape,
    /// Seed of the rest-shape jitter.
    pub seed: u64,
    /// Stiffness: N/m for springs, Pa for tet strain.
    pub stiffness: f64,
    /// Masses in kg.
    pub masses: Vec<f64>,
    /// Velocities in m/s.
    pub velocities: Vec<Point>,
}

/// Most vertices a [`Scene`] can have (a 2 x 2 x 2 box).
pub const MAX_VERTICES: usize = 27;

impl Scene {
    /// The meshes of the scene, one per body.
    pub fn meshes(&self) -> Vec<Mesh> {
        match self.shape {
            Shape::Box { cells } => vec![jittered_box(cells, [1.0, 0.7, 0.4], 0.15, self.seed)],
            Shape::Chain { points } => vec![generators::chain(points, 1.0).unwrap()],
            Shape::ChainAndCube { points } => vec![
                generators::chain(points, 1.0).unwrap(),
                jittered_box([1, 1, 1], [0.3, 0.3, 0.3], 0.1, self.seed)
                    .translated(Point::new(2.0, 0.0, 0.0)),
            ],
            Shape::Cloth { cells } => vec![self.cloth(cells)],
        }
    }

    /// The cloth of [`Shape::Cloth`]: bent along y by a seeded smooth field
    /// for an odd seed.
    fn cloth(&self, cells: [usize; 2]) -> Mesh {
        let flat = generators::cloth([1.0, 0.7], cells).unwrap();
        if self.seed.is_multiple_of(2) {
            return flat;
        }
        let phase = self.seed as f64 * 0.37;
        let vertices = flat
            .vertices()
            .iter()
            .map(|p| p + Point::y() * (0.1 * (3.0 * p.x + 2.0 * p.z + phase).sin()))
            .collect();
        Mesh::from_triangles(vertices, flat.triangles().to_vec()).unwrap()
    }

    /// The model with `material`; `pin_first` hard-fixes the first vertex.
    pub fn model(&self, material: Material, pin_first: bool) -> Model {
        let mut model = Model::new();
        let mut used = 0;
        for mesh in self.meshes() {
            let n = mesh.num_vertices();
            let has_tets = !mesh.tets().is_empty();
            let is_cloth = !has_tets && !mesh.triangles().is_empty();
            let body = model
                .add_body(mesh, self.masses[used..used + n].to_vec())
                .unwrap();
            used += n;
            match (material, has_tets) {
                (Material::ZeroLengthSprings, _) => {
                    model
                        .add_springs_with_rest_length(body, self.stiffness, Some(0.0))
                        .unwrap();
                }
                (Material::Elastic, true) => {
                    model.add_tet_strain(body, self.stiffness, None).unwrap();
                    model.add_volume(body, 0.5 * self.stiffness).unwrap();
                }
                (Material::Elastic, false) if is_cloth => {
                    model
                        .add_triangle_strain(body, self.stiffness, None)
                        .unwrap();
                    model.add_bending(body, 1e-3 * self.stiffness).unwrap();
                    model.add_area(body, 0.1 * self.stiffness).unwrap();
                }
                (Material::Elastic, false) => {
                    model.add_springs(body, self.stiffness).unwrap();
                }
            }
        }
        if pin_first {
            model.fix_vertices(pd_solver::BodyId(0), &[0]).unwrap();
        }
        model
    }

    /// The initial velocities of a model of this scene (fixed vertices get
    /// zero from `Simulation::set_state`).
    pub fn initial_velocities(&self, n: usize) -> Vec<Point> {
        self.velocities[..n].to_vec()
    }
}

/// `n` random vectors with coordinates in `(-bound, bound)`.
pub fn points(n: usize, bound: f64) -> impl Strategy<Value = Vec<Point>> {
    proptest::collection::vec((-bound..bound, -bound..bound, -bound..bound), n)
        .prop_map(|v| v.into_iter().map(|(x, y, z)| Point::new(x, y, z)).collect())
}

/// Random scene shapes, at most [`MAX_VERTICES`] vertices.
pub fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        (1usize..=2, 1usize..=2, 1usize..=2).prop_map(|(a, b, c)| Shape::Box { cells: [a, b, c] }),
        (2usize..=8).prop_map(|points| Shape::Chain { points }),
        (2usize..=8).prop_map(|points| Shape::ChainAndCube { points }),
        (1usize..=2, 1usize..=2).prop_map(|(a, b)| Shape::Cloth { cells: [a, b] }),
    ]
}

/// Random scenes with stiffness in `stiffness` and velocities up to
/// `speed` m/s per coordinate; masses from 0.01 to 10 kg.
pub fn scene(stiffness: std::ops::Range<f64>, speed: f64) -> impl Strategy<Value = Scene> {
    (
        shape(),
        0u64..1000,
        stiffness,
        proptest::collection::vec(0.01..10.0f64, MAX_VERTICES),
        points(MAX_VERTICES, speed),
    )
        .prop_map(|(shape, seed, stiffness, masses, velocities)| Scene {
            shape,
            seed,
            stiffness,
            masses,
            velocities,
        })
}

/// A damping model with its parameters, so that a case can be rebuilt and
/// printed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DampingChoice {
    /// No damping.
    None,
    /// Explicit ether drag `v <- (1 - k) v`.
    EtherFactor(f64),
    /// Explicit ether drag `v <- exp(-c h) v`, `c` in 1/s.
    EtherRate(f64),
    /// Implicit ether drag `D = a1 M`, `a1` in 1/s.
    EtherImplicit(f64),
    /// PBD damping with factor `k`.
    Pbd(f64),
    /// Laplacian damping `D = a2 L_d + a1 M` (a2 in s, a1 in 1/s); the flag
    /// selects the rotation-preserving variant.
    Laplacian {
        /// `a2` in s.
        stiffness: f64,
        /// `a1` in 1/s.
        mass: f64,
        /// The rotation-preserving variant.
        preserve_rotation: bool,
    },
    /// Lagged Rayleigh damping `D = a3 K(x_n) + a1 M`.
    RayleighLagged {
        /// `a3` in s.
        stiffness: f64,
        /// `a1` in 1/s.
        mass: f64,
    },
}

impl DampingChoice {
    /// A fresh damping model.
    pub fn create(self) -> Box<dyn Damping> {
        match self {
            Self::None => Box::new(NoDamping),
            Self::EtherFactor(k) => Box::new(EtherDrag::factor(k).unwrap()),
            Self::EtherRate(c) => Box::new(EtherDrag::rate(c).unwrap()),
            Self::EtherImplicit(a1) => Box::new(EtherDrag::implicit(a1).unwrap()),
            Self::Pbd(k) => Box::new(PbdDamping::new(k).unwrap()),
            Self::Laplacian {
                stiffness,
                mass,
                preserve_rotation,
            } => Box::new(LaplacianDamping::new(stiffness, mass, preserve_rotation).unwrap()),
            Self::RayleighLagged { stiffness, mass } => {
                Box::new(RayleighLagged::new(stiffness, mass).unwrap())
            }
        }
    }

    /// Whether the model acts only through a constant or lagged PSD matrix
    /// `D` (no velocity filter, no angular-momentum restoration), so that
    /// implicit midpoint's energy balance is `-h v_mid^T D v_mid`.
    pub fn is_matrix_only(self) -> bool {
        matches!(
            self,
            Self::None
                | Self::EtherImplicit(_)
                | Self::Laplacian {
                    preserve_rotation: false,
                    ..
                }
                | Self::RayleighLagged { .. }
        )
    }
}

/// Every damping model with random parameters: damping coefficients up to
/// `a2_max` s (Laplacian, lagged Rayleigh) and rates up to 50 1/s.
pub fn damping(a2_max: f64) -> impl Strategy<Value = DampingChoice> {
    prop_oneof![
        Just(DampingChoice::None),
        (0.0..=1.0f64).prop_map(DampingChoice::EtherFactor),
        (0.0..50.0f64).prop_map(DampingChoice::EtherRate),
        (0.0..50.0f64).prop_map(DampingChoice::EtherImplicit),
        (0.0..=1.0f64).prop_map(DampingChoice::Pbd),
        (0.0..a2_max, 0.0..10.0f64, any::<bool>()).prop_map(|(stiffness, mass, p)| {
            DampingChoice::Laplacian {
                stiffness,
                mass,
                preserve_rotation: p,
            }
        }),
        (0.0..a2_max, 0.0..10.0f64)
            .prop_map(|(stiffness, mass)| DampingChoice::RayleighLagged { stiffness, mass }),
    ]
}

/// Settings without gravity (or with it) for one thread.
pub fn settings(dt: f64, iterations: usize, gravity: bool) -> Settings {
    Settings {
        dt,
        iterations,
        gravity: if gravity {
            Point::new(0.0, -9.81, 0.0)
        } else {
            Point::zeros()
        },
        threads: 1,
        ..Settings::default()
    }
}

/// `sum_i max(|a_i|)`: a scale for round-off in sums over vertices.
pub fn max_norm(points: &[Point]) -> f64 {
    points.iter().map(|p| p.amax()).fold(0.0, f64::max)
}

/// An irregular tet mesh: a jittered box of `cells` cells (1 m x 0.7 m x
/// 0.5 m, jitter 0.15 of a cell) from which each tet is kept with
/// probability `keep` (deterministic in `seed`; at least one tet), and the
/// vertices no kept tet uses are removed. The result can have several
/// pieces, vertices of very different valence and thin parts.
pub fn irregular_box(cells: [usize; 3], seed: u64, keep: f64) -> Mesh {
    let full = jittered_box(cells, [1.0, 0.7, 0.5], 0.15, seed);
    let mut state = seed ^ 0x9e37_79b9_7f4a_7c15;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut tets: Vec<[usize; 4]> = full
        .tets()
        .iter()
        .copied()
        .filter(|_| uniform() < keep)
        .collect();
    if tets.is_empty() {
        tets.push(full.tets()[0]);
    }
    kept_tets(&full, tets).unwrap()
}

/// The TetGen armadillo beside the repository
/// (`../shared/meshes/armadillo/armadillo.node` and `.ele`: 14,779
/// vertices, a real mesh with elements of every size and shape), read once;
/// `None` (with one line saying so) where it is absent.
pub fn armadillo() -> Option<&'static Mesh> {
    static MESH: std::sync::OnceLock<Option<Mesh>> = std::sync::OnceLock::new();
    MESH.get_or_init(|| {
        let base = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/meshes/armadillo/armadillo");
        pd_io::tetgen::read_tetgen_base(&base)
            .map_err(|e| println!("armadillo pieces skipped: {}: {e}", base.display()))
            .ok()
    })
    .as_ref()
}

/// A piece of the armadillo: every tet whose four vertices lie within
/// `radius` m of vertex `seed % n` (about 50 vertices at 0.08 m, 250 at
/// 0.16 m; it can have several pieces), its unused vertices removed.
/// `None` without the armadillo.
pub fn armadillo_piece(seed: u64, radius: f64) -> Option<Mesh> {
    let full = armadillo()?;
    let centre = full.vertices()[(seed % full.num_vertices() as u64) as usize];
    let near: Vec<bool> = (full.vertices().iter())
        .map(|p| (p - centre).norm() <= radius)
        .collect();
    let tets: Vec<[usize; 4]> = (full.tets().iter())
        .filter(|t| t.iter().all(|&v| near[v]))
        .copied()
        .collect();
    if tets.is_empty() {
        return None;
    }
    kept_tets(full, tets).ok()
}

/// The mesh of `tets` (a subset of `full`'s), with the vertices no kept
/// tet uses removed and the rest renumbered in order of first use.
fn kept_tets(full: &Mesh, mut tets: Vec<[usize; 4]>) -> Result<Mesh, pd_mesh::MeshError> {
    let mut index = vec![usize::MAX; full.num_vertices()];
    let mut vertices = Vec::new();
    for tet in &mut tets {
        for v in tet.iter_mut() {
            if index[*v] == usize::MAX {
                index[*v] = vertices.len();
                vertices.push(full.vertices()[*v]);
            }
            *v = index[*v];
        }
    }
    Mesh::from_tets(vertices, tets)
}
