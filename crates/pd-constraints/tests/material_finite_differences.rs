//! Hyperelastic materials (`neo-hookean`, `stvk`, `corotated`): energy,
//! gradient and Hessian of one element agree with central differences; the
//! rest state has zero energy and force; energy and forces are invariant
//! under rotation; the projected Hessian is PSD; parameters are checked.
//!
//! The element's positions are `O(1)` m and the material `young = 1` Pa,
//! `poisson = 0.3`, so energies, gradients and Hessians are `O(1)` (up to
//! about 10 for the large deformations below). Central differences with step
//! `h = 1e-5` have truncation error `h^2/6 |f'''|`, about `1e-10 * 10`, and
//! round-off `eps |f| / h`, about `2e-16 * 10 / 1e-5 = 2e-10`: a tolerance
//! of `1e-7` relative to the largest entry (at least 1) is three orders above
//! both and still catches any wrong term (an error in a formula is `O(1)`).

#![allow(clippy::needless_range_loop)] // index loops mirror the (vertex, axis) notation

use nalgebra::{Matrix3, Rotation3, SymmetricEigen, Vector3};
use pd_constraints::{ConstraintBlock, MaterialKind, MaterialSet, MaterialTet};
use pd_mesh::Point;

const STEP: f64 = 1e-5;
const TOLERANCE: f64 = 1e-7;

fn rest() -> Vec<Point> {
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.1, 0.0),
        Point::new(0.2, 0.9, 0.1),
        Point::new(0.1, 0.2, 1.1),
    ]
}

fn set(kind: MaterialKind) -> MaterialSet {
    let tet = MaterialTet::new(&rest(), [0, 1, 2, 3]).unwrap();
    MaterialSet::new(kind, 1.0, 0.3, vec![tet]).unwrap()
}

/// Deformed states: moderate, large stretch with shear, compression to 0.3,
/// inverted (one vertex through the opposite face), nearly flat.
fn states() -> Vec<Vec<Point>> {
    let x = rest();
    let map = |f: Matrix3<f64>| x.iter().map(|p| f * p).collect::<Vec<_>>();
    let mut inverted = x.clone();
    inverted[3] = Point::new(0.3, 0.3, -0.4);
    let mut flat = x.clone();
    flat[3] = Point::new(0.4, 0.3, 0.02);
    vec![
        map(Matrix3::new(
            1.1, 0.05, 0.0, -0.02, 0.95, 0.1, 0.03, 0.0, 1.02,
        )),
        map(Matrix3::new(1.6, 0.4, 0.1, 0.0, 0.8, -0.3, 0.2, 0.1, 1.3)),
        map(Matrix3::from_diagonal(&Vector3::new(0.3, 0.3, 0.3))),
        inverted,
        flat,
    ]
}

fn energy(block: &MaterialSet, q: &[Point]) -> f64 {
    block.energy_range(q, 0..1)
}

fn gradient(block: &MaterialSet, q: &[Point]) -> Vec<Point> {
    let mut g = vec![Point::zeros(); q.len()];
    block.add_gradient(q, &mut g);
    g
}

fn hessian(block: &MaterialSet, q: &[Point], psd: bool) -> Vec<f64> {
    let mut h = vec![0.0; 144];
    block.hessian_range(q, 0, psd, &mut h);
    h
}

fn nudged(q: &[Point], v: usize, a: usize, by: f64) -> Vec<Point> {
    let mut q = q.to_vec();
    q[v][a] += by;
    q
}

#[test]
fn gradient_matches_central_differences_of_the_energy() {
    for kind in MaterialKind::ALL {
        let block = set(kind);
        for (s, q) in states().iter().enumerate() {
            let g = gradient(&block, q);
            let scale = g.iter().map(|g| g.amax()).fold(1.0, f64::max);
            for v in 0..4 {
                for a in 0..3 {
                    let fd = (energy(&block, &nudged(q, v, a, STEP))
                        - energy(&block, &nudged(q, v, a, -STEP)))
                        / (2.0 * STEP);
                    assert!(
                        (fd - g[v][a]).abs() <= TOLERANCE * scale,
                        "{} state {s} vertex {v} axis {a}: gradient {} vs differences {fd}",
                        kind.name(),
                        g[v][a]
                    );
                }
            }
        }
    }
}

