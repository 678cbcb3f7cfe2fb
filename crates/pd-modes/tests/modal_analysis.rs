//! Modal analysis (`pd_modes`) against analytic frequencies: a
//! fixed-fixed spring chain (exact discrete frequencies) and a clamped tet
//! beam (Euler-Bernoulli, approached from above with refinement).

mod common;

use std::f64::consts::PI;

use pd_mesh::{Mesh, Point, generators};
use pd_modes::ModalAnalysis;
use pd_solver::Model;

/// Free vertices of the chain.
const N: usize = 10;
/// Spring stiffness (N/m) and vertex mass (kg): `sqrt(k/m) = 100` rad/s.
const K: f64 = 100.0;
const M: f64 = 0.01;

fn chain() -> Model {
    let mesh = generators::chain(N + 2, 0.1 * (N + 1) as f64).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, vec![M; N + 2]).unwrap();
    model.add_springs(body, K).unwrap();
    model.fix_vertices(body, &[0, N + 1]).unwrap();
    model
}

#[test]
fn spring_chain_frequencies_are_exact() {
    let analysis = pd_modes::elastic_modes(&chain(), N).unwrap();
    // At rest a spring has no transverse stiffness: the 2N sideways motions
    // are mechanisms, skipped; the chain is held at both ends (no rigid mode).
    assert_eq!(analysis.method, "dense");
    assert_eq!(analysis.rigid_modes, 0);
    assert_eq!(analysis.mechanisms, 2 * N);
    assert_eq!(analysis.modes.len(), N);
    // Round-off: the dense symmetric eigensolver is backward stable, so each
    // eigenvalue of M^-1/2 K M^-1/2 errs by at most c n u |A| with |A| <=
    // 4 k/m (Gershgorin) and n = 3N; c = 16 covers the constants of the
    // tridiagonal reduction and QR. omega = sqrt(lambda) halves the relative
    // error: |d omega| / omega <= 8 n u |A| / lambda.
    let norm = 4.0 * K / M;
    for (j, mode) in analysis.modes.iter().enumerate() {
        let j = j + 1;
        let exact = 2.0 * (K / M).sqrt() * (j as f64 * PI / (2.0 * (N + 1) as f64)).sin();
        let tolerance = 8.0 * (3 * N) as f64 * f64::EPSILON * norm / exact.powi(2);
        let error = (mode.omega - exact).abs() / exact;
        assert!(
            error <= tolerance,
            "mode {j}: {} vs {exact}: {error:e} > {tolerance:e}",
            mode.omega
        );
        // Mass-normalised and axial; on the chain L_d = K, so the quotient
        // is omega^2.
        let norm: f64 = mode.shape.iter().map(|p| M * p.norm_squared()).sum();
        assert!((norm - 1.0).abs() < 1e-12, "mode {j}: |phi|_M^2 = {norm}");
        assert!(
            mode.shape
                .iter()
                .all(|p| p.y == 0.0 && p.z == 0.0 || p.x.abs() >= 0.0)
        );
        let q = mode.laplacian_quotient;
        assert!(
            (q - exact * exact).abs() <= tolerance * 2.0 * exact * exact,
            "mode {j}: {q}"
        );
    }
}

/// The bending frequencies, lowest first. A bending mode moves across the
/// axis (more than 75% of the mass-weighted motion in y and z) and moves the
/// beam's centre line: its effective modal mass fraction
/// `|sum m phi_t|^2 / (sum m sum m |phi_t|^2)` is 61%, 19% and 6.5% for the
/// first three cantilever modes, while torsion's is zero by the section's
/// symmetry (the 1% threshold separates them). The Kuhn split makes the two
/// diagonal bending directions slightly unequal, so each bending frequency
/// comes as a close pair (y + z, y - z); the lower member of each pair is
/// kept.
fn bending(analysis: &ModalAnalysis, model: &Model) -> Vec<f64> {
    let masses = model.masses();
    let total: f64 = masses.iter().sum();
    let across: Vec<f64> = analysis
        .modes
        .iter()
        .filter(|mode| {
            let along = |axis: usize| -> f64 {
                mode.shape
                    .iter()
                    .zip(masses)
                    .map(|(p, m)| m * p[axis] * p[axis])
                    .sum()
            };
            let transverse = along(1) + along(2);
            let mean = |axis: usize| -> f64 {
                mode.shape
                    .iter()
                    .zip(masses)
                    .map(|(p, m)| m * p[axis])
                    .sum()
            };
            let fraction = (mean(1).powi(2) + mean(2).powi(2)) / (total * transverse);
            transverse > 0.75 * (transverse + along(0)) && fraction > 0.01
        })
        .map(|mode| mode.omega)
        .collect();
    across.iter().step_by(2).copied().collect()
}

