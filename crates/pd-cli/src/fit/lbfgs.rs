//! A compact L-BFGS minimiser (Nocedal and Wright, "Numerical
//! Optimization", 2nd ed., algorithms 7.4 and 7.5) with a backtracking
//! Armijo line search, which also doubles a full step accepted at once
//! while that lowers the value further, for the few unconstrained
//! variables of `pd fit` (the logarithms of positive scene parameters).
//!
//! The line search asks only for values; gradients are asked for at the
//! accepted points, which is what makes a finite-difference gradient
//! affordable. A pair `(s, y)` with `s . y <= 0` (no positive curvature
//! seen, possible without the Wolfe curvature condition) is not stored, so
//! the inverse Hessian approximation stays positive definite and every
//! direction is a descent direction.
//!
//! Stops (whichever comes first):
//! - the gradient's largest component is at most `gradient_tolerance`
//!   times the value (a unit change of any variable changes the value by
//!   at most that fraction, to first order);
//! - an iteration lowers the value by at most `loss_tolerance` times the
//!   value before it;
//! - no step along the direction lowers the value (the value's own noise);
//! - `max_iterations` iterations.

/// What is minimised: a value, and a value with its gradient.
pub(crate) trait Objective {
    /// The error an evaluation can fail with (stops the minimisation).
    type Error;

    /// The value at `z`; `f64::INFINITY` where it is undefined (a trial
    /// point the line search must back away from).
    fn value(&mut self, z: &[f64]) -> Result<f64, Self::Error>;

    /// The value and the gradient at `z` (finite).
    fn value_and_gradient(&mut self, z: &[f64]) -> Result<(f64, Vec<f64>), Self::Error>;

    /// Called after each accepted iteration (progress).
    fn progress(&mut self, _iteration: &Iteration) {}
}

/// Settings of the minimiser.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    /// Most iterations (0: only the gradient at the start).
    pub max_iterations: usize,
    /// Stop once `max_i |g_i| <= gradient_tolerance * |f|`.
    pub gradient_tolerance: f64,
    /// Stop once an iteration's decrease is `<= loss_tolerance * f`.
    pub loss_tolerance: f64,
    /// Largest change of any variable in one iteration (a trust bound).
    pub max_step: f64,
    /// Pairs kept.
    pub memory: usize,
}

/// Armijo's sufficient-decrease constant (Nocedal and Wright's usual
/// `c1 = 1e-4`).
const ARMIJO: f64 = 1e-4;
/// Backtracking factor of the step length.
const BACKTRACK: f64 = 0.5;
/// Trial steps of one line search before giving up (`0.5^40 ~ 1e-12`).
const MAX_TRIALS: usize = 40;
/// Factor by which an accepted full step is lengthened while that lowers
/// the value further.
const EXTEND: f64 = 2.0;
/// Most lengthenings in one iteration (`2^8 = 256` times the full step).
const MAX_EXTENSIONS: usize = 8;

/// One accepted iteration.
#[derive(Debug, Clone)]
pub(crate) struct Iteration {
    /// 1-based.
    pub number: usize,
    /// The new point.
    pub z: Vec<f64>,
    /// Value there.
    pub value: f64,
    /// Gradient there.
    pub gradient: Vec<f64>,
    /// The largest change of a variable in this iteration.
    pub change: f64,
}

/// Why the minimisation stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stop {
    /// The gradient is within its tolerance.
    Gradient,
    /// The last iteration lowered the value by less than its tolerance.
    LossChange,
    /// No step along the search direction lowered the value.
    NoDecrease,
    /// `max_iterations` reached.
    MaxIterations,
}

impl Stop {
    /// For messages and `fit.json`.
    pub(crate) fn describe(self) -> &'static str {
        match self {
            Stop::Gradient => "gradient within tolerance",
            Stop::LossChange => "relative loss change within tolerance",
            Stop::NoDecrease => "no step along the search direction lowers the loss",
            Stop::MaxIterations => "maximum number of iterations",
        }
    }
}

