//! PBD damping leaves rigid motion alone and damps only the rest, per
//! component, without touching vertices outside the components.

mod common;

use common::{CASES, Reference, Rng, SHAPES, Scene, Shape, U, random_scene, random_scene_of};
use pd_damping::{Damping, PbdDamping, Point};

fn filter(scene: &Scene, k: f64, velocities: &mut [Point]) {
    PbdDamping::new(k).unwrap().filter_velocities(
        &scene.context(0.01),
        &scene.positions,
        velocities,
    );
}

#[test]
fn rigid_velocity_field_is_unchanged() {
    let mut rng = Rng::new(21);
    for case in 0..CASES {
        let mut scene = random_scene(&mut rng);
        // Replace each component's velocities by a rigid field a + b x x.
        let mut fields = Vec::new();
        for component in &scene.components {
            let speed = rng.log_range(1e-3, 1e3);
            // A spin of about `speed` at the far end of the body (a lone
            // vertex has no far end).
            let extent = component
                .iter()
                .map(|&i| (scene.positions[i] - scene.positions[component[0]]).norm())
                .fold(0.0, f64::max);
            let a = rng.vector(10.0 * speed);
            let b = rng.vector(if extent > 0.0 { speed / extent } else { speed });
            for &i in component {
                scene.velocities[i] = a + b.cross(&scene.positions[i]);
            }
            fields.push(b);
        }
        // k = 1 every other case: the field must already be its own rigid fit.
        let k = if case % 2 == 0 { 1.0 } else { rng.factor() };
        let mut filtered = scene.velocities.clone();
        filter(&scene, k, &mut filtered);
        for (component, b) in scene.components.iter().zip(&fields) {
            let reference = Reference::of(component, &scene);
            let n = component.len() as f64;
            let mass: f64 = component.iter().map(|&i| scene.masses[i]).sum();
            let centre = reference.centre.norm();
            let v_cm = reference.linear_velocity.norm();
            // Exactly, v_cm + I^+ J x r_i = v_i for a rigid field (J = I b,
            // and the part of b that I^+ drops is along a chain's line, where
            // b x r_i = 0). In floating point the rigid fit w_i errs by:
            // - v_cm: (n + 2) u sum m_j |v_j| / M;
            // - omega: J rounds by (n + 4) u sum m_j |r_j| (|v_j| + |v_cm|)
            //   (v_j - v_cm rounds relative to its operands), which I^+
            //   amplifies by 1 / lambda_min, and the eigensolver adds
            //   u kappa |b|; times |r_i|;
            // - r_i: x_i - c with c known to (n + 2) u (max |x_j| + |c|),
            //   times |b|; a chain is straight only to that, which also
            //   bounds the dropped spin about its line.
            let momentum_scale: f64 = component
                .iter()
                .map(|&j| scene.masses[j] * scene.velocities[j].norm())
                .sum();
            let spin_scale: f64 = component
                .iter()
                .map(|&j| {
                    let r = (scene.positions[j] - reference.centre).norm();
                    scene.masses[j] * r * (scene.velocities[j].norm() + v_cm + b.norm() * r)
                })
                .sum();
            let omega_error = if reference.smallest_inertia > 0.0 {
                (n + 4.0) * spin_scale / reference.smallest_inertia + reference.condition * b.norm()
            } else {
                0.0
            };
            let reach = component
                .iter()
                .map(|&j| scene.positions[j].norm())
                .fold(0.0, f64::max);
            for &i in component {
                let r = (scene.positions[i] - reference.centre).norm();
                let tolerance = 4.0
                    * U
                    * ((n + 4.0) * momentum_scale / mass
                        + scene.velocities[i].norm()
                        + omega_error * r
                        + (n + 4.0) * b.norm() * (reach + centre));
                let error = (filtered[i] - scene.velocities[i]).norm();
                assert!(
                    error <= tolerance,
                    "k = {k}, {n} vertices: rigid velocity moved by {error:e} > {tolerance:e}"
                );
            }
        }
    }
}

