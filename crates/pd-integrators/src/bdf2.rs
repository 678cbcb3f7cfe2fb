//! The second-order backward differentiation formula.

use crate::{
    BackwardEuler, History, HistoryError, Integrator, Point, StepCoefficients, StepTargets,
};

/// BDF-2: `x_{n+1} - 4/3 x_n + 1/3 x_{n-1} = 2h/3 v_{n+1}` and the same for
/// velocities. With `x_hat = (4 x_n - x_{n-1})/3`: `c1 = 4/9`, `c2 = 1`,
/// `z = 0`, `y = x_hat + h (8 v_n - 2 v_{n-1})/9 + 4h^2/9 a`,
/// `gamma = 3/(2h)`, and `v_{n+1} = (3 x_{n+1} - 4 x_n + x_{n-1})/(2h)`.
///
/// It needs the previous state, so its first step (and the first after
/// [`Integrator::reset`]) is one backward Euler step. Second order; its
/// numerical damping ratio for a mode of frequency `omega` is about
/// `(h omega)^3 / 4` (an amplitude loss of about `(h omega)^4 / 4` per step).
///
/// An explicit velocity filter run through [`Integrator::filter_velocities`]
/// that changes a velocity by `dv` shifts that vertex's previous state to
/// `(x_{n-1} - h dv, v_{n-1} + dv)`: the history becomes the motion with the
/// extra velocity `dv` all along, so a filter acts at its configured rate
/// (`docs/design/integrators.md`).
#[derive(Debug, Clone, Default)]
pub struct Bdf2 {
    previous_positions: Vec<Point>,
    previous_velocities: Vec<Point>,
    has_history: bool,
    /// The velocities before a filter, scratch of
    /// [`Integrator::filter_velocities`].
    unfiltered: Vec<Point>,
}

impl Bdf2 {
    /// The name scenes, the command line and the registry use.
    pub const NAME: &'static str = "bdf2";

    /// A new BDF-2 integrator without history.
    pub fn new() -> Self {
        Self::default()
    }

    /// The previous state `(x_{n-1}, v_{n-1})`, once one step has been taken.
    pub fn history(&self) -> Option<(&[Point], &[Point])> {
        self.has_history
            .then_some((&self.previous_positions[..], &self.previous_velocities[..]))
    }

    /// Sets the previous state `(x_{n-1}, v_{n-1})`, e.g. from a checkpoint.
    ///
    /// # Errors
    /// [`HistoryError::WrongLength`] if `positions` and `velocities` differ
    /// in length, [`HistoryError::NonFinite`] if a coordinate is NaN or
    /// infinite (the next step would turn it into a non-finite state); the
    /// integrator is then unchanged.
    pub fn set_history(
        &mut self,
        positions: &[Point],
        velocities: &[Point],
    ) -> Result<(), HistoryError> {
        if positions.len() != velocities.len() {
            return Err(HistoryError::WrongLength {
                integrator: Self::NAME,
                state: 0,
                positions: positions.len(),
                velocities: velocities.len(),
                vertices: positions.len(),
            });
        }
        for (quantity, values) in [("position", positions), ("velocity", velocities)] {
            if let Some(vertex) = values.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                return Err(HistoryError::NonFinite {
                    integrator: Self::NAME,
                    state: 0,
                    quantity,
                    vertex,
                });
            }
        }
        self.store_history(positions, velocities);
        Ok(())
    }

    /// Stores `(x_{n-1}, v_{n-1})` unchecked, in the buffers it has.
    fn store_history(&mut self, positions: &[Point], velocities: &[Point]) {
        self.previous_positions.clear();
        self.previous_positions.extend_from_slice(positions);
        self.previous_velocities.clear();
        self.previous_velocities.extend_from_slice(velocities);
        self.has_history = true;
    }
}

impl Integrator for Bdf2 {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn coefficients(&self, h: f64) -> StepCoefficients {
        if !self.has_history {
            return BackwardEuler.coefficients(h);
        }
        StepCoefficients {
            c1: 4.0 / 9.0,
            c2: 1.0,
            gamma: 1.5 / h,
        }
    }

