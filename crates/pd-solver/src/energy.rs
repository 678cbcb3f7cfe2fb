//! Small sums over vertices shared by the step and the simulation's
//! queries.

use pd_mesh::Point;

/// Index of the first point with a non-finite coordinate.
pub(crate) fn first_non_finite(points: &[Point]) -> Option<usize> {
    points.iter().position(|p| !p.iter().all(|c| c.is_finite()))
}

/// Hard-fixed vertices never move: their velocity is zero.
pub(crate) fn zero_fixed(velocities: &mut [Point], fixed: &[bool]) {
    for (v, &fixed) in velocities.iter_mut().zip(fixed) {
        if fixed {
            *v = Point::zeros();
        }
    }
}

/// `1/2 sum m v^2` in J.
pub(crate) fn kinetic_energy(masses: &[f64], velocities: &[Point]) -> f64 {
    0.5 * masses
        .iter()
        .zip(velocities)
        .map(|(m, v)| m * v.norm_squared())
        .sum::<f64>()
}

/// `-sum m g . x` in J (zero at the origin).
pub(crate) fn gravity_energy(masses: &[f64], positions: &[Point], gravity: Point) -> f64 {
    -masses
        .iter()
        .zip(positions)
        .map(|(m, x)| m * gravity.dot(x))
        .sum::<f64>()
}

/// The axis-aligned bounding box `(min, max)` of `points` (m).
pub(crate) fn bounding_box(points: &[Point]) -> (Point, Point) {
    points.iter().fold(
        (
            Point::repeat(f64::INFINITY),
            Point::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}
