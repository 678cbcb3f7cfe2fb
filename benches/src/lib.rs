//! Shared set-up of the benchmarks (`benches/*.rs`, run with `cargo bench
//! -p pd-benches`) and of the `pd-probe` measurement binary that
//! `cargo xtask bench-report` and `cargo xtask cpp-compare` run.
//!
//! The benchmark scene is a box cantilever `1 x 0.2 x 0.2` m, corotational
//! strain (stiffness 1e5 Pa), density 1000 kg/m^3, gravity, clamped at
//! `x = 0`, meshed by [`pd_mesh::generators::box_tets`] (the same Kuhn split
//! and vertex numbering as the C++ reference's `gen-beam`).
//!
//! ```
//! let sim = pd_benches::Beam { cells: [4, 1, 1], ..pd_benches::Beam::default() }
//!     .simulation(pd_damping::registry::UNDAMPED, "be")
//!     .unwrap();
//! assert_eq!(sim.model().num_vertices(), 20);
//! ```

use pd_damping::Damping;
use pd_damping::registry;
use pd_integrators::Integrator;
use pd_integrators::registry as integrators;
use pd_mesh::{Mesh, Point};
use pd_solver::{Model, Settings, Simulation};

pub mod accuracy_target;
pub mod contact;
pub mod methods;
mod options;
pub mod schema;

pub use options::Options;

/// FNV-1a over the bits of every position and velocity of a state (the
/// one implementation, in `pd_io::hash`).
pub use pd_io::hash::state_hash;

/// The damping models every benchmark runs: the main preset of each model
/// of `pd_damping::registry`, by name, in registry order (the undamped
/// baseline, [`registry::UNDAMPED`], first).
pub fn damping_models() -> Vec<&'static str> {
    registry::presets()
        .iter()
        .filter(|p| p.is_main())
        .map(|p| p.name)
        .collect()
}

/// The integrators the benchmarks run: backward Euler and implicit midpoint.
pub const INTEGRATORS: [&str; 2] = ["be", "im"];

/// The three benchmark sizes: cells of the beam and a label. They are the
/// C++ reference's small / medium / large meshes (2,304, 19,456 and
/// 95,499 vertices).
pub const SIZES: [([usize; 3], &str); 3] = [
    ([35, 7, 7], "2k"),
    ([75, 15, 15], "20k"),
    ([130, 26, 26], "100k"),
];

/// The sizes a criterion run measures: only the smallest under
/// `cargo bench -- --test` (the smoke run), else those named in the
/// comma-separated `PD_BENCH_SIZES` (e.g. `2k,20k`), else all of [`SIZES`].
pub fn selected_sizes() -> Vec<([usize; 3], &'static str)> {
    if std::env::args().any(|a| a == "--test") {
        return vec![SIZES[0]];
    }
    let wanted = std::env::var("PD_BENCH_SIZES").ok();
    SIZES
        .into_iter()
        .filter(|(_, label)| {
            wanted
                .as_deref()
                .is_none_or(|w| w.split(',').any(|s| s.trim() == *label))
        })
        .collect()
}

/// The damping model of the registry's preset `name`, with the
/// coefficients of the benchmarks (`docs/design/performance.md`): ether drag at a
/// rate of 1/s (explicit), PBD with factor 0.05, lagged Rayleigh and
/// Laplacian damping with a stiffness coefficient of 0.003 s.
///
/// # Errors
/// An unknown name.
pub fn damping(name: &str) -> Result<Box<dyn Damping>, String> {
    let preset = registry::preset(name).ok_or_else(|| {
        format!(
            "unknown damping model {name:?}; expected one of {:?}",
            registry::preset_names()
        )
    })?;
    preset
        .spec()
        .and_then(|spec| spec.create())
        .map_err(|e| e.to_string())
}

/// The integrator whose short name in `pd_integrators::registry` is `name`:
/// `be` (backward Euler), `im` (implicit midpoint) or `bdf2` (used by the
/// speed-against-accuracy report only).
///
/// # Errors
/// An unknown name.
pub fn integrator(name: &str) -> Result<Box<dyn Integrator>, String> {
    integrators::by_short_name(name)
        .map(integrators::Entry::create)
        .ok_or_else(|| {
            let names = integrators::short_names();
            let (last, rest) = names.split_last().unwrap_or((&"", &[]));
            format!(
                "unknown integrator {name:?}; expected {} or {last}",
                rest.join(", ")
            )
        })
}

