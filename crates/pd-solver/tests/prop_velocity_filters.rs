//! The velocity filters of explicit ether drag and PBD damping never
//! increase the kinetic energy, and PBD damping keeps each component's
//! linear and angular momentum, over random point sets (3-D clouds, exactly
//! collinear sets with a singular inertia, single vertices), masses,
//! velocities, fixed vertices and factors.
//!
//! - Ether drag multiplies every velocity by `s = 1 - k` or `exp(-c h)`,
//!   `0 <= s <= 1`. Rounding is monotone, so `|fl(s v)| <= |v|` coordinate
//!   by coordinate, and the kinetic energy, a sum of the same monotone
//!   operations in the same order, cannot grow even by round-off: the check
//!   has no tolerance.
//! - PBD sets `v' = (1 - k) v + k P v` with `P v` the rigid field with the
//!   component's linear and angular momentum, which is the `M`-orthogonal
//!   projection of `v` onto rigid fields (a pseudo-inverse of the inertia for
//!   a line). So `|v'|_M^2 = |P v|_M^2 + (1 - k)^2 |v - P v|_M^2 <= |v|_M^2`
//!   for `0 <= k <= 1`, and `P v` has the momenta of `v`. Round-off: the
//!   fit's sums round by `n u` of their absolute sums, `omega = I^+ J` by
//!   `kappa u` relatively (`kappa` the condition number of the inertia's
//!   non-zero part), and the lever `x - x_cm` by `u |x|`, which `omega`
//!   turns into a velocity error `u |omega| |x|` (large for a light vertex
//!   spinning close to a heavy one); a factor 16 covers the constants.

mod common;
mod prop_common;

use common::U;
use nalgebra::SymmetricEigen;
use pd_damping::rigid::RigidFit;
use pd_damping::{Damping, DampingContext, EtherDrag, PbdDamping};
use pd_mesh::Point;
use prop_common::{config, points};
use proptest::prelude::*;

/// A random set of components, some vertices fixed.
#[derive(Debug, Clone)]
struct Layout {
    positions: Vec<Point>,
    velocities: Vec<Point>,
    masses: Vec<f64>,
    fixed: Vec<bool>,
    components: Vec<Vec<usize>>,
}

/// How a component's points lie.
#[derive(Debug, Clone, Copy)]
enum Spread {
    Cloud,
    Line,
    Single,
}

fn layout() -> impl Strategy<Value = Layout> {
    let spread = prop_oneof![
        Just(Spread::Cloud),
        Just(Spread::Line),
        Just(Spread::Single)
    ];
    let component = (
        spread,
        2usize..=9,
        points(9, 2.0),
        points(9, 5.0),
        points(1, 10.0),
    );
    (
        proptest::collection::vec(component, 1..=3),
        proptest::collection::vec(1e-3..10.0f64, 30),
        proptest::collection::vec(proptest::bool::weighted(0.15), 30),
    )
        .prop_map(|(parts, masses, fixed_flags)| {
            let mut layout = Layout {
                positions: Vec::new(),
                velocities: Vec::new(),
                masses: Vec::new(),
                fixed: Vec::new(),
                components: Vec::new(),
            };
            for (spread, count, shape, velocities, offset) in parts {
                let count = if matches!(spread, Spread::Single) {
                    1
                } else {
                    count
                };
                let mut component = Vec::new();
                for k in 0..count {
                    let v = layout.positions.len();
                    let local = match spread {
                        // Exactly on the x axis: the inertia has an exact
                        // zero eigenvalue along it.
                        Spread::Line => Point::new(shape[k].x, 0.0, 0.0),
                        _ => shape[k],
                    };
                    let offset = match spread {
                        Spread::Line => Point::zeros(),
                        _ => offset[0],
                    };
                    layout.positions.push(local + offset);
                    layout.velocities.push(velocities[k]);
                    layout.masses.push(masses[v]);
                    layout.fixed.push(fixed_flags[v]);
                    if !fixed_flags[v] {
                        component.push(v);
                    }
                }
                if !component.is_empty() {
                    layout.components.push(component);
                }
            }
            layout
        })
}

fn kinetic(masses: &[f64], velocities: &[Point]) -> f64 {
    0.5 * masses
        .iter()
        .zip(velocities)
        .map(|(m, v)| m * v.norm_squared())
        .sum::<f64>()
}

/// Applies `damping`'s filter to the layout; returns the new velocities.
fn filtered(damping: &dyn Damping, layout: &Layout, h: f64) -> Vec<Point> {
    // One body holding every vertex.
    let body = 0..layout.positions.len();
    let context = DampingContext {
        h,
        masses: &layout.masses,
        bodies: std::slice::from_ref(&body),
        components: &layout.components,
        fixed: &layout.fixed,
    };
    let mut velocities = layout.velocities.clone();
    damping.filter_velocities(&context, &layout.positions, &mut velocities);
    velocities
}

