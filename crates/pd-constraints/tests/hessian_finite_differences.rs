//! The energy Hessian of every constraint kind (through
//! `ConstraintBlock::hessian_range`, so the chain rule `G^T H_gx G` is
//! checked too):
//!
//! - agrees with central finite differences of the energy gradient wherever
//!   the energy is smooth;
//! - once projected, is symmetric, positive semi-definite and bounded by the
//!   constraint's Laplacian `w G^T G` (x) `I_3`, everywhere, including
//!   inverted and degenerate elements;
//! - is left unchanged by the projection where it is already PSD;
//! - has the rigid motions in its kernel at the rest shape, and translations
//!   for every configuration of a translation-invariant kind.
//!
//! Finite-difference tolerance: a central difference of the gradient with
//! step `eps = 1e-6` has truncation error `eps^2/6 |E''''|` and round-off
//! `u |grad E| / eps` (u = 2.2e-16, a little more for the SVD's ~1e-15
//! accuracy). With positions O(1), `|G| <= 2` and, for tets, the singular
//! values kept 0.2 away from the kink `s_i + s_j = 0` (so `E''''` is at most
//! of order `w |G|^4 / 0.2^3 ~ 1e4 w`), both are around `1e-9` of the
//! Hessian's scale; we allow `1e-6` of it, a thousand times more, still far
//! below the O(1) relative error of a wrong eigenvalue or mode.

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, SymmetricEigen, Vector3};
use pd_constraints::{Attachment, ConstraintBlock, ConstraintSet, Spring, TetStrain};
use pd_mesh::Point;
use proptest::prelude::*;

const EPS: f64 = 1e-6;

/// The Hessian of the block's single constraint, whose stencil must be
/// `0..q.len()` in order, as a dense matrix (index `3 k + a`).
fn hessian(block: &dyn ConstraintBlock, q: &[Point], project_psd: bool) -> DMatrix<f64> {
    assert_eq!(block.len(), 1);
    assert!(block.stencil(0).iter().copied().eq(0..q.len()));
    let size = 3 * q.len();
    let mut out = vec![0.0; block.hessian_len()];
    block.hessian_range(q, 0, project_psd, &mut out);
    DMatrix::from_row_slice(size, size, &out)
}

/// `w G^T G` (x) `I_3`: the Hessian of `w/2 |G x|^2`, an upper bound of every
/// projected Hessian (whose `gx`-eigenvalues lie in `[0, w]`).
fn laplacian_bound(block: &dyn ConstraintBlock, stencil: usize) -> DMatrix<f64> {
    let mut triplets = Vec::new();
    block.add_laplacian(&mut triplets);
    let mut bound = DMatrix::zeros(3 * stencil, 3 * stencil);
    for t in triplets {
        for a in 0..3 {
            bound[(3 * t.row + a, 3 * t.column + a)] += t.value;
        }
    }
    bound
}

fn check_against_finite_differences(
    block: &dyn ConstraintBlock,
    q: &[Point],
) -> Result<(), TestCaseError> {
    let analytic = hessian(block, q, false);
    // The Hessian's natural scale is that of `w G^T G`, even where it
    // vanishes (inside strain limits the gradient is zero up to round-off of
    // order `u w`, which the difference quotient amplifies by `1/eps`).
    let scale = analytic.amax().max(laplacian_bound(block, q.len()).amax());
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

/// Symmetric, finite, PSD and at most `w G^T G` (x) `I_3`, up to round-off
/// relative to that bound's largest eigenvalue.
fn check_projected(block: &dyn ConstraintBlock, q: &[Point]) -> Result<(), TestCaseError> {
    let h = hessian(block, q, true);
    prop_assert!(
        h.iter().all(|x| x.is_finite()),
        "non-finite projected Hessian {h}"
    );
    let bound = laplacian_bound(block, q.len());
    let scale = SymmetricEigen::new(bound.clone()).eigenvalues.amax();
    prop_assert!(
        (&h - h.transpose()).amax() <= 1e-12 * scale,
        "asymmetric {h}"
    );
    let smallest = SymmetricEigen::new(h.clone()).eigenvalues.min();
    prop_assert!(smallest >= -1e-10 * scale, "eigenvalue {smallest} of {h}");
    let gap = SymmetricEigen::new(bound - &h).eigenvalues.min();
    prop_assert!(gap >= -1e-10 * scale, "exceeds w G^T G by {gap}");
    Ok(())
}

/// `H t = 0` for the translation `t` along each axis, up to the round-off of
/// summing a row of `H`.
fn check_translation_kernel(h: &DMatrix<f64>) -> Result<(), TestCaseError> {
    let vertices = h.nrows() / 3;
    for axis in 0..3 {
        let t = DVector::from_fn(3 * vertices, |i, _| if i % 3 == axis { 1.0 } else { 0.0 });
        let residual = (h * t).amax();
        prop_assert!(
            residual <= 1e-12 * h.amax(),
            "axis {axis}: |H t| = {residual}"
        );
    }
    Ok(())
}

fn point() -> impl Strategy<Value = Point> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| Point::new(x, y, z))
}

