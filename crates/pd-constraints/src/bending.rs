//! Bending of a triangle surface: one hinge per interior edge, with the
//! cotangent-weighted four-vertex stencil of Bergou et al. 2006 ("A
//! quadratic bending model for inextensible surfaces") and Wardetzky et al.
//! (`docs/design/constraints.md`, "Bending").
//!
//! For the hinge of edge `x0 x1` with opposite vertices `x2` (triangle A)
//! and `x3` (triangle B), and `a_k^T` the interior angle at `x_k` of
//! triangle `T` (`c_kT = cot a_kT`), the operator is the single row
//!
//! ```text
//! K = [-(c_1A + c_1B), -(c_0A + c_0B), c_0A + c_1A, c_0B + c_1B]
//! ```
//!
//! It sums to zero and annihilates every planar configuration of the rest
//! hinge (linear precision), and near flat `K x = |e| theta n` for a dihedral
//! angle `theta`. The weight `D / (A_A + A_B)` makes the sum over hinges
//! approximate `D/2 integral kappa^2 dA` for cylindrical bending, so a strip
//! of width `w` bends like a beam of rigidity `D w`.
//!
//! The projection is onto `{ |K x| = r }` with `r = |K X|` at rest: for a
//! flat rest hinge `r = 0` and the projection is the constant 0 (the
//! quadratic, isometric bending energy: its Hessian is the constant
//! `w K^T K`, exactly the Laplacian); for a curved rest hinge the current
//! hinge vector is scaled to its rest length (Bouaziz et al. 2014), which
//! keeps the rest curvature magnitude (but not its sign).

use pd_mesh::Point;

use crate::tet_strain::{check_stiffness, check_vertices};
use crate::{Constraint, ConstraintError};

/// A bending hinge on an interior edge (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Bending {
    vertices: [usize; 4],
    weight: f64,
    operator: [f64; 4],
    rest_magnitude: f64,
    rest_direction: Point,
}

/// Cotangent of the angle between `a` and `b`.
fn cot(a: Point, b: Point) -> f64 {
    a.dot(&b) / a.cross(&b).norm()
}

/// The hinge row `K` of `[x0, x1, x2, x3]` and the sum of its two triangles'
/// rest areas (m^2).
///
/// # Errors
/// [`ConstraintError::DegenerateElement`] if either triangle has (nearly)
/// zero area.
pub(crate) fn hinge_operator(
    rest: &[Point],
    hinge: [usize; 4],
) -> Result<([f64; 4], f64), ConstraintError> {
    let [x0, x1, x2, x3] = hinge.map(|v| rest[v]);
    let e = x1 - x0;
    let area_a = 0.5 * e.cross(&(x2 - x0)).norm();
    let area_b = 0.5 * e.cross(&(x3 - x0)).norm();
    let size = e.norm().max((x2 - x0).norm()).max((x3 - x0).norm());
    let flat = |area: f64| !(area.is_finite() && area > 1e-12 * size * size);
    if flat(area_a) || flat(area_b) {
        return Err(ConstraintError::DegenerateElement {
            vertices: hinge.to_vec(),
        });
    }
    let (c0a, c1a) = (cot(e, x2 - x0), cot(-e, x2 - x1));
    let (c0b, c1b) = (cot(e, x3 - x0), cot(-e, x3 - x1));
    Ok((
        [-(c1a + c1b), -(c0a + c0b), c0a + c1a, c0b + c1b],
        area_a + area_b,
    ))
}

