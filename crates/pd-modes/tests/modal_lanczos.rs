//! Block Lanczos, the modal analysis of large models (`Method::Lanczos`),
//! against the dense eigensolver (values and shapes), its fallback to
//! subspace iteration on a model with mechanisms, its determinism across
//! thread counts, and the number of columns it solves.

mod common;

use pd_mesh::generators;
use pd_modes::{Method, Mode};
use pd_solver::Model;

/// A free tet body: six rigid motions, deflated by Lanczos, found as zero
/// modes by the dense solver.
fn free_box() -> Model {
    let mesh = generators::box_tets([0.3, 0.2, 0.1], [3, 2, 1]).unwrap();
    let mut model = Model::new();
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1.0e5, None).unwrap();
    model
}

/// `|a^T M b|` for mass-normalised shapes.
fn mass_cosine(model: &Model, a: &Mode, b: &Mode) -> f64 {
    a.shape
        .iter()
        .zip(&b.shape)
        .zip(model.masses())
        .map(|((p, q), m)| m * p.dot(q))
        .sum::<f64>()
        .abs()
}

/// Frequencies agree to the convergence tolerance (residual <= 1e-9
/// lambda, so omega within 5e-10 relative; the Rayleigh quotient Lanczos
/// reports is closer still) plus the dense solver's round-off. Shapes agree
/// by Davis-Kahan: the angle between a Ritz vector and the eigenvector
/// satisfies `sin <= |r|_{M^-1} / gap`, `gap` the distance from `lambda` to
/// the rest of the spectrum, and the dense eigenvector errs by about `n u
/// lambda_max / gap` (`n` dofs, `u` the unit round-off): `1 - |cos| <=
/// sin^2 / 2 + ...`, bounded here by `sin` itself.
#[test]
fn dense_and_lanczos_agree() {
    let clamped = common::beam([1.0, 0.1, 0.1], [20, 2, 2]);
    for (name, model, rigid) in [("clamped", clamped, 0), ("free", free_box(), 6)] {
        let all = pd_modes::elastic_modes_by(&model, usize::MAX, Method::Dense).unwrap();
        let lanczos = pd_modes::elastic_modes_by(&model, 8, Method::Lanczos).unwrap();
        println!(
            "{name}: {} blocks, {} restarts",
            lanczos.iterations, lanczos.restarts
        );
        assert_eq!(lanczos.method, "shift-invert block Lanczos", "{name}");
        // 8 modes keep 14 Ritz vectors in a basis of 38 columns: both
        // models need more, so the thick restart is exercised.
        assert!(lanczos.restarts >= 1, "{name}");
        assert_eq!(lanczos.rigid_modes, rigid, "{name}");
        assert_eq!(all.mechanisms + lanczos.mechanisms, 0, "{name}");
        assert_eq!(lanczos.modes.len(), 8, "{name}");
        let lambda_max = all.modes.last().unwrap().omega.powi(2);
        let round_off = all.dofs as f64 * f64::EPSILON * lambda_max;
        for (j, (a, b)) in all.modes.iter().zip(&lanczos.modes).enumerate() {
            assert!(
                (a.omega - b.omega).abs() <= 1e-9 * a.omega,
                "{name} mode {j}: {} vs {}",
                a.omega,
                b.omega
            );
            let lambda = a.omega * a.omega;
            let gap = all
                .modes
                .iter()
                .enumerate()
                .filter(|&(k, _)| k != j)
                .map(|(_, m)| (m.omega * m.omega - lambda).abs())
                .fold(f64::INFINITY, f64::min);
            let sine = (1e-9 * lambda + round_off) / gap;
            let cosine = mass_cosine(&model, a, b);
            assert!(
                1.0 - cosine <= sine,
                "{name} mode {j}: |cos| = {cosine}, sin bound {sine:e}"
            );
        }
    }
}

/// A clamped beam (540 dofs, above the dense limit) and, beside it, one
/// vertex held between two fixed ones by springs: its two sideways motions
/// have no stiffness at rest (mechanisms). Lanczos sees them as Ritz values
/// at zero and hands the model to subspace iteration, which counts both;
/// the frequencies agree with the dense solver to the convergence
/// tolerance (omega within 5e-10 relative) plus its round-off (1e-12).
#[test]
fn a_model_with_mechanisms_falls_back_to_subspace_iteration() {
    let mut model = common::beam([1.0, 0.1, 0.1], [20, 2, 2]);
    let mesh = generators::chain(3, 0.2).unwrap();
    let body = model.add_body(mesh, vec![0.01; 3]).unwrap();
    model.add_springs(body, 100.0).unwrap();
    model.fix_vertices(body, &[0, 2]).unwrap();
    let analysis = pd_modes::elastic_modes(&model, 6).unwrap();
    let dense = pd_modes::elastic_modes_by(&model, 6, Method::Dense).unwrap();
    assert_eq!(analysis.dofs, 543);
    assert_eq!(analysis.method, "shift-invert subspace iteration");
    assert_eq!(analysis.mechanisms, 2);
    assert_eq!(dense.mechanisms, 2);
    assert_eq!(analysis.modes.len(), 6);
    for (j, (a, b)) in dense.modes.iter().zip(&analysis.modes).enumerate() {
        assert!(
            (a.omega - b.omega).abs() <= 1e-9 * a.omega,
            "mode {j}: {} vs {}",
            a.omega,
            b.omega
        );
    }
}

