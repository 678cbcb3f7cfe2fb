//! Quadratic bending of a flat rest sheet, one constraint per triangle:
//! `D A / 2 |H_T|_F^2` with `H_T` the triangle's discrete Hessian of the
//! out-of-plane displacement, built from the hinge vectors of its interior
//! edges (`docs/design/constraints.md`, "Bending").
//!
//! For edge `j` of triangle `T` (from `t_j` to `t_{j+1}`) with in-plane unit
//! normal `nu_j` and hinge row `K_j` (`crate::bending`, `K_j x = |e| theta n`
//! near flat),
//!
//! ```text
//! H_T = 1 / (2 A_T) sum_j (K_j x) nu_j nu_j^T
//! ```
//!
//! (the divergence theorem applied to the piecewise-constant gradient,
//! whose jump across edge `j` is `theta_j nu_j`). It reproduces the Hessian
//! of every quadratic displacement on interior triangles, so the energy
//! `D A_T / 2 (H_xx^2 + H_yy^2 + 2 H_xy^2)` is the plate energy with Poisson
//! ratio 0 without the mesh-direction coupling of the per-edge hinge sum
//! (which on the generator's grids couples bending to twist and makes a
//! strip 20 % too soft). Open edges contribute no hinge: their curvature
//! across the edge is free, which is the free-edge condition.

use pd_mesh::Point;

use crate::bending::hinge_operator;
use crate::tet_strain::{check_stiffness, check_vertices};
use crate::{Constraint, ConstraintError};

/// Plate bending of one triangle: stencil `[t0, t1, t2, o0, o1, o2]` with
/// `o_j` the vertex across edge `j`; across an open edge the slot holds
/// `t_{j+2}` again with a zero operator column. Three rows (`H_xx`, `H_yy`,
/// `sqrt 2 H_xy` in the triangle's rest frame), projection 0, weight
/// `D A_T`.
#[derive(Debug, Clone, PartialEq)]
pub struct PlateBending {
    vertices: [usize; 6],
    weight: f64,
    operator: [[f64; 6]; 3],
}

impl PlateBending {
    /// Builds the constraint of `triangle` with `across[j]` the vertex
    /// opposite edge `j` (`triangle[j]` to `triangle[j + 1]`) in the
    /// neighbouring triangle, `None` for an open edge; `stiffness` is the
    /// flexural rigidity `D` in N m.
    ///
    /// # Errors
    /// A negative or non-finite stiffness, or a (nearly) zero-area triangle
    /// among the triangle and its neighbours.
    pub fn new(
        rest: &[Point],
        triangle: [usize; 3],
        across: [Option<usize>; 3],
        stiffness: f64,
    ) -> Result<Self, ConstraintError> {
        let neighbours = across.iter().flatten().copied();
        check_vertices(
            rest,
            &triangle.into_iter().chain(neighbours).collect::<Vec<_>>(),
        )?;
        check_stiffness(stiffness)?;
        let [x0, x1, x2] = triangle.map(|v| rest[v]);
        let normal = (x1 - x0).cross(&(x2 - x0));
        let area = 0.5 * normal.norm();
        let size2 = (x1 - x0).norm_squared().max((x2 - x0).norm_squared());
        if !(area.is_finite() && area > 1e-12 * size2) {
            return Err(ConstraintError::DegenerateElement {
                vertices: triangle.to_vec(),
            });
        }
        let normal = normal / (2.0 * area);
        let b1 = (x1 - x0).normalize();
        let b2 = normal.cross(&b1);
        let mut vertices = [0; 6];
        vertices[..3].copy_from_slice(&triangle);
        let mut operator = [[0.0; 6]; 3];
        for j in 0..3 {
            let (a, b, c) = (triangle[j], triangle[(j + 1) % 3], triangle[(j + 2) % 3]);
            let Some(o) = across[j] else {
                vertices[3 + j] = c;
                continue;
            };
            vertices[3 + j] = o;
            let (k, _) = hinge_operator(rest, [a, b, c, o])?;
            let nu = (rest[b] - rest[a]).cross(&normal).normalize();
            let (n1, n2) = (nu.dot(&b1), nu.dot(&b2));
            let rows = [n1 * n1, n2 * n2, std::f64::consts::SQRT_2 * n1 * n2];
            let columns = [j, (j + 1) % 3, (j + 2) % 3, 3 + j];
            for (row, factor) in operator.iter_mut().zip(rows) {
                for (&column, kc) in columns.iter().zip(k) {
                    row[column] += factor * kc / (2.0 * area);
                }
            }
        }
        Ok(Self {
            vertices,
            weight: stiffness * area,
            operator,
        })
    }
}

impl Constraint for PlateBending {
    const STENCIL: usize = 6;
    const ROWS: usize = 3;
    const TRANSLATION_INVARIANT: bool = true;
    const KIND: &'static str = "bending";

    type Vertices<'a> = &'a [usize];

    fn vertices(&self) -> &[usize] {
        &self.vertices
    }

    fn weight(&self) -> f64 {
        self.weight
    }

    fn operator(&self, row: usize, column: usize) -> f64 {
        self.operator[row][column]
    }

    fn project(&self, _gx: &[Point], out: &mut [Point]) {
        out[..3].fill(Point::zeros());
    }

