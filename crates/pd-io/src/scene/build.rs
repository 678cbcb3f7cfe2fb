//! Building: a validated [`Scene`] becomes a [`Model`] and a ready
//! [`Simulation`]. Meshes are generated or read here, so the checks that
//! need them (selections and probes in range, masses, initial states that
//! fit) report here, by field path like validation.

use std::ops::Range;

use pd_mesh::{Mesh, Point, generators};
use pd_solver::{Model, Simulation, State};

use super::spec::{BodySpec, ConstraintSpec, MassSpec, MeshSource, Scene};
use crate::{Error, Result, gmsh, medit, obj, state, tetgen};

impl Scene {
    /// Builds the model and the simulation: generates or reads every mesh,
    /// computes masses, adds constraints, fixes vertices, applies initial
    /// states and velocities.
    ///
    /// # Errors
    /// A mesh that cannot be built or read, a selection or probe out of
    /// range, an initial state that does not fit, or a model the solver
    /// rejects; each names the field.
    pub fn build(&self) -> Result<Simulation> {
        self.build_with_ratios().map(|(simulation, _)| simulation)
    }

    /// [`Scene::build`], with the damping ratios a Caughey series fit
    /// (`[damping]` with three or more `ratios`, or a `band`) achieves at
    /// the modes it was fitted to; empty for any other damping.
    ///
    /// # Errors
    /// As [`Scene::build`].
    pub fn build_with_ratios(&self) -> Result<(Simulation, Vec<pd_damping::ratio::AchievedRatio>)> {
        let mut model = Model::new();
        for (b, body) in self.bodies.iter().enumerate() {
            self.add_body(&mut model, b, body)?;
        }
        self.check_probes(model.num_vertices())?;
        let offsets: Vec<_> = model.bodies().iter().map(|b| b.vertices()).collect();
        let mut achieved = Vec::new();
        let damping = self.damping_model(&model, &mut achieved)?;
        let mut simulation = Simulation::new(
            model,
            self.integrator.create(),
            damping,
            self.settings.clone(),
        )
        .map_err(|e| self.field_error("scene", e))?;
        if self.solver != pd_solver::SolverSpec::default() {
            let solver = self
                .solver
                .create()
                .map_err(|e| self.field_error("solver", e))?;
            simulation.set_position_solver(solver);
        }
        simulation.set_predictor(self.predictor);
        if let Some(contact) = &self.contact {
            simulation.set_contact(contact.clone()).map_err(|e| {
                // The method cannot run with colliders: the error is the method's.
                let field = match e {
                    pd_solver::SolverError::Unsupported { .. } => "solver.method",
                    _ => "collider",
                };
                self.field_error(field, e)
            })?;
        }
        if let Some(bodies) = &self.body_contact {
            (simulation.set_surface_contact(bodies.clone(), self.surface_pairs))
                .map_err(|e| self.field_error("contact", e))?;
        }
        // A method that cannot run this damping (or these materials or
        // colliders) is refused here, before a run writes anything. A
        // method to be chosen is checked once chosen.
        if !self.choose_method {
            simulation
                .check_position_solver()
                .map_err(|e| self.field_error("solver.method", e))?;
        }
        self.apply_initial_states(&mut simulation, &offsets)?;
        for (b, body) in self.bodies.iter().enumerate() {
            if body.initial_velocity != Point::zeros() || body.angular_velocity != Point::zeros() {
                (simulation.add_rigid_velocity(b, body.initial_velocity, body.angular_velocity))
                    .map_err(|e| self.field_error(format!("body[{b}].initial_velocity"), e))?;
            }
        }
        if self.choose_method {
            self.choose_method(&mut simulation)?;
        }
        Ok((simulation, achieved))
    }

    /// Chooses the method for the scene's `accuracy` by measurement, from
    /// the initial state; an error when no method can run the scene.
    fn choose_method(&self, simulation: &mut Simulation) -> Result<()> {
        let choice = simulation
            .choose_method()
            .map_err(|e| self.field_error("simulation.accuracy", e))?;
        simulation.check_position_solver().map_err(|e| {
            let reasons: Vec<String> = choice.candidates.iter().map(|c| c.describe()).collect();
            self.field_error(
                "solver.method",
                format!(
                    "no iteration method can run this scene for `accuracy` ({e}); \
                     the candidates: {}",
                    reasons.join("; ")
                ),
            )
        })
    }