fn rotation() -> impl Strategy<Value = Matrix3<f64>> {
    (-3.2..3.2f64, -3.2..3.2f64, -3.2..3.2f64)
        .prop_map(|(x, y, z)| Rotation3::new(Vector3::new(x, y, z)).into_inner())
}

fn rest_tet() -> Vec<Point> {
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.1, 0.0),
        Point::new(0.2, 0.9, 0.1),
        Point::new(0.1, 0.2, 1.1),
    ]
}

fn tet_block(stiffness: f64, limits: Option<(f64, f64)>) -> ConstraintSet<TetStrain> {
    ConstraintSet::new(vec![
        TetStrain::new(&rest_tet(), [0, 1, 2, 3], stiffness, limits).unwrap(),
    ])
}

/// Positions `x_k = F X_k + t` of the rest tet under an affine map.
fn deform(f: &Matrix3<f64>, t: Point) -> Vec<Point> {
    rest_tet().iter().map(|x| f * x + t).collect()
}

fn deformation_gradient(q: &[Point]) -> Matrix3<f64> {
    let edges = |x: &[Point]| Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]);
    edges(q) * edges(&rest_tet()).try_inverse().unwrap()
}

/// Singular values, the smallest carrying the sign of `det F`, computed
/// independently of the library's `signed_svd`.
fn signed_singular_values(f: &Matrix3<f64>) -> Vector3<f64> {
    let mut s = f.singular_values();
    if f.determinant() < 0.0 {
        let smallest = s.imin();
        s[smallest] = -s[smallest];
    }
    s
}

const PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// Away from the kink `s_i + s_j = 0` of the corotational energy.
fn far_from_kink(s: &Vector3<f64>) -> bool {
    PAIRS.iter().all(|&(i, j)| (s[i] + s[j]).abs() > 0.2)
}

/// Also away from the limits, where the second derivative jumps, and from
/// repeated singular values.
fn smooth_with_limits(s: &Vector3<f64>, min: f64, max: f64) -> bool {
    far_from_kink(s)
        && s.iter()
            .all(|&x| (x - min).abs() > 1e-3 && (x - max).abs() > 1e-3)
        && PAIRS.iter().all(|&(i, j)| (s[i] - s[j]).abs() > 1e-3)
}

