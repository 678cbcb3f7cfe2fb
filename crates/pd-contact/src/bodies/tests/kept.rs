//! Tests of the in-place pair updates and the kept counts
//! (docs/design/contact.md, "Detection and the broad phase"), with the
//! helpers of `bodies/tests.rs`.

use super::{Lcg, Point, sheet, two_sheets};
use crate::bodies::pair_force;
use crate::clearance::largest_motion;

/// The inline weighted sum of the pair updates is the iterator sum bit for
/// bit, signed zeros included (a sum without the leading `0 +` gives `-0`
/// where the iterator gives `+0`, and fails here).
#[test]
fn weighted_sum_is_the_iterator_sum_bit_for_bit() {
    let values = [0.0, -0.0, 1.5, -2.25, 1e-300, -3.0e10, 0.1];
    let mut compared = 0;
    for (a, &x) in values.iter().enumerate() {
        for &y in &values {
            for &w in &[0.0, -0.0, 0.25, -1.0, 0.7] {
                let p = [
                    Point::new(x, y, -0.0),
                    Point::new(y, -0.0, x),
                    Point::new(-0.0, x * 0.5, y),
                ];
                let weights = [w, 1.0 - w, values[(a + 3) % values.len()]];
                let iterator = (0..3).map(|k| p[k] * weights[k]).sum::<Point>();
                let inline = pair_force::weighted(p, &weights);
                for k in 0..3 {
                    assert_eq!(
                        inline[k].to_bits(),
                        iterator[k].to_bits(),
                        "{p:?} {weights:?}"
                    );
                }
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 245);
}

/// The counts and the list of paired vertices kept from one iteration to
/// the next (`bodies/counts.rs`) are those of a pass over every vertex in
/// every iteration: sheets sinking onto each other over eight iterations,
/// so that pairs appear in later iterations too, with a growing list of
/// collider contacts, over two steps (the second starting from the
/// first's pairs).
#[test]
fn kept_counts_are_a_pass_over_every_vertex_in_every_iteration() {
    let (n, thickness) = (6, 0.01);
    let mut rng = Lcg(9);
    let (mut later_pairs, mut later_colliders) = (0, 0);
    for trial in 0..8 {
        let shift = if trial % 2 == 0 { 0.0 } else { 0.029 };
        let (mut rest, lower) = sheet(n, 0.0, 0.0, 0);
        let (upper_points, upper) = sheet(n, 0.012, shift, n * n);
        rest.extend(upper_points);
        let mut bodies = two_sheets(&rest, [lower, upper], trial % 4 < 2, false, thickness);
        let mut x_n: Vec<Point> = rest
            .iter()
            .map(|p| p + Point::new(rng.next(), rng.next(), rng.next()) * 1e-4)
            .collect();
        for _step in 0..2 {
            // A step's start over the listed pairs (`pair_slots`) keeps
            // the pairs a pass over every slot keeps.
            let mut every_slot = bodies.clone();
            every_slot.counted = false;
            every_slot.begin_step(&x_n);
            bodies.begin_step(&x_n);
            assert_eq!(bodies.pairs, every_slot.pairs, "trial {trial}");
            let mut collider = Vec::new();
            let mut dx = vec![Point::zeros(); rest.len()];
            for iteration in 0..8 {
                // Each iteration sinks the upper sheet further (new pairs)
                // and adds collider contacts (kept in increasing order).
                for (v, d) in dx.iter_mut().enumerate() {
                    let down = if v >= n * n { -0.002 } else { 0.0 };
                    *d += Point::new(rng.next() * 1e-4, down, rng.next() * 1e-4);
                }
                for _ in 0..3 {
                    let v = ((rng.next() + 1.0) * 0.5 * rest.len() as f64) as usize;
                    if v < rest.len() && !collider.contains(&v) {
                        collider.push(v);
                        later_colliders += usize::from(iteration > 0);
                    }
                }
                collider.sort_unstable();
                let paired_before = bodies.paired.len();
                bodies.detect(&x_n, &dx, (thickness, largest_motion(&dx)), &collider);
                if iteration > 0 {
                    later_pairs += bodies.paired.len() - paired_before;
                }
                let mut count: Vec<u32> = (0..rest.len())
                    .map(|v| u32::from(collider.contains(&v)))
                    .collect();
                let mut paired = Vec::new();
                for (v, pair) in bodies.pairs.iter().enumerate() {
                    let Some(p) = pair else { continue };
                    paired.push(v);
                    count[v] += 1;
                    for (&i, &w) in bodies.faces[p.face].vertices.iter().zip(&p.weights) {
                        count[i] += u32::from(w != 0.0);
                    }
                }
                assert_eq!(bodies.count, count, "trial {trial} iteration {iteration}");
                assert_eq!(bodies.paired, paired, "trial {trial} iteration {iteration}");
                let (listed, slots) = bodies.pair_slots();
                let visited: Vec<_> = (0..slots).map(|k| bodies.pair_slot(k, listed)).collect();
                assert!(
                    listed && visited == paired,
                    "trial {trial} iteration {iteration}"
                );
            }
            // The projection over the listed pairs is the one over every
            // slot, bit for bit.
            let mut every_slot = bodies.clone();
            every_slot.counted = false;
            let mut x: Vec<Point> = x_n.iter().zip(&dx).map(|(x, d)| x + d).collect();
            let mut y = x.clone();
            let (deepest, expected) = (
                bodies.project(&mut x, thickness),
                every_slot.project(&mut y, thickness),
            );
            assert_eq!(deepest.to_bits(), expected.to_bits(), "trial {trial}");
            assert!(x == y && bodies.pairs == every_slot.pairs, "trial {trial}");
            // The next step starts where this one ended, with forces that
            // keep every pair.
            for pair in bodies.pairs.iter_mut().flatten() {
                pair.force = pair.normal;
            }
            x_n = x_n.iter().zip(&dx).map(|(x, d)| x + d).collect();
        }
    }
    // Not vacuous: pairs and collider contacts were added after the first
    // iteration of a step, where only the kept counts are updated.
    println!("{later_pairs} pairs and {later_colliders} collider contacts added later");
    assert!(
        later_pairs > 20 && later_colliders > 20,
        "{later_pairs} pairs, {later_colliders} collider contacts added later"
    );
}

/// Detection through [`BodyContact::detect`] gives the grid's pair for
/// every searching vertex, also in the iterations whose iterate leaves
/// the lists: they are rebuilt and the fast path runs on them (seen by
/// its start planes being taken), with ties handed to the slow path.
#[test]
fn detection_after_a_rebuild_is_the_grid_detection_bit_for_bit() {
    let (n, thickness) = (6, 0.01);
    let mut rng = Lcg(13);
    let (mut rebuilt_fast, mut hits) = (0, 0);
    for trial in 0..12 {
        let shift = if trial % 3 == 0 { 0.0 } else { 0.031 };
        let (mut rest, lower) = sheet(n, 0.0, 0.0, 0);
        let (upper_points, upper) = sheet(n, 0.006, shift, n * n);
        rest.extend(upper_points);
        let mut bodies = two_sheets(&rest, [lower, upper], trial % 2 == 0, false, thickness);
        let mut x_n: Vec<Point> = rest.clone();
        for step in 0..4 {
            bodies.begin_step(&x_n);
            let mut dx = vec![Point::zeros(); rest.len()];
            for iteration in 0..6 {
                // Growing steps down, so that the lists of one iteration
                // do not cover the next.
                let size = 1e-3 * f64::from(1 << iteration);
                for (v, d) in dx.iter_mut().enumerate() {
                    let down = if v >= n * n { -size } else { 0.0 };
                    *d += Point::new(rng.next() * 1e-4, down, rng.next() * 1e-4);
                }
                let expected = super::grid_reference(&bodies, (&x_n, &dx), thickness);
                let covered = bodies.candidates.valid
                    && bodies.candidates.covers(&x_n, &dx, &bodies.on_surface);
                bodies.detect(&x_n, &dx, (thickness, largest_motion(&dx)), &[]);
                rebuilt_fast += usize::from(!covered && bodies.start_planes_fresh);
                let context = format!("trial {trial}, step {step}, iteration {iteration}");
                hits += super::matching_hits(&bodies.pairs, &expected, &context);
            }
            for pair in bodies.pairs.iter_mut().flatten() {
                pair.force = pair.normal;
            }
            x_n = x_n.iter().zip(&dx).map(|(x, d)| x + d * 0.1).collect();
        }
    }
    println!("{rebuilt_fast} rebuilt and fast, {hits} hits");
    assert!(
        rebuilt_fast > 20 && hits > 50,
        "{rebuilt_fast} rebuilt and fast, {hits} hits"
    );
}