/// How the beam is held at `x = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Clamp {
    /// The clamped vertices are removed from the unknowns (pd's own way).
    Fixed,
    /// Every vertex stays an unknown and the clamped ones are attached to
    /// their rest positions with weight `1e6 mean(m) / h^2` (N/m): the C++
    /// reference's formulation, for like-for-like comparisons.
    SoftLikeReference,
}

/// The benchmark cantilever and its settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Beam {
    /// Cells along x, y, z (6 tetrahedra each).
    pub cells: [usize; 3],
    /// Side lengths in m.
    pub size: [f64; 3],
    /// Strain stiffness in Pa (weight = stiffness x rest volume).
    pub stiffness: f64,
    /// Density in kg/m^3.
    pub density: f64,
    /// Time step in s.
    pub dt: f64,
    /// Local-global iterations per step (fixed: no tolerance).
    pub iterations: usize,
    /// Threads of the local step and right-hand side (0: rayon's default).
    pub threads: usize,
    /// How the end at `x = 0` is held.
    pub clamp: Clamp,
}

impl Default for Beam {
    fn default() -> Self {
        Self {
            cells: SIZES[0].0,
            size: [1.0, 0.2, 0.2],
            stiffness: 1e5,
            density: 1000.0,
            dt: 0.01,
            iterations: 10,
            threads: 1,
            clamp: Clamp::Fixed,
        }
    }
}

impl Beam {
    /// The beam's mesh.
    ///
    /// # Errors
    /// Invalid cell counts or sizes.
    pub fn mesh(&self) -> Result<Mesh, String> {
        pd_mesh::generators::box_tets(self.size, self.cells).map_err(|e| e.to_string())
    }

    /// The model on a given mesh (for meshes read from TetGen files): strain
    /// on every tetrahedron, lumped masses, the vertices at the smallest x
    /// clamped as [`Beam::clamp`] says.
    ///
    /// # Errors
    /// A mesh without tetrahedra or with degenerate ones.
    pub fn model_on(&self, mesh: Mesh) -> Result<Model, String> {
        let masses = mesh
            .lumped_masses(self.density)
            .map_err(|e| e.to_string())?;
        let min_x = mesh
            .vertices()
            .iter()
            .map(|p| p.x)
            .fold(f64::INFINITY, f64::min);
        let clamped: Vec<usize> = (0..mesh.num_vertices())
            .filter(|&v| mesh.vertices()[v].x <= min_x + 1e-9)
            .collect();
        let mean_mass = masses.iter().sum::<f64>() / masses.len() as f64;
        let mut model = Model::new();
        let body = model.add_body(mesh, masses).map_err(|e| e.to_string())?;
        model
            .add_tet_strain(body, self.stiffness, None)
            .map_err(|e| e.to_string())?;
        match self.clamp {
            Clamp::Fixed => model.fix_vertices(body, &clamped),
            Clamp::SoftLikeReference => {
                model.add_attachments(body, &clamped, 1e6 * mean_mass / (self.dt * self.dt))
            }
        }
        .map_err(|e| e.to_string())?;
        Ok(model)
    }

    /// The settings: gravity `(0, -9.81, 0)`, [`Beam::dt`],
    /// [`Beam::iterations`] without early exit, [`Beam::threads`].
    pub fn settings(&self) -> Settings {
        Settings {
            dt: self.dt,
            iterations: self.iterations,
            tolerance: 0.0,
            gravity: Point::new(0.0, -9.81, 0.0),
            threads: self.threads,
            ..Settings::default()
        }
    }

    /// A simulation of the generated beam with the named damping model and
    /// integrator.
    ///
    /// # Errors
    /// Unknown names, or a model the solver rejects.
    pub fn simulation(
        &self,
        damping_name: &str,
        integrator_name: &str,
    ) -> Result<Simulation, String> {
        self.simulation_on(self.mesh()?, damping_name, integrator_name)
    }

    /// As [`Beam::simulation`] on a given mesh.
    ///
    /// # Errors
    /// Unknown names, or a model the solver rejects.
    pub fn simulation_on(
        &self,
        mesh: Mesh,
        damping_name: &str,
        integrator_name: &str,
    ) -> Result<Simulation, String> {
        Simulation::new(
            self.model_on(mesh)?,
            integrator(integrator_name)?,
            damping(damping_name)?,
            self.settings(),
        )
        .map_err(|e| e.to_string())
    }
}

