//! The cloth and shell kinds (`triangle-strain`, `bending`, `area`,
//! `volume`): their gradients and Hessians (through `ConstraintBlock`, so the
//! chain rule `G^T H_gx G` is checked too) agree with central finite
//! differences wherever the energy is smooth, including inverted
//! (triangles flipped through their plane, inverted tetrahedra) and nearly
//! degenerate configurations; projected Hessians are symmetric, finite and
//! PSD everywhere, degenerate configurations included; translations are in
//! every Hessian's kernel.
//!
//! Tolerances, as in `hessian_finite_differences.rs`: a central difference
//! with step `eps = 1e-6` has truncation error `eps^2/6 |E''''|` and
//! round-off `u |E'| / eps`. Configurations are kept 0.2 away from the kinks
//! (a singular value of a triangle below 0.2, `s_i + s_j < 0.2` for a tet, a
//! curved hinge vector shorter than 0.2 of its rest length), where `E''''`
//! is at most of order `w / 0.2^3`; both errors are then around `1e-9` of the
//! scale `max |w G^T G|`, and we allow `1e-6` of it. A wrong mode or
//! eigenvalue gives an O(1) relative error.

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Matrix3x2, SymmetricEigen};
use pd_constraints::{
    Area, Bending, Constraint, ConstraintBlock, ConstraintSet, PlateBending, TriangleStrain, Volume,
};
use pd_mesh::Point;
use proptest::prelude::*;

const EPS: f64 = 1e-6;

fn hessian(block: &dyn ConstraintBlock, q: &[Point], project_psd: bool) -> DMatrix<f64> {
    let size = 3 * q.len();
    let mut out = vec![0.0; block.hessian_len()];
    block.hessian_range(q, 0, project_psd, &mut out);
    DMatrix::from_row_slice(size, size, &out)
}

fn laplacian_scale(block: &dyn ConstraintBlock) -> f64 {
    let mut triplets = Vec::new();
    block.add_laplacian(&mut triplets);
    triplets.iter().map(|t| t.value.abs()).fold(0.0, f64::max)
}

fn check_gradient(block: &dyn ConstraintBlock, q: &[Point]) -> Result<(), TestCaseError> {
    let mut analytic = vec![Point::zeros(); q.len()];
    block.add_gradient(q, &mut analytic);
    let energy = |q: &[Point]| block.energy_range(q, 0..block.len());
    let scale = laplacian_scale(block);
    let mut moved = q.to_vec();
    for v in 0..q.len() {
        for k in 0..3 {
            moved[v][k] = q[v][k] + EPS;
            let plus = energy(&moved);
            moved[v][k] = q[v][k] - EPS;
            let minus = energy(&moved);
            moved[v][k] = q[v][k];
            let numeric = (plus - minus) / (2.0 * EPS);
            prop_assert!(
                (numeric - analytic[v][k]).abs() <= 1e-6 * scale,
                "vertex {v} axis {k}: finite difference {numeric}, gradient {}",
                analytic[v][k]
            );
        }
    }
    Ok(())
}

fn check_hessian(block: &dyn ConstraintBlock, q: &[Point]) -> Result<(), TestCaseError> {
    let analytic = hessian(block, q, false);
    let scale = laplacian_scale(block).max(analytic.amax());
    let gradient = |q: &[Point]| {
        let mut g = vec![Point::zeros(); q.len()];
        block.add_gradient(q, &mut g);
        g
    };
    let mut moved = q.to_vec();
    for l in 0..q.len() {
        for b in 0..3 {
            moved[l][b] = q[l][b] + EPS;
            let plus = gradient(&moved);
            moved[l][b] = q[l][b] - EPS;
            let minus = gradient(&moved);
            moved[l][b] = q[l][b];
            for k in 0..q.len() {
                for a in 0..3 {
                    let numeric = (plus[k][a] - minus[k][a]) / (2.0 * EPS);
                    let exact = analytic[(3 * k + a, 3 * l + b)];
                    prop_assert!(
                        (numeric - exact).abs() <= 1e-6 * scale,
                        "entry ({k}, {a}), ({l}, {b}): finite difference {numeric}, Hessian {exact}"
                    );
                }
            }
        }
    }
    Ok(())
}

