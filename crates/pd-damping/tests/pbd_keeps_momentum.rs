//! PBD damping keeps each component's linear momentum and its angular
//! momentum about the origin and about the centre of mass, for clouds,
//! chains (singular inertia), pairs and single vertices.

mod common;

use common::{CASES, Reference, Rng, U, angular_momentum, linear_momentum, random_scene};
use pd_damping::{Damping, PbdDamping, Point};

/// Runs `check(scene, component, reference, filtered velocities, k)` on every
/// component of `CASES` random scenes.
fn for_each_filtered_component(
    seed: u64,
    mut check: impl FnMut(&common::Scene, &[usize], &Reference, &[Point], f64),
) {
    let mut rng = Rng::new(seed);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let k = rng.factor();
        let mut filtered = scene.velocities.clone();
        PbdDamping::new(k).unwrap().filter_velocities(
            &scene.context(0.01),
            &scene.positions,
            &mut filtered,
        );
        for component in &scene.components {
            let reference = Reference::of(component, &scene);
            check(&scene, component, &reference, &filtered, k);
        }
    }
}

/// The scale of an angular momentum's rounding, with lever arms `a_i`:
/// `sum_i m_i [a_i (|v_i| + |v'_i| + |v_cm| + |omega| a_i) + (|x_i| + |x_cm|) |v_i - v_cm|]`.
/// The last term is the spin about the line of a chain: its vertices are
/// collinear only to the rounding of their coordinates, u (|x_i| + |x_cm|),
/// the pseudo-inverse drops the spin about the line, and with it a component
/// of `J` of at most `u sum_i m_i (|x_i| + |x_cm|) |v_i - v_cm|`.
fn angular_scale(
    scene: &common::Scene,
    component: &[usize],
    reference: &Reference,
    filtered: &[Point],
    lever_arm: impl Fn(usize) -> f64,
) -> f64 {
    let omega = reference.angular_velocity.norm();
    let centre = reference.centre.norm();
    let linear_velocity = reference.linear_velocity;
    component
        .iter()
        .map(|&i| {
            let arm = lever_arm(i);
            let velocity = scene.velocities[i];
            scene.masses[i]
                * (arm
                    * (velocity.norm() + filtered[i].norm() + linear_velocity.norm() + omega * arm)
                    + (scene.positions[i].norm() + centre) * (velocity - linear_velocity).norm())
        })
        .sum()
}

#[test]
fn linear_momentum_is_kept() {
    for_each_filtered_component(1, |scene, component, reference, filtered, _| {
        let before = linear_momentum(component, &scene.masses, &scene.velocities);
        let after = linear_momentum(component, &scene.masses, filtered);
        // Exactly, sum m_i dv_i = k (M v_cm + omega x sum m_i r_i - M v_cm) = 0.
        // In floating point: each of the two sums here and in the fit errs by
        // at most (n + 1) u sum m_i |v_i| (Higham's gamma_n bound); the
        // update rounds each dv_i by a few u (|v_i| + |v'_i|); and
        // sum m_i r_i vanishes only to (n + 2) u sum m_i (|x_i| + |x_cm|),
        // which omega x multiplies. Four roundings per term cover all of it.
        let n = component.len() as f64;
        let omega = reference.angular_velocity.norm();
        let scale: f64 = component
            .iter()
            .map(|&i| {
                scene.masses[i]
                    * (scene.velocities[i].norm()
                        + filtered[i].norm()
                        + omega * (scene.positions[i].norm() + reference.centre.norm()))
            })
            .sum();
        let tolerance = 4.0 * (n + 4.0) * U * scale;
        let error = (after - before).norm();
        assert!(
            error <= tolerance,
            "linear momentum changed by {error:e} > {tolerance:e}"
        );
    });
}

#[test]
fn angular_momentum_about_the_centre_of_mass_is_kept() {
    for_each_filtered_component(2, |scene, component, reference, filtered, _| {
        let centre = reference.centre;
        let before = angular_momentum(
            component,
            &scene.masses,
            &scene.positions,
            &scene.velocities,
            &centre,
        );
        let after = angular_momentum(
            component,
            &scene.masses,
            &scene.positions,
            filtered,
            &centre,
        );
        // Exactly, sum r_i x m_i dv_i = k (I omega - J) = 0 since J lies in the
        // range of I (see `pd_damping::rigid`). In floating point: the sums
        // and cross products here and in the fit err by (n + 4) u times the
        // sum of m_i |r_i| |v_i|-like terms (x_i - c itself rounds relative
        // to |r_i|; the error of the centre c is common to all vertices and
        // multiplies sum m_i dv_i = 0); the eigensolver is backward stable,
        // I omega - J = O(u lambda_max |omega|), and
        // lambda_max <= trace I = 2 sum m_i |r_i|^2 is inside the same scale;
        // chains lose their rounding-level spin (see `angular_scale`).
        let n = component.len() as f64;
        let lever_arm = |i: usize| (scene.positions[i] - reference.centre).norm();
        let tolerance =
            4.0 * (n + 4.0) * U * angular_scale(scene, component, reference, filtered, lever_arm);
        let error = (after - before).norm();
        assert!(
            error <= tolerance,
            "angular momentum about the centre changed by {error:e} > {tolerance:e}"
        );
    });
}

#[test]
fn angular_momentum_about_the_origin_is_kept() {
    for_each_filtered_component(3, |scene, component, reference, filtered, _| {
        let origin = Point::zeros();
        let before = angular_momentum(
            component,
            &scene.masses,
            &scene.positions,
            &scene.velocities,
            &origin,
        );
        let after = angular_momentum(
            component,
            &scene.masses,
            &scene.positions,
            filtered,
            &origin,
        );
        // L_0 = x_cm x P + J: both kept, so L_0 is. The rounding is that of
        // the previous two tests, the linear one times |x_cm|, so the lever
        // arm is |x_i| + |x_cm|.
        let n = component.len() as f64;
        let lever_arm = |i: usize| scene.positions[i].norm() + reference.centre.norm();
        let tolerance =
            4.0 * (n + 4.0) * U * angular_scale(scene, component, reference, filtered, lever_arm);
        let error = (after - before).norm();
        assert!(
            error <= tolerance,
            "angular momentum about the origin changed by {error:e} > {tolerance:e}"
        );
    });
}