    /// The projection is 0 whatever the positions: written without
    /// gathering `G q` (the default computes it for each constraint and
    /// discards it). The same bits.
    fn project_many(_constraints: &[Self], _q: &[Point], out: &mut [Point]) {
        out.fill(Point::zeros());
    }

    fn gx_hessian(&self, _gx: &[Point], _project_psd: bool, out: &mut [f64]) {
        // w/2 |G x|^2: the constant w I.
        for (i, h) in out[..81].iter_mut().enumerate() {
            *h = if i % 10 == 0 { self.weight } else { 0.0 };
        }
    }
}

/// For every triangle, the vertex across each of its edges (`None` on an
/// open edge), for [`PlateBending::new`].
///
/// # Errors
/// [`ConstraintError::NonManifoldEdge`] for an edge of more than two
/// triangles.
pub fn neighbours(triangles: &[[usize; 3]]) -> Result<Vec<[Option<usize>; 3]>, ConstraintError> {
    let mut out = vec![[None; 3]; triangles.len()];
    for (edge, sides) in crate::bending::edge_sides(triangles)? {
        if let [(t, _), (u, _)] = sides[..] {
            for (me, other) in [(t, u), (u, t)] {
                let tri = triangles[me];
                let j = (0..3)
                    .find(|&j| {
                        let (a, b) = (tri[j], tri[(j + 1) % 3]);
                        [a.min(b), a.max(b)] == edge
                    })
                    .unwrap_or(0);
                let o = triangles[other]
                    .iter()
                    .copied()
                    .find(|v| !edge.contains(v))
                    .unwrap_or(tri[(j + 2) % 3]);
                out[me][j] = Some(o);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraint::apply_operator;

    /// A 4 x 4 grid of right triangles in the xz plane, as the `cloth`
    /// generator makes it.
    fn grid() -> (Vec<Point>, Vec<[usize; 3]>) {
        let n = 4;
        let index = |i: usize, k: usize| i + (n + 1) * k;
        let mut vertices = Vec::new();
        for k in 0..=n {
            for i in 0..=n {
                vertices.push(Point::new(i as f64 / n as f64, 0.0, k as f64 / n as f64));
            }
        }
        let mut triangles = Vec::new();
        for k in 0..n {
            for i in 0..n {
                let (c, ax, az, o) = (
                    index(i, k),
                    index(i + 1, k),
                    index(i, k + 1),
                    index(i + 1, k + 1),
                );
                triangles.push([c, az, o]);
                triangles.push([c, o, ax]);
            }
        }
        (vertices, triangles)
    }

    /// `project_many` (zeros without `G q`) and the energies give the
    /// one-at-a-time bits on a bent, moved grid.
    #[test]
    fn batched_projection_is_bit_identical() {
        let (rest, triangles) = grid();
        let across = neighbours(&triangles).unwrap();
        let constraints: Vec<PlateBending> = triangles
            .iter()
            .zip(&across)
            .map(|(&t, &a)| PlateBending::new(&rest, t, a, 0.7).unwrap())
            .collect();
        let q: Vec<Point> = rest
            .iter()
            .map(|p| p + Point::new(0.1 * p.z, (3.0 * p.x).sin() * p.z, 0.2))
            .collect();
        crate::lane_rows::test_support::assert_all_bit_identical(&constraints, &q);
    }

    #[test]
    fn interior_triangles_reproduce_the_hessian_of_quadratics() {
        let (rest, triangles) = grid();
        let across = neighbours(&triangles).unwrap();
        // Displacements along y: x^2/2 (H_xx = 1), z^2/2 (H_zz = 1), x z
        // (H_xz = 1): |G x|^2 / 2 = |H|_F^2 / 2 is 1/2, 1/2 and 1 (the energy
        // density over D).
        type Field = fn(&Point) -> f64;
        let fields: [(Field, f64); 3] = [
            (|p| p.x * p.x / 2.0, 0.5),
            (|p| p.z * p.z / 2.0, 0.5),
            (|p| p.x * p.z, 1.0),
        ];
        for (field, expected) in fields {
            let q: Vec<Point> = rest.iter().map(|p| p + Point::y() * field(p)).collect();
            let mut interior = 0;
            for (t, tri) in triangles.iter().enumerate() {
                if across[t].iter().any(Option::is_none) {
                    continue;
                }
                interior += 1;
                let c = PlateBending::new(&rest, *tri, across[t], 2.0).unwrap();
                let mut gx = [Point::zeros(); 3];
                apply_operator(&c, &q, &mut gx);
                let density: f64 = gx.iter().map(|r| r.norm_squared()).sum::<f64>() / 2.0;
                // Round-off of cotangents of 45 and 90 degrees.
                assert!((density - expected).abs() < 1e-12, "{density}");
            }
            assert!(interior > 0);
        }
    }

    #[test]
    fn open_edges_leave_a_zero_column() {
        let rest = vec![Point::zeros(), Point::x(), Point::z()];
        let c = PlateBending::new(&rest, [0, 1, 2], [None; 3], 1.0).unwrap();
        assert!((0..3).all(|r| (0..6).all(|k| c.operator(r, k) == 0.0)));
        assert_eq!(neighbours(&[[0, 1, 2]]).unwrap(), vec![[None; 3]]);
    }
}