    /// `x - x_hat = x_{n+1} - (4 x_n - x_{n-1}) / 3` after the start-up.
    fn damping_stencil(&self) -> &'static [f64] {
        if self.has_history {
            &[1.0, -4.0 / 3.0, 1.0 / 3.0]
        } else {
            BackwardEuler.damping_stencil()
        }
    }

    fn prepare(
        &self,
        h: f64,
        positions: &[Point],
        velocities: &[Point],
        acceleration: Point,
        targets: &mut StepTargets,
    ) {
        if !self.has_history {
            BackwardEuler.prepare(h, positions, velocities, acceleration, targets);
            return;
        }
        let accel_term = acceleration * (4.0 * h * h / 9.0);
        for (((y, anchor), (x, v)), (x_old, v_old)) in targets
            .inertial_displacement
            .iter_mut()
            .zip(targets.anchor_displacement.iter_mut())
            .zip(positions.iter().zip(velocities))
            .zip(
                self.previous_positions
                    .iter()
                    .zip(&self.previous_velocities),
            )
        {
            // x_hat - x_n = (4 x_n - x_{n-1})/3 - x_n, from the difference of
            // the two positions (exact for nearby floats), not from x_hat.
            let anchor_step = (x - x_old) / 3.0;
            *y = anchor_step + (v * 8.0 - v_old * 2.0) * (h / 9.0) + accel_term;
            *anchor = anchor_step;
        }
    }

    fn finish(
        &mut self,
        h: f64,
        previous_positions: &[Point],
        previous_velocities: &[Point],
        positions: &[Point],
        velocities: &mut [Point],
    ) {
        if self.has_history {
            let inv_2h = 0.5 / h;
            for ((v, x), (x0, x_old)) in velocities
                .iter_mut()
                .zip(positions)
                .zip(previous_positions.iter().zip(&self.previous_positions))
            {
                *v = (x * 3.0 - x0 * 4.0 + x_old) * inv_2h;
            }
        } else {
            BackwardEuler.finish(
                h,
                previous_positions,
                previous_velocities,
                positions,
                velocities,
            );
        }
        // x_n and v_n become the history; the buffers keep their capacity.
        // (The divergence check judges the step's own result.)
        self.store_history(previous_positions, previous_velocities);
    }

    fn filter_velocities(
        &mut self,
        h: f64,
        velocities: &mut [Point],
        filter: &mut dyn FnMut(&mut [Point]),
    ) {
        if !self.has_history {
            filter(velocities);
            return;
        }
        self.unfiltered.clear();
        self.unfiltered.extend_from_slice(velocities);
        filter(velocities);
        for ((after, before), (x_old, v_old)) in velocities.iter().zip(&self.unfiltered).zip(
            self.previous_positions
                .iter_mut()
                .zip(self.previous_velocities.iter_mut()),
        ) {
            // Untouched vertices keep their history bit for bit.
            if after != before {
                let change = after - before;
                *x_old -= change * h;
                *v_old += change;
            }
        }
    }

    fn reset(&mut self) {
        self.has_history = false;
    }

    fn history(&self) -> History {
        History {
            states: Bdf2::history(self)
                .map(|(x, v)| (x.to_vec(), v.to_vec()))
                .into_iter()
                .collect(),
        }
    }

    fn restore_history(&mut self, history: &History, vertices: usize) -> Result<(), HistoryError> {
        match history.states.as_slice() {
            [] => {
                self.reset();
                Ok(())
            }
            [(x, v)] if x.len() == vertices && v.len() == vertices => self.set_history(x, v),
            [(x, v)] => Err(HistoryError::WrongLength {
                integrator: self.name(),
                state: 0,
                positions: x.len(),
                velocities: v.len(),
                vertices,
            }),
            states => Err(HistoryError::TooManyStates {
                integrator: self.name(),
                kept: 1,
                given: states.len(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_is_backward_euler_then_bdf2() {
        let mut bdf = Bdf2::new();
        let h = 0.1;
        assert_eq!(bdf.coefficients(h), BackwardEuler.coefficients(h));
        let x0 = [Point::new(0.0, 0.0, 0.0)];
        let v0 = [Point::new(1.0, 0.0, 0.0)];
        let x1 = [Point::new(0.1, 0.0, 0.0)];
        let mut v1 = [Point::zeros()];
        bdf.finish(h, &x0, &v0, &x1, &mut v1);
        assert_eq!(v1[0], Point::new(1.0, 0.0, 0.0));
        let c = bdf.coefficients(h);
        assert_eq!((c.c1, c.c2), (4.0 / 9.0, 1.0));
        // Uniform motion is reproduced exactly by the BDF-2 targets:
        // x_hat = (4 * 0.1 - 0) / 3, y = x_hat + h (8 - 2) / 9 = 0.2, so
        // y - x_n = 0.1 and x_hat - x_n = 0.1 / 3.
        let mut t = StepTargets::with_len(1);
        bdf.prepare(h, &x1, &v1, Point::zeros(), &mut t);
        assert!((t.inertial_displacement[0].x - 0.1).abs() < 1e-15);
        assert!((t.anchor_displacement[0].x - 0.1 / 3.0).abs() < 1e-15);
    }

    #[test]
    fn history_round_trips_through_the_trait() {
        let mut bdf = Bdf2::new();
        assert!(Integrator::history(&bdf).states.is_empty());
        let x0 = [Point::new(0.0, 1.0, 0.0)];
        let v0 = [Point::new(1.0, 0.0, 0.0)];
        let x1 = [Point::new(0.1, 1.0, 0.0)];
        let mut v1 = [Point::zeros()];
        bdf.finish(0.1, &x0, &v0, &x1, &mut v1);
        let saved = Integrator::history(&bdf);
        assert_eq!(saved.states, vec![(x0.to_vec(), v0.to_vec())]);
        let mut fresh = Bdf2::new();
        fresh.restore_history(&saved, 1).unwrap();
        assert_eq!(fresh.coefficients(0.1), bdf.coefficients(0.1));
        assert_eq!(Integrator::history(&fresh), saved);
        assert_eq!(
            fresh.restore_history(&saved, 2),
            Err(HistoryError::WrongLength {
                integrator: "bdf2",
                state: 0,
                positions: 1,
                velocities: 1,
                vertices: 2,
            })
        );
        let two = History {
            states: vec![saved.states[0].clone(), saved.states[0].clone()],
        };
        let too_many = fresh.restore_history(&two, 1).unwrap_err();
        assert_eq!(
            too_many,
            HistoryError::TooManyStates {
                integrator: "bdf2",
                kept: 1,
                given: 2,
            }
        );
        assert!(too_many.to_string().contains("keeps 1 previous state"));
        assert_eq!(
            crate::BackwardEuler.restore_history(&saved, 1),
            Err(HistoryError::TooManyStates {
                integrator: "backward-euler",
                kept: 0,
                given: 1,
            })
        );
    }

    #[test]
    fn refuses_a_non_finite_or_mismatched_history_and_keeps_its_own() {
        let mut bdf = Bdf2::new();
        let x = [Point::new(0.0, 1.0, 0.0), Point::new(1.0, 1.0, 0.0)];
        let v = [Point::new(1.0, 0.0, 0.0), Point::new(0.0, 0.0, 0.0)];
        bdf.set_history(&x, &v).unwrap();
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut x_bad = x;
            x_bad[1].y = bad;
            let err = bdf.set_history(&x_bad, &v).unwrap_err();
            assert_eq!(
                err,
                HistoryError::NonFinite {
                    integrator: "bdf2",
                    state: 0,
                    quantity: "position",
                    vertex: 1,
                }
            );
            assert!(err.to_string().contains("position of vertex 1"), "{err}");
            let mut v_bad = v;
            v_bad[0].z = bad;
            let err = bdf.set_history(&x, &v_bad).unwrap_err();
            assert!(matches!(
                err,
                HistoryError::NonFinite {
                    quantity: "velocity",
                    vertex: 0,
                    ..
                }
            ));
            // Through the trait, as a checkpoint restores it.
            let history = History {
                states: vec![(x.to_vec(), v_bad.to_vec())],
            };
            assert!(bdf.restore_history(&history, 2).is_err());
        }
        assert!(bdf.set_history(&x, &v[..1]).is_err());
        // Every refusal left the history that was set first.
        assert_eq!(bdf.history(), Some((&x[..], &v[..])));
    }

    /// Uniform motion under a filter `v <- s v` decays as `s^n` exactly:
    /// after the shift the history is uniform motion at `s v`, which BDF-2
    /// continues exactly (`x_hat = x_n + h s v/3`, `y = x_n + h s v`). The
    /// velocities are exact binary fractions here (`h = 1/8`, `s = 1/2`),
    /// so the check is exact; without the shift the second step gives
    /// `s (4 s - 1)/3 = 1/6`, not `1/4`.
    #[test]
    fn filtered_history_decays_a_translation_at_the_filter_rate() {
        let h = 0.125;
        let mut bdf = Bdf2::new();
        let mut x = [Point::new(0.0, 0.0, 0.0)];
        let mut v = [Point::new(1.0, 0.0, 0.0)];
        let mut expected = 1.0;
        for step in 1..=6 {
            let mut targets = StepTargets::with_len(1);
            bdf.prepare(h, &x, &v, Point::zeros(), &mut targets);
            // A free particle: the solve returns the inertial target.
            let x_new = [x[0] + targets.inertial_displacement[0]];
            let mut v_new = [Point::zeros()];
            bdf.finish(h, &x, &v, &x_new, &mut v_new);
            bdf.filter_velocities(h, &mut v_new, &mut |v| v[0] *= 0.5);
            expected *= 0.5;
            assert_eq!(v_new[0], Point::new(expected, 0.0, 0.0), "step {step}");
            (x, v) = (x_new, v_new);
        }
    }

    #[test]
    fn a_filter_that_changes_nothing_keeps_the_history_bits() {
        let mut bdf = Bdf2::new();
        let x0 = [Point::new(0.0, 1.0, 0.0)];
        let v0 = [Point::new(-0.0, 0.0, 0.0)];
        let x1 = [Point::new(0.0, 1.0, 0.0)];
        let mut v1 = [Point::zeros()];
        bdf.finish(0.1, &x0, &v0, &x1, &mut v1);
        bdf.filter_velocities(0.1, &mut v1, &mut |_| {});
        let (_, v) = bdf.history().unwrap();
        assert!(v[0].x.is_sign_negative(), "-0.0 became {}", v[0].x);
    }
}
