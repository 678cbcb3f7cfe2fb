//! The rigid motion that best fits the velocities of a set of vertices.
//!
//! For vertices `i` with masses `m_i`, positions `x_i` and velocities `v_i`:
//! total mass `M = sum m_i`, centre of mass `x_cm = sum m_i x_i / M`, linear
//! velocity `v_cm = sum m_i v_i / M`, and with `r_i = x_i - x_cm` the angular
//! momentum about the centre `J = sum r_i x m_i v_i` and the inertia tensor
//! `I = sum m_i (|r_i|^2 I3 - r_i r_i^T)`. The angular velocity `omega` with
//! `I omega = J` makes the rigid field `v_cm + omega x r_i` carry the same
//! linear and angular momentum as the `v_i`; it is also the rigid field
//! closest to the `v_i` in the mass-weighted norm.
//!
//! `I` is symmetric positive semi-definite and singular exactly when all
//! `r_i` lie on one line (two vertices, a chain, a single vertex). `J` is then
//! orthogonal to the null space of `I`, so the pseudo-inverse `I^+` still
//! solves `I omega = J`; it only drops the spin about the line, which moves no
//! vertex.
//!
//! Used by [`crate::PbdDamping`]; [`RigidFreedom`] tells the solver which
//! rigid rotations the rotation-preserving Laplacian damping leaves
//! undamped.
//!
//! ```
//! use pd_damping::Point;
//! use pd_damping::rigid::RigidFit;
//!
//! // Two unit masses spinning about the z axis at 2 rad/s.
//! let masses = [1.0, 1.0];
//! let positions = [Point::new(-1.0, 0.0, 0.0), Point::new(1.0, 0.0, 0.0)];
//! let velocities = [Point::new(0.0, -2.0, 0.0), Point::new(0.0, 2.0, 0.0)];
//! let fit = RigidFit::of(&[0, 1], &masses, &positions, &velocities);
//! assert_eq!(fit.mass, 2.0);
//! assert_eq!(fit.angular_momentum, Point::new(0.0, 0.0, 4.0));
//! let omega = fit.angular_velocity();
//! assert!((omega - Point::new(0.0, 0.0, 2.0)).norm() < 1e-14);
//! ```

use nalgebra::{Matrix3, SymmetricEigen};

use crate::Point;

/// Eigenvalues of the inertia tensor at or below this fraction of the largest
/// count as zero in the pseudo-inverse: far above the round-off of an exactly
/// singular tensor (about `1e-16` relative), far below the smallest eigenvalue
/// of any body a simulation would hold.
pub const INERTIA_RELATIVE_CUTOFF: f64 = 1e-12;

/// Iteration cap of the 3 x 3 symmetric eigensolver; it converges in a
/// handful, the cap only guards against non-convergence.
const EIGEN_MAX_ITERATIONS: usize = 256;

/// How a connected component can move rigidly, given what holds it
/// (fixed vertices and attachments, at their rest positions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RigidFreedom {
    /// Nothing holds it: it translates and turns freely, and keeps its spin
    /// about its centre of mass.
    Free,
    /// Held at one point (m): it can turn about it, like a pendulum.
    Pivot {
        /// The point, m.
        point: Point,
    },
    /// Held along a line: it can turn about it, like a door.
    Hinge {
        /// A point on the line, m.
        point: Point,
        /// The line's unit direction.
        axis: Point,
    },
    /// Held at points that span a plane or more: no rigid motion is left.
    Held,
}

/// A connected component and how it can move rigidly.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidBody {
    /// Its free vertices.
    pub vertices: Vec<usize>,
    /// What holding it leaves of its rigid motion.
    pub freedom: RigidFreedom,
}

