//! `projdyn.Model`: bodies given as NumPy arrays, with the constraints,
//! masses and fixed vertices of a scene's `[[body]]` entries under the
//! scene's names and units. Each body is kept as its mesh and the TOML
//! table a scene would hold for it, so that the scene loader validates and
//! builds it when a `Simulation` is made.

use pd_mesh::{ElementKind, Mesh, MeshError, Point};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{index_list, indices, points, to_table, to_toml};

/// One body: its mesh and its `[[body]]` table (without `mesh`).
#[derive(Debug, Clone)]
pub(crate) struct BodyEntry {
    pub(crate) mesh: Mesh,
    pub(crate) table: toml::Table,
}

/// A model: bodies (NumPy arrays) and their constraints, under the names
/// and units of the scene format (docs/reference/scene-format.md).
///
/// A model is a recipe: each `Simulation(model, ...)` takes a copy, so a
/// model can be handed to several simulations and changed afterwards
/// without changing them. Values are checked when the simulation is made,
/// by the scene loader, and errors name them as a scene's would
/// (`body[0].constraints[1].stiffness`); the arrays are checked at once.
#[pyclass(module = "projdyn")]
#[derive(Debug, Clone, Default)]
pub struct Model {
    pub(crate) bodies: Vec<BodyEntry>,
}

/// The mesh argument a mesh error is about.
fn mesh_argument(e: &MeshError) -> &'static str {
    match e {
        MeshError::IndexOutOfRange { kind, .. } | MeshError::RepeatedVertex { kind, .. } => {
            match kind {
                ElementKind::Tet => "tets",
                ElementKind::Triangle => "triangles",
                _ => "edges",
            }
        }
        MeshError::NonPositiveVolume { .. } => "tets",
        MeshError::ZeroArea { .. } => "triangles",
        MeshError::SizeOverflow { kind, .. } => match kind {
            ElementKind::Tet => "tets",
            _ => "triangles",
        },
        _ => "vertices",
    }
}

/// Builds a mesh from the arrays, with errors naming the argument.
pub(crate) fn make_mesh(
    vertices: Vec<Point>,
    tets: Vec<[usize; 4]>,
    triangles: Vec<[usize; 3]>,
    edges: Option<Vec<[usize; 2]>>,
) -> PyResult<Mesh> {
    Mesh::new(vertices, tets, triangles, edges)
        .map_err(|e| PyValueError::new_err(format!("{}: {e}", mesh_argument(&e))))
}

impl Model {
    fn body_mut(&mut self, body: usize) -> PyResult<&mut BodyEntry> {
        let count = self.bodies.len();
        self.bodies.get_mut(body).ok_or_else(|| {
            PyIndexError::new_err(format!(
                "body: there is no body {body}; the model has {count}"
            ))
        })
    }

