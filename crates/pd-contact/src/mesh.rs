//! Triangle-mesh colliders: the surface's data, and (with the
//! `mesh-collider` feature) its queries through parry3d-f64's bounding-volume
//! hierarchy: closest point with the side it lies on, and ray casts for
//! continuous detection.
//!
//! The surface is one-sided: its outside is where the triangles' normals
//! (counter-clockwise winding) point. A closed surface is a solid; an open
//! one (a bowl) keeps vertices on its front side.

use std::sync::Arc;

use pd_mesh::Point;

use crate::geometry::Hit;

/// A static triangle surface (m), as a collider.
#[derive(Clone)]
pub struct TriangleSurface {
    vertices: Vec<Point>,
    triangles: Vec<[usize; 3]>,
    #[cfg(feature = "mesh-collider")]
    query: Option<Arc<parry3d_f64::shape::TriMesh>>,
    /// Never built without the feature (`prepare` fails).
    #[cfg(not(feature = "mesh-collider"))]
    #[allow(dead_code)]
    query: Option<Arc<()>>,
}

impl std::fmt::Debug for TriangleSurface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriangleSurface")
            .field("vertices", &self.vertices.len())
            .field("triangles", &self.triangles.len())
            .finish()
    }
}

impl PartialEq for TriangleSurface {
    fn eq(&self, other: &Self) -> bool {
        self.vertices == other.vertices && self.triangles == other.triangles
    }
}

impl TriangleSurface {
    /// A surface of `triangles` (indices into `vertices`, counter-clockwise
    /// seen from outside). Checked and indexed by
    /// [`crate::ContactSettings::validated`].
    pub fn new(vertices: Vec<Point>, triangles: Vec<[usize; 3]>) -> Self {
        Self {
            vertices,
            triangles,
            query: None,
        }
    }

    /// The vertices, m.
    pub fn vertices(&self) -> &[Point] {
        &self.vertices
    }

    /// The triangles.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// Checks the surface and builds its query structure (once; a clone
    /// shares it). [`crate::ContactSettings::validated`] calls it.
    ///
    /// # Errors
    /// Why the surface cannot be a collider (no triangles, an index out of
    /// range, a non-finite vertex, the feature missing).
    pub fn prepare(&mut self) -> Result<(), String> {
        if self.query.is_some() {
            return Ok(());
        }
        if self.triangles.is_empty() {
            return Err("the surface has no triangles".into());
        }
        if !self.vertices.iter().flatten().all(|v| v.is_finite()) {
            return Err("a vertex is not finite".into());
        }
        if let Some(t) = self.triangles.iter().position(|t| {
            t.iter()
                .any(|&i| i >= self.vertices.len() || i > u32::MAX as usize)
        }) {
            return Err(format!("triangle {t} refers to a missing vertex"));
        }
        build(self)
    }

    /// Signed distance to the surface thickened by `thickness` (negative
    /// behind it) and the outward normal.
    pub(crate) fn gap(&self, p: &Point, thickness: f64) -> (f64, Point) {
        query_gap(self, p, thickness)
    }

    /// The first point of `a -> b` on or behind the thickened surface.
    pub(crate) fn first_hit(&self, a: &Point, b: &Point, thickness: f64) -> Option<Hit> {
        query_first_hit(self, a, b, thickness)
    }
}

#[cfg(not(feature = "mesh-collider"))]
fn build(_: &mut TriangleSurface) -> Result<(), String> {
    Err("mesh colliders need pd-solver's `mesh-collider` feature".into())
}

#[cfg(not(feature = "mesh-collider"))]
fn query_gap(_: &TriangleSurface, _: &Point, _: f64) -> (f64, Point) {
    (f64::INFINITY, Point::y())
}

#[cfg(not(feature = "mesh-collider"))]
fn query_first_hit(_: &TriangleSurface, _: &Point, _: &Point, _: f64) -> Option<Hit> {
    None
}

#[cfg(feature = "mesh-collider")]
use parry3d_f64::math::Vector;

#[cfg(feature = "mesh-collider")]
fn to_parry(p: &Point) -> Vector {
    Vector::new(p.x, p.y, p.z)
}