#[test]
fn clamped_beam_bending_converges_to_euler_bernoulli_from_above() {
    let (size, b) = ([1.0, 0.1, 0.1], 0.1);
    let reference = common::DENSITY;
    let ei = common::YOUNGS_MODULUS * b * b * b * b / 12.0;
    let base = (ei / (reference * b * b)).sqrt();
    let euler_bernoulli: Vec<f64> = [1.875104, 4.694091, 7.854757]
        .iter()
        .map(|beta: &f64| beta * beta * base)
        .collect();
    // FEM omega_1 of the same meshes by inverse iteration (docs/design/validation.md
    // 4b), residual bound 3e-10 rad/s: this analysis must agree to that plus
    // its own convergence tolerance (1e-9 relative in subspace iteration).
    let independent = [5.798936, 4.033651, 3.424420];
    let mut previous: Option<Vec<f64>> = None;
    for (n, expected) in [1, 2, 4].into_iter().zip(independent) {
        let model = common::beam(size, [10 * n, n, n]);
        let analysis = pd_modes::elastic_modes(&model, 12).unwrap();
        let bending = bending(&analysis, &model);
        println!(
            "n = {n}: {} dofs, {} ({} iterations, factor {:.3} s, total {:.3} s): bending y {:?}, / EB {:?}",
            analysis.dofs,
            analysis.method,
            analysis.iterations,
            analysis.factor_seconds,
            analysis.seconds,
            bending,
            bending
                .iter()
                .zip(&euler_bernoulli)
                .map(|(a, e)| a / e)
                .collect::<Vec<_>>()
        );
        assert_eq!(analysis.rigid_modes + analysis.mechanisms, 0);
        assert!(bending.len() >= 3, "n = {n}: {bending:?}");
        // The table's values carry 7 significant digits.
        assert!(
            (bending[0] - expected).abs() <= 1e-6 * expected + 1e-6,
            "n = {n}: {}",
            bending[0]
        );
        // From above: the discrete frequencies decrease with refinement
        // (Rayleigh-Ritz on nested Kuhn meshes, docs/design/validation.md 4b) towards
        // the 3D continuum, which lies below Euler-Bernoulli by shear and
        // rotary inertia (Timoshenko): the pinned-beam estimate
        // `(1 + (beta r)^2 (1 + E/(kappa G)))^-1/2`, `r^2 = b^2/12`,
        // `kappa = 5/6`, `E/G = 2`, is -0.5%, -3.0% and -7.7% for modes 1-3.
        // Every discrete frequency must stay above that continuum estimate
        // (and mode 1 above Euler-Bernoulli itself, as 4b found).
        assert!(bending[0] > euler_bernoulli[0]);
        for j in 0..3 {
            let beta: f64 = [1.875104, 4.694091, 7.854757][j];
            let timoshenko = (1.0 + beta * beta * b * b / 12.0 * (1.0 + 2.0 / (5.0 / 6.0))).sqrt();
            assert!(
                bending[j] > euler_bernoulli[j] / timoshenko,
                "n = {n}, mode {}",
                j + 1
            );
        }
        if let Some(coarse) = &previous {
            for j in 0..3 {
                assert!(
                    bending[j] < coarse[j],
                    "n = {n}, mode {}: not decreasing",
                    j + 1
                );
            }
        }
        previous = Some(bending);
    }
}

/// Free-free chain: the same chain without fixed ends has
/// `omega_j = 2 sqrt(k/m) sin(j pi / (2 N))`, `j = 1..N-1` (the lumped
/// free-free rod). Its rigid motions (3 translations, 2 rotations: a turn
/// about its own axis moves nothing) are deflated, and the 2N sideways
/// motions less the 4 rigid ones among them are mechanisms.
#[test]
fn free_chain_skips_its_rigid_motions() {
    let n = 12;
    let mesh = generators::chain(n, 1.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, vec![M; n]).unwrap();
    model.add_springs(body, K).unwrap();
    let analysis = pd_modes::elastic_modes(&model, n - 1).unwrap();
    assert_eq!(analysis.rigid_modes, 5);
    assert_eq!(analysis.mechanisms, 2 * n - 4);
    assert_eq!(analysis.modes.len(), n - 1);
    // Round-off as in the fixed chain (|A| <= 4 k/m, 3n dofs).
    for (j, mode) in analysis.modes.iter().enumerate() {
        let j = j + 1;
        let exact = 2.0 * (K / M).sqrt() * (j as f64 * PI / (2.0 * n as f64)).sin();
        let tolerance = 8.0 * (3 * n) as f64 * f64::EPSILON * (4.0 * K / M) / exact.powi(2);
        assert!(
            (mode.omega - exact).abs() <= tolerance * exact,
            "mode {j}: {}",
            mode.omega
        );
    }
}