/// The result of a minimisation.
#[derive(Debug, Clone)]
pub(crate) struct Minimum {
    /// The last accepted point.
    pub z: Vec<f64>,
    /// Its value.
    pub value: f64,
    /// Its gradient.
    pub gradient: Vec<f64>,
    /// Accepted iterations.
    pub iterations: usize,
    /// Why it stopped.
    pub stop: Stop,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn max_abs(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// The L-BFGS direction `-H g` by the two-loop recursion over the stored
/// pairs (oldest first), with `H0 = (s.y / y.y) I` from the newest pair,
/// or `I` without pairs.
fn direction(gradient: &[f64], pairs: &[(Vec<f64>, Vec<f64>)]) -> Vec<f64> {
    let mut q = gradient.to_vec();
    let mut alphas = Vec::with_capacity(pairs.len());
    for (s, y) in pairs.iter().rev() {
        let rho = 1.0 / dot(y, s);
        let alpha = rho * dot(s, &q);
        for (qi, yi) in q.iter_mut().zip(y) {
            *qi -= alpha * yi;
        }
        alphas.push((alpha, rho));
    }
    let gamma = pairs.last().map_or(1.0, |(s, y)| dot(s, y) / dot(y, y));
    for qi in &mut q {
        *qi *= gamma;
    }
    for ((s, y), (alpha, rho)) in pairs.iter().zip(alphas.iter().rev()) {
        let beta = rho * dot(y, &q);
        for (qi, si) in q.iter_mut().zip(s) {
            *qi += (alpha - beta) * si;
        }
    }
    q.iter().map(|x| -x).collect()
}

/// Minimises `objective` from `start`, where its value and gradient are
/// `at_start` (as [`Objective::value_and_gradient`] gives them).
///
/// # Errors
/// The first error of the objective.
pub(crate) fn minimise<O: Objective>(
    objective: &mut O,
    start: &[f64],
    at_start: (f64, Vec<f64>),
    settings: &Settings,
) -> Result<Minimum, O::Error> {
    let (mut value, mut gradient) = at_start;
    let mut z = start.to_vec();
    let mut pairs: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
    let mut iterations = 0;
    let mut small_decrease = false;
    let stop = loop {
        if max_abs(&gradient) <= settings.gradient_tolerance * value.abs() {
            break Stop::Gradient;
        }
        if small_decrease {
            break Stop::LossChange;
        }
        if iterations >= settings.max_iterations {
            break Stop::MaxIterations;
        }
        let mut d = direction(&gradient, &pairs);
        let mut slope = dot(&gradient, &d);
        if slope >= 0.0 || !slope.is_finite() {
            // Cannot happen with positive-curvature pairs, but rounding
            // can: restart from steepest descent.
            pairs.clear();
            d = gradient.iter().map(|g| -g).collect();
            slope = dot(&gradient, &d);
        }
        // The trust bound, and on the first (unscaled) direction a first
        // step of at most that size.
        let longest = max_abs(&d);
        let mut step = if longest > settings.max_step || pairs.is_empty() {
            settings.max_step / longest
        } else {
            1.0
        };
        let at = |t: f64| -> Vec<f64> { z.iter().zip(&d).map(|(zi, di)| zi + t * di).collect() };
        let mut accepted = None;
        for trial in 0..MAX_TRIALS {
            let trial_value = objective.value(&at(step))?;
            if trial_value <= value + ARMIJO * step * slope {
                accepted = Some((trial, trial_value));
                break;
            }
            step *= BACKTRACK;
        }
        let Some((backtracked, mut accepted_value)) = accepted else {
            break Stop::NoDecrease;
        };
        // The full step was taken at once: the direction may be too short
        // (an inverse Hessian approximation too small along it, which
        // BFGS corrects slowly). Longer steps are tried while they lower
        // the value further, within the trust bound.
        if backtracked == 0 {
            for _ in 0..MAX_EXTENSIONS {
                let longer = step * EXTEND;
                if longer * longest > settings.max_step {
                    break;
                }
                let longer_value = objective.value(&at(longer))?;
                if longer_value >= accepted_value {
                    break;
                }
                step = longer;
                accepted_value = longer_value;
            }
        }
        let next = at(step);
        let (next_value, next_gradient) = objective.value_and_gradient(&next)?;
        iterations += 1;
        let s: Vec<f64> = next.iter().zip(&z).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = next_gradient
            .iter()
            .zip(&gradient)
            .map(|(a, b)| a - b)
            .collect();
        if dot(&s, &y) > f64::EPSILON * dot(&y, &y).sqrt() * dot(&s, &s).sqrt() {
            pairs.push((s, y));
            if pairs.len() > settings.memory {
                pairs.remove(0);
            }
        }
        let decrease = value - next_value;
        let before = value;
        z = next;
        value = next_value;
        gradient = next_gradient;
        objective.progress(&Iteration {
            number: iterations,
            z: z.clone(),
            value,
            gradient: gradient.clone(),
            change: step * longest,
        });
        small_decrease = decrease <= settings.loss_tolerance * before.abs();
    };
    Ok(Minimum {
        z,
        value,
        gradient,
        iterations,
        stop,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A function given by closures, counting evaluations.
    struct Function<F: FnMut(&[f64]) -> (f64, Vec<f64>)> {
        f: F,
        values: usize,
        gradients: usize,
    }

    impl<F: FnMut(&[f64]) -> (f64, Vec<f64>)> Objective for Function<F> {
        type Error = ();
        fn value(&mut self, z: &[f64]) -> Result<f64, ()> {
            self.values += 1;
            Ok((self.f)(z).0)
        }
        fn value_and_gradient(&mut self, z: &[f64]) -> Result<(f64, Vec<f64>), ()> {
            self.gradients += 1;
            Ok((self.f)(z))
        }
    }

    /// [`minimise`] from `start`, evaluating it first.
    fn run<O: Objective<Error = ()>>(f: &mut O, start: &[f64], settings: &Settings) -> Minimum {
        let at_start = f.value_and_gradient(start).unwrap();
        minimise(f, start, at_start, settings).unwrap()
    }

    fn settings(max_iterations: usize) -> Settings {
        Settings {
            max_iterations,
            gradient_tolerance: 1e-10,
            loss_tolerance: 0.0,
            max_step: 2.0,
            memory: 10,
        }
    }

    fn rosenbrock(z: &[f64]) -> (f64, Vec<f64>) {
        let (x, y) = (z[0], z[1]);
        let f = (1.0 - x).powi(2) + 100.0 * (y - x * x).powi(2);
        let g = vec![
            -2.0 * (1.0 - x) - 400.0 * x * (y - x * x),
            200.0 * (y - x * x),
        ];
        (f, g)
    }

    #[test]
    fn rosenbrock_is_minimised_from_the_classic_start() {
        let mut f = Function {
            f: rosenbrock,
            values: 0,
            gradients: 0,
        };
        let m = run(&mut f, &[-1.2, 1.0], &settings(200));
        // The minimum value is 0, so the relative gradient test is not met
        // and the iteration stops once no step lowers the value: at a value
        // of rounding level (~1e-20 and below), which with the Hessian's
        // smallest eigenvalue (~0.4) means a distance to (1, 1) of ~1e-10;
        // 1e-7 leaves room.
        assert!(
            (m.z[0] - 1.0).abs() < 1e-7 && (m.z[1] - 1.0).abs() < 1e-7,
            "{m:?}"
        );
        // Quasi-Newton methods with a line search take a few dozen
        // iterations from this start; 100 catches a broken update (steepest
        // descent takes thousands).
        assert!(m.iterations < 100, "{m:?}");
    }

    #[test]
    fn an_ill_conditioned_quadratic_is_solved_in_few_iterations() {
        // f = 1 + sum_i c_i (z_i - 1)^2 with condition number 1e4, in 3
        // variables: quasi-Newton with exact pairs needs about n + 1 = 4
        // iterations after the first (the Armijo steps are not exact line
        // searches, hence the margin).
        let c = [1.0, 100.0, 1e4];
        let quadratic = |z: &[f64]| {
            let f = 1.0 + (0..3).map(|i| c[i] * (z[i] - 1.0).powi(2)).sum::<f64>();
            let g = (0..3).map(|i| 2.0 * c[i] * (z[i] - 1.0)).collect();
            (f, g)
        };
        let mut f = Function {
            f: quadratic,
            values: 0,
            gradients: 0,
        };
        let m = run(
            &mut f,
            &[-0.4, 2.3, 0.2],
            &Settings {
                gradient_tolerance: 1e-8,
                ..settings(100)
            },
        );
        assert_eq!(m.stop, Stop::Gradient, "{m:?}");
        // A gradient below 1e-8 f (f ~ 1 there) with the smallest
        // curvature 2 puts every variable within 5e-9 of 1.
        assert!(m.z.iter().all(|z| (z - 1.0).abs() < 5e-9), "{m:?}");
        assert!(m.iterations <= 20, "{m:?}");
    }

    #[test]
    fn the_line_search_backs_away_from_undefined_values() {
        // The minimum of (z - 3)^2 is at 3, but values beyond 3.5 are
        // undefined (a diverging run): the first step (length 2, the trust
        // bound) lands at 2 from 0 and the next ones must avoid z > 3.5.
        let guarded = |z: &[f64]| {
            if z[0] > 3.5 {
                (f64::INFINITY, vec![0.0])
            } else {
                ((z[0] - 3.0).powi(2), vec![2.0 * (z[0] - 3.0)])
            }
        };
        let mut f = Function {
            f: guarded,
            values: 0,
            gradients: 0,
        };
        let m = run(&mut f, &[0.0], &settings(50));
        assert!((m.z[0] - 3.0).abs() < 1e-9, "{m:?}");
    }

    #[test]
    fn zero_iterations_only_evaluate_the_start() {
        let mut f = Function {
            f: rosenbrock,
            values: 0,
            gradients: 0,
        };
        let m = run(&mut f, &[-1.2, 1.0], &settings(0));
        assert_eq!((m.iterations, m.stop), (0, Stop::MaxIterations));
        assert_eq!((f.values, f.gradients), (0, 1));
        assert_eq!(m.z, vec![-1.2, 1.0]);
        assert_eq!(m.gradient, rosenbrock(&[-1.2, 1.0]).1);
    }

    #[test]
    fn a_small_decrease_stops_on_the_loss_tolerance() {
        // Steepest descent on a flat valley: with a tolerance of 0.5 the
        // first iteration that lowers the value by less than half stops.
        let mut f = Function {
            f: rosenbrock,
            values: 0,
            gradients: 0,
        };
        let m = run(
            &mut f,
            &[-1.2, 1.0],
            &Settings {
                loss_tolerance: 0.5,
                ..settings(100)
            },
        );
        assert_eq!(m.stop, Stop::LossChange, "{m:?}");
        assert!(m.iterations < 100);
    }
}