#[cfg(feature = "mesh-collider")]
fn from_parry(v: Vector) -> Point {
    Point::new(v.x, v.y, v.z)
}

#[cfg(feature = "mesh-collider")]
fn build(surface: &mut TriangleSurface) -> Result<(), String> {
    use parry3d_f64::shape::{TriMesh, TriMeshFlags};
    let vertices = surface.vertices.iter().map(to_parry).collect();
    // Indices were checked to fit u32.
    let indices = surface
        .triangles
        .iter()
        .map(|t| t.map(|i| i as u32))
        .collect();
    let mesh = TriMesh::with_flags(vertices, indices, TriMeshFlags::ORIENTED)
        .map_err(|e| format!("invalid triangle surface: {e:?}"))?;
    surface.query = Some(Arc::new(mesh));
    Ok(())
}

#[cfg(feature = "mesh-collider")]
fn query_gap(surface: &TriangleSurface, p: &Point, thickness: f64) -> (f64, Point) {
    use parry3d_f64::query::PointQuery;
    let Some(mesh) = &surface.query else {
        return (f64::INFINITY, Point::y());
    };
    let projection = mesh.project_local_point(to_parry(p), false);
    let closest = from_parry(projection.point);
    let offset = p - closest;
    let distance = offset.norm();
    let sign = if projection.is_inside { -1.0 } else { 1.0 };
    let normal = if distance > 1e-12 {
        offset * (sign / distance)
    } else {
        face_normal(surface, p)
    };
    (sign * distance - thickness, normal)
}

/// The outward normal of the triangle nearest to `p` (for a point on the
/// surface, where the offset gives no direction).
#[cfg(feature = "mesh-collider")]
fn face_normal(surface: &TriangleSurface, p: &Point) -> Point {
    use parry3d_f64::query::PointQuery;
    use parry3d_f64::shape::FeatureId;
    let Some(mesh) = &surface.query else {
        return Point::y();
    };
    let (_, feature) = mesh.project_local_point_and_get_feature(to_parry(p));
    let t = match feature {
        FeatureId::Face(t) => t as usize,
        _ => 0,
    };
    let [a, b, c] = surface.triangles[t % surface.triangles.len()].map(|i| surface.vertices[i]);
    let n = (b - a).cross(&(c - a));
    let length = n.norm();
    if length > 0.0 { n / length } else { Point::y() }
}

#[cfg(feature = "mesh-collider")]
fn query_first_hit(surface: &TriangleSurface, a: &Point, b: &Point, thickness: f64) -> Option<Hit> {
    use parry3d_f64::query::{Ray, RayCast};
    let (gap_a, normal_a) = query_gap(surface, a, thickness);
    if gap_a <= 0.0 {
        return Some(Hit {
            t: 0.0,
            point: a - normal_a * gap_a,
            normal: normal_a,
        });
    }
    let mesh = surface.query.as_ref()?;
    let d = b - a;
    let ray = Ray::new(to_parry(a), to_parry(&d));
    if let Some(hit) = mesh.cast_local_ray_and_get_normal(&ray, 1.0, false) {
        let mut normal = from_parry(hit.normal);
        if normal.dot(&d) > 0.0 {
            normal = -normal;
        }
        // Where the segment meets the surface thickened by `thickness`.
        let approach = -normal.dot(&d);
        let back = if approach > 0.0 {
            thickness / approach
        } else {
            0.0
        };
        let t = (hit.time_of_impact - back).clamp(0.0, 1.0);
        let point = a + d * t;
        return Some(Hit { t, point, normal });
    }
    // No crossing, but the end may lie within the thickness in front: the
    // segment enters the thickened surface where its gap, linear along the
    // segment near a face, reaches 0.
    let (gap_b, normal_b) = query_gap(surface, b, thickness);
    (gap_b <= 0.0).then(|| {
        let t = (gap_a / (gap_a - gap_b)).clamp(0.0, 1.0);
        Hit {
            t,
            point: a + d * t,
            normal: normal_b,
        }
    })
}
