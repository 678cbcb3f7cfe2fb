//! Self-contact's rest neighbourhood (`contact.self = true`,
//! docs/design/contact.md, "Self-contact"): which triangles of a vertex's own
//! surface it may never pair with.
//!
//! Rule: a vertex `v` and a triangle `F` of the same body are neighbours
//! when, in the rest configuration, the distance from `v` to the closed
//! triangle `F` is below one mean surface edge plus the thickness. This
//! holds for every triangle that contains `v` (distance 0) and for the
//! triangles around its 1-ring. Two reasons:
//!
//! - At rest no pair can form. Detection admits a pair only if the vertex
//!   projects into the triangle and lies less than `thickness` in front of
//!   it or less than `thickness + reach` behind it (`reach` is a quarter of
//!   the mean edge), i.e. within `thickness + reach` of the triangle. The
//!   radius is four times the reach: the margin of three quarters of an
//!   edge is what a body may deform before a neighbour comes that close.
//!   It also covers what a surface n-ring would miss: the opposite face of
//!   a body one element thick lies one (short) edge away at rest.
//! - What it gives up cannot be represented anyway: a fold whose two sides
//!   are within one element of each other along the surface is a crease
//!   sharper than the mesh resolves.

use pd_mesh::Point;

use crate::grid::Grid;

/// Per vertex, the sorted triangles of its own body it never pairs with.
#[derive(Debug, Clone, Default)]
pub(super) struct RestNeighbourhood {
    /// `faces[start[v]..start[v + 1]]`: vertex `v`'s excluded triangles.
    start: Vec<usize>,
    faces: Vec<u32>,
}

impl RestNeighbourhood {
    /// For every vertex that lies on a triangle of `triangles` (each with
    /// its body), the triangles of the same body within `radius` of it at
    /// `rest` (m). `body_of[v]` is the body of vertex `v`'s surface.
    pub fn new(
        triangles: &[([usize; 3], usize)],
        body_of: &[usize],
        rest: &[Point],
        radius: f64,
    ) -> Self {
        let margin = Point::repeat(radius);
        let boxes: Vec<(Point, Point)> = triangles
            .iter()
            .map(|(t, _)| {
                let (lo, hi) = t.iter().fold((rest[t[0]], rest[t[0]]), |(lo, hi), &i| {
                    (lo.inf(&rest[i]), hi.sup(&rest[i]))
                });
                (lo - margin, hi + margin)
            })
            .collect();
        let mut grid = Grid::default();
        grid.build(&boxes);
        let mut start = Vec::with_capacity(rest.len() + 1);
        let mut faces = Vec::new();
        let mut near = Vec::new();
        for (v, p) in rest.iter().enumerate() {
            start.push(faces.len());
            if body_of[v] == usize::MAX {
                continue;
            }
            near.clear();
            grid.query(p, p, |f| {
                let (t, body) = triangles[f];
                if body == body_of[v]
                    && (t.contains(&v) || distance(&t.map(|i| rest[i]), p) < radius)
                {
                    near.push(f as u32);
                }
            });
            near.sort_unstable();
            near.dedup();
            faces.extend_from_slice(&near);
        }
        start.push(faces.len());
        Self { start, faces }
    }

    /// Whether vertex `v` and triangle `face` are rest neighbours.
    pub fn excludes(&self, v: usize, face: usize) -> bool {
        let list = &self.faces[self.start[v]..self.start[v + 1]];
        list.binary_search(&(face as u32)).is_ok()
    }

    /// The number of excluded (vertex, triangle) pairs.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.faces.len()
    }
}

/// Distance from `p` to the closed triangle `t`, m: to its plane if `p`
/// projects inside it, else to the nearest edge (a degenerate triangle is
/// its edges).
pub(super) fn distance(t: &[Point; 3], p: &Point) -> f64 {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let cross = e1.cross(&e2);
    let area2 = cross.norm_squared();
    if area2 > 0.0 {
        let q = p - t[0];
        let w1 = -e2.cross(&q).dot(&cross) / area2;
        let w2 = e1.cross(&q).dot(&cross) / area2;
        if w1 >= 0.0 && w2 >= 0.0 && w1 + w2 <= 1.0 {
            return cross.dot(&q).abs() / area2.sqrt();
        }
    }
    (0..3)
        .map(|k| segment_distance(&t[k], &t[(k + 1) % 3], p))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `p` to the segment `a b`, m.
fn segment_distance(a: &Point, b: &Point, p: &Point) -> f64 {
    let d = b - a;
    let length2 = d.norm_squared();
    let s = if length2 > 0.0 {
        ((p - a).dot(&d) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + d * s)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_triangle_is_to_its_plane_edge_or_corner() {
        let t = [Point::zeros(), Point::x(), Point::y()];
        // Above the inside: the height.
        assert_eq!(distance(&t, &Point::new(0.25, 0.25, 2.0)), 2.0);
        // Beside the hypotenuse, in the plane.
        let d = distance(&t, &Point::new(1.0, 1.0, 0.0));
        assert!((d - 0.5_f64.sqrt()).abs() < 1e-15, "{d}");
        // Past a corner.
        assert_eq!(distance(&t, &Point::new(-3.0, -4.0, 0.0)), 5.0);
    }

    #[test]
    fn a_flat_strip_excludes_the_triangles_within_the_radius_only() {
        // A strip of 4 unit squares along x, two triangles each.
        let rest: Vec<Point> = (0..10)
            .map(|i| Point::new((i / 2) as f64, (i % 2) as f64, 0.0))
            .collect();
        let triangles: Vec<([usize; 3], usize)> = (0..4)
            .flat_map(|c| {
                let a = 2 * c;
                [([a, a + 2, a + 3], 0), ([a, a + 3, a + 1], 0)]
            })
            .collect();
        let body_of = vec![0; rest.len()];
        let near = RestNeighbourhood::new(&triangles, &body_of, &rest, 1.1);
        // Vertex 0 at x = 0: the first square's triangles (distance 0) and
        // the second's (distance 1 < 1.1), not the third (distance 2).
        assert!((0..4).all(|f| near.excludes(0, f)));
        assert!((4..8).all(|f| !near.excludes(0, f)));
        // Another body's triangle is never excluded.
        let other = vec![1; rest.len()];
        let none = RestNeighbourhood::new(&triangles, &other, &rest, 1.1);
        assert!((0..8).all(|f| !none.excludes(0, f)));
        assert_eq!(none.len(), 0);
    }
}