    /// Appends a `constraints` entry of `kind` with the keyword values
    /// given (those not `None`) to `body`.
    fn add_kind(
        &mut self,
        body: usize,
        kind: &str,
        pairs: &[(&str, Option<Bound<'_, PyAny>>)],
    ) -> PyResult<()> {
        let table = params(pairs)?;
        self.push_constraint(body, kind, table)
    }

    /// Appends a `constraints` entry of `kind` with `params` to `body`.
    fn push_constraint(&mut self, body: usize, kind: &str, params: toml::Table) -> PyResult<()> {
        let entry = self.body_mut(body)?;
        let mut constraint = toml::Table::new();
        constraint.insert("kind".into(), toml::Value::String(kind.into()));
        constraint.extend(params);
        let list = entry
            .table
            .entry("constraints")
            .or_insert_with(|| toml::Value::Array(Vec::new()));
        if let toml::Value::Array(items) = list {
            items.push(toml::Value::Table(constraint));
        }
        Ok(())
    }
}

/// A table of the keyword values given (those not `None`).
fn params(pairs: &[(&str, Option<Bound<'_, PyAny>>)]) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (key, value) in pairs {
        if let Some(value) = value
            && let Some(v) = to_toml(key, value)?
        {
            table.insert((*key).into(), v);
        }
    }
    Ok(table)
}

/// A vertex selection (`vertices` or `box`) as a scene's table.
fn selection(
    vertices: Option<&Bound<'_, PyAny>>,
    bounds: Option<&Bound<'_, PyAny>>,
) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    if let Some(v) = vertices {
        let list = index_list("vertices", v)?;
        let values = list
            .into_iter()
            .map(|i| {
                i64::try_from(i)
                    .map(toml::Value::Integer)
                    .map_err(|_| PyValueError::new_err(format!("vertices: index {i} is too large")))
            })
            .collect::<PyResult<Vec<_>>>()?;
        table.insert("vertices".into(), toml::Value::Array(values));
    }
    if let Some(b) = bounds
        && let Some(v) = to_toml("box", b)?
    {
        table.insert("box".into(), v);
    }
    Ok(table)
}

#[pymethods]
impl Model {
    /// An empty model.
    #[new]
    fn new() -> Self {
        Self::default()
    }

    /// Adds a body and returns its index (0 for the first).
    ///
    /// `vertices` is an (N, 3) array of rest positions in m. Give `tets`
    /// (M, 4) for a solid, `triangles` (M, 3) for cloth or a shell, or
    /// `edges` (M, 2) for a spring network (indices from 0; tets ordered
    /// with positive volume). Masses come from `density` (kg/m^3, kg/m^2 or
    /// kg/m by the element kind) or `vertex_mass` (kg), one of the two.
    /// `initial_velocity` (m/s) and `angular_velocity` (rad/s, about the
    /// centre of mass) set the initial motion; `damping` is the body's own
    /// damping table (a dict with the keys of `[damping]`).
    ///
    /// Raises `ValueError` naming the argument for arrays of the wrong
    /// shape, a non-finite coordinate, an index out of range and an
    /// inverted or flat element.
    #[pyo3(signature = (vertices, *, tets=None, triangles=None, edges=None, density=None,
                        vertex_mass=None, name=None, initial_velocity=None,
                        angular_velocity=None, damping=None))]
    #[allow(clippy::too_many_arguments)]
    fn add_body(
        &mut self,
        vertices: &Bound<'_, PyAny>,
        tets: Option<&Bound<'_, PyAny>>,
        triangles: Option<&Bound<'_, PyAny>>,
        edges: Option<&Bound<'_, PyAny>>,
        density: Option<Bound<'_, PyAny>>,
        vertex_mass: Option<Bound<'_, PyAny>>,
        name: Option<Bound<'_, PyAny>>,
        initial_velocity: Option<Bound<'_, PyAny>>,
        angular_velocity: Option<Bound<'_, PyAny>>,
        damping: Option<Bound<'_, PyAny>>,
    ) -> PyResult<usize> {
        let vertices = points("vertices", vertices, None)?;
        let tets = tets.map(|t| indices::<4>("tets", t)).transpose()?;
        let triangles = triangles
            .map(|t| indices::<3>("triangles", t))
            .transpose()?;
        let edges = edges.map(|e| indices::<2>("edges", e)).transpose()?;
        if tets.is_none() && triangles.is_none() && edges.is_none() {
            return Err(PyValueError::new_err(
                "add_body: give the elements: tets=, triangles= or edges=",
            ));
        }
        let mesh = make_mesh(
            vertices,
            tets.unwrap_or_default(),
            triangles.unwrap_or_default(),
            edges,
        )?;
        let table = params(&[
            ("name", name),
            ("density", density),
            ("vertex_mass", vertex_mass),
            ("initial_velocity", initial_velocity),
            ("angular_velocity", angular_velocity),
            ("damping", damping),
        ])?;
        self.bodies.push(BodyEntry { mesh, table });
        Ok(self.bodies.len() - 1)
    }

    /// Adds a constraint of any kind of the scene format to `body`: `kind`
    /// and the keys of a `constraints` entry, e.g.
    /// `add_constraint(b, "attachment", stiffness=1e4, vertices=[0, 1])`.
    #[pyo3(signature = (body, kind, **params))]
    fn add_constraint(
        &mut self,
        body: usize,
        kind: &str,
        params: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<()> {
        let table = match params {
            Some(p) => to_table("constraint", p)?,
            None => toml::Table::new(),
        };
        self.push_constraint(body, kind, table)
    }

    /// Corotational strain on every tetrahedron of `body`: `stiffness` in
    /// Pa, optional `limits = (min, max)` principal stretches.
    #[pyo3(signature = (body, stiffness, *, limits=None))]
    fn add_tet_strain(
        &mut self,
        body: usize,
        stiffness: Bound<'_, PyAny>,
        limits: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.add_kind(
            body,
            "tet-strain",
            &[("stiffness", Some(stiffness)), ("limits", limits)],
        )
    }

    /// A spring along every edge of `body`: `stiffness` in N/m.
    fn add_springs(&mut self, body: usize, stiffness: Bound<'_, PyAny>) -> PyResult<()> {
        self.add_kind(body, "spring", &[("stiffness", Some(stiffness))])
    }

    /// Membrane strain on every triangle of `body`: `stiffness` (E t) in
    /// N/m, optional `limits = (min, max)`.
    #[pyo3(signature = (body, stiffness, *, limits=None))]
    fn add_triangle_strain(
        &mut self,
        body: usize,
        stiffness: Bound<'_, PyAny>,
        limits: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.add_kind(
            body,
            "triangle-strain",
            &[("stiffness", Some(stiffness)), ("limits", limits)],
        )
    }

    /// Bending on every interior edge of `body`: flexural rigidity in N m.
    fn add_bending(&mut self, body: usize, stiffness: Bound<'_, PyAny>) -> PyResult<()> {
        self.add_kind(body, "bending", &[("stiffness", Some(stiffness))])
    }

    /// Area preservation of every triangle of `body`: N/m.
    fn add_area(&mut self, body: usize, stiffness: Bound<'_, PyAny>) -> PyResult<()> {
        self.add_kind(body, "area", &[("stiffness", Some(stiffness))])
    }

    /// Volume preservation of every tetrahedron of `body`: Pa.
    fn add_volume(&mut self, body: usize, stiffness: Bound<'_, PyAny>) -> PyResult<()> {
        self.add_kind(body, "volume", &[("stiffness", Some(stiffness))])
    }

    /// A hyperelastic material on every tetrahedron of `body`: `kind` is
    /// `"neo-hookean"`, `"stvk"` or `"corotated"`, `young` in Pa, `poisson`
    /// in [0, 0.5).
    fn add_material(
        &mut self,
        body: usize,
        kind: &str,
        young: Bound<'_, PyAny>,
        poisson: Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let p = params(&[("young", Some(young)), ("poisson", Some(poisson))])?;
        self.push_constraint(body, kind, p)
    }

    /// Attaches vertices of `body` to their rest positions by springs of
    /// `stiffness` N/m: the vertices listed (`vertices`, indices within the
    /// body) or those inside `box = {"min": [..], "max": [..]}` (m).
    #[pyo3(signature = (body, stiffness, *, vertices=None, r#box=None))]
    fn add_attachment(
        &mut self,
        body: usize,
        stiffness: Bound<'_, PyAny>,
        vertices: Option<&Bound<'_, PyAny>>,
        r#box: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let mut p = params(&[("stiffness", Some(stiffness))])?;
        p.extend(selection(vertices, r#box)?);
        self.push_constraint(body, "attachment", p)
    }

    /// Fixes vertices of `body` in place: `indices` (within the body; a
    /// list or 1-D array) or the vertices inside `box = {"min": [..],
    /// "max": [..]}`. Calling it again replaces the selection.
    #[pyo3(signature = (body, indices=None, *, r#box=None))]
    fn fix(
        &mut self,
        body: usize,
        indices: Option<&Bound<'_, PyAny>>,
        r#box: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        if indices.is_none() && r#box.is_none() {
            return Err(PyValueError::new_err("fix: give indices or box="));
        }
        let table = selection(indices, r#box)?;
        self.body_mut(body)?
            .table
            .insert("fixed".into(), toml::Value::Table(table));
        Ok(())
    }

    /// Number of bodies.
    #[getter]
    fn num_bodies(&self) -> usize {
        self.bodies.len()
    }

    /// Number of vertices of all bodies.
    #[getter]
    fn num_vertices(&self) -> usize {
        self.bodies.iter().map(|b| b.mesh.num_vertices()).sum()
    }

    /// The scene entry of body `body` (without its mesh) as TOML text.
    fn body_toml(&self, body: usize) -> PyResult<String> {
        let entry = self.bodies.get(body).ok_or_else(|| {
            PyIndexError::new_err(format!(
                "body: there is no body {body}; the model has {}",
                self.bodies.len()
            ))
        })?;
        toml::to_string(&entry.table).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({} bodies, {} vertices)",
            self.bodies.len(),
            self.num_vertices()
        )
    }

    fn __copy__(&self) -> Self {
        self.clone()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
    }

    /// Pickling: the bodies as JSON (coordinates round-trip bit for bit).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let text = model_to_json(&slf.borrow())?;
        let restore = py.import("projdyn._projdyn")?.getattr("restore_model")?;
        PyTuple::new(py, [restore, PyTuple::new(py, [text])?.into_any()])
    }
}