impl RigidFreedom {
    /// The freedom left by holding points `held` (m), `size` (m) the body's
    /// size: points within `1e-9 size` of a point or a line count as one.
    ///
    /// The test is geometric, on distances: the line is the one through the
    /// first point and the point farthest from it, and every point's
    /// distance from it is compared with the tolerance. Distances are
    /// computed to about `u size`, far inside the tolerance, so the answer
    /// does not depend on how the body is oriented (an eigenvalue of the
    /// points' spread compared with the tolerance squared would: its
    /// round-off, about `u` times the largest eigenvalue, is far above
    /// `(1e-9 size)^2`).
    pub fn of_held_points(held: &[Point], size: f64) -> Self {
        let Some(&first) = held.first() else {
            return Self::Free;
        };
        let tolerance = 1e-9 * size;
        let centre = held.iter().sum::<Point>() / held.len() as f64;
        let farthest = held
            .iter()
            .map(|p| p - first)
            .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))
            .unwrap_or_else(Point::zeros);
        let length = farthest.norm();
        if !(length > tolerance) {
            // Every point is within the tolerance of the first (or a
            // coordinate is not finite, where no line is defined either).
            return if length.is_finite() {
                Self::Pivot { point: centre }
            } else {
                Self::Held
            };
        }
        let axis = farthest / length;
        let on_line = held.iter().all(|p| {
            let r = p - first;
            (r - axis * axis.dot(&r)).norm() <= tolerance
        });
        if on_line {
            Self::Hinge {
                point: centre,
                axis,
            }
        } else {
            Self::Held
        }
    }
}

/// Mass, centre, momenta and inertia of a set of vertices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidFit {
    /// Total mass `M` in kg.
    pub mass: f64,
    /// Centre of mass `x_cm` in m (zero when `M` is zero).
    pub centre: Point,
    /// Velocity of the centre of mass `v_cm` in m/s (zero when `M` is zero).
    pub linear_velocity: Point,
    /// Angular momentum about the centre of mass `J` in kg m^2/s.
    pub angular_momentum: Point,
    /// Inertia tensor about the centre of mass `I` in kg m^2.
    pub inertia: Matrix3<f64>,
}

/// A rigid velocity field `v(x) = linear_velocity + angular_velocity x (x - centre)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidMotion {
    /// The point the rotation is about, in m.
    pub centre: Point,
    /// Velocity of `centre` in m/s.
    pub linear_velocity: Point,
    /// Angular velocity in rad/s.
    pub angular_velocity: Point,
}

impl RigidMotion {
    /// The velocity (m/s) of the field at `position` (m).
    pub fn velocity_at(&self, position: &Point) -> Point {
        self.linear_velocity + self.angular_velocity.cross(&(position - self.centre))
    }
}

impl RigidFit {
    /// Fits the vertices listed in `vertices`, indices into `masses` (kg),
    /// `positions` (m) and `velocities` (m/s). Two passes over `vertices`, no
    /// allocation. An empty list or zero total mass gives an all-zero fit.
    ///
    /// # Panics
    /// If an index in `vertices` is out of bounds of the three slices.
    pub fn of(
        vertices: &[usize],
        masses: &[f64],
        positions: &[Point],
        velocities: &[Point],
    ) -> Self {
        let mut mass = 0.0;
        let mut first_moment = Point::zeros();
        let mut momentum = Point::zeros();
        for &i in vertices {
            mass += masses[i];
            first_moment += masses[i] * positions[i];
            momentum += masses[i] * velocities[i];
        }
        if !(mass > 0.0) {
            return Self {
                mass,
                centre: Point::zeros(),
                linear_velocity: Point::zeros(),
                angular_momentum: Point::zeros(),
                inertia: Matrix3::zeros(),
            };
        }
        let centre = first_moment / mass;
        let linear_velocity = momentum / mass;

        let mut angular_momentum = Point::zeros();
        let mut inertia = Matrix3::zeros();
        for &i in vertices {
            let m = masses[i];
            let r = positions[i] - centre;
            // `sum m_i r_i = 0`, so subtracting `v_cm` leaves `J` unchanged in
            // exact arithmetic and spares it the cancellation of a large
            // common velocity.
            angular_momentum += m * r.cross(&(velocities[i] - linear_velocity));
            inertia += m * (Matrix3::from_diagonal_element(r.norm_squared()) - r * r.transpose());
        }
        Self {
            mass,
            centre,
            linear_velocity,
            angular_momentum,
            inertia,
        }
    }

