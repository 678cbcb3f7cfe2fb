//! PBD damping sets each component's kinetic energy to
//! `KE_rigid + (1 - k)^2 KE_deform`, so it never increases it.
//!
//! Why: split `v_i = w_i + d_i` into the rigid field `w_i = v_cm + omega x r_i`
//! and the remainder `d_i`. The filter gives `v'_i = w_i + (1 - k) d_i`, so
//! `KE' = KE_rigid + (1 - k) sum_i m_i w_i . d_i + (1 - k)^2 KE_deform`, and
//! the cross term vanishes:
//! `sum_i m_i w_i . d_i = v_cm . sum_i m_i d_i + omega . sum_i r_i x m_i d_i`.
//! The first sum is `M v_cm - M v_cm - omega x sum_i m_i r_i = 0`; the second
//! is `J - sum_i m_i r_i x (omega x r_i) = J - I omega`, and
//! `omega . (J - I omega) = J^T I^+ J - J^T I^+ I I^+ J = 0` because
//! `I^+ I I^+ = I^+`: it holds for the pseudo-inverse too, so for chains and
//! single vertices as well. With `0 <= k <= 1`, `(1 - k)^2 <= 1` and
//! `KE' <= KE_rigid + KE_deform = KE`.

mod common;

use common::{CASES, Reference, Rng, Scene, U, kinetic_energy, random_scene};
use pd_damping::{Damping, PbdDamping, Point};

/// Kinetic energies of one component before and after the filter, its rigid
/// and deformation parts (with the independent reference fit), and a
/// round-off tolerance for comparing them.
struct Energies {
    before: f64,
    after: f64,
    rigid: f64,
    deform: f64,
    tolerance: f64,
}

fn energies(scene: &Scene, component: &[usize], filtered: &[Point]) -> Energies {
    let reference = Reference::of(component, scene);
    let mut rigid = 0.0;
    let mut deform = 0.0;
    let mut scale = 0.0;
    let omega = reference.angular_velocity.norm();
    let centre = reference.centre.norm();
    for &i in component {
        let m = scene.masses[i];
        let w = reference.rigid_velocity(&scene.positions[i]);
        rigid += 0.5 * m * w.norm_squared();
        deform += 0.5 * m * (scene.velocities[i] - w).norm_squared();
        let lever_arm = scene.positions[i].norm() + centre;
        scale += 0.5
            * m
            * (scene.velocities[i].norm() + reference.linear_velocity.norm() + omega * lever_arm)
                .powi(2);
    }
    // Each energy is a sum of n terms of a few roundings each, all bounded by
    // `scale`: (n + 4) u scale. The lever arm is |x_i| + |x_cm|, not |r_i|:
    // the centre is only known to u |x_cm| (n + 2), which shifts every rigid
    // velocity by omega x delta_c and the energy by about
    // M |v_cm| |omega| |delta_c|, the cross term of `scale`. The two fits (SVD
    // here, eigendecomposition in the filter) agree to u kappa |omega|,
    // which moves KE' by about k |delta omega| |J| (first-order change of the
    // energy in omega) and leaves the reference's cross term
    // omega . (J - I omega) at u kappa lambda_max |omega|^2 instead of 0.
    let n = component.len() as f64;
    let kappa = reference.condition;
    let tolerance = 4.0
        * U
        * ((n + 4.0) * scale
            + kappa
                * omega
                * (reference.angular_momentum.norm() + reference.largest_inertia * omega));
    Energies {
        before: kinetic_energy(component, &scene.masses, &scene.velocities),
        after: kinetic_energy(component, &scene.masses, filtered),
        rigid,
        deform,
        tolerance,
    }
}

fn filtered(scene: &Scene, k: f64) -> Vec<Point> {
    let mut velocities = scene.velocities.clone();
    PbdDamping::new(k).unwrap().filter_velocities(
        &scene.context(0.01),
        &scene.positions,
        &mut velocities,
    );
    velocities
}

#[test]
fn kinetic_energy_becomes_rigid_plus_damped_deformation() {
    let mut rng = Rng::new(11);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let k = rng.factor();
        let after = filtered(&scene, k);
        for component in &scene.components {
            let e = energies(&scene, component, &after);
            let expected = e.rigid + (1.0 - k).powi(2) * e.deform;
            let error = (e.after - expected).abs();
            assert!(
                error <= e.tolerance,
                "k = {k}: KE' = {:e}, KE_rigid + (1 - k)^2 KE_deform = {expected:e}, error {error:e} > {:e}",
                e.after,
                e.tolerance
            );
            // The split itself must be exact up to round-off (no cross term in
            // the original energy either).
            let split_error = (e.before - e.rigid - e.deform).abs();
            assert!(
                split_error <= e.tolerance,
                "KE != KE_rigid + KE_deform by {split_error:e}"
            );
        }
    }
}

#[test]
fn kinetic_energy_never_increases() {
    let mut rng = Rng::new(12);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let k = rng.factor();
        let after = filtered(&scene, k);
        for component in &scene.components {
            let e = energies(&scene, component, &after);
            assert!(
                e.after <= e.before + e.tolerance,
                "k = {k}: kinetic energy rose from {:e} to {:e}",
                e.before,
                e.after
            );
        }
    }
}

#[test]
fn full_damping_leaves_only_the_rigid_energy() {
    let mut rng = Rng::new(13);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let after = filtered(&scene, 1.0);
        for component in &scene.components {
            let e = energies(&scene, component, &after);
            let error = (e.after - e.rigid).abs();
            assert!(
                error <= e.tolerance,
                "k = 1: KE' - KE_rigid = {error:e} > {:e}",
                e.tolerance
            );
        }
    }
}
