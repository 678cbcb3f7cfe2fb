//! Static collider shapes: signed distance to the surface thickened by the
//! contact thickness, the outward normal, and the first crossing of a
//! segment (continuous detection, docs/design/contact.md).

use pd_mesh::Point;

/// The shape of a static collider, in world coordinates (m).
#[derive(Debug, Clone, PartialEq)]
pub enum ColliderShape {
    /// The half-space behind a plane through `point` with outward unit
    /// `normal`.
    Plane {
        /// A point on the plane, m.
        point: Point,
        /// The outward unit normal.
        normal: Point,
    },
    /// A solid sphere.
    Sphere {
        /// Its centre, m.
        center: Point,
        /// Its radius, m (> 0).
        radius: f64,
    },
    /// A solid axis-aligned box.
    Box {
        /// The lower corner, m.
        min: Point,
        /// The upper corner, m (`>= min` in every coordinate).
        max: Point,
    },
    /// A triangle surface, one-sided (its outside is where the normals of
    /// counter-clockwise triangles point); needs the `mesh-collider`
    /// feature.
    Mesh(crate::TriangleSurface),
}

/// Where a vertex meets a collider: the contact point on the thickened
/// surface (m) and the outward unit normal there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hit {
    /// Fraction of the segment at which it enters (0 if it starts inside).
    pub t: f64,
    /// The contact point on the thickened surface, m.
    pub point: Point,
    /// The outward unit normal at `point`.
    pub normal: Point,
}

impl ColliderShape {
    /// Signed distance from `p` to the surface thickened by `thickness`
    /// (negative inside), m, and the outward unit normal of the closest
    /// feature.
    pub(crate) fn gap(&self, p: &Point, thickness: f64) -> (f64, Point) {
        match self {
            Self::Plane { point, normal } => (normal.dot(&(p - point)) - thickness, *normal),
            Self::Sphere { center, radius } => {
                let r = p - center;
                let d = r.norm();
                let n = if d > 0.0 { r / d } else { Point::y() };
                (d - radius - thickness, n)
            }
            Self::Box { min, max } => box_gap(min, max, p, thickness),
            Self::Mesh(surface) => surface.gap(p, thickness),
        }
    }

    /// Whether [`ColliderShape::first_hit`] surely returns `None` for the
    /// segment `a -> b`, from a test cheaper than it: for a plane, both
    /// ends outside the thickened half-space (the same expressions as
    /// `first_hit`, so the same verdict); `false` (not known) for the
    /// other shapes.
    #[inline]
    pub(crate) fn misses(&self, a: &Point, b: &Point, thickness: f64) -> bool {
        match self {
            Self::Plane { point, normal } => {
                let gap = |p: &Point| normal.dot(&(p - point)) - thickness;
                !(gap(a) <= 0.0) && gap(b) > 0.0
            }
            _ => false,
        }
    }

    /// The first point of the segment `a -> b` on or inside the thickened
    /// surface. A segment that starts inside hits at `t = 0`, at the
    /// closest point of the thickened surface to `a`.
    pub(crate) fn first_hit(&self, a: &Point, b: &Point, thickness: f64) -> Option<Hit> {
        if let Self::Mesh(surface) = self {
            return surface.first_hit(a, b, thickness);
        }
        let (gap_a, normal_a) = self.gap(a, thickness);
        if gap_a <= 0.0 {
            return Some(Hit {
                t: 0.0,
                point: a - normal_a * gap_a,
                normal: normal_a,
            });
        }
        let d = b - a;
        let (t, normal) = match self {
            Self::Plane { normal, .. } => {
                let (gap_b, _) = self.gap(b, thickness);
                if gap_b > 0.0 {
                    return None;
                }
                ((gap_a / -normal.dot(&d)).clamp(0.0, 1.0), *normal)
            }
            Self::Sphere { center, radius } => {
                let t = sphere_entry(a, &d, center, radius + thickness)?;
                (t, self.gap(&(a + d * t), thickness).1)
            }
            Self::Box { min, max } => {
                let pad = Point::repeat(thickness);
                box_entry(a, &d, &(min - pad), &(max + pad))?
            }
            Self::Mesh(_) => return None,
        };
        let point = a + d * t;
        Some(Hit { t, point, normal })
    }
}

