//! What contact is asked for: the colliders, the thickness, the friction
//! between surfaces, and their validation.

use pd_mesh::Point;

use crate::{ColliderShape, ContactError};

/// A static collider: a shape, a Coulomb friction coefficient and a
/// coefficient of restitution.
#[derive(Debug, Clone, PartialEq)]
pub struct Collider {
    /// The shape, in world coordinates (m).
    pub shape: ColliderShape,
    /// Coulomb coefficient (>= 0; the same for sticking and sliding).
    pub friction: f64,
    /// Coefficient of restitution, in `[0, 1]`: the ratio of the normal
    /// speed leaving the collider to the speed hitting it.
    pub restitution: f64,
}

/// `v` scaled to unit length, `None` for the zero vector. A finite `v`
/// whose length overflows or underflows (entries of 1e300 or 1e-320) is
/// scaled by its largest entry first; any other `v` is divided by its
/// length, as `v / |v|`.
pub fn unit_vector(v: Point) -> Option<Point> {
    let largest = v.amax();
    if largest == 0.0 {
        return None;
    }
    let length = v.norm();
    Some(if length.is_normal() {
        v / length
    } else {
        (v / largest).normalize()
    })
}

impl Collider {
    /// The collider's velocity at `p`, m/s (zero: colliders are static, but
    /// friction and restitution are written relative to it).
    pub(crate) fn velocity(&self, _p: &Point) -> Point {
        Point::zeros()
    }
}

/// Contact settings of a simulation.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ContactSettings {
    /// The static colliders.
    pub colliders: Vec<Collider>,
    /// Contact offset, m (>= 0): vertices are kept this far outside every
    /// collider.
    pub thickness: f64,
}

impl ContactSettings {
    /// Checks every value; normalises plane normals.
    ///
    /// # Errors
    /// A non-finite value, a zero normal, a non-positive radius, a box with
    /// `min > max`, a negative friction, a restitution outside `[0, 1]` or
    /// a negative thickness, naming the collider (`collider[2].normal`).
    pub fn validated(mut self) -> Result<Self, ContactError> {
        let bad = |field: String, reason: &str| ContactError::InvalidSettings {
            reason: format!("{field}: {reason}"),
        };
        if !(self.thickness.is_finite() && self.thickness >= 0.0) {
            return Err(bad("contact.thickness".into(), "must be finite and >= 0"));
        }
        for (i, c) in self.colliders.iter_mut().enumerate() {
            let field = |name: &str| format!("collider[{i}].{name}");
            if !(c.friction.is_finite() && c.friction >= 0.0) {
                return Err(bad(field("friction"), "must be finite and >= 0"));
            }
            if !(0.0..=1.0).contains(&c.restitution) {
                return Err(bad(field("restitution"), "must be in [0, 1]"));
            }
            match &mut c.shape {
                ColliderShape::Plane { point, normal } => {
                    if !point.iter().chain(normal.iter()).all(|v| v.is_finite()) {
                        return Err(bad(field("normal"), "point and normal must be finite"));
                    }
                    *normal =
                        unit_vector(*normal).ok_or_else(|| bad(field("normal"), "zero vector"))?;
                }
                ColliderShape::Sphere { center, radius } => {
                    if !(radius.is_finite() && *radius > 0.0) {
                        return Err(bad(field("radius"), "must be finite and > 0"));
                    }
                    if !center.iter().all(|v| v.is_finite()) {
                        return Err(bad(field("center"), "must be finite"));
                    }
                }
                ColliderShape::Box { min, max } => {
                    if !min.iter().chain(max.iter()).all(|v| v.is_finite()) {
                        return Err(bad(field("min"), "min and max must be finite"));
                    }
                    if (0..3).any(|a| min[a] > max[a]) {
                        return Err(bad(field("max"), "min > max"));
                    }
                }
                ColliderShape::Mesh(surface) => {
                    surface.prepare().map_err(|e| bad(field("file"), &e))?;
                }
            }
        }
        Ok(self)
    }
}

/// Contact between bodies (`contact.bodies = true`): vertices of each body
/// against the surface triangles of every other body (docs/design/contact.md).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BodyContactSettings {
    /// Coulomb coefficient between bodies (>= 0; default 0).
    pub friction: f64,
}

impl BodyContactSettings {
    /// Checks the friction.
    ///
    /// # Errors
    /// A negative or non-finite friction (`contact.friction`).
    pub fn validated(self) -> Result<Self, ContactError> {
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(ContactError::InvalidSettings {
                reason: "contact.friction: must be finite and >= 0".into(),
            });
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(normal: Point) -> Collider {
        Collider {
            shape: ColliderShape::Plane {
                point: Point::zeros(),
                normal,
            },
            friction: 0.5,
            restitution: 0.0,
        }
    }

    /// What the solver reports as an invalid model: the setting named, in
    /// the reason's text.
    #[test]
    fn invalid_settings_name_the_setting() {
        let reason = |s: ContactSettings| s.validated().unwrap_err().reason().to_owned();
        let thickness = ContactSettings {
            colliders: Vec::new(),
            thickness: -1.0,
        };
        assert_eq!(
            reason(thickness),
            "contact.thickness: must be finite and >= 0"
        );
        let zero_normal = ContactSettings {
            colliders: vec![plane(Point::y()), plane(Point::zeros())],
            thickness: 0.0,
        };
        assert_eq!(reason(zero_normal), "collider[1].normal: zero vector");
        let friction = BodyContactSettings { friction: f64::NAN };
        let error = friction.validated().unwrap_err();
        assert!(matches!(error, ContactError::InvalidSettings { .. }));
        assert_eq!(error.reason(), "contact.friction: must be finite and >= 0");
    }

    #[test]
    fn plane_normals_come_out_unit() {
        let settings = ContactSettings {
            colliders: vec![plane(Point::new(0.0, 3.0, 4.0))],
            thickness: 0.01,
        };
        let settings = settings.validated().unwrap();
        let ColliderShape::Plane { normal, .. } = settings.colliders[0].shape else {
            panic!("a plane stays a plane");
        };
        assert_eq!(normal, Point::new(0.0, 0.6, 0.8));
    }
}
