//! The scene's `[[collider]]` and `[contact]` sections (docs/reference/scene-format.md,
//! "Contact"): their serde image and their validation into
//! [`ContactSettings`], errors by field path (`collider[2].normal`).

use std::path::{Path, PathBuf};

use pd_mesh::Point;
use pd_solver::contact::{
    BodyContactSettings, Collider, ColliderShape, ContactSettings, SurfacePairs, TriangleSurface,
};
use serde::Deserialize;

use crate::Result;

/// One `[[collider]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCollider {
    shape: Option<String>,
    point: Option<[f64; 3]>,
    normal: Option<[f64; 3]>,
    center: Option<[f64; 3]>,
    radius: Option<f64>,
    min: Option<[f64; 3]>,
    max: Option<[f64; 3]>,
    file: Option<PathBuf>,
    friction: Option<f64>,
    restitution: Option<f64>,
}

/// The `[contact]` table as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawContact {
    bodies: Option<bool>,
    #[serde(rename = "self")]
    self_contact: Option<bool>,
    thickness: Option<f64>,
    /// Coulomb coefficient of surface contact (with `bodies` or `self`).
    friction: Option<f64>,
}

/// What the `[[collider]]` and `[contact]` sections ask for: the collider
/// settings (`None` without colliders and without contact between bodies)
/// and contact of the bodies' surfaces (between bodies, self-contact).
pub(super) type Validated = (
    Option<ContactSettings>,
    Option<BodyContactSettings>,
    SurfacePairs,
);

/// Validates the colliders and the `[contact]` table of the scene `source`.
/// `None` when the scene names no collider and no contact between bodies:
/// then no contact code runs.
pub(super) fn validate(
    source: &Path,
    colliders: Vec<RawCollider>,
    contact: Option<RawContact>,
) -> Result<Validated> {
    let error = |field: String, message: String| super::field_error(source, field, message);
    let mut thickness = 0.0;
    let mut bodies = None;
    let mut pairs = SurfacePairs::default();
    if let Some(c) = contact {
        pairs = SurfacePairs {
            between_bodies: c.bodies == Some(true),
            self_contact: c.self_contact == Some(true),
        };
        if pairs.between_bodies || pairs.self_contact {
            let friction = c.friction.unwrap_or(0.0);
            if !(friction.is_finite() && friction >= 0.0) {
                return Err(error(
                    "contact.friction".into(),
                    format!("must be finite and >= 0, got {friction}"),
                ));
            }
            bodies = Some(BodyContactSettings { friction });
        } else if c.friction.is_some() {
            return Err(error(
                "contact.friction".into(),
                "only with bodies = true or self = true (a collider's friction is its own key)"
                    .into(),
            ));
        }
        if let Some(t) = c.thickness {
            if !(t.is_finite() && t >= 0.0) {
                return Err(error(
                    "contact.thickness".into(),
                    format!("must be finite and >= 0, got {t}"),
                ));
            }
            thickness = t;
        }
    }
    if colliders.is_empty() {
        let only_bodies = bodies.as_ref().map(|_| ContactSettings {
            colliders: Vec::new(),
            thickness,
        });
        return Ok((only_bodies, bodies, pairs));
    }
    let colliders = colliders
        .into_iter()
        .enumerate()
        .map(|(i, raw)| collider(source, i, raw))
        .collect::<Result<Vec<_>>>()?;
    Ok((
        Some(ContactSettings {
            colliders,
            thickness,
        }),
        bodies,
        pairs,
    ))
}