/// Signed distance to an axis-aligned box with rounded offset `thickness`,
/// and the outward normal: the nearest face's inside, the direction from the
/// closest point outside.
fn box_gap(min: &Point, max: &Point, p: &Point, thickness: f64) -> (f64, Point) {
    let clamped = p.sup(min).inf(max);
    let out = p - clamped;
    let d = out.norm();
    if d > 0.0 {
        return (d - thickness, out / d);
    }
    // Inside: the face nearest to p.
    let mut best = (f64::INFINITY, Point::zeros());
    for axis in 0..3 {
        for (depth, sign) in [(p[axis] - min[axis], -1.0), (max[axis] - p[axis], 1.0)] {
            if depth < best.0 {
                let mut n = Point::zeros();
                n[axis] = sign;
                best = (depth, n);
            }
        }
    }
    (-best.0 - thickness, best.1)
}

/// The smallest `t` in `[0, 1]` at which `a + t d` enters the sphere of
/// radius `r` about `c`, with `a` outside it.
fn sphere_entry(a: &Point, d: &Point, c: &Point, r: f64) -> Option<f64> {
    let f = a - c;
    let dd = d.norm_squared();
    if dd == 0.0 {
        return None;
    }
    let b = f.dot(d);
    let disc = b * b - dd * (f.norm_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / dd;
    (0.0..=1.0).contains(&t).then_some(t)
}

/// The slab test: the smallest `t` in `[0, 1]` at which `a + t d` enters the
/// box `[lo, hi]`, with `a` outside it, and the outward normal of the face
/// it enters through.
fn box_entry(a: &Point, d: &Point, lo: &Point, hi: &Point) -> Option<(f64, Point)> {
    let (mut t_in, mut t_out) = (0.0_f64, 1.0_f64);
    let mut normal = Point::zeros();
    for axis in 0..3 {
        if d[axis] == 0.0 {
            if a[axis] < lo[axis] || a[axis] > hi[axis] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[axis];
        let (t0, t1) = ((lo[axis] - a[axis]) * inv, (hi[axis] - a[axis]) * inv);
        let (near, far, sign) = if t0 <= t1 {
            (t0, t1, -1.0)
        } else {
            (t1, t0, 1.0)
        };
        if near > t_in {
            t_in = near;
            normal = Point::zeros();
            normal[axis] = sign;
        }
        t_out = t_out.min(far);
        if t_in > t_out {
            return None;
        }
    }
    (normal != Point::zeros()).then_some((t_in, normal))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_hit_is_where_the_segment_crosses() {
        let plane = ColliderShape::Plane {
            point: Point::zeros(),
            normal: Point::y(),
        };
        let hit = plane
            .first_hit(&Point::new(0.0, 1.0, 0.0), &Point::new(2.0, -3.0, 0.0), 0.0)
            .unwrap();
        assert_eq!(hit.t, 0.25);
        assert_eq!(hit.point, Point::new(0.5, 0.0, 0.0));
        assert!(
            plane
                .first_hit(&Point::y(), &(Point::y() * 0.5), 0.0)
                .is_none()
        );
    }

    #[test]
    fn a_fast_segment_through_a_sphere_or_box_is_caught() {
        let (a, b) = (Point::new(-5.0, 0.1, 0.0), Point::new(5.0, 0.1, 0.0));
        let sphere = ColliderShape::Sphere {
            center: Point::zeros(),
            radius: 0.5,
        };
        let hit = sphere.first_hit(&a, &b, 0.0).unwrap();
        assert!(hit.normal.x < 0.0 && (hit.point.norm() - 0.5).abs() < 1e-12);
        let cube = ColliderShape::Box {
            min: Point::repeat(-0.5),
            max: Point::repeat(0.5),
        };
        let hit = cube.first_hit(&a, &b, 0.01).unwrap();
        assert_eq!(hit.normal, -Point::x());
        assert!((hit.point.x + 0.51).abs() < 1e-12);
        // Past the box, above it: no hit.
        let above = Point::new(0.0, 0.6, 0.0);
        assert!(cube.first_hit(&(a + above), &(b + above), 0.01).is_none());
    }

    #[test]
    fn inside_the_box_the_nearest_face_pushes_out() {
        let cube = ColliderShape::Box {
            min: Point::zeros(),
            max: Point::new(1.0, 1.0, 1.0),
        };
        let (gap, n) = cube.gap(&Point::new(0.5, 0.9, 0.5), 0.0);
        assert!((gap + 0.1).abs() < 1e-12);
        assert_eq!(n, Point::y());
    }
}
