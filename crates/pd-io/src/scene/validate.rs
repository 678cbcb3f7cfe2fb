//! Validation: the raw serde image of a scene becomes the typed [`Scene`],
//! or an [`Error::Field`] naming the offending value by its field path
//! (`body[0].mesh.cells`). Checks run in file order, section by section, so
//! the first error reported is the first in the file.
//!
//! What needs the mesh (selections in range, generator counts, masses) is
//! checked when the scene is built, not here. The one look at the file
//! system is for a mesh `file` that names a directory, which would
//! otherwise be taken for a TetGen base name and reported as a missing
//! `.node` file.

use std::path::{Path, PathBuf};

use pd_damping::DampingError;
use pd_damping::registry::DampingSpec;
use pd_mesh::{Point, VertexSelection};
use pd_solver::Settings;

use super::raw;
use super::spec::{
    BodySpec, ConstraintSpec, FrameFormat, IntegratorKind, MassSpec, MeshSource, OutputSpec, Scene,
};
use crate::{Error, Result};

/// The iteration cap of a scene with `accuracy` and no `iterations`.
pub const ACCURACY_ITERATIONS: usize = 10_000;

/// The accuracy target of a scene that sets none of `iterations`,
/// `tolerance` and `accuracy` (docs/guide/03-accuracy-and-solvers.md,
/// "Defaults"): each step within 1% of its converged answer, the method
/// chosen for the scene. A scene that sets `iterations` runs that many, as
/// it always did.
pub const DEFAULT_ACCURACY: f64 = 0.01;

/// Checks an accuracy target as `simulation.accuracy` takes it: a relative
/// error in (0, 1) (so finite); the message says what is wrong with it.
///
/// # Errors
/// The value is out of (0, 1) or NaN.
pub fn check_accuracy(accuracy: f64) -> std::result::Result<f64, String> {
    if accuracy > 0.0 && accuracy < 1.0 {
        Ok(accuracy)
    } else {
        Err(format!(
            "must be a relative error in (0, 1), e.g. 0.01, got {accuracy}"
        ))
    }
}

/// Turns raw sections into validated ones, naming fields in errors.
pub(super) struct Validator<'a> {
    pub(super) source: &'a Path,
}