#[test]
fn hessian_matches_central_differences_of_the_gradient() {
    for kind in MaterialKind::ALL {
        let block = set(kind);
        for (s, q) in states().iter().enumerate() {
            let h = hessian(&block, q, false);
            let scale = h.iter().fold(1.0, |m: f64, x| m.max(x.abs()));
            for v in 0..4 {
                for a in 0..3 {
                    let plus = gradient(&block, &nudged(q, v, a, STEP));
                    let minus = gradient(&block, &nudged(q, v, a, -STEP));
                    for u in 0..4 {
                        for b in 0..3 {
                            let fd = (plus[u][b] - minus[u][b]) / (2.0 * STEP);
                            let exact = h[(3 * u + b) * 12 + 3 * v + a];
                            assert!(
                                (fd - exact).abs() <= TOLERANCE * scale,
                                "{} state {s}: H[({u},{b}),({v},{a})] = {exact} vs differences {fd}",
                                kind.name()
                            );
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn rest_state_has_zero_energy_and_force() {
    // Round-off of O(1) sums: 1e-14 is a few dozen ulps.
    for kind in MaterialKind::ALL {
        let block = set(kind);
        let x = rest();
        assert!(energy(&block, &x).abs() < 1e-14, "{}", kind.name());
        for g in gradient(&block, &x) {
            assert!(g.amax() < 1e-14, "{}: rest force {g:?}", kind.name());
        }
        // And a rigid motion of the rest shape.
        let r = Rotation3::from_axis_angle(&Vector3::y_axis(), 2.0);
        let moved: Vec<Point> = x
            .iter()
            .map(|p| r * p + Point::new(3.0, -1.0, 2.0))
            .collect();
        assert!(energy(&block, &moved).abs() < 1e-13, "{}", kind.name());
        for g in gradient(&block, &moved) {
            assert!(
                g.amax() < 1e-13,
                "{}: rigid-motion force {g:?}",
                kind.name()
            );
        }
    }
}

#[test]
fn energy_is_rotation_invariant_and_forces_rotate() {
    let r = Rotation3::from_axis_angle(&Vector3::x_axis(), 0.7)
        * Rotation3::from_axis_angle(&Vector3::z_axis(), -1.3);
    for kind in MaterialKind::ALL {
        let block = set(kind);
        for (s, q) in states().iter().enumerate() {
            let rotated: Vec<Point> = q.iter().map(|p| r * p).collect();
            let (e, er) = (energy(&block, q), energy(&block, &rotated));
            // Relative round-off of an O(10) sum of products.
            assert!(
                (e - er).abs() <= 1e-12 * e.abs().max(1.0),
                "{} state {s}",
                kind.name()
            );
            let (g, gr) = (gradient(&block, q), gradient(&block, &rotated));
            for (g, gr) in g.iter().zip(&gr) {
                assert!((r * g - gr).amax() <= 1e-11, "{} state {s}", kind.name());
            }
        }
    }
}

#[test]
fn projected_hessian_is_positive_semidefinite() {
    for kind in MaterialKind::ALL {
        let block = set(kind);
        let mut clamped_somewhere = false;
        for q in states() {
            let raw = nalgebra::SMatrix::<f64, 12, 12>::from_row_slice(&hessian(&block, &q, false));
            let psd = nalgebra::SMatrix::<f64, 12, 12>::from_row_slice(&hessian(&block, &q, true));
            let min_raw = SymmetricEigen::new(raw).eigenvalues.min();
            let eigen = SymmetricEigen::new(psd).eigenvalues;
            // Round-off of the eigen-decomposition: 1e-12 of the largest.
            assert!(
                eigen.min() >= -1e-12 * eigen.amax(),
                "{}: {eigen:?}",
                kind.name()
            );
            clamped_somewhere |= min_raw < -1e-9;
        }
        // The states include inverted and compressed ones, where every law
        // here is non-convex: the projection must have had work to do.
        assert!(
            clamped_somewhere,
            "{}: no indefinite Hessian met",
            kind.name()
        );
    }
}

#[test]
fn parameters_are_checked() {
    let tet = || vec![MaterialTet::new(&rest(), [0, 1, 2, 3]).unwrap()];
    let kind = MaterialKind::NeoHookean;
    for (young, poisson) in [
        (0.0, 0.3),
        (-1.0, 0.3),
        (f64::NAN, 0.3),
        (f64::INFINITY, 0.3),
        (1.0, 0.5),
        (1.0, -0.1),
        (1.0, f64::NAN),
    ] {
        let err = MaterialSet::new(kind, young, poisson, tet())
            .unwrap_err()
            .to_string();
        let field = if young > 0.0 && young.is_finite() {
            "poisson"
        } else {
            "young"
        };
        assert!(
            err.contains(field),
            "young {young}, poisson {poisson}: {err}"
        );
    }
    assert!(MaterialSet::new(kind, 1.0, 0.0, tet()).is_ok());
    let flat = vec![
        Point::zeros(),
        Point::x(),
        Point::y(),
        Point::new(1.0, 1.0, 0.0),
    ];
    assert!(MaterialTet::new(&flat, [0, 1, 2, 3]).is_err());
}