/// Flat, collapsed to a line or to a point (a random line or plane through
/// the first vertex), or left as it is.
fn degenerate(q: Vec<Point>, kind: usize, direction: Point) -> Vec<Point> {
    let n = direction.try_normalize(1e-3).unwrap_or_else(Point::z);
    let origin = q[0];
    q.iter()
        .map(|x| {
            let d = x - origin;
            origin
                + match kind {
                    0 => d - n * n.dot(&d),
                    1 => n * n.dot(&d),
                    2 => Point::zeros(),
                    _ => d,
                }
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, max_shrink_iters: 200, ..ProptestConfig::default() })]

    #[test]
    fn tet_strain_hessian(moves in proptest::collection::vec(point(), 4), stiffness in 0.1..1e3f64) {
        // Stretched, sheared, rotated and inverted configurations all occur.
        let q: Vec<Point> = rest_tet().iter().zip(&moves).map(|(x, d)| x + d * 0.8).collect();
        prop_assume!(far_from_kink(&signed_singular_values(&deformation_gradient(&q))));
        check_against_finite_differences(&tet_block(stiffness, None), &q)?;
    }

    #[test]
    fn strain_limited_tet_hessian(
        moves in proptest::collection::vec(point(), 4),
        stiffness in 0.1..1e3f64,
        min in 0.0..1.0f64,
        max in 1.0..1.5f64,
    ) {
        let q: Vec<Point> = rest_tet().iter().zip(&moves).map(|(x, d)| x + d * 0.6).collect();
        let s = signed_singular_values(&deformation_gradient(&q));
        prop_assume!(smooth_with_limits(&s, min, max));
        check_against_finite_differences(&tet_block(stiffness, Some((min, max))), &q)?;
    }

    #[test]
    fn spring_hessian(a in point(), b in point(), stiffness in 0.1..1e3f64, rest_length in 0.1..2.0f64) {
        // Compressed (|d| < L0, a negative transverse eigenvalue) and
        // stretched springs; away from the singularity at d = 0.
        prop_assume!((a - b).norm() > 0.1);
        let rest = vec![Point::zeros(), Point::x()];
        let spring = Spring::with_rest_length(&rest, [0, 1], stiffness, Some(rest_length)).unwrap();
        check_against_finite_differences(&ConstraintSet::new(vec![spring]), &[a, b])?;
    }

    #[test]
    fn zero_rest_length_spring_hessian(a in point(), b in point(), stiffness in 0.1..1e3f64) {
        // Quadratic energy: smooth even at d = 0.
        let rest = vec![Point::zeros(), Point::x()];
        let spring = Spring::with_rest_length(&rest, [0, 1], stiffness, Some(0.0)).unwrap();
        check_against_finite_differences(&ConstraintSet::new(vec![spring]), &[a, b])?;
    }

    #[test]
    fn attachment_hessian(x in point(), target in point(), stiffness in 0.1..1e3f64) {
        let block = ConstraintSet::new(vec![Attachment::new(0, target, stiffness).unwrap()]);
        check_against_finite_differences(&block, &[x])?;
    }

    #[test]
    fn projected_tet_hessians_are_psd_even_when_inverted_or_degenerate(
        moves in proptest::collection::vec(point(), 4),
        kind in 0..4usize,
        direction in point(),
        stiffness in 0.1..1e3f64,
        limits in proptest::option::of((0.0..1.0f64, 1.0..1.5f64)),
    ) {
        let q: Vec<Point> = rest_tet().iter().zip(&moves).map(|(x, d)| x + d * 1.5).collect();
        let q = degenerate(q, kind, direction);
        check_projected(&tet_block(stiffness, limits), &q)?;
    }

    #[test]
    fn projected_spring_and_attachment_hessians_are_psd(
        a in point(),
        b in point(),
        collapsed in any::<bool>(),
        stiffness in 0.1..1e3f64,
        rest_length in 0.0..2.0f64,
    ) {
        let b = if collapsed { a } else { b };
        let rest = vec![Point::zeros(), Point::x()];
        let spring = Spring::with_rest_length(&rest, [0, 1], stiffness, Some(rest_length)).unwrap();
        check_projected(&ConstraintSet::new(vec![spring]), &[a, b])?;
        let attachment = Attachment::new(0, b, stiffness).unwrap();
        check_projected(&ConstraintSet::new(vec![attachment]), &[a])?;
    }

    #[test]
    fn projection_keeps_a_hessian_that_is_already_psd(
        u in rotation(),
        v in rotation(),
        stretches in (1.01..2.0f64, 1.01..2.0f64, 1.01..2.0f64),
        t in point(),
        stiffness in 0.1..1e3f64,
        limits in proptest::option::of((0.0..1.0f64, 1.0..1.5f64)),
    ) {
        // s_i > 1 >= min: every twist eigenvalue 1 - (c_i + c_j)/(s_i + s_j)
        // is positive, and the others always are.
        let s = Vector3::new(stretches.0, stretches.1, stretches.2);
        let q = deform(&(u * Matrix3::from_diagonal(&s) * v.transpose()), t);
        let block = tet_block(stiffness, limits);
        prop_assert_eq!(hessian(&block, &q, true), hessian(&block, &q, false));
    }

    #[test]
    fn projection_keeps_stretched_spring_hessians(a in point(), b in point(), stiffness in 0.1..1e3f64) {
        let length = (a - b).norm();
        prop_assume!(length > 1e-3);
        let rest = vec![Point::zeros(), Point::x()];
        for rest_length in [0.0, 0.5 * length, length] {
            let spring = Spring::with_rest_length(&rest, [0, 1], stiffness, Some(rest_length)).unwrap();
            let block = ConstraintSet::new(vec![spring]);
            prop_assert_eq!(hessian(&block, &[a, b], true), hessian(&block, &[a, b], false));
        }
        let attachment = ConstraintSet::new(vec![Attachment::new(0, b, stiffness).unwrap()]);
        prop_assert_eq!(hessian(&attachment, &[a], true), hessian(&attachment, &[a], false));
    }

    #[test]
    fn rigid_motions_are_in_the_kernel_at_rest(
        r in rotation(),
        t in point(),
        omega in point(),
        stiffness in 0.1..1e3f64,
    ) {
        // Any rigid placement of the rest shape: F = R, s = (1, 1, 1), twist
        // eigenvalues 1 - 2/(1 + 1) = 0. Rayleigh damping built from this
        // Hessian does not damp rigid rotation.
        let q = deform(&r, t);
        let block = tet_block(stiffness, None);
        let rotation = DVector::from_iterator(12, q.iter().flat_map(|x| omega.cross(x).into_iter().copied().collect::<Vec<_>>()));
        for project_psd in [false, true] {
            let h = hessian(&block, &q, project_psd);
            check_translation_kernel(&h)?;
            let residual = (&h * &rotation).norm();
            prop_assert!(
                residual <= 1e-10 * h.norm() * rotation.norm(),
                "|H (omega x x)| = {residual}"
            );
        }
        // With strain limits the rest shape is strictly inside them: no
        // energy nearby and a zero Hessian.
        let limited = tet_block(stiffness, Some((0.9, 1.1)));
        let h = hessian(&limited, &q, false);
        prop_assert!(h.amax() <= 1e-12 * stiffness, "{h}");
    }

    #[test]
    fn translations_are_in_the_kernel_everywhere(
        moves in proptest::collection::vec(point(), 4),
        stiffness in 0.1..1e3f64,
        limits in proptest::option::of((0.0..1.0f64, 1.0..1.5f64)),
        rest_length in 0.0..2.0f64,
    ) {
        let q: Vec<Point> = rest_tet().iter().zip(&moves).map(|(x, d)| x + d * 0.8).collect();
        let tet = tet_block(stiffness, limits);
        check_translation_kernel(&hessian(&tet, &q, true))?;
        if far_from_kink(&signed_singular_values(&deformation_gradient(&q))) {
            check_translation_kernel(&hessian(&tet, &q, false))?;
        }
        let spring = Spring::with_rest_length(&q, [0, 1], stiffness, Some(rest_length)).unwrap();
        let spring = ConstraintSet::new(vec![spring]);
        check_translation_kernel(&hessian(&spring, &q[..2], true))?;
    }
}