    /// Body `b`: its mesh (translated), masses, constraints and fixed
    /// vertices.
    pub(super) fn add_body(&self, model: &mut Model, b: usize, body: &BodySpec) -> Result<()> {
        let field = |name: &str| format!("body[{b}].{name}");
        let mesh = self.mesh(&body.mesh, &field("mesh"))?;
        let mesh = if body.translate == Point::zeros() {
            mesh
        } else {
            mesh.translated(body.translate)
        };
        // The key that carries the masses names every error about them.
        let mass_field = field(match body.mass {
            MassSpec::Density(_) => "density",
            MassSpec::VertexMass(_) => "vertex_mass",
        });
        let masses = match body.mass {
            MassSpec::Density(rho) => mesh
                .lumped_masses(rho)
                .map_err(|e| self.field_error(&mass_field, e))?,
            // A scene file's value is checked when it is read; a `Scene`
            // built in code is checked here.
            MassSpec::VertexMass(m) if !(m.is_finite() && m > 0.0) => {
                return Err(
                    self.field_error(mass_field, format!("must be finite and > 0, got {m}"))
                );
            }
            MassSpec::VertexMass(m) => vec![m; mesh.num_vertices()],
        };
        let fixed = match &body.fixed {
            Some(selection) => selection
                .resolve(&mesh)
                .map_err(|e| self.field_error(field("fixed"), e))?,
            None => Vec::new(),
        };
        // `add_body` refuses only masses (a count or a value).
        let id = model
            .add_body(mesh.clone(), masses)
            .map_err(|e| self.field_error(&mass_field, e))?;
        for (c, constraint) in body.constraints.iter().enumerate() {
            let here = field(&format!("constraints[{c}]"));
            let result = match constraint {
                ConstraintSpec::TetStrain { stiffness, limits } => {
                    model.add_tet_strain(id, *stiffness, *limits).map(drop)
                }
                ConstraintSpec::Spring { stiffness } => model.add_springs(id, *stiffness).map(drop),
                ConstraintSpec::TriangleStrain { stiffness, limits } => {
                    model.add_triangle_strain(id, *stiffness, *limits).map(drop)
                }
                ConstraintSpec::Bending { stiffness } => {
                    model.add_bending(id, *stiffness).map(drop)
                }
                ConstraintSpec::Area { stiffness } => model.add_area(id, *stiffness).map(drop),
                ConstraintSpec::Volume { stiffness } => model.add_volume(id, *stiffness).map(drop),
                ConstraintSpec::Material {
                    kind,
                    young,
                    poisson,
                } => model.add_material(id, *kind, *young, *poisson).map(drop),
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
            .map_err(|e| self.field_error(field("fixed"), e))
    }

    pub(crate) fn check_probes(&self, total: usize) -> Result<()> {
        match self
            .output
            .probes
            .iter()
            .enumerate()
            .find(|(_, p)| **p >= total)
        {
            Some((i, &p)) => Err(self.field_error(
                format!("output.probes[{i}]"),
                format!("vertex {p} is out of range: the scene has {total} vertices"),
            )),
            None => Ok(()),
        }
    }

    /// Replaces the state of every body with an `initial_state` file by the
    /// file's; `offsets` are the bodies' vertex ranges.
    fn apply_initial_states(
        &self,
        simulation: &mut Simulation,
        offsets: &[Range<usize>],
    ) -> Result<()> {
        let mut initial = simulation.state().clone();
        let mut from_file = false;
        for (b, (body, range)) in self.bodies.iter().zip(offsets).enumerate() {
            let Some(file) = &body.initial_state else {
                continue;
            };
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
        if from_file {
            simulation
                .set_state(State {
                    positions: initial.positions,
                    velocities: initial.velocities,
                })
                .map_err(|e| self.field_error("initial_state", e))?;
        }
        Ok(())
    }

    fn mesh(&self, source: &MeshSource, field: &str) -> Result<Mesh> {
        let generated = match source {
            MeshSource::Box { size, cells } => generators::box_tets(*size, *cells),
            MeshSource::Chain { points, length } => generators::chain(*points, *length),
            MeshSource::Cloth { size, cells } => generators::cloth(*size, *cells),
            MeshSource::Ball { radius, cells } => generators::ball(*radius, *cells),
            MeshSource::TetGen(path) => return tetgen::read_tetgen_base(path),
            MeshSource::TetGenSurface(path) => return tetgen::read_tetgen_surface_base(path),
            MeshSource::Gmsh(path) => return gmsh::read_gmsh(path),
            MeshSource::Obj(path) => return obj::read_obj(path),
            MeshSource::Medit(path) => return medit::read_medit(path),
            MeshSource::Given(mesh) => return Ok(mesh.clone()),
        };
        generated.map_err(|e| self.field_error(field, e))
    }

    fn field_error(&self, field: impl Into<String>, message: impl std::fmt::Display) -> Error {
        super::field_error(&self.source, field, message)
    }
}