/// The supernodal solve splits its tree between two threads in a fixed
/// way, and everything else is sequential: the modes are the same bits on
/// one thread and on two.
#[test]
fn lanczos_is_the_same_on_one_and_two_threads() {
    let model = common::beam([1.0, 0.1, 0.1], [40, 4, 4]);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| pd_modes::elastic_modes(&model, 6).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.method, "shift-invert block Lanczos");
    assert_eq!(one.solved_columns, two.solved_columns);
    for (a, b) in one.modes.iter().zip(&two.modes) {
        assert_eq!(a.omega.to_bits(), b.omega.to_bits());
        for (p, q) in a.shape.iter().zip(&b.shape) {
            for axis in 0..3 {
                assert_eq!(p[axis].to_bits(), q[axis].to_bits());
            }
        }
    }
}

/// The blocks Lanczos expands stay below the Kaniel-Paige-Saad bound for
/// block Lanczos (Saad 1980, the block form of Golub and Underwood): with
/// blocks of `p = 3` columns and `theta = 1 / lambda` the shift-invert
/// eigenvalues (the shift, 1e-8 of the largest, is negligible), the angle
/// between eigenvector `j` and the Krylov space after `k` blocks falls like
/// `tan(start) / T_d(1 + 2 gamma_j)`, `d = k - ceil(j / p)`, `T_d` the
/// Chebyshev polynomial and `gamma_j = (theta_j - theta_{j+p}) /
/// (theta_{j+p} - theta_min)`: the gap to the `p`-th next eigenvalue, not
/// the next, so close pairs do not slow a block of three. A residual
/// `|K x - lambda M x|_{M^-1} <= 1e-9 lambda` needs the angle below `1e-9
/// lambda_j / lambda_max` (`K` magnifies the error by at most
/// `lambda_max`). `tan(start)` is taken as 1e3 (a random start block has
/// components of about `1/sqrt(n)` along each eigenvector, `tan` about
/// `sqrt(n)`, 23 here; the seed is fixed). One block more for the
/// Rayleigh-Ritz check.
#[test]
fn lanczos_blocks_stay_below_the_kaniel_paige_saad_bound() {
    let model = common::beam([1.0, 0.1, 0.1], [20, 2, 2]);
    let count = 6;
    let p = 3;
    let all = pd_modes::elastic_modes_by(&model, usize::MAX, Method::Dense).unwrap();
    let lambda: Vec<f64> = all.modes.iter().map(|m| m.omega * m.omega).collect();
    let theta = |i: usize| 1.0 / lambda[i - 1];
    let theta_min = theta(lambda.len());
    let bound = (1..=count)
        .map(|j| {
            let gamma = (theta(j) - theta(j + p)) / (theta(j + p) - theta_min);
            let needed = 1e3 * lambda.last().unwrap() / lambda[j - 1] / 1e-9;
            let d = (needed.acosh() / (1.0 + 2.0 * gamma).acosh()).ceil() as usize;
            d + j.div_ceil(p) + 1
        })
        .max()
        .unwrap();
    let lanczos = pd_modes::elastic_modes_by(&model, count, Method::Lanczos).unwrap();
    println!(
        "{} blocks ({} columns, {} restarts); bound {bound} blocks",
        lanczos.iterations, lanczos.solved_columns, lanczos.restarts
    );
    assert_eq!(lanczos.method, "shift-invert block Lanczos");
    assert!(lanczos.iterations <= bound);
    assert_eq!(lanczos.solved_columns, p * lanczos.iterations);
}

/// A model smaller than Lanczos's basis: the blocks end when they span
/// every elastic motion (18 of a free 8-vertex cube), and then every mode
/// is exact to round-off; asked for all of them, Lanczos returns all 18 as
/// the dense solver does (to the convergence tolerance).
#[test]
fn lanczos_spans_a_small_model_entirely() {
    let mesh = generators::box_tets([0.1, 0.1, 0.1], [1, 1, 1]).unwrap();
    let mut model = Model::new();
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1.0e5, None).unwrap();
    let dense = pd_modes::elastic_modes_by(&model, usize::MAX, Method::Dense).unwrap();
    let lanczos = pd_modes::elastic_modes_by(&model, usize::MAX, Method::Lanczos).unwrap();
    assert_eq!(lanczos.method, "shift-invert block Lanczos");
    assert_eq!(lanczos.rigid_modes, 6);
    assert_eq!(dense.modes.len(), 18);
    assert_eq!(lanczos.modes.len(), 18);
    for (a, b) in dense.modes.iter().zip(&lanczos.modes) {
        assert!((a.omega - b.omega).abs() <= 1e-9 * a.omega);
    }
}