    /// Angular momentum (kg m^2/s) about `point` (m):
    /// `J + (x_cm - point) x M v_cm`.
    pub fn angular_momentum_about(&self, point: &Point) -> Point {
        self.angular_momentum + (self.centre - point).cross(&(self.mass * self.linear_velocity))
    }

    /// The angular velocity `omega = I^+ J` in rad/s.
    pub fn angular_velocity(&self) -> Point {
        self.solve_inertia(&self.angular_momentum)
    }

    /// The angular velocity (rad/s) of the rotation about `point` (m) that
    /// best fits the velocities when the body can only turn about that point
    /// (`axis = None`) or about the line through it along the unit vector
    /// `axis`: `I_p^+ J_p` with the inertia and angular momentum about the
    /// point, restricted to the axis when there is one. Equals
    /// [`RigidFit::angular_velocity`] when the velocities are a rigid
    /// rotation about `point`.
    pub fn angular_velocity_about(&self, point: &Point, axis: Option<&Point>) -> Point {
        let d = self.centre - point;
        let inertia = self.inertia
            + self.mass * (Matrix3::from_diagonal_element(d.norm_squared()) - d * d.transpose());
        let momentum = self.angular_momentum_about(point);
        match axis {
            Some(axis) => {
                let moment = axis.dot(&(inertia * axis));
                if moment > 0.0 {
                    axis * (axis.dot(&momentum) / moment)
                } else {
                    Point::zeros()
                }
            }
            None => Self {
                inertia,
                angular_momentum: momentum,
                ..*self
            }
            .angular_velocity(),
        }
    }

    /// The rigid field `v_cm + omega x (x - x_cm)` with the fitted momenta.
    pub fn motion(&self) -> RigidMotion {
        RigidMotion {
            centre: self.centre,
            linear_velocity: self.linear_velocity,
            angular_velocity: self.angular_velocity(),
        }
    }

    /// Applies the pseudo-inverse of the inertia tensor to `rhs`: `I^+ rhs`,
    /// e.g. an angular momentum (kg m^2/s) to an angular velocity (rad/s).
    ///
    /// `I^+` comes from a symmetric eigendecomposition; eigenvalues at or
    /// below [`INERTIA_RELATIVE_CUTOFF`] times the largest count as zero.
    /// Returns zero when `I` is zero (a single vertex) or not finite. Cost: one
    /// 3 x 3 eigendecomposition, no allocation.
    pub fn solve_inertia(&self, rhs: &Point) -> Point {
        let Some((axes, eigenvalues)) = self.principal_axes() else {
            return Point::zeros();
        };
        let cutoff = INERTIA_RELATIVE_CUTOFF * eigenvalues.max();
        let mut solution = Point::zeros();
        for (axis, &eigenvalue) in axes.column_iter().zip(&eigenvalues) {
            if eigenvalue > cutoff {
                solution += axis * (axis.dot(rhs) / eigenvalue);
            }
        }
        solution
    }