/// The cloth benchmark of `pd-probe --cloth`: a square sheet of side
/// [`Sheet::side`] in the `xz` plane, meshed by
/// [`pd_mesh::generators::cloth`] (`2 cells[0] cells[1]` triangles),
/// triangle strain on every triangle, lumped masses, the edge `x = 0`
/// fixed; released from horizontal under gravity it swings down, so the
/// triangles rotate and stretch a little, as in `scenes/cloth_*.toml`.
/// Bending is optional, so that the triangle-strain pass can be measured
/// alone; so are stretch limits (`scenes/cloth_flag.toml` and two more
/// cloth scenes have them).
///
/// ```
/// let sheet = pd_benches::Sheet { cells: [4, 3], ..pd_benches::Sheet::default() };
/// let mut sim = sheet.simulation(&pd_benches::Beam::default().settings()).unwrap();
/// assert_eq!(sim.model().num_vertices(), 20);
/// sim.step().unwrap();
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Sheet {
    /// Cells along x and z (2 triangles each).
    pub cells: [usize; 2],
    /// Side length in m.
    pub side: f64,
    /// Membrane stiffness `E t` in N/m (weight = stiffness x rest area).
    pub stiffness: f64,
    /// Area density in kg/m^2.
    pub density: f64,
    /// Flexural rigidity `D` in N m of the bending constraints, or `None`
    /// for none.
    pub bending: Option<f64>,
    /// Stretch limits `(min, max)` of every triangle's principal stretches
    /// (`0 <= min <= 1 <= max`), or `None` for none.
    pub limits: Option<(f64, f64)>,
}

impl Default for Sheet {
    /// The material of `scenes/cloth_hanging_sheet.toml`: `E t = 5e3` N/m,
    /// 0.2 kg/m^2; 224 x 224 cells (100,352 triangles) on a 1 m side.
    fn default() -> Self {
        Self {
            cells: [224, 224],
            side: 1.0,
            stiffness: 5e3,
            density: 0.2,
            bending: None,
            limits: None,
        }
    }
}

impl Sheet {
    /// A simulation of the sheet with `settings` (undamped, backward
    /// Euler).
    ///
    /// # Errors
    /// Invalid cell counts or parameters, or a model the solver rejects.
    pub fn simulation(&self, settings: &Settings) -> Result<Simulation, String> {
        let mesh =
            pd_mesh::generators::cloth([self.side; 2], self.cells).map_err(|e| e.to_string())?;
        let masses = mesh
            .lumped_masses(self.density)
            .map_err(|e| e.to_string())?;
        let fixed: Vec<usize> = (0..mesh.num_vertices())
            .filter(|&v| mesh.vertices()[v].x <= 1e-9)
            .collect();
        let mut model = Model::new();
        let body = model.add_body(mesh, masses).map_err(|e| e.to_string())?;
        model
            .add_triangle_strain(body, self.stiffness, self.limits)
            .map_err(|e| e.to_string())?;
        if let Some(rigidity) = self.bending {
            model
                .add_bending(body, rigidity)
                .map_err(|e| e.to_string())?;
        }
        model
            .fix_vertices(body, &fixed)
            .map_err(|e| e.to_string())?;
        Simulation::new(
            model,
            integrator("be")?,
            damping(registry::UNDAMPED)?,
            settings.clone(),
        )
        .map_err(|e| e.to_string())
    }
}

/// Peak resident memory of this process so far (`VmHWM` in
/// `/proc/self/status`), in bytes; `None` where that file does not exist.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_model_and_integrator_builds() {
        let beam = Beam {
            cells: [3, 1, 1],
            ..Beam::default()
        };
        for model in damping_models() {
            for integrator in INTEGRATORS {
                let mut sim = beam.simulation(model, integrator).unwrap();
                sim.step().unwrap();
            }
        }
        assert!(damping("viscous").is_err());
        assert!(integrator("rk4").is_err());
    }

    #[test]
    fn soft_clamp_keeps_every_vertex_free() {
        let beam = Beam {
            cells: [3, 1, 1],
            clamp: Clamp::SoftLikeReference,
            ..Beam::default()
        };
        let sim = beam.simulation(registry::UNDAMPED, "be").unwrap();
        assert_eq!(sim.num_free_vertices(), sim.model().num_vertices());
    }
}
