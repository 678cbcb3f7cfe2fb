//! The energy gradient of every constraint kind agrees with central finite
//! differences of its energy, at random deformed (including inverted)
//! configurations.
//!
//! Tolerance: a central difference with step `eps` has truncation error
//! `O(eps^2 |E'''|)` and round-off `O(u |E| / eps)` (u = 2.2e-16). With
//! `eps = 1e-6` and energies and derivatives of order `w` (positions O(1)),
//! both are below `1e-9 w`; we allow `1e-6` relative to the gradient's scale,
//! a thousand times that, and far below any error a wrong projection would
//! cause (those are O(1) relative).

use pd_constraints::{Attachment, ConstraintBlock, ConstraintSet, Spring, TetStrain};
use pd_mesh::Point;
use proptest::prelude::*;

const EPS: f64 = 1e-6;

fn check_gradient(block: &dyn ConstraintBlock, q: &[Point]) -> Result<(), TestCaseError> {
    let mut analytic = vec![Point::zeros(); q.len()];
    block.add_gradient(q, &mut analytic);
    let energy = |q: &[Point]| block.energy_range(q, 0..block.len());
    let scale = analytic
        .iter()
        .map(|g| g.amax())
        .fold(0.0, f64::max)
        .max(1e-3);
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

fn point() -> impl Strategy<Value = Point> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| Point::new(x, y, z))
}

fn rest_tet() -> Vec<Point> {
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.1, 0.0),
        Point::new(0.2, 0.9, 0.1),
        Point::new(0.1, 0.2, 1.1),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, max_shrink_iters: 200, ..ProptestConfig::default() })]

    #[test]
    fn tet_strain_gradient(moves in proptest::collection::vec(point(), 4), stiffness in 0.1..1e3f64) {
        let rest = rest_tet();
        // Deformations up to the element's size: stretched, sheared, rotated
        // and inverted configurations all occur.
        let q: Vec<Point> = rest.iter().zip(&moves).map(|(x, d)| x + d * 0.8).collect();
        let block = ConstraintSet::new(vec![TetStrain::new(&rest, [0, 1, 2, 3], stiffness, None).unwrap()]);
        check_gradient(&block, &q)?;
    }

    #[test]
    fn strain_limited_tet_gradient(moves in proptest::collection::vec(point(), 4), min in 0.5..1.0f64, max in 1.0..1.5f64) {
        let rest = rest_tet();
        let q: Vec<Point> = rest.iter().zip(&moves).map(|(x, d)| x + d * 0.5).collect();
        let block = ConstraintSet::new(vec![TetStrain::new(&rest, [0, 1, 2, 3], 10.0, Some((min, max))).unwrap()]);
        check_gradient(&block, &q)?;
    }

    #[test]
    fn spring_gradient(a in point(), b in point(), stiffness in 0.1..1e3f64, rest_length in 0.0..2.0f64) {
        prop_assume!((a - b).norm() > 1e-3); // the projection is not differentiable at d = 0
        let rest = vec![Point::zeros(), Point::x()];
        let spring = Spring::with_rest_length(&rest, [0, 1], stiffness, Some(rest_length)).unwrap();
        check_gradient(&ConstraintSet::new(vec![spring]), &[a, b])?;
    }

    #[test]
    fn attachment_gradient(x in point(), target in point(), stiffness in 0.1..1e3f64) {
        let block = ConstraintSet::new(vec![Attachment::new(0, target, stiffness).unwrap()]);
        check_gradient(&block, &[x])?;
    }
}

#[test]
fn translation_invariant_kinds_have_zero_row_sums() {
    // L 1 = 0 for strain and springs: they exert no net force
    // (docs/design/formulation.md, "Energy and Laplacians").
    let rest = rest_tet();
    let blocks: Vec<Box<dyn ConstraintBlock>> = vec![
        Box::new(ConstraintSet::new(vec![
            TetStrain::new(&rest, [0, 1, 2, 3], 7.0, None).unwrap(),
        ])),
        Box::new(ConstraintSet::new(vec![
            Spring::new(&rest, [0, 2], 3.0).unwrap(),
        ])),
    ];
    let l = pd_constraints::assembly::laplacian(
        &blocks,
        4,
        pd_constraints::assembly::LaplacianKind::System,
    );
    for r in 0..4 {
        let sum: f64 = l.row(r).map(|(_, v)| v).sum();
        let scale: f64 = l.row(r).map(|(_, v)| v.abs()).sum();
        // Round-off of a sum of a few terms of size `scale`.
        assert!(sum.abs() <= 1e-14 * scale, "row {r}: sum {sum}");
    }
    // An attachment is not translation invariant and stays out of L_d.
    let with_attachment: Vec<Box<dyn ConstraintBlock>> = vec![Box::new(ConstraintSet::new(vec![
        Attachment::new(1, Point::x(), 5.0).unwrap(),
    ]))];
    let l_d = pd_constraints::assembly::laplacian(
        &with_attachment,
        4,
        pd_constraints::assembly::LaplacianKind::Damping,
    );
    assert_eq!(l_d.nnz(), 0);
}