/// Projected: finite, symmetric, PSD (up to round-off of the scale), with
/// translations in the kernel; `bounded` adds `H <= w G^T G (x) I_3`.
fn check_projected(
    block: &dyn ConstraintBlock,
    q: &[Point],
    bounded: bool,
) -> Result<(), TestCaseError> {
    let h = hessian(block, q, true);
    prop_assert!(h.iter().all(|x| x.is_finite()), "non-finite {h}");
    let mut triplets = Vec::new();
    block.add_laplacian(&mut triplets);
    let mut bound = DMatrix::zeros(h.nrows(), h.ncols());
    for t in triplets {
        for a in 0..3 {
            bound[(3 * t.row + a, 3 * t.column + a)] += t.value;
        }
    }
    let scale = SymmetricEigen::new(bound.clone()).eigenvalues.amax();
    prop_assert!((&h - h.transpose()).amax() <= 1e-12 * scale);
    let smallest = SymmetricEigen::new(h.clone()).eigenvalues.min();
    prop_assert!(smallest >= -1e-10 * scale, "eigenvalue {smallest} of {h}");
    if bounded {
        let gap = SymmetricEigen::new(bound - &h).eigenvalues.min();
        prop_assert!(gap >= -1e-10 * scale, "exceeds w G^T G by {gap}");
    }
    for axis in 0..3 {
        let t = DVector::from_fn(h.nrows(), |i, _| if i % 3 == axis { 1.0 } else { 0.0 });
        prop_assert!((&h * t).amax() <= 1e-12 * scale.max(h.amax()));
    }
    Ok(())
}

fn point() -> impl Strategy<Value = Point> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| Point::new(x, y, z))
}

/// A rest triangle in the xy plane: `Dm = [[1, 0.3], [0, 0.9]]`.
fn rest_triangle() -> Vec<Point> {
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
        Point::new(0.3, 0.9, 0.0),
    ]
}

fn triangle_singular_values(q: &[Point]) -> (f64, f64) {
    let dm = Matrix2::new(1.0, 0.3, 0.0, 0.9);
    let f = Matrix3x2::from_columns(&[q[1] - q[0], q[2] - q[0]]) * dm.try_inverse().unwrap();
    let s = f.svd(false, false).singular_values;
    (s.max(), s.min())
}

fn rest_tet() -> Vec<Point> {
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.1, 0.0),
        Point::new(0.2, 0.9, 0.1),
        Point::new(0.1, 0.2, 1.1),
    ]
}

/// Signed singular values of a tet's `F`, sorted descending by magnitude
/// with the sign of `det F` on the last.
fn tet_singular_values(rest: &[Point], q: &[Point]) -> [f64; 3] {
    let dm = Matrix3::from_columns(&[rest[1] - rest[0], rest[2] - rest[0], rest[3] - rest[0]]);
    let ds = Matrix3::from_columns(&[q[1] - q[0], q[2] - q[0], q[3] - q[0]]);
    let f = ds * dm.try_inverse().unwrap();
    let mut s: Vec<f64> = f
        .svd(false, false)
        .singular_values
        .iter()
        .copied()
        .collect();
    s.sort_by(|a, b| b.total_cmp(a));
    if f.determinant() < 0.0 {
        s[2] = -s[2];
    }
    [s[0], s[1], s[2]]
}

/// The hinge `[x0, x1, x2, x3]`: edge along x, wings folded by `fold`.
fn hinge(fold: f64) -> Vec<Point> {
    let (s, c) = fold.sin_cos();
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
        Point::new(0.3, 0.5 * c, 0.5 * s),
        Point::new(0.6, -0.7 * c, 0.7 * s),
    ]
}