/// Condition number of the inertia's non-zero part (eigenvalues above the
/// pseudo-inverse's cutoff), 1 for a single vertex.
fn inertia_condition(fit: &RigidFit) -> f64 {
    let eigen = SymmetricEigen::new(fit.inertia);
    let largest = eigen.eigenvalues.max();
    if !(largest > 0.0) {
        return 1.0;
    }
    let cutoff = pd_damping::rigid::INERTIA_RELATIVE_CUTOFF * largest;
    let smallest = eigen
        .eigenvalues
        .iter()
        .copied()
        .filter(|&e| e > cutoff)
        .fold(f64::INFINITY, f64::min);
    largest / smallest
}

proptest! {
    #![proptest_config(config(256))]

    #[test]
    fn ether_drag_never_increases_kinetic_energy(
        layout in layout(),
        factor in 0.0..=1.0f64,
        rate in 0.0..1e3f64,
        h in 1e-5..0.1f64,
    ) {
        let before = kinetic(&layout.masses, &layout.velocities);
        for drag in [EtherDrag::factor(factor).unwrap(), EtherDrag::rate(rate).unwrap()] {
            let after = kinetic(&layout.masses, &filtered(&drag, &layout, h));
            prop_assert!(after <= before, "{drag:?}: {before:e} -> {after:e} J");
        }
    }

    #[test]
    fn pbd_damping_never_increases_kinetic_energy_and_keeps_momenta(
        layout in layout(),
        factor in 0.0..=1.0f64,
    ) {
        let pbd = PbdDamping::new(factor).unwrap();
        let after = filtered(&pbd, &layout, 0.01);
        let (masses, x) = (&layout.masses, &layout.positions);
        let mut energy_tolerance = 0.0;
        for component in &layout.components {
            let before = RigidFit::of(component, masses, x, &layout.velocities);
            let now = RigidFit::of(component, masses, x, &after);
            let n = component.len() as f64;
            let kappa = inertia_condition(&before);
            // Velocity scale of each vertex: its own velocity and the rigid
            // field's, which rounds by u times |omega| |x| since `x - x_cm`
            // is a difference of absolute positions.
            let omega = before.angular_velocity().norm();
            let speed = |i: usize| {
                layout.velocities[i].norm()
                    + before.linear_velocity.norm()
                    + omega * (x[i].norm() + before.centre.norm())
            };
            let lever = |i: usize| x[i].norm() + before.centre.norm();
            let p_scale: f64 = component.iter().map(|&i| masses[i] * speed(i)).sum();
            let j_scale: f64 = component.iter().map(|&i| masses[i] * speed(i) * lever(i)).sum();
            energy_tolerance += 16.0 * U * n * (1.0 + kappa)
                * component.iter().map(|&i| masses[i] * speed(i).powi(2)).sum::<f64>();
            let p_error = (now.linear_velocity - before.linear_velocity).norm() * before.mass;
            let p_tolerance = 16.0 * U * n * (1.0 + kappa) * p_scale;
            prop_assert!(p_error <= p_tolerance, "momentum moved by {p_error:e} > {p_tolerance:e}");
            let j_error = (now.angular_momentum - before.angular_momentum).norm();
            let j_tolerance = 16.0 * U * n * (1.0 + kappa) * j_scale;
            prop_assert!(j_error <= j_tolerance, "angular momentum moved by {j_error:e} > {j_tolerance:e}");
        }
        for (i, fixed) in layout.fixed.iter().enumerate() {
            if *fixed {
                prop_assert_eq!(after[i], layout.velocities[i]);
            }
        }
        let before = kinetic(masses, &layout.velocities);
        let now = kinetic(masses, &after);
        prop_assert!(
            now <= before + energy_tolerance,
            "kinetic energy {before:e} -> {now:e} J (tolerance {energy_tolerance:e})"
        );
    }
}

#[test]
fn controls_fail_the_same_checks() {
    // A filter that overshoots the rigid fit (k = 2.5, outside PBD's domain)
    // raises the kinetic energy of a deforming cloud: the check can fail.
    let layout = Layout {
        positions: vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
        ],
        velocities: vec![
            Point::new(1.0, 0.0, 0.0),
            Point::new(-1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::zeros(),
        ],
        masses: vec![1.0; 4],
        fixed: vec![false; 4],
        components: vec![vec![0, 1, 2, 3]],
    };
    let rigid = RigidFit::of(
        &layout.components[0],
        &layout.masses,
        &layout.positions,
        &layout.velocities,
    )
    .motion();
    let overshoot: Vec<Point> = layout
        .positions
        .iter()
        .zip(&layout.velocities)
        .map(|(x, v)| v + (rigid.velocity_at(x) - v) * 2.5)
        .collect();
    let before = kinetic(&layout.masses, &layout.velocities);
    assert!(kinetic(&layout.masses, &overshoot) > before * 1.01);
    let pbd = kinetic(
        &layout.masses,
        &filtered(&PbdDamping::new(1.0).unwrap(), &layout, 0.01),
    );
    assert!(pbd < before * 0.99, "the rigid part alone has less energy");
}
