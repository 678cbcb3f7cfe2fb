//! Scene files: TOML or JSON with the same structure (reference in
//! `docs/scene-format.md`). Parsing rejects unknown keys; validation checks
//! every value and reports it by its field path (`body[0].density`); building
//! turns a valid scene into a ready [`Simulation`].

use std::path::{Path, PathBuf};

use crate::{Error, Result, gmsh, medit, obj, state, tetgen};
use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged};
use pd_integrators::{BackwardEuler, Bdf2, ImplicitMidpoint, Integrator};
use pd_mesh::{Mesh, Point, VertexSelection, generators};
use pd_solver::{Model, Settings, Simulation, State};

/// The serde image of a scene file: every optional key is an `Option`, so
/// that validation, not serde, decides what is missing and names it.
mod raw {
    use std::path::PathBuf;

    use serde::Deserialize;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Scene {
        pub simulation: Simulation,
        pub damping: Option<Damping>,
        #[serde(rename = "body", default)]
        pub bodies: Vec<Body>,
        pub output: Option<Output>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Simulation {
        pub dt: f64,
        pub steps: usize,
        pub gravity: Option<[f64; 3]>,
        pub integrator: Option<String>,
        pub iterations: Option<usize>,
        pub tolerance: Option<f64>,
        pub threads: Option<usize>,
        pub divergence_energy_factor: Option<f64>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Damping {
        pub model: String,
        pub factor: Option<f64>,
        pub rate: Option<f64>,
        pub implicit: Option<bool>,
        pub mass: Option<f64>,
        pub stiffness: Option<f64>,
        pub preserve_rotation: Option<bool>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Body {
        pub name: Option<String>,
        pub mesh: Mesh,
        pub density: Option<f64>,
        pub vertex_mass: Option<f64>,
        #[serde(default)]
        pub constraints: Vec<Constraint>,
        pub fixed: Option<Selection>,
        pub initial_state: Option<PathBuf>,
        pub initial_velocity: Option<[f64; 3]>,
        pub angular_velocity: Option<[f64; 3]>,
        pub translate: Option<[f64; 3]>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Mesh {
        pub generator: Option<String>,
        pub file: Option<PathBuf>,
        pub size: Option<Vec<f64>>,
        pub cells: Option<Vec<usize>>,
        pub points: Option<usize>,
        pub length: Option<f64>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Constraint {
        pub kind: String,
        pub stiffness: f64,
        pub limits: Option<[f64; 2]>,
        pub vertices: Option<Vec<usize>>,
        #[serde(rename = "box")]
        pub bounds: Option<Bounds>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Selection {
        pub vertices: Option<Vec<usize>>,
        #[serde(rename = "box")]
        pub bounds: Option<Bounds>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Bounds {
        pub min: [f64; 3],
        pub max: [f64; 3],
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Output {
        pub every: Option<usize>,
        pub formats: Option<Vec<String>>,
        pub probes: Option<Vec<usize>>,
    }
}

/// Integrators a scene can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum IntegratorKind {
    /// `backward-euler`.
    BackwardEuler,
    /// `implicit-midpoint`.
    ImplicitMidpoint,
    /// `bdf2`.
    Bdf2,
}

impl IntegratorKind {
    /// Every integrator, in the order scenes list them.
    pub const ALL: [IntegratorKind; 3] = [Self::BackwardEuler, Self::ImplicitMidpoint, Self::Bdf2];

    /// The name scenes use.
    pub fn name(self) -> &'static str {
        match self {
            Self::BackwardEuler => "backward-euler",
            Self::ImplicitMidpoint => "implicit-midpoint",
            Self::Bdf2 => "bdf2",
        }
    }

    /// The integrator a scene name stands for.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// A fresh integrator of this kind.
    pub fn create(self) -> Box<dyn Integrator> {
        match self {
            Self::BackwardEuler => Box::new(BackwardEuler),
            Self::ImplicitMidpoint => Box::new(ImplicitMidpoint),
            Self::Bdf2 => Box::new(Bdf2::new()),
        }
    }
}

/// Damping models a scene can name, with their parameters (SI units).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum DampingSpec {
    /// `none`.
    None,
    /// `ether-drag` with `factor = k` per step (explicit).
    EtherFactor {
        /// k in [0, 1].
        factor: f64,
    },
    /// `ether-drag` with `rate = c` in 1/s: explicit `v <- exp(-c h) v`, or
    /// with `implicit = true`, `D = c M` inside the solve.
    EtherRate {
        /// c in 1/s.
        rate: f64,
        /// Inside the solve rather than after it.
        implicit: bool,
    },
    /// `pbd` with `factor = k` in [0, 1].
    Pbd {
        /// k.
        factor: f64,
    },
    /// `rayleigh-lagged`: `D_n = mass M + stiffness K(x_n)`.
    RayleighLagged {
        /// a1 in 1/s.
        mass: f64,
        /// a2 in s.
        stiffness: f64,
    },
    /// `laplacian`: `D = mass M + stiffness L_d`.
    Laplacian {
        /// a2 in s.
        stiffness: f64,
        /// a1 in 1/s.
        mass: f64,
        /// Give back the angular momentum the damping removed.
        preserve_rotation: bool,
    },
}

impl DampingSpec {
    const NAMES: &'static [&'static str] =
        &["none", "ether-drag", "pbd", "rayleigh-lagged", "laplacian"];

    /// The name scenes use.
    pub fn name(&self) -> &'static str {
        match self {
            Self::None => "none",
            Self::EtherFactor { .. } | Self::EtherRate { .. } => "ether-drag",
            Self::Pbd { .. } => "pbd",
            Self::RayleighLagged { .. } => "rayleigh-lagged",
            Self::Laplacian { .. } => "laplacian",
        }
    }

    /// The damping model.
    ///
    /// # Errors
    /// A parameter outside its domain, named.
    pub fn create(&self) -> std::result::Result<Box<dyn Damping>, pd_damping::DampingError> {
        Ok(match *self {
            Self::None => Box::new(NoDamping),
            Self::EtherFactor { factor } => Box::new(EtherDrag::factor(factor)?),
            Self::EtherRate {
                rate,
                implicit: false,
            } => Box::new(EtherDrag::rate(rate)?),
            Self::EtherRate {
                rate,
                implicit: true,
            } => Box::new(EtherDrag::implicit(rate)?),
            Self::Pbd { factor } => Box::new(PbdDamping::new(factor)?),
            Self::RayleighLagged { mass, stiffness } => {
                Box::new(RayleighLagged::new(stiffness, mass)?)
            }
            Self::Laplacian {
                stiffness,
                mass,
                preserve_rotation,
            } => Box::new(LaplacianDamping::new(stiffness, mass, preserve_rotation)?),
        })
    }
}

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
}

/// Scene file syntax, chosen by extension (`.json` is JSON, anything else TOML).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Syntax {
    /// TOML.
    Toml,
    /// JSON.
    Json,
}

impl Syntax {
    /// The syntax a file name implies.
    pub fn of(path: &Path) -> Self {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("json") => Syntax::Json,
            _ => Syntax::Toml,
        }
    }
}

