//! Explicit ether drag scales every free velocity by one factor, `1 - k` or
//! `exp(-c h)`; the implicit form filters nothing and only contributes
//! `D = c M`.

mod common;

use common::{CASES, Rng, U, kinetic_energy, random_scene};
use pd_damping::{Damping, DampingMatrix, EtherDrag, Point};

/// Filters a copy of the scene's velocities with step `h` (s).
fn filtered(drag: &EtherDrag, scene: &common::Scene, h: f64) -> Vec<Point> {
    let mut velocities = scene.velocities.clone();
    drag.filter_velocities(&scene.context(h), &scene.positions, &mut velocities);
    velocities
}

/// Asserts `after[i] == before[i] * scale` bit for bit on free vertices, and
/// `after[i] == before[i]` on fixed ones.
fn assert_scaled(scene: &common::Scene, after: &[Point], scale: f64) {
    for (i, (&before, &after)) in scene.velocities.iter().zip(after).enumerate() {
        if scene.fixed[i] {
            assert_eq!(after, before, "fixed vertex {i} moved");
        } else {
            // One multiplication per coordinate, the same one the filter does.
            assert_eq!(after, before * scale, "vertex {i} not scaled by {scale}");
        }
    }
}

#[test]
fn factor_scales_every_free_velocity_by_one_minus_k() {
    let mut rng = Rng::new(31);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let k = rng.factor();
        let drag = EtherDrag::factor(k).unwrap();
        let h = rng.log_range(1e-5, 1.0);
        assert_eq!(drag.velocity_scale(h), 1.0 - k);
        assert_scaled(&scene, &filtered(&drag, &scene, h), 1.0 - k);
    }
}

#[test]
fn rate_scales_by_exp_minus_c_h_for_each_step() {
    let mut rng = Rng::new(32);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let c = rng.log_range(1e-3, 1e3);
        let drag = EtherDrag::rate(c).unwrap();
        for h in [rng.log_range(1e-5, 1.0), rng.log_range(1e-5, 1.0)] {
            let scale = (-c * h).exp();
            assert_eq!(drag.velocity_scale(h), scale);
            assert_scaled(&scene, &filtered(&drag, &scene, h), scale);
        }
    }
}

#[test]
fn rate_does_not_depend_on_how_the_time_is_cut() {
    let mut rng = Rng::new(33);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let c = rng.log_range(1e-3, 1e3);
        let h = rng.log_range(1e-5, 1.0);
        let drag = EtherDrag::rate(c).unwrap();
        let once = filtered(&drag, &scene, h);
        let mut twice = scene.velocities.clone();
        for _ in 0..2 {
            drag.filter_velocities(&scene.context(h / 2.0), &scene.positions, &mut twice);
        }
        for (once, twice) in once.iter().zip(&twice) {
            // exp rounds once (about 1 u, correctly rounded or nearly so) per
            // call, each multiplication once: 1 + 2 roundings against 2 + 2,
            // so within 8 u |v| with room.
            assert!((once - twice).norm() <= 8.0 * U * once.norm().max(twice.norm()));
        }
    }
}

#[test]
fn kinetic_energy_never_increases() {
    let mut rng = Rng::new(34);
    for case in 0..CASES {
        let scene = random_scene(&mut rng);
        let drag = if case % 2 == 0 {
            EtherDrag::factor(rng.factor()).unwrap()
        } else {
            EtherDrag::rate(rng.log_range(1e-3, 1e3)).unwrap()
        };
        let after = filtered(&drag, &scene, rng.log_range(1e-5, 1.0));
        let all: Vec<usize> = (0..scene.masses.len()).collect();
        // No tolerance: with 0 <= s <= 1, |fl(s v)| <= |v| coordinate by
        // coordinate (rounding is monotone and v is representable), and the
        // kinetic energy is evaluated by the same monotone sequence of
        // operations on both sides.
        assert!(
            kinetic_energy(&all, &scene.masses, &after)
                <= kinetic_energy(&all, &scene.masses, &scene.velocities)
        );
    }
}

#[test]
fn implicit_form_filters_nothing_and_gives_the_mass_matrix() {
    let mut rng = Rng::new(35);
    for _ in 0..CASES {
        let scene = random_scene(&mut rng);
        let c = rng.log_range(1e-3, 1e3);
        let drag = EtherDrag::implicit(c).unwrap();
        assert_eq!(drag.velocity_scale(0.01), 1.0);
        assert_eq!(filtered(&drag, &scene, 0.01), scene.velocities);
        assert_eq!(
            drag.implicit_matrix(),
            DampingMatrix {
                mass: c,
                damping_laplacian: 0.0,
                lagged_stiffness: 0.0,
                ..DampingMatrix::default()
            }
        );
    }
}

#[test]
fn explicit_forms_have_no_matrix() {
    assert!(EtherDrag::factor(0.5).unwrap().implicit_matrix().is_zero());
    assert!(EtherDrag::rate(2.0).unwrap().implicit_matrix().is_zero());
}

#[test]
fn fixed_vertices_keep_a_nonzero_velocity_untouched() {
    // The filter never writes a fixed vertex, even if the caller left a
    // velocity there.
    let mut rng = Rng::new(36);
    let mut scene = random_scene(&mut rng);
    scene.fixed[0] = true;
    scene.velocities[0] = Point::new(1.0, 2.0, 3.0);
    let drag = EtherDrag::factor(0.5).unwrap();
    assert_scaled(&scene, &filtered(&drag, &scene, 0.01), 0.5);
}