/// One collider, `collider[i]`.
fn collider(source: &Path, i: usize, raw: RawCollider) -> Result<Collider> {
    let error = |name: &str, message: String| {
        super::field_error(source, format!("collider[{i}].{name}"), message)
    };
    let vector = |name: &str, value: Option<[f64; 3]>| -> Result<Point> {
        let value = value.ok_or_else(|| error(name, "missing".into()))?;
        if let Some(v) = value.iter().find(|v| !v.is_finite()) {
            return Err(error(name, format!("must be finite, got {v}")));
        }
        Ok(Point::from(value))
    };
    let shape_name = raw
        .shape
        .as_deref()
        .ok_or_else(|| error("shape", "missing (plane, sphere, box or mesh)".into()))?;
    let keys = [
        ("point", raw.point.is_some()),
        ("normal", raw.normal.is_some()),
        ("center", raw.center.is_some()),
        ("radius", raw.radius.is_some()),
        ("min", raw.min.is_some()),
        ("max", raw.max.is_some()),
        ("file", raw.file.is_some()),
    ];
    let allowed: &[&str] = match shape_name {
        "plane" => &["point", "normal"],
        "sphere" => &["center", "radius"],
        "box" => &["min", "max"],
        "mesh" => &["file"],
        other => {
            return Err(error(
                "shape",
                format!("unknown shape \"{other}\" (plane, sphere, box or mesh)"),
            ));
        }
    };
    if let Some((key, _)) = keys
        .iter()
        .find(|(k, given)| *given && !allowed.contains(k))
    {
        return Err(error(key, format!("not a key of shape \"{shape_name}\"")));
    }
    let shape = match shape_name {
        "plane" => {
            let point = vector("point", raw.point)?;
            let normal = vector("normal", raw.normal)?;
            let normal = pd_solver::contact::unit_vector(normal)
                .ok_or_else(|| error("normal", "zero vector".into()))?;
            ColliderShape::Plane { point, normal }
        }
        "sphere" => {
            let center = vector("center", raw.center)?;
            let radius = raw
                .radius
                .ok_or_else(|| error("radius", "missing".into()))?;
            if !(radius.is_finite() && radius > 0.0) {
                return Err(error(
                    "radius",
                    format!("must be finite and > 0, got {radius}"),
                ));
            }
            ColliderShape::Sphere { center, radius }
        }
        "box" => {
            let (min, max) = (vector("min", raw.min)?, vector("max", raw.max)?);
            if let Some(axis) = (0..3).find(|&a| min[a] > max[a]) {
                return Err(error(
                    "max",
                    format!(
                        "min > max along axis {axis} ({} > {})",
                        min[axis], max[axis]
                    ),
                ));
            }
            ColliderShape::Box { min, max }
        }
        _ => mesh(source, i, raw.file.as_deref())?,
    };
    let friction = raw.friction.unwrap_or(0.0);
    if !(friction.is_finite() && friction >= 0.0) {
        return Err(error(
            "friction",
            format!("must be finite and >= 0, got {friction}"),
        ));
    }
    let restitution = raw.restitution.unwrap_or(0.0);
    if !(0.0..=1.0).contains(&restitution) {
        return Err(error(
            "restitution",
            format!("must be in [0, 1], got {restitution}"),
        ));
    }
    Ok(Collider {
        shape,
        friction,
        restitution,
    })
}

/// A mesh collider, `collider[i]`: its OBJ surface, relative to the scene.
fn mesh(source: &Path, i: usize, file: Option<&Path>) -> Result<ColliderShape> {
    let field = |name: &str| format!("collider[{i}].{name}");
    let Some(file) = file else {
        return Err(super::field_error(
            source,
            field("file"),
            "missing (an OBJ triangle surface)",
        ));
    };
    let path = match source.parent() {
        Some(dir) if file.is_relative() => dir.join(file),
        _ => file.to_path_buf(),
    };
    if !path.is_file() {
        return Err(super::field_error(
            source,
            field("file"),
            format!("no such file: {}", path.display()),
        ));
    }
    if !cfg!(feature = "mesh-collider") {
        return Err(super::field_error(
            source,
            field("shape"),
            "mesh colliders need the `mesh-collider` feature (on in the `pd` binary; docs/design/contact.md)",
        ));
    }
    let surface =
        crate::obj::read_obj(&path).map_err(|e| super::field_error(source, field("file"), e))?;
    if surface.triangles().is_empty() {
        return Err(super::field_error(
            source,
            field("file"),
            format!("{} has no triangles", path.display()),
        ));
    }
    let mut surface =
        TriangleSurface::new(surface.vertices().to_vec(), surface.triangles().to_vec());
    surface
        .prepare()
        .map_err(|e| super::field_error(source, field("file"), e))?;
    Ok(ColliderShape::Mesh(surface))
}