#[test]
fn strain_limited_hessian_is_smooth_through_repeated_singular_values() {
    // s_0 and s_1 within 1e-9 of each other, both above the limit: the SVD's
    // U and V are ill-determined there but the Hessian is not.
    let u = Rotation3::from_euler_angles(0.3, 1.0, -0.4).into_inner();
    let v = Rotation3::from_euler_angles(-0.8, 0.2, 0.6).into_inner();
    for (s, limits) in [
        (Vector3::new(1.3, 1.3 + 1e-9, 0.7), Some((0.8, 1.2))),
        (Vector3::new(1.0, 1.0 + 1e-9, 0.7), Some((0.8, 1.2))),
        (Vector3::new(1.0, 1.0, 0.6), Some((0.8, 1.2))),
        (Vector3::new(1.0, 1.0, 1.0), None),
    ] {
        let q = deform(
            &(u * Matrix3::from_diagonal(&s) * v.transpose()),
            Point::zeros(),
        );
        check_against_finite_differences(&tet_block(5.0, limits), &q)
            .unwrap_or_else(|e| panic!("s = {s}, limits {limits:?}: {e}"));
    }
}

#[test]
fn explicit_degenerate_and_inverted_tets_have_psd_projections() {
    let r = Rotation3::from_euler_angles(0.7, -0.2, 1.9).into_inner();
    let cases = [
        Vector3::new(1.0, 1.0, -1.0), // reflected
        Vector3::new(1.0, 0.5, -0.5), // on the kink s_1 + s_2 = 0
        Vector3::new(2.0, 0.5, -0.1),
        Vector3::new(1.0, 1.0, 0.0), // flat
        Vector3::new(1.0, 0.0, 0.0), // a line
        Vector3::new(0.0, 0.0, 0.0), // a point
        Vector3::new(-1.0, -1.0, -1.0),
    ];
    for s in cases {
        let q = deform(
            &(r * Matrix3::from_diagonal(&s)),
            Point::new(0.3, -0.1, 2.0),
        );
        for limits in [None, Some((0.0, 1.0)), Some((0.5, 1.2)), Some((1.0, 1.0))] {
            check_projected(&tet_block(3.0, limits), &q)
                .unwrap_or_else(|e| panic!("s = {s}, limits {limits:?}: {e}"));
        }
    }
}