    /// The principal axes (columns) and moments of `I`, or `None` when `I`
    /// is zero, not finite or the eigensolver fails.
    fn principal_axes(&self) -> Option<(Matrix3<f64>, Point)> {
        if !self.inertia.iter().all(|entry| entry.is_finite()) {
            return None;
        }
        let eigen = SymmetricEigen::try_new(self.inertia, f64::EPSILON, EIGEN_MAX_ITERATIONS)?;
        (eigen.eigenvalues.max() > 0.0).then_some((eigen.eigenvectors, eigen.eigenvalues))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_vertex_has_no_inertia_and_no_spin() {
        let fit = RigidFit::of(
            &[0],
            &[2.0],
            &[Point::new(1.0, 2.0, 3.0)],
            &[Point::new(4.0, 5.0, 6.0)],
        );
        assert_eq!(fit.mass, 2.0);
        assert_eq!(fit.centre, Point::new(1.0, 2.0, 3.0));
        assert_eq!(fit.linear_velocity, Point::new(4.0, 5.0, 6.0));
        assert_eq!(fit.inertia, Matrix3::zeros());
        assert_eq!(fit.angular_velocity(), Point::zeros());
    }

    #[test]
    fn empty_set_is_all_zero() {
        let fit = RigidFit::of(&[], &[], &[], &[]);
        assert_eq!(fit.mass, 0.0);
        assert_eq!(
            fit.motion().velocity_at(&Point::new(1.0, 1.0, 1.0)),
            Point::zeros()
        );
    }

    #[test]
    fn holding_points_give_the_same_freedom_in_every_orientation() {
        // Two points hold a door on its hinge, three collinear ones too,
        // one (or two within the tolerance) a pendulum, three in a triangle
        // hold it, however the scene is turned.
        type HoldingSet<'a> = (&'a [Point], fn(&RigidFreedom) -> bool);
        let sets: [HoldingSet<'_>; 4] = [
            (
                &[Point::new(0.09, -0.05, 0.007), Point::new(1.13, 0.05, 0.28)],
                |f| matches!(f, RigidFreedom::Hinge { .. }),
            ),
            (
                &[
                    Point::new(0.1, 0.2, 0.3),
                    Point::new(0.4, 0.7, 0.9),
                    Point::new(0.7, 1.2, 1.5),
                ],
                |f| matches!(f, RigidFreedom::Hinge { .. }),
            ),
            (
                &[Point::new(0.1, 0.2, 0.3), Point::new(0.1, 0.2, 0.3 + 1e-12)],
                |f| matches!(f, RigidFreedom::Pivot { .. }),
            ),
            (
                &[
                    Point::new(0.0, 0.0, 0.0),
                    Point::new(1.0, 0.0, 0.0),
                    Point::new(0.0, 0.5, 0.0),
                ],
                |f| *f == RigidFreedom::Held,
            ),
        ];
        for k in 0..200 {
            let t = k as f64;
            let rotation = nalgebra::Rotation3::new(Point::new(
                (0.37 * t).sin() * 3.0,
                (0.91 * t).cos() * 2.0,
                0.013 * t,
            ));
            for (points, expected) in &sets {
                let turned: Vec<Point> = points.iter().map(|p| rotation * p).collect();
                let freedom = RigidFreedom::of_held_points(&turned, 1.2);
                assert!(
                    expected(&freedom),
                    "orientation {k}: {points:?} gave {freedom:?}"
                );
            }
        }
    }

    #[test]
    fn line_drops_only_the_spin_about_itself() {
        // Unit masses at x = -1, 0, 1: I = diag(0, 2, 2), exactly singular.
        let positions = [
            Point::new(-1.0, 0.0, 0.0),
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
        ];
        let fit = RigidFit::of(&[0, 1, 2], &[1.0; 3], &positions, &[Point::zeros(); 3]);
        assert_eq!(
            fit.inertia,
            Matrix3::from_diagonal(&Point::new(0.0, 2.0, 2.0))
        );
        // The x component lies in the null space and is dropped; y and z are
        // divided by 2. Values of size 2: a few roundings of the eigensolver,
        // 8 u each.
        let solved = fit.solve_inertia(&Point::new(5.0, 3.0, -4.0));
        let error = (solved - Point::new(0.0, 1.5, -2.0)).norm();
        assert!(error <= 8.0 * f64::EPSILON * 2.0, "{solved:?}");
    }

    #[test]
    fn angular_momentum_about_a_point_adds_the_orbital_term() {
        let positions = [Point::new(1.0, 0.0, 0.0), Point::new(3.0, 0.0, 0.0)];
        let velocities = [Point::new(0.0, 1.0, 0.0); 2];
        let fit = RigidFit::of(&[0, 1], &[1.0, 1.0], &positions, &velocities);
        // Pure translation: J = 0 about the centre (2, 0, 0); about the origin
        // (2, 0, 0) x (0, 2, 0) = (0, 0, 4).
        assert_eq!(fit.angular_momentum, Point::zeros());
        assert_eq!(
            fit.angular_momentum_about(&Point::zeros()),
            Point::new(0.0, 0.0, 4.0)
        );
    }
}