impl Scene {
    /// Reads and validates a scene file.
    ///
    /// # Errors
    /// The file cannot be read, is malformed (file, line and field path), has
    /// unknown keys, or holds an invalid value (field path).
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse(&text, Syntax::of(path), path)
    }

    /// Parses and validates scene text; `source` names it in messages and
    /// anchors relative paths.
    ///
    /// # Errors
    /// As [`Scene::load`].
    pub fn parse(text: &str, syntax: Syntax, source: &Path) -> Result<Self> {
        let raw: raw::Scene = match syntax {
            Syntax::Toml => parse_toml(text, source)?,
            Syntax::Json => parse_json(text, source)?,
        };
        Validator { source }.scene(raw)
    }

    /// Builds the model and the simulation: generates or reads every mesh,
    /// computes masses, adds constraints, fixes vertices, applies initial
    /// states and velocities.
    ///
    /// # Errors
    /// A mesh that cannot be built or read, a selection or probe out of
    /// range, an initial state that does not fit, or a model the solver
    /// rejects; each names the field.
    pub fn build(&self) -> Result<Simulation> {
        let mut model = Model::new();
        for (b, body) in self.bodies.iter().enumerate() {
            let field = |name: &str| format!("body[{b}].{name}");
            let mesh = self.mesh(&body.mesh, &field("mesh"))?;
            let mesh = if body.translate == Point::zeros() {
                mesh
            } else {
                mesh.translated(body.translate)
            };
            let masses = match body.mass {
                MassSpec::Density(rho) => mesh
                    .lumped_masses(rho)
                    .map_err(|e| self.field_error(field("density"), e))?,
                MassSpec::VertexMass(m) => vec![m; mesh.num_vertices()],
            };
            let fixed = match &body.fixed {
                Some(selection) => selection
                    .resolve(&mesh)
                    .map_err(|e| self.field_error(field("fixed"), e))?,
                None => Vec::new(),
            };
            let id = model
                .add_body(mesh.clone(), masses)
                .map_err(|e| self.field_error(field("mesh"), e))?;
            for (c, constraint) in body.constraints.iter().enumerate() {
                let here = field(&format!("constraints[{c}]"));
                let result = match constraint {
                    ConstraintSpec::TetStrain { stiffness, limits } => {
                        model.add_tet_strain(id, *stiffness, *limits).map(drop)
                    }
                    ConstraintSpec::Spring { stiffness } => {
                        model.add_springs(id, *stiffness).map(drop)
                    }
                    ConstraintSpec::Attachment {
                        stiffness,
                        selection,
                    } => {
                        let vertices = selection
                            .resolve(&mesh)
                            .map_err(|e| self.field_error(here.clone(), e))?;
                        model.add_attachments(id, &vertices, *stiffness)
                    }
                };
                result.map_err(|e| self.field_error(here, e))?;
            }
            model
                .fix_vertices(id, &fixed)
                .map_err(|e| self.field_error(field("fixed"), e))?;
        }
        let total = model.num_vertices();
        if let Some((i, &p)) = self
            .output
            .probes
            .iter()
            .enumerate()
            .find(|(_, p)| **p >= total)
        {
            return Err(self.field_error(
                format!("output.probes[{i}]"),
                format!("vertex {p} is out of range: the scene has {total} vertices"),
            ));
        }
        let offsets: Vec<_> = model.bodies().iter().map(|b| b.vertices()).collect();
        let damping = self
            .damping
            .create()
            .map_err(|e| self.field_error("damping".into(), e))?;
        let mut simulation = Simulation::new(
            model,
            self.integrator.create(),
            damping,
            self.settings.clone(),
        )
        .map_err(|e| self.field_error("scene".into(), e))?;

        let mut initial = simulation.state().clone();
        let mut from_file = false;
        for (b, (body, range)) in self.bodies.iter().zip(&offsets).enumerate() {
            if let Some(file) = &body.initial_state {
                let loaded = state::read_state(file)?;
                let positions = loaded.positions_as_points();
                let velocities = loaded.velocities_as_points();
                if positions.len() != range.len() {
                    return Err(self.field_error(
                        format!("body[{b}].initial_state"),
                        format!(
                            "{} holds {} positions but the body has {} vertices",
                            file.display(),
                            positions.len(),
                            range.len()
                        ),
                    ));
                }
                initial.positions[range.clone()].copy_from_slice(&positions);
                initial.velocities[range.clone()].copy_from_slice(&velocities);
                from_file = true;
            }
        }
        if from_file {
            simulation
                .set_state(State {
                    positions: initial.positions,
                    velocities: initial.velocities,
                })
                .map_err(|e| self.field_error("initial_state".into(), e))?;
        }
        for (b, body) in self.bodies.iter().enumerate() {
            if body.initial_velocity != Point::zeros() || body.angular_velocity != Point::zeros() {
                simulation.add_rigid_velocity(b, body.initial_velocity, body.angular_velocity);
            }
        }
        Ok(simulation)
    }

    fn mesh(&self, source: &MeshSource, field: &str) -> Result<Mesh> {
        let generated = match source {
            MeshSource::Box { size, cells } => generators::box_tets(*size, *cells),
            MeshSource::Chain { points, length } => generators::chain(*points, *length),
            MeshSource::Cloth { size, cells } => generators::cloth(*size, *cells),
            MeshSource::TetGen(path) => return tetgen::read_tetgen_base(path),
            MeshSource::TetGenSurface(path) => return tetgen::read_tetgen_surface_base(path),
            MeshSource::Gmsh(path) => return gmsh::read_gmsh(path),
            MeshSource::Obj(path) => return obj::read_obj(path),
            MeshSource::Medit(path) => return medit::read_medit(path),
        };
        generated.map_err(|e| self.field_error(field.to_string(), e))
    }

    fn field_error(&self, field: String, message: impl std::fmt::Display) -> Error {
        Error::Field {
            path: self.source.clone(),
            field,
            message: message.to_string(),
        }
    }
}