impl Validator<'_> {
    /// An error at `field` (for the section validators in other files).
    pub(super) fn field(&self, field: impl Into<String>, message: impl Into<String>) -> Error {
        self.error(field, message)
    }

    fn error(&self, field: impl Into<String>, message: impl Into<String>) -> Error {
        super::field_error(self.source, field, message.into())
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

    /// The whole scene, section by section.
    pub(super) fn scene(&self, raw: raw::Scene) -> Result<Scene> {
        let settings = self.settings(&raw.simulation)?;
        let integrator = self.integrator(raw.simulation.integrator.as_deref())?;
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
        let output = self.output(raw.output)?;
        let predictor = self.predictor(raw.solver.as_ref())?;
        // With an accuracy target and no method named, building measures
        // which method reaches it fastest (and excludes those that cannot
        // run the materials).
        let choose_method =
            settings.accuracy > 0.0 && raw.solver.as_ref().is_none_or(|s| s.method.is_none());
        let solver = self.solver(raw.solver)?;
        if !choose_method {
            self.check_material_method(&bodies, &solver)?;
        }
        let (contact, body_contact, surface_pairs) =
            super::contact::validate(self.source, raw.colliders, raw.contact)?;
        Ok(Scene {
            source: self.source.to_path_buf(),
            steps: raw.simulation.steps,
            settings,
            integrator,
            damping,
            bodies,
            output,
            solver,
            choose_method,
            predictor,
            contact,
            body_contact,
            surface_pairs,
        })
    }

    /// `simulation.accuracy`: in (0, 1), and not with a tolerance (0 when
    /// not given).
    fn accuracy(&self, s: &raw::Simulation) -> Result<f64> {
        let Some(accuracy) = s.accuracy else {
            let budget_given = s.iterations.is_some() || s.tolerance.is_some();
            return Ok(if budget_given { 0.0 } else { DEFAULT_ACCURACY });
        };
        check_accuracy(accuracy).map_err(|e| self.error("simulation.accuracy", e))?;
        if let Some(tolerance) = s.tolerance.filter(|&t| t != 0.0) {
            return Err(self.error(
                "simulation.accuracy",
                format!(
                    "cannot be combined with simulation.tolerance ({tolerance}): each is a \
                     stopping rule; keep one"
                ),
            ));
        }
        Ok(accuracy)
    }

    fn settings(&self, s: &raw::Simulation) -> Result<Settings> {
        let defaults = Settings::default();
        Ok(Settings {
            dt: self.positive("simulation.dt", s.dt)?,
            iterations: match s.iterations {
                Some(0) => return Err(self.error("simulation.iterations", "must be at least 1")),
                Some(k) => k,
                // With an accuracy target (the scene's, or the default
                // when it sets no budget), `iterations` is only the cap.
                None if s.accuracy.is_some() || s.tolerance.is_none() => ACCURACY_ITERATIONS,
                None => defaults.iterations,
            },
            tolerance: self.non_negative("simulation.tolerance", s.tolerance.unwrap_or(0.0))?,
            accuracy: self.accuracy(s)?,
            gravity: match s.gravity {
                Some(g) => {
                    let g = self.vector("simulation.gravity", g)?;
                    // The largest component first: the norm of 1e300
                    // overflows.
                    if g.amax() > Settings::MAX_GRAVITY || g.norm() > Settings::MAX_GRAVITY {
                        return Err(self.error(
                            "simulation.gravity",
                            format!(
                                "is [{:e}, {:e}, {:e}] m/s^2; its magnitude must be at most \
                                 {:e} m/s^2, where its square still fits in a 64-bit float",
                                g.x,
                                g.y,
                                g.z,
                                Settings::MAX_GRAVITY
                            ),
                        ));
                    }
                    g
                }
                None => defaults.gravity,
            },
            threads: match s.threads {
                Some(t) if t > Settings::MAX_THREADS => {
                    return Err(self.error(
                        "simulation.threads",
                        format!(
                            "must be at most {} (0: all cores), got {t}",
                            Settings::MAX_THREADS
                        ),
                    ));
                }
                t => t.unwrap_or(0),
            },
            divergence_energy_factor: self.positive(
                "simulation.divergence_energy_factor",
                s.divergence_energy_factor
                    .unwrap_or(defaults.divergence_energy_factor),
            )?,
        })
    }

    fn integrator(&self, name: Option<&str>) -> Result<IntegratorKind> {
        let name = name.unwrap_or(IntegratorKind::BackwardEuler.name());
        IntegratorKind::parse(name).ok_or_else(|| {
            self.error(
                "simulation.integrator",
                format!(
                    "unknown integrator \"{name}\"; expected one of: {}",
                    pd_integrators::registry::names().join(", ")
                ),
            )
        })
    }

    /// The registry checks the parameters against the model's and the
    /// model's constructor checks their values; both name the key.
    fn damping(&self, raw: raw::Damping) -> Result<DampingSpec> {
        DampingSpec::new(&raw.model, raw.arguments).map_err(|e| self.damping_error(&e))
    }

    /// A damping error at `damping.KEY`, or at `damping` for a value out of
    /// its domain (the message names the parameter).
    pub(super) fn damping_error(&self, error: &DampingError) -> Error {
        match error.key_and_reason() {
            Some((key, reason)) => self.error(format!("damping.{key}"), reason),
            None => self.error("damping", error.to_string()),
        }
    }

    /// Body `b`'s own damping, errors at `body[b].damping.KEY`.
    fn body_damping(&self, b: usize, raw: raw::Damping) -> Result<DampingSpec> {
        DampingSpec::new(&raw.model, raw.arguments).map_err(|e| {
            super::per_body::damping_error(self.source, &format!("body[{b}].damping"), &e)
        })
    }

    fn output(&self, raw: Option<raw::Output>) -> Result<OutputSpec> {
        let Some(o) = raw else {
            return Ok(OutputSpec {
                every: 1,
                formats: vec![FrameFormat::Vtk],
                probes: Vec::new(),
            });
        };
        let formats = match o.formats {
            None => vec![FrameFormat::Vtk],
            Some(names) => names
                .iter()
                .enumerate()
                .map(|(i, name)| {
                    FrameFormat::parse(name).ok_or_else(|| {
                        self.error(
                            format!("output.formats[{i}]"),
                            format!(
                                "unknown format \"{name}\"; expected {}",
                                quoted_choice(&FrameFormat::ALL.map(FrameFormat::name))
                            ),
                        )
                    })
                })
                .collect::<Result<Vec<_>>>()?,
        };
        Ok(OutputSpec {
            every: o.every.unwrap_or(1),
            formats,
            probes: o.probes.unwrap_or_default(),
        })
    }

    fn body(&self, b: usize, raw: raw::Body) -> Result<BodySpec> {
        let field = |name: &str| format!("body[{b}].{name}");
        let mass = self.mass(&field, raw.density, raw.vertex_mass)?;
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
            damping: raw.damping.map(|d| self.body_damping(b, d)).transpose()?,
        })
    }

    fn mass(
        &self,
        field: &dyn Fn(&str) -> String,
        density: Option<f64>,
        vertex_mass: Option<f64>,
    ) -> Result<MassSpec> {
        match (density, vertex_mass) {
            (Some(rho), None) => Ok(MassSpec::Density(self.positive(&field("density"), rho)?)),
            (None, Some(m)) => Ok(MassSpec::VertexMass(
                self.positive(&field("vertex_mass"), m)?,
            )),
            (None, None) => Err(self.error(
                field("density"),
                "give the body's density (kg/m^3) or vertex_mass (kg)",
            )),
            (Some(_), Some(_)) => Err(self.error(
                field("vertex_mass"),
                "give density or vertex_mass, not both",
            )),
        }
    }

    fn mesh(&self, field: &str, raw: raw::Mesh) -> Result<MeshSource> {
        match (raw.generator.as_deref(), &raw.file) {
            (Some(_), Some(_)) => Err(self.error(field, "give a generator or a file, not both")),
            (None, None) => Err(self.error(
                field,
                "give generator = \"box\" | \"ball\" | \"chain\" | \"cloth\", or file = \"...\"",
            )),
            (None, Some(file)) => self.mesh_file(field, &raw, file),
            (Some(generator), None) => self.generator(field, generator, &raw),
        }
    }

    /// Rejects the first of `names` that is present, as not a parameter of
    /// `for_what`.
    fn unexpected(&self, field: &str, names: &[(&str, bool)], for_what: &str) -> Result<()> {
        match names.iter().find(|(_, present)| *present) {
            Some((name, _)) => Err(self.error(
                format!("{field}.{name}"),
                format!("is not a parameter of {for_what}"),
            )),
            None => Ok(()),
        }
    }

    fn mesh_file(&self, field: &str, raw: &raw::Mesh, file: &Path) -> Result<MeshSource> {
        self.unexpected(
            field,
            &[
                ("size", raw.size.is_some()),
                ("cells", raw.cells.is_some()),
                ("points", raw.points.is_some()),
                ("length", raw.length.is_some()),
                ("radius", raw.radius.is_some()),
            ],
            "a mesh file",
        )?;
        let file_field = || format!("{field}.file");
        if file.as_os_str().is_empty() {
            return Err(self.error(file_field(), "is empty"));
        }
        let path = self.path(file);
        // Checked here, before the extension picks a reader: a directory
        // has none, and would be taken for a TetGen base name (`dir.node`).
        if path.is_dir() {
            return Err(self.error(
                file_field(),
                format!("{} is a directory, not a mesh file", path.display()),
            ));
        }
        match path.extension().and_then(|e| e.to_str()) {
            // TetGen names its outputs `bar.1.node`; the base `bar.1` ends in
            // the iteration number.
            Some("node" | "ele") | None => Ok(MeshSource::TetGen(path)),
            Some(e) if e.bytes().all(|b| b.is_ascii_digit()) => Ok(MeshSource::TetGen(path)),
            Some("face") => Ok(MeshSource::TetGenSurface(path)),
            Some(e) if e.eq_ignore_ascii_case("msh") => Ok(MeshSource::Gmsh(path)),
            Some(e) if e.eq_ignore_ascii_case("obj") => Ok(MeshSource::Obj(path)),
            Some(e) if e.eq_ignore_ascii_case("mesh") => Ok(MeshSource::Medit(path)),
            Some(other) => Err(self.error(
                file_field(),
                format!(
                    "unsupported mesh format \".{other}\"; supported: TetGen .node/.ele \
                     (or .face for a surface), Gmsh .msh, Wavefront .obj, Medit .mesh"
                ),
            )),
        }
    }

    fn generator(&self, field: &str, generator: &str, raw: &raw::Mesh) -> Result<MeshSource> {
        let sub = |name: &str| format!("{field}.{name}");
        let line_keys = [
            ("points", raw.points.is_some()),
            ("length", raw.length.is_some()),
            ("radius", raw.radius.is_some()),
        ];
        match generator {
            "box" => {
                self.unexpected(field, &line_keys, "the box generator")?;
                Ok(MeshSource::Box {
                    size: self.array(&sub("size"), raw.size.clone())?,
                    cells: self.array(&sub("cells"), raw.cells.clone())?,
                })
            }
            "cloth" => {
                self.unexpected(field, &line_keys, "the cloth generator")?;
                Ok(MeshSource::Cloth {
                    size: self.array(&sub("size"), raw.size.clone())?,
                    cells: self.array(&sub("cells"), raw.cells.clone())?,
                })
            }
            "chain" => {
                self.unexpected(
                    field,
                    &[
                        ("size", raw.size.is_some()),
                        ("cells", raw.cells.is_some()),
                        ("radius", raw.radius.is_some()),
                    ],
                    "the chain generator",
                )?;
                let missing = |name: &str| self.error(sub(name), "missing");
                Ok(MeshSource::Chain {
                    points: raw.points.ok_or_else(|| missing("points"))?,
                    length: self
                        .positive(&sub("length"), raw.length.ok_or_else(|| missing("length"))?)?,
                })
            }
            "ball" => self.ball(field, raw),
            other => Err(self.error(
                sub("generator"),
                format!(
                    "unknown generator \"{other}\"; expected \"box\", \"ball\", \"chain\" or \"cloth\""
                ),
            )),
        }
    }

    /// `generator = "ball"`: `radius` (m) and `cells = [n]` across it.
    fn ball(&self, field: &str, raw: &raw::Mesh) -> Result<MeshSource> {
        let sub = |name: &str| format!("{field}.{name}");
        let others = [
            ("size", raw.size.is_some()),
            ("points", raw.points.is_some()),
            ("length", raw.length.is_some()),
        ];
        self.unexpected(field, &others, "the ball generator")?;
        let radius = raw
            .radius
            .ok_or_else(|| self.error(sub("radius"), "missing"))?;
        let [cells] = self.array(&sub("cells"), raw.cells.clone())?;
        Ok(MeshSource::Ball {
            radius: self.positive(&sub("radius"), radius)?,
            cells,
        })
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
        if let Some(kind) = pd_constraints::MaterialKind::parse(&raw.kind) {
            return self.material(field, kind, &raw);
        }
        self.no_material_keys(field, &raw)?;
        let stiffness = raw
            .stiffness
            .ok_or_else(|| self.error(sub("stiffness"), "missing"))?;
        let stiffness = self.non_negative(&sub("stiffness"), stiffness)?;
        let selection_given = raw.vertices.is_some() || raw.bounds.is_some();
        match raw.kind.as_str() {
            "tet-strain" | "spring" | "triangle-strain" | "bending" | "area" | "volume"
                if selection_given =>
            {
                Err(self.error(
                    sub(if raw.vertices.is_some() {
                        "vertices"
                    } else {
                        "box"
                    }),
                    format!("is not a parameter of {}", raw.kind),
                ))
            }
            "triangle-strain" => {
                let limits = match raw.limits {
                    None => None,
                    Some([min, max]) => {
                        pd_constraints::TetStrain::check_limits(min, max)
                            .map_err(|e| self.error(sub("limits"), e.to_string()))?;
                        Some((min, max))
                    }
                };
                Ok(ConstraintSpec::TriangleStrain { stiffness, limits })
            }
            "bending" | "area" | "volume" if raw.limits.is_some() => {
                Err(self.error(sub("limits"), format!("is not a parameter of {}", raw.kind)))
            }
            "bending" => Ok(ConstraintSpec::Bending { stiffness }),
            "area" => Ok(ConstraintSpec::Area { stiffness }),
            "volume" => Ok(ConstraintSpec::Volume { stiffness }),
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
                format!(
                    "unknown constraint kind \"{other}\"; expected \"tet-strain\", \"spring\", \
                     \"attachment\", \"triangle-strain\", \"bending\", \"area\", \"volume\", \
                     \"neo-hookean\", \"stvk\" or \"corotated\""
                ),
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

/// `"a", "b" or "c"`.
fn quoted_choice(names: &[&str]) -> String {
    let quoted: Vec<String> = names.iter().map(|n| format!("\"{n}\"")).collect();
    match quoted.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => quoted.concat(),
    }
}