fn hinge_vector(c: &Bending, q: &[Point]) -> Point {
    (0..4).map(|k| q[k] * c.operator(0, k)).sum()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, max_shrink_iters: 200, ..ProptestConfig::default() })]

    #[test]
    fn triangle_strain_derivatives(
        moves in proptest::collection::vec(point(), 3),
        stiffness in 0.1..1e3f64,
        limited in any::<bool>(),
        min in 0.5..1.0f64,
        max in 1.0..1.5f64,
    ) {
        let rest = rest_triangle();
        // Up to the triangle's size: stretched, sheared, rotated and flipped
        // through its plane (the "inverted" triangle).
        let q: Vec<Point> = rest.iter().zip(&moves).map(|(x, d)| x + d * 0.7).collect();
        let limits = limited.then_some((min, max));
        let block = ConstraintSet::new(vec![TriangleStrain::new(&rest, [0, 1, 2], stiffness, limits).unwrap()]);
        check_gradient(&block, &q)?;
        check_projected(&block, &q, true)?;
        let (s0, s1) = triangle_singular_values(&q);
        let near_limit = |s: f64| limited && ((s - min).abs() < 0.02 || (s - max).abs() < 0.02);
        prop_assume!(s1 > 0.2 && (s0 - s1).abs() > 1e-3 && !near_limit(s0) && !near_limit(s1));
        check_hessian(&block, &q)?;
    }

    #[test]
    fn bending_derivatives(
        moves in proptest::collection::vec(point(), 4),
        stiffness in 0.1..1e3f64,
        rest_fold in prop_oneof![Just(0.0), 0.1..0.6f64],
    ) {
        let rest = hinge(rest_fold);
        let c = Bending::new(&rest, [0, 1, 2, 3], stiffness).unwrap();
        let q: Vec<Point> = rest.iter().zip(&moves).map(|(x, d)| x + d * 0.4).collect();
        let block = ConstraintSet::new(vec![c.clone()]);
        check_gradient(&block, &q)?;
        check_projected(&block, &q, true)?;
        prop_assume!(hinge_vector(&c, &q).norm() > 0.2 * c.rest_magnitude());
        check_hessian(&block, &q)?;
    }

    #[test]
    fn plate_bending_derivatives(moves in proptest::collection::vec(point(), 6), stiffness in 0.1..1e3f64) {
        // Triangle 0-1-2 with all three neighbours 3, 4, 5 (a flat patch).
        let rest = vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.4, 0.9, 0.0),
            Point::new(0.6, -0.8, 0.0),
            Point::new(1.2, 0.9, 0.0),
            Point::new(-0.5, 0.7, 0.0),
        ];
        let c = PlateBending::new(&rest, [0, 1, 2], [Some(3), Some(4), Some(5)], stiffness).unwrap();
        let q: Vec<Point> = rest.iter().zip(&moves).map(|(x, d)| x + d * 0.5).collect();
        let block = ConstraintSet::new(vec![c]);
        check_gradient(&block, &q)?;
        check_hessian(&block, &q)?;
        check_projected(&block, &q, true)?;
    }

    #[test]
    fn area_derivatives(moves in proptest::collection::vec(point(), 3), stiffness in 0.1..1e3f64) {
        let rest = rest_triangle();
        let q: Vec<Point> = rest.iter().zip(&moves).map(|(x, d)| x + d * 0.5).collect();
        let block = ConstraintSet::new(vec![Area::new(&rest, [0, 1, 2], stiffness).unwrap()]);
        check_projected(&block, &q, false)?;
        let (s0, s1) = triangle_singular_values(&q);
        check_gradient(&block, &q)?;
        prop_assume!(s1 > 0.2 && (s0 - s1).abs() > 1e-3);
        check_hessian(&block, &q)?;
    }

    #[test]
    fn volume_derivatives(moves in proptest::collection::vec(point(), 4), stiffness in 0.1..1e3f64) {
        let rest = rest_tet();
        // Inverted configurations occur (det F < 0).
        let q: Vec<Point> = rest.iter().zip(&moves).map(|(x, d)| x + d * 0.6).collect();
        let block = ConstraintSet::new(vec![Volume::new(&rest, [0, 1, 2, 3], stiffness).unwrap()]);
        check_projected(&block, &q, false)?;
        let s = tet_singular_values(&rest, &q);
        check_gradient(&block, &q)?;
        let apart = (s[0] - s[1]).abs() > 1e-3 && (s[1] - s[2]).abs() > 1e-3;
        prop_assume!(s[1] + s[2] > 0.2 && s[2].abs() > 0.05 && apart);
        check_hessian(&block, &q)?;
    }
}

#[test]
fn degenerate_configurations_have_finite_psd_projected_hessians() {
    let rest = rest_triangle();
    let collapsed_to_line = vec![rest[0], rest[1], Point::new(0.5, 0.0, 0.0)];
    let collapsed_to_point = vec![Point::zeros(); 3];
    let strain = ConstraintSet::new(vec![
        TriangleStrain::new(&rest, [0, 1, 2], 3.0, None).unwrap(),
    ]);
    let area = ConstraintSet::new(vec![Area::new(&rest, [0, 1, 2], 3.0).unwrap()]);
    for q in [&collapsed_to_line, &collapsed_to_point] {
        check_projected(&strain, q, true).unwrap();
        check_projected(&area, q, false).unwrap();
        // The unprojected Hessian has the kink's non-finite entries.
        assert!(hessian(&strain, q, false).iter().any(|x| !x.is_finite()));
    }
    let tet = rest_tet();
    let volume = ConstraintSet::new(vec![Volume::new(&tet, [0, 1, 2, 3], 3.0).unwrap()]);
    let flat = vec![tet[0], tet[1], tet[2], Point::new(0.4, 0.4, 0.0)];
    let inverted = vec![tet[0], tet[1], tet[2], Point::new(0.1, 0.2, -1.1)];
    for q in [&flat, &inverted, &vec![Point::zeros(); 4]] {
        check_projected(&volume, q, false).unwrap();
    }
    let curved = hinge(0.4);
    let bending = ConstraintSet::new(vec![Bending::new(&curved, [0, 1, 2, 3], 3.0).unwrap()]);
    let folded_flat = hinge(0.0);
    check_projected(&bending, &folded_flat, true).unwrap();
}

#[test]
fn flat_bending_hessian_is_the_constant_laplacian() {
    // Projection to 0: the energy is w/2 |K x|^2, Hessian exactly w K^T K.
    let rest = hinge(0.0);
    let block = ConstraintSet::new(vec![Bending::new(&rest, [0, 1, 2, 3], 2.0).unwrap()]);
    let q = hinge(0.9);
    let h = hessian(&block, &q, false);
    let mut triplets = Vec::new();
    block.add_laplacian(&mut triplets);
    let mut l = DMatrix::zeros(12, 12);
    for t in triplets {
        for a in 0..3 {
            l[(3 * t.row + a, 3 * t.column + a)] += t.value;
        }
    }
    assert!((h - l).amax() < 1e-13 * block.constraints()[0].weight());
}