fn parse_toml(text: &str, source: &Path) -> Result<raw::Scene> {
    let line_of = |span: Option<std::ops::Range<usize>>| {
        span.map_or(1, |s| {
            text[..s.start.min(text.len())].matches('\n').count() + 1
        })
    };
    let deserializer = toml::Deserializer::parse(text).map_err(|e| Error::Parse {
        path: source.to_path_buf(),
        line: line_of(e.span()),
        message: e.message().to_string(),
    })?;
    serde_path_to_error::deserialize(deserializer).map_err(|e| {
        let field = e.path().to_string();
        let inner = e.into_inner();
        Error::Parse {
            path: source.to_path_buf(),
            line: line_of(inner.span()),
            message: format!("{}: {}", display_field(&field), inner.message()),
        }
    })
}

fn parse_json(text: &str, source: &Path) -> Result<raw::Scene> {
    let mut deserializer = serde_json::Deserializer::from_str(text);
    let to_error = |field: Option<String>, inner: serde_json::Error| {
        let message = inner.to_string();
        // serde_json appends " at line L column C"; the line goes in its own field.
        let message = message
            .rsplit_once(" at line ")
            .map_or(message.as_str(), |(m, _)| m)
            .to_string();
        let message = match field {
            Some(field) => format!("{}: {message}", display_field(&field)),
            None => message,
        };
        Error::Parse {
            path: source.to_path_buf(),
            line: inner.line().max(1),
            message,
        }
    };
    let scene = serde_path_to_error::deserialize(&mut deserializer).map_err(|e| {
        let field = e.path().to_string();
        // `?` is serde_path_to_error's "no path known" (a syntax error):
        // there is no field to name, only the line.
        let field = (field != "?").then_some(field);
        to_error(field, e.into_inner())
    })?;
    // Anything after the scene object is an error, not silently ignored.
    deserializer.end().map_err(|e| to_error(None, e))?;
    Ok(scene)
}