#[test]
fn a_pair_keeps_its_spin_and_loses_its_stretching() {
    // Unit masses at -e_x and +e_x. Relative velocity (2, 4, -6): its x part
    // stretches the pair and is damped by (1 - k); y and z are rigid spin.
    let positions = [Point::new(-1.0, 0.0, 0.0), Point::new(1.0, 0.0, 0.0)];
    let velocities = [Point::new(-1.0, -2.0, 3.0), Point::new(1.0, 2.0, -3.0)];
    let scene = Scene {
        masses: vec![1.0, 1.0],
        positions: positions.to_vec(),
        velocities: velocities.to_vec(),
        components: vec![vec![0, 1]],
        fixed: vec![false, false],
    };
    for k in [0.0, 0.25, 0.5, 1.0] {
        let mut filtered = scene.velocities.clone();
        filter(&scene, k, &mut filtered);
        let expected = [
            Point::new(-(1.0 - k), -2.0, 3.0),
            Point::new(1.0 - k, 2.0, -3.0),
        ];
        for (got, want) in filtered.iter().zip(&expected) {
            // Values of size at most 4: a few roundings of the eigensolver
            // and the update, 16 u each.
            assert!(
                (got - want).norm() <= 16.0 * U * 4.0,
                "k = {k}: {got:?} != {want:?}"
            );
        }
    }
}

#[test]
fn a_single_vertex_keeps_its_velocity() {
    let mut rng = Rng::new(22);
    for _ in 0..CASES {
        let scene = random_scene_of(&mut rng, &[Shape::Single]);
        let mut filtered = scene.velocities.clone();
        filter(&scene, rng.factor(), &mut filtered);
        let i = scene.components[0][0];
        // A lone vertex is its own rigid motion. v_cm = (m v) / m rounds twice;
        // the centre rounds to u |x|, which gives a spurious omega with
        // omega x r of order u |v|; the update rounds twice: 16 u |v| covers
        // them.
        let error = (filtered[i] - scene.velocities[i]).norm();
        assert!(
            error <= 16.0 * U * scene.velocities[i].norm(),
            "moved by {error:e}"
        );
    }
}

#[test]
fn vertices_outside_the_components_are_untouched() {
    let mut rng = Rng::new(23);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let mut filtered = scene.velocities.clone();
        filter(&scene, rng.factor(), &mut filtered);
        for i in scene.outside_components() {
            assert_eq!(
                filtered[i], scene.velocities[i],
                "vertex {i} outside the components moved"
            );
        }
        for (i, &fixed) in scene.fixed.iter().enumerate() {
            if fixed {
                assert_eq!(filtered[i], Point::zeros(), "fixed vertex {i} moved");
            }
        }
    }
}

#[test]
fn components_are_damped_independently() {
    let mut rng = Rng::new(24);
    for _ in 0..CASES {
        let shapes: Vec<Shape> = (0..2 + rng.below(3))
            .map(|_| SHAPES[rng.below(SHAPES.len())])
            .collect();
        let scene = random_scene_of(&mut rng, &shapes);
        let k = rng.factor();
        let mut together = scene.velocities.clone();
        filter(&scene, k, &mut together);
        // One component at a time, in reverse order: the same numbers,
        // bit for bit, since each fit reads only its own vertices.
        let mut one_by_one = scene.velocities.clone();
        for component in scene.components.iter().rev() {
            let alone = Scene {
                components: vec![component.clone()],
                ..scene.clone()
            };
            filter(&alone, k, &mut one_by_one);
        }
        assert_eq!(together, one_by_one);
    }
}

#[test]
fn factor_zero_changes_nothing() {
    let mut rng = Rng::new(25);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let mut filtered = scene.velocities.clone();
        filter(&scene, 0.0, &mut filtered);
        assert_eq!(filtered, scene.velocities);
    }
}