/// The two eigensolvers agree, on a clamped beam and on a free tet body
/// (six rigid motions deflated in the subspace iteration, found as zero
/// modes by the dense solver): to the subspace iteration's convergence
/// tolerance (residual <= 1e-9 lambda, so omega within 5e-10 relative, plus
/// the dense solver's round-off, 1e-12 here).
#[test]
fn dense_and_subspace_iteration_agree() {
    let clamped = common::beam([1.0, 0.1, 0.1], [20, 2, 2]);
    let mesh = generators::box_tets([0.3, 0.2, 0.1], [3, 2, 1]).unwrap();
    let mut free = Model::new();
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let body = free.add_body(mesh, masses).unwrap();
    free.add_tet_strain(body, 1.0e5, None).unwrap();
    for (name, model, rigid) in [("clamped", clamped, 0), ("free", free, 6)] {
        let dense = pd_modes::elastic_modes_by(&model, 8, pd_modes::Method::Dense).unwrap();
        let subspace = pd_modes::elastic_modes_by(&model, 8, pd_modes::Method::Subspace).unwrap();
        assert_eq!(dense.rigid_modes, rigid, "{name}");
        assert_eq!(subspace.rigid_modes, rigid, "{name}");
        assert_eq!(dense.mechanisms + subspace.mechanisms, 0, "{name}");
        assert_eq!(subspace.modes.len(), 8, "{name}");
        for (a, b) in dense.modes.iter().zip(&subspace.modes) {
            assert!(
                (a.omega - b.omega).abs() <= 1e-9 * a.omega,
                "{name}: {} vs {}",
                a.omega,
                b.omega
            );
        }
    }
}

/// `Auto` takes the dense solver for a request of a quarter or more of a
/// mid-sized model's dofs, and block Lanczos for a few modes of it.
#[test]
fn auto_solves_many_modes_of_a_mid_sized_model_densely() {
    // 40 x 2 x 2 cells, one end clamped: 360 free vertices, 1,080 dofs.
    let model = common::beam([1.0, 0.1, 0.1], [40, 2, 2]);
    let few = pd_modes::elastic_modes(&model, 4).unwrap();
    assert!(few.dofs > pd_modes::DENSE_LIMIT, "{}", few.dofs);
    assert_eq!(few.method, "shift-invert block Lanczos");
    let many = pd_modes::elastic_modes(&model, few.dofs.div_ceil(4)).unwrap();
    assert_eq!(many.method, "dense");
    // The same lowest modes either way (Lanczos converged to 1e-9 relative,
    // the threshold of `dense_and_subspace_iteration_agree`).
    for (a, b) in few.modes.iter().zip(&many.modes) {
        assert!(
            (a.omega - b.omega).abs() <= 1e-9 * a.omega,
            "{} vs {}",
            a.omega,
            b.omega
        );
    }
}

#[test]
fn a_free_vertex_without_mass_is_named_by_body_and_local_index() {
    let mut model = Model::new();
    let first = model
        .add_body(generators::chain(4, 0.3).unwrap(), vec![M; 4])
        .unwrap();
    model.add_springs(first, K).unwrap();
    // The second body's vertex 3 is touched by no edge, so it has no mass.
    let vertices = (0..4).map(|i| Point::new(i as f64, 1.0, 0.0)).collect();
    let mesh = Mesh::from_edges(vertices, vec![[0, 1], [1, 2]]).unwrap();
    let second = model.add_body(mesh, vec![M, M, M, 0.0]).unwrap();
    model.add_springs(second, K).unwrap();
    let expected = "body 1 vertex 3 (vertex 7 of the model) is free but has mass 0";
    let message = pd_modes::elastic_modes(&model, 2).unwrap_err().to_string();
    assert!(message.contains(expected), "{message}");
    // A simulation of the same model says the same.
    let message = pd_solver::Simulation::new(
        model,
        Box::new(pd_integrators::BackwardEuler),
        Box::new(pd_damping::NoDamping),
        pd_solver::Settings::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(message.contains(expected), "{message}");
}