fn mesh_json(mesh: &Mesh) -> serde_json::Value {
    let vertices: Vec<[f64; 3]> = mesh.vertices().iter().map(|p| [p.x, p.y, p.z]).collect();
    serde_json::json!({
        "vertices": vertices,
        "tets": mesh.tets(),
        "triangles": mesh.triangles(),
        "edges": mesh.edges(),
    })
}

/// The model as JSON text: each body's table (as TOML text) and mesh.
pub(crate) fn model_to_json(model: &Model) -> PyResult<String> {
    let bodies = model
        .bodies
        .iter()
        .map(|b| {
            let table =
                toml::to_string(&b.table).map_err(|e| PyValueError::new_err(e.to_string()))?;
            Ok(serde_json::json!({ "table": table, "mesh": mesh_json(&b.mesh) }))
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok(serde_json::Value::Array(bodies).to_string())
}

/// A model from [`model_to_json`]'s text.
pub(crate) fn model_from_json(text: &str) -> PyResult<Model> {
    let bad = |e: String| PyValueError::new_err(format!("not a pickled projdyn.Model: {e}"));
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
    let items = value.as_array().ok_or_else(|| bad("no body list".into()))?;
    let mut model = Model::default();
    for item in items {
        let table: toml::Table = item["table"]
            .as_str()
            .ok_or_else(|| bad("no table".into()))
            .and_then(|t| toml::from_str(t).map_err(|e| bad(e.to_string())))?;
        let field = |key: &str| item["mesh"][key].clone();
        let vertices: Vec<[f64; 3]> =
            serde_json::from_value(field("vertices")).map_err(|e| bad(e.to_string()))?;
        let tets: Vec<[usize; 4]> =
            serde_json::from_value(field("tets")).map_err(|e| bad(e.to_string()))?;
        let triangles: Vec<[usize; 3]> =
            serde_json::from_value(field("triangles")).map_err(|e| bad(e.to_string()))?;
        let edges: Vec<[usize; 2]> =
            serde_json::from_value(field("edges")).map_err(|e| bad(e.to_string()))?;
        let mesh = make_mesh(
            vertices.into_iter().map(Point::from).collect(),
            tets,
            triangles,
            Some(edges),
        )?;
        model.bodies.push(BodyEntry { mesh, table });
    }
    Ok(model)
}

/// Unpickles a [`Model`].
#[pyfunction]
pub(crate) fn restore_model(text: &str) -> PyResult<Model> {
    model_from_json(text)
}