impl Bending {
    /// Builds the hinge `[x0, x1, x2, x3]` (edge `x0 x1`, opposite vertices
    /// `x2` and `x3`) from rest positions; `stiffness` is the flexural
    /// rigidity `D` in N m.
    ///
    /// A rest hinge whose vector `K X` is below `1e-9` of the hinge's size
    /// (a dihedral angle below about `1e-9` rad, i.e. round-off) counts as
    /// flat and gets the quadratic energy.
    ///
    /// # Errors
    /// A negative or non-finite stiffness, or a zero-area rest triangle
    /// ([`ConstraintError::DegenerateElement`]).
    pub fn new(rest: &[Point], hinge: [usize; 4], stiffness: f64) -> Result<Self, ConstraintError> {
        check_vertices(rest, &hinge)?;
        check_stiffness(stiffness)?;
        let [x0, x1, x2, x3] = hinge.map(|v| rest[v]);
        let (operator, areas) = hinge_operator(rest, hinge)?;
        let e = x1 - x0;
        let size = e.norm().max((x2 - x0).norm()).max((x3 - x0).norm());
        // K X from differences to x0 (K sums to 0), free of the origin's
        // round-off.
        let rest_vector: Point = [x1 - x0, x2 - x0, x3 - x0]
            .iter()
            .zip(&operator[1..])
            .map(|(d, k)| d * *k)
            .sum();
        let scale: f64 = operator.iter().map(|k| k.abs()).sum::<f64>() * size;
        let rest_magnitude = if rest_vector.norm() <= 1e-9 * scale {
            0.0
        } else {
            rest_vector.norm()
        };
        let normal = e.cross(&(x2 - x0)).normalize();
        Ok(Self {
            vertices: hinge,
            weight: stiffness / areas,
            operator,
            rest_magnitude,
            rest_direction: rest_vector.try_normalize(0.0).unwrap_or(normal),
        })
    }

    /// `|K X|` at rest in m: 0 for a flat hinge (quadratic bending).
    pub fn rest_magnitude(&self) -> f64 {
        self.rest_magnitude
    }
}

impl Constraint for Bending {
    const STENCIL: usize = 4;
    const ROWS: usize = 1;
    const TRANSLATION_INVARIANT: bool = true;
    const KIND: &'static str = "bending-curved";

    type Vertices<'a> = &'a [usize];

    fn vertices(&self) -> &[usize] {
        &self.vertices
    }

    fn weight(&self) -> f64 {
        self.weight
    }

    fn operator(&self, _row: usize, column: usize) -> f64 {
        self.operator[column]
    }

    fn project(&self, gx: &[Point], out: &mut [Point]) {
        out[0] = if self.rest_magnitude == 0.0 {
            Point::zeros()
        } else {
            // A vanished hinge vector has no direction: take the rest one.
            gx[0].try_normalize(0.0).unwrap_or(self.rest_direction) * self.rest_magnitude
        };
    }

    fn gx_hessian(&self, gx: &[Point], project_psd: bool, out: &mut [f64]) {
        // w/2 (|d| - r)^2: Hessian w [d^ d^T + (1 - r/|d|)(I - d^ d^T)], the
        // constant w I when r = 0.
        let length = gx[0].norm();
        let direction = gx[0].try_normalize(0.0).unwrap_or(self.rest_direction);
        let mut transverse = if self.rest_magnitude == 0.0 {
            1.0
        } else if length > 0.0 {
            1.0 - self.rest_magnitude / length
        } else {
            f64::NEG_INFINITY
        };
        if project_psd {
            transverse = transverse.max(0.0);
        }
        for a in 0..3 {
            for b in 0..3 {
                let along = direction[a] * direction[b];
                let identity = if a == b { 1.0 } else { 0.0 };
                out[3 * a + b] = self.weight * (along + transverse * (identity - along));
            }
        }
    }
}

/// The hinges `[x0, x1, x2, x3]` of a triangle mesh: one per interior edge
/// (shared by exactly two triangles), in order of first appearance. Open
/// edges (one triangle) get none.
///
/// # Errors
/// [`ConstraintError::NonManifoldEdge`] naming the edge and its triangles
/// if an edge is shared by more than two triangles.
pub fn hinges(triangles: &[[usize; 3]]) -> Result<Vec<[usize; 4]>, ConstraintError> {
    Ok(edge_sides(triangles)?
        .into_iter()
        .filter_map(|(edge, sides)| match sides.as_slice() {
            [(_, a), (_, b)] => Some([edge[0], edge[1], *a, *b]),
            _ => None,
        })
        .collect())
}

/// An edge (sorted vertex pair) and its `(triangle, opposite vertex)` sides.
pub(crate) type EdgeSides = ([usize; 2], Vec<(usize, usize)>);