/// serde_path_to_error prints the root as `.`; scenes call it `scene`.
fn display_field(field: &str) -> &str {
    if field == "." { "scene" } else { field }
}

/// Turns raw sections into validated ones, naming fields in errors.
struct Validator<'a> {
    source: &'a Path,
}

impl Validator<'_> {
    fn error(&self, field: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Field {
            path: self.source.to_path_buf(),
            field: field.into(),
            message: message.into(),
        }
    }

    fn finite(&self, field: &str, value: f64) -> Result<f64> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.error(field, format!("must be finite, got {value}")))
        }
    }

    fn positive(&self, field: &str, value: f64) -> Result<f64> {
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(self.error(field, format!("must be finite and > 0, got {value}")))
        }
    }

    fn non_negative(&self, field: &str, value: f64) -> Result<f64> {
        if value.is_finite() && value >= 0.0 {
            Ok(value)
        } else {
            Err(self.error(field, format!("must be finite and >= 0, got {value}")))
        }
    }

    fn vector(&self, field: &str, value: [f64; 3]) -> Result<Point> {
        for (axis, v) in value.iter().enumerate() {
            self.finite(&format!("{field}[{axis}]"), *v)?;
        }
        Ok(Point::from(value))
    }

    fn path(&self, relative: &Path) -> PathBuf {
        match self.source.parent() {
            Some(dir) if relative.is_relative() => dir.join(relative),
            _ => relative.to_path_buf(),
        }
    }

    fn scene(&self, raw: raw::Scene) -> Result<Scene> {
        let s = raw.simulation;
        let defaults = Settings::default();
        let settings = Settings {
            dt: self.positive("simulation.dt", s.dt)?,
            iterations: match s.iterations {
                Some(0) => return Err(self.error("simulation.iterations", "must be at least 1")),
                Some(k) => k,
                None => defaults.iterations,
            },
            tolerance: self.non_negative("simulation.tolerance", s.tolerance.unwrap_or(0.0))?,
            gravity: match s.gravity {
                Some(g) => self.vector("simulation.gravity", g)?,
                None => defaults.gravity,
            },
            threads: s.threads.unwrap_or(0),
            divergence_energy_factor: self.positive(
                "simulation.divergence_energy_factor",
                s.divergence_energy_factor
                    .unwrap_or(defaults.divergence_energy_factor),
            )?,
        };
        let integrator_name = s.integrator.as_deref().unwrap_or("backward-euler");
        let integrator = IntegratorKind::parse(integrator_name).ok_or_else(|| {
            self.error(
                "simulation.integrator",
                format!(
                    "unknown integrator \"{integrator_name}\"; expected one of: {}",
                    IntegratorKind::ALL.map(IntegratorKind::name).join(", ")
                ),
            )
        })?;
        let damping = match raw.damping {
            None => DampingSpec::None,
            Some(d) => self.damping(d)?,
        };
        if raw.bodies.is_empty() {
            return Err(self.error("body", "a scene needs at least one [[body]]"));
        }
        let bodies = raw
            .bodies
            .into_iter()
            .enumerate()
            .map(|(b, body)| self.body(b, body))
            .collect::<Result<Vec<_>>>()?;
        let output = match raw.output {
            None => OutputSpec {
                every: 1,
                formats: vec![FrameFormat::Vtk],
                probes: Vec::new(),
            },
            Some(o) => OutputSpec {
                every: o.every.unwrap_or(1),
                formats: o
                    .formats
                    .unwrap_or_else(|| vec!["vtk".into()])
                    .iter()
                    .enumerate()
                    .map(|(i, f)| match f.as_str() {
                        "vtk" => Ok(FrameFormat::Vtk),
                        "obj" => Ok(FrameFormat::Obj),
                        "vtu" => Ok(FrameFormat::Vtu),
                        "ply" => Ok(FrameFormat::Ply),
                        other => Err(self.error(
                            format!("output.formats[{i}]"),
                            format!(
                                "unknown format \"{other}\"; expected \"vtk\", \"vtu\", \"obj\" or \"ply\""
                            ),
                        )),
                    })
                    .collect::<Result<Vec<_>>>()?,
                probes: o.probes.unwrap_or_default(),
            },
        };
        Ok(Scene {
            source: self.source.to_path_buf(),
            steps: s.steps,
            settings,
            integrator,
            damping,
            bodies,
            output,
        })
    }

    fn damping(&self, raw: raw::Damping) -> Result<DampingSpec> {
        let given = [
            ("factor", raw.factor.is_some()),
            ("rate", raw.rate.is_some()),
            ("implicit", raw.implicit.is_some()),
            ("mass", raw.mass.is_some()),
            ("stiffness", raw.stiffness.is_some()),
            ("preserve_rotation", raw.preserve_rotation.is_some()),
        ];
        let only = |allowed: &[&str]| -> Result<()> {
            match given
                .iter()
                .find(|(name, present)| *present && !allowed.contains(name))
            {
                Some((name, _)) => Err(self.error(
                    format!("damping.{name}"),
                    format!("is not a parameter of model \"{}\"", raw.model),
                )),
                None => Ok(()),
            }
        };
        let required = |name: &str, value: Option<f64>| -> Result<f64> {
            value.ok_or_else(|| {
                self.error(
                    format!("damping.{name}"),
                    format!("model \"{}\" needs it", raw.model),
                )
            })
        };
        let spec = match raw.model.as_str() {
            "none" => {
                only(&[])?;
                DampingSpec::None
            }
            "ether-drag" => {
                only(&["factor", "rate", "implicit"])?;
                match (raw.factor, raw.rate) {
                    (Some(factor), None) => {
                        if raw.implicit == Some(true) {
                            return Err(self.error(
                                "damping.implicit",
                                "implicit ether drag takes a rate (1/s), not a per-step factor",
                            ));
                        }
                        DampingSpec::EtherFactor { factor }
                    }
                    (None, Some(rate)) => DampingSpec::EtherRate {
                        rate,
                        implicit: raw.implicit.unwrap_or(false),
                    },
                    _ => {
                        return Err(self.error(
                            "damping.factor",
                            "ether-drag needs exactly one of factor (per step) or rate (1/s)",
                        ));
                    }
                }
            }
            "pbd" => {
                only(&["factor"])?;
                DampingSpec::Pbd {
                    factor: required("factor", raw.factor)?,
                }
            }
            "rayleigh-lagged" => {
                only(&["mass", "stiffness"])?;
                DampingSpec::RayleighLagged {
                    mass: raw.mass.unwrap_or(0.0),
                    stiffness: required("stiffness", raw.stiffness)?,
                }
            }
            "laplacian" => {
                only(&["mass", "stiffness", "preserve_rotation"])?;
                DampingSpec::Laplacian {
                    stiffness: required("stiffness", raw.stiffness)?,
                    mass: raw.mass.unwrap_or(0.0),
                    preserve_rotation: raw.preserve_rotation.unwrap_or(false),
                }
            }
            other => {
                return Err(self.error(
                    "damping.model",
                    format!(
                        "unknown damping model \"{other}\"; expected one of: {}",
                        DampingSpec::NAMES.join(", ")
                    ),
                ));
            }
        };
        // The model's own constructor is the one place its parameters are
        // checked; its error names the parameter.
        spec.create()
            .map_err(|e| self.error("damping", e.to_string()))?;
        Ok(spec)
    }

    fn body(&self, b: usize, raw: raw::Body) -> Result<BodySpec> {
        let field = |name: &str| format!("body[{b}].{name}");
        let mass = match (raw.density, raw.vertex_mass) {
            (Some(rho), None) => MassSpec::Density(self.positive(&field("density"), rho)?),
            (None, Some(m)) => MassSpec::VertexMass(self.positive(&field("vertex_mass"), m)?),
            (None, None) => {
                return Err(self.error(
                    field("density"),
                    "give the body's density (kg/m^3) or vertex_mass (kg)",
                ));
            }
            (Some(_), Some(_)) => {
                return Err(self.error(
                    field("vertex_mass"),
                    "give density or vertex_mass, not both",
                ));
            }
        };
        let mesh = self.mesh(&field("mesh"), raw.mesh)?;
        let constraints = raw
            .constraints
            .into_iter()
            .enumerate()
            .map(|(c, constraint)| {
                self.constraint(&field(&format!("constraints[{c}]")), constraint)
            })
            .collect::<Result<Vec<_>>>()?;
        let fixed = raw
            .fixed
            .map(|s| self.selection(&field("fixed"), s.vertices, s.bounds))
            .transpose()?;
        let zero_or = |name: &str, v: Option<[f64; 3]>| -> Result<Point> {
            v.map_or(Ok(Point::zeros()), |v| self.vector(&field(name), v))
        };
        Ok(BodySpec {
            name: raw.name.unwrap_or_else(|| format!("body{b}")),
            mesh,
            mass,
            constraints,
            fixed,
            initial_state: raw.initial_state.map(|p| self.path(&p)),
            initial_velocity: zero_or("initial_velocity", raw.initial_velocity)?,
            angular_velocity: zero_or("angular_velocity", raw.angular_velocity)?,
            translate: zero_or("translate", raw.translate)?,
        })
    }

    fn mesh(&self, field: &str, raw: raw::Mesh) -> Result<MeshSource> {
        let sub = |name: &str| format!("{field}.{name}");
        let unexpected = |names: &[(&str, bool)], for_what: &str| -> Result<()> {
            match names.iter().find(|(_, present)| *present) {
                Some((name, _)) => {
                    Err(self.error(sub(name), format!("is not a parameter of {for_what}")))
                }
                None => Ok(()),
            }
        };
        let (size, cells, points, length) = (raw.size, raw.cells, raw.points, raw.length);
        match (raw.generator.as_deref(), raw.file) {
            (Some(_), Some(_)) => Err(self.error(field, "give a generator or a file, not both")),
            (None, None) => Err(self.error(
                field,
                "give generator = \"box\" | \"chain\" | \"cloth\", or file = \"...\"",
            )),
            (None, Some(file)) => {
                unexpected(
                    &[
                        ("size", size.is_some()),
                        ("cells", cells.is_some()),
                        ("points", points.is_some()),
                        ("length", length.is_some()),
                    ],
                    "a mesh file",
                )?;
                let path = self.path(&file);
                match path.extension().and_then(|e| e.to_str()) {
                    // TetGen names its outputs `bar.1.node`; the base `bar.1`
                    // ends in the iteration number.
                    Some("node" | "ele") | None => Ok(MeshSource::TetGen(path)),
                    Some(e) if e.bytes().all(|b| b.is_ascii_digit()) => {
                        Ok(MeshSource::TetGen(path))
                    }
                    Some("face") => Ok(MeshSource::TetGenSurface(path)),
                    Some(e) if e.eq_ignore_ascii_case("msh") => Ok(MeshSource::Gmsh(path)),
                    Some(e) if e.eq_ignore_ascii_case("obj") => Ok(MeshSource::Obj(path)),
                    Some(e) if e.eq_ignore_ascii_case("mesh") => Ok(MeshSource::Medit(path)),
                    Some(other) => Err(self.error(
                        sub("file"),
                        format!(
                            "unsupported mesh format \".{other}\"; supported: TetGen .node/.ele \
                             (or .face for a surface), Gmsh .msh, Wavefront .obj, Medit .mesh"
                        ),
                    )),
                }
            }
            (Some("box"), None) => {
                unexpected(
                    &[("points", points.is_some()), ("length", length.is_some())],
                    "the box generator",
                )?;
                Ok(MeshSource::Box {
                    size: self.array(&sub("size"), size)?,
                    cells: self.array(&sub("cells"), cells)?,
                })
            }
            (Some("cloth"), None) => {
                unexpected(
                    &[("points", points.is_some()), ("length", length.is_some())],
                    "the cloth generator",
                )?;
                Ok(MeshSource::Cloth {
                    size: self.array(&sub("size"), size)?,
                    cells: self.array(&sub("cells"), cells)?,
                })
            }
            (Some("chain"), None) => {
                unexpected(
                    &[("size", size.is_some()), ("cells", cells.is_some())],
                    "the chain generator",
                )?;
                Ok(MeshSource::Chain {
                    points: points.ok_or_else(|| self.error(sub("points"), "missing"))?,
                    length: self.positive(
                        &sub("length"),
                        length.ok_or_else(|| self.error(sub("length"), "missing"))?,
                    )?,
                })
            }
            (Some(other), None) => Err(self.error(
                sub("generator"),
                format!("unknown generator \"{other}\"; expected \"box\", \"chain\" or \"cloth\""),
            )),
        }
    }

    fn array<T: Copy + std::fmt::Debug, const N: usize>(
        &self,
        field: &str,
        value: Option<Vec<T>>,
    ) -> Result<[T; N]> {
        let value = value.ok_or_else(|| self.error(field, "missing"))?;
        <[T; N]>::try_from(value.as_slice())
            .map_err(|_| self.error(field, format!("needs {N} values, got {}", value.len())))
    }

    fn constraint(&self, field: &str, raw: raw::Constraint) -> Result<ConstraintSpec> {
        let sub = |name: &str| format!("{field}.{name}");
        let stiffness = self.non_negative(&sub("stiffness"), raw.stiffness)?;
        let selection_given = raw.vertices.is_some() || raw.bounds.is_some();
        match raw.kind.as_str() {
            "tet-strain" | "spring" if selection_given => Err(self.error(
                sub(if raw.vertices.is_some() { "vertices" } else { "box" }),
                format!("is not a parameter of {}", raw.kind),
            )),
            "tet-strain" => {
                let limits = match raw.limits {
                    None => None,
                    Some([min, max]) => {
                        pd_constraints::TetStrain::check_limits(min, max)
                            .map_err(|e| self.error(sub("limits"), e.to_string()))?;
                        Some((min, max))
                    }
                };
                Ok(ConstraintSpec::TetStrain { stiffness, limits })
            }
            "spring" | "attachment" if raw.limits.is_some() => {
                Err(self.error(sub("limits"), format!("is not a parameter of {}", raw.kind)))
            }
            "spring" => Ok(ConstraintSpec::Spring { stiffness }),
            "attachment" => Ok(ConstraintSpec::Attachment {
                stiffness,
                selection: self.selection(field, raw.vertices, raw.bounds)?,
            }),
            other => Err(self.error(
                sub("kind"),
                format!("unknown constraint kind \"{other}\"; expected \"tet-strain\", \"spring\" or \"attachment\""),
            )),
        }
    }

    fn selection(
        &self,
        field: &str,
        vertices: Option<Vec<usize>>,
        bounds: Option<raw::Bounds>,
    ) -> Result<VertexSelection> {
        match (vertices, bounds) {
            (Some(v), None) => Ok(VertexSelection::Indices(v)),
            (None, Some(b)) => {
                self.vector(&format!("{field}.box.min"), b.min)?;
                self.vector(&format!("{field}.box.max"), b.max)?;
                Ok(VertexSelection::Box {
                    min: b.min,
                    max: b.max,
                })
            }
            (None, None) => Err(self.error(
                field,
                "select vertices with vertices = [...] or box = { min, max }",
            )),
            (Some(_), Some(_)) => Err(self.error(field, "give vertices or box, not both")),
        }
    }
}