/// Every edge of a triangle mesh (sorted vertex pair) with its one or two
/// `(triangle, opposite vertex)` sides, in order of first appearance.
///
/// # Errors
/// [`ConstraintError::NonManifoldEdge`] for an edge of more than two
/// triangles.
pub(crate) fn edge_sides(triangles: &[[usize; 3]]) -> Result<Vec<EdgeSides>, ConstraintError> {
    // Edge -> (order of first appearance, [(triangle, opposite vertex)]).
    type Sides = (usize, Vec<(usize, usize)>);
    let mut edges: std::collections::HashMap<[usize; 2], Sides> =
        std::collections::HashMap::with_capacity(3 * triangles.len() / 2 + 1);
    for (t, tri) in triangles.iter().enumerate() {
        for j in 0..3 {
            let (a, b, opposite) = (tri[j], tri[(j + 1) % 3], tri[(j + 2) % 3]);
            let next = edges.len();
            let entry = edges
                .entry([a.min(b), a.max(b)])
                .or_insert((next, Vec::new()));
            entry.1.push((t, opposite));
        }
    }
    let mut ordered: Vec<_> = edges.into_iter().collect();
    ordered.sort_unstable_by_key(|(_, (first, _))| *first);
    let mut out = Vec::with_capacity(ordered.len());
    for (edge, (_, sides)) in ordered {
        if sides.len() > 2 {
            return Err(ConstraintError::NonManifoldEdge {
                edge,
                triangles: sides.iter().map(|(t, _)| *t).collect(),
            });
        }
        out.push((edge, sides));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraint::apply_operator;

    fn hinge_points(fold: f64) -> Vec<Point> {
        // Edge along x of length 1, wings of height 0.5 and 0.7 folded up by
        // `fold` each.
        let (s, c) = fold.sin_cos();
        vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.3, 0.5 * c, 0.5 * s),
            Point::new(0.6, -0.7 * c, 0.7 * s),
        ]
    }

    #[test]
    fn flat_hinge_is_quadratic_and_measures_the_dihedral_angle() {
        let c = Bending::new(&hinge_points(0.0), [0, 1, 2, 3], 2.0).unwrap();
        assert_eq!(c.rest_magnitude(), 0.0);
        assert!((c.weight() - 2.0 / (0.25 + 0.35)).abs() < 1e-14);
        // Folding each wing by `fold` keeps the in-plane coordinates a
        // linear image of the rest ones (annihilated by K) and lifts the
        // wings by h sin(fold): |K x| = |e| 2 sin(fold) exactly, about
        // |e| theta for the dihedral angle theta = 2 fold. Round-off only.
        for fold in [1e-3, 0.3] {
            let mut gx = [Point::zeros()];
            apply_operator(&c, &hinge_points(fold), &mut gx);
            assert!((gx[0].norm() - 2.0 * fold.sin()).abs() < 1e-14, "{}", gx[0]);
        }
    }

    #[test]
    fn curved_hinge_keeps_its_rest_curvature() {
        let rest = hinge_points(0.2);
        let c = Bending::new(&rest, [0, 1, 2, 3], 1.0).unwrap();
        assert!(c.rest_magnitude() > 0.1);
        let mut gx = [Point::zeros()];
        let mut p = [Point::zeros()];
        apply_operator(&c, &rest, &mut gx);
        c.project(&gx, &mut p);
        assert!((gx[0] - p[0]).norm() < 1e-14);
    }

    #[test]
    fn hinges_of_a_strip_and_non_manifold_edges() {
        // Two triangles sharing edge 1-2, one open boundary elsewhere.
        let tris = [[0, 1, 2], [2, 1, 3]];
        assert_eq!(hinges(&tris).unwrap(), vec![[1, 2, 0, 3]]);
        let fan = [[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        assert_eq!(
            hinges(&fan),
            Err(ConstraintError::NonManifoldEdge {
                edge: [0, 1],
                triangles: vec![0, 1, 2]
            })
        );
    }

    #[test]
    fn degenerate_hinges_are_rejected() {
        let mut rest = hinge_points(0.0);
        rest[3] = Point::new(2.0, 0.0, 0.0);
        assert!(Bending::new(&rest, [0, 1, 2, 3], 1.0).is_err());
        assert!(Bending::new(&hinge_points(0.0), [0, 1, 2, 3], f64::NAN).is_err());
    }
}
