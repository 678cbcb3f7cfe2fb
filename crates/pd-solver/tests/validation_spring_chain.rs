//! Validation against analytic results (docs/design/validation.md): a chain of
//! `N` free vertices of mass `m` between two fixed ends, joined by springs of
//! stiffness `k`, moving along its axis.
//!
//! Along the axis a spring's projection `L0 d/|d|` is the constant
//! `L0 e_x` as long as no spring inverts, so the PD energy is exactly
//! `k/2 sum (u_{i+1} - u_i)^2` in the axial displacements `u`, the system
//! Laplacian is the stiffness matrix `K = k tridiag(-1, 2, -1)`, and the
//! damping Laplacian `L_d` is the same matrix. The first local step of every
//! time step therefore already projects to the final constant, and its global
//! solve is the exact linear implicit step; the tests still solve to a
//! relative tolerance of 1e-12 and check that it was met.
//!
//! `M = m I`, `K` and `D = a1 M + a2 K` share the eigenvectors
//! `u_i = sin(i j pi/(N+1))` (`i = 1..N`) with
//! `omega_j = 2 sqrt(k/m) sin(j pi/(2(N+1)))`, so the modal coordinate of
//! mode `j` evolves alone, as the scalar `q'' + (a1 + a2 omega^2) q' +
//! omega^2 q = 0` under the integrator's discrete map. Each integrator's map
//! is exactly known for that scalar equation (first-order form `y' = A y`,
//! `A = [[0, 1], [-omega^2, -c]]`, eigenvalues `lambda`):
//!
//! - implicit midpoint is the trapezoidal rule, `mu = (1 + h lambda/2)/(1 - h lambda/2)`;
//! - backward Euler, `mu = 1/(1 - h lambda)`;
//! - BDF-2, the principal root of `(3 - 2 h lambda) mu^2 - 4 mu + 1 = 0`,
//!   `mu = (2 + sqrt(1 + 2 h lambda))/(3 - 2 h lambda)`.
//!
//! The modal coordinate is then `q_n = Re(C mu^n)` (for BDF-2 plus a
//! parasitic part that decays like `3^-n` after the backward Euler start),
//! and the tests measure `|mu|` and `arg mu` from it and compare with these
//! exact discrete values, not with small-`h` approximations.
//!
//! **Round-off model** used by every tolerance: each step solves a system
//! dominated by `M/h^2` (condition number `1 + (h omega_max)^2/4` or so, with
//! `h omega_max <= 0.7` here), so each step perturbs positions of magnitude
//! up to [`EXTENT`] by at most a few `u |x|` (16 covers the constants of the
//! Cholesky backward error, the right-hand side sums and the velocity
//! update). The velocity update divides that by `h` (`2/h` for implicit
//! midpoint, the largest), and a velocity error `dv` counts as `dv/omega` in
//! the amplitude of a mode of frequency `omega`, so per step the amplitude
//! error is at most `16 u EXTENT (1 + 2/(h omega_1))`, `omega_1` the lowest
//! frequency. The discrete maps do not amplify amplitudes (`|mu| <= 1`), so
//! the errors add up at most linearly: relative to the modal amplitude `a`,
//! `q_n` errs by at most `n 16 u EXTENT (1 + 2/(h omega_1))/a`
//! ([`relative_roundoff`]).

mod common;

use std::f64::consts::PI;

use common::{SCHEMES, Scheme, U};
use nalgebra::Complex;
use pd_damping::{Damping, LaplacianDamping, NoDamping};
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation, State};

/// Free vertices.
const N: usize = 10;
/// Rest distance between neighbours, m.
const SPACING: f64 = 0.1;
/// Spring stiffness, N/m.
const STIFFNESS: f64 = 100.0;
/// Vertex mass, kg (`sqrt(k/m) = 100` rad/s).
const MASS: f64 = 0.01;
/// Initial modal amplitude, m. The energy is exactly quadratic for any
/// amplitude at which no spring inverts (a mode's neighbour differences are
/// below its amplitude), so the amplitude only sets how large round-off is
/// relative to the motion: a tenth of the spacing keeps that small.
const AMPLITUDE: f64 = 0.1 * SPACING;
/// Largest coordinate in the scene, m: the scale of position round-off.
const EXTENT: f64 = SPACING * (N + 1) as f64;

/// `omega_j` in rad/s.
fn omega(j: usize) -> f64 {
    2.0 * (STIFFNESS / MASS).sqrt() * (j as f64 * PI / (2.0 * (N + 1) as f64)).sin()
}

/// Mode `j`'s shape at vertex `i` (0 and `N + 1` are the fixed ends).
fn shape(j: usize, i: usize) -> f64 {
    ((i * j) as f64 * PI / (N + 1) as f64).sin()
}

/// Projection of the axial displacement on mode `j` (`sum shape^2 = (N+1)/2`).
fn modal_coordinate(j: usize, positions: &[Point], rest: &[Point]) -> f64 {
    (1..=N)
        .map(|i| (positions[i].x - rest[i].x) * shape(j, i))
        .sum::<f64>()
        / ((N + 1) as f64 / 2.0)
}

/// The round-off of `q_n` relative to the amplitude `amplitude` after
/// `steps` steps of `dt` (module docs).
fn relative_roundoff(steps: usize, dt: f64, amplitude: f64) -> f64 {
    steps as f64 * 16.0 * U * EXTENT * (1.0 + 2.0 / (dt * omega(1))) / amplitude
}

/// Runs `steps` steps of the chain started in mode `j` at rest with
/// amplitude [`AMPLITUDE`], converged every step; returns `q_0 .. q_steps`.
/// Also checks that the motion stays in mode `j` and on the axis.
fn modal_history(
    scheme: Scheme,
    damping: Box<dyn Damping>,
    j: usize,
    dt: f64,
    steps: usize,
) -> Vec<f64> {
    let mesh = generators::chain(N + 2, EXTENT).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, vec![MASS; N + 2]).unwrap();
    model.add_springs(body, STIFFNESS).unwrap();
    model.fix_vertices(body, &[0, N + 1]).unwrap();
    let settings = Settings {
        dt,
        iterations: 1000,
        tolerance: 1e-12,
        gravity: Point::zeros(),
        threads: 1,
        ..Settings::default()
    };
    let mut sim = Simulation::new(model, scheme.integrator(), damping, settings).unwrap();
    let rest = sim.state().positions.clone();
    let positions = rest
        .iter()
        .enumerate()
        .map(|(i, p)| p + Point::x() * (AMPLITUDE * shape(j, i)))
        .collect();
    sim.set_state(State {
        positions,
        velocities: vec![Point::zeros(); N + 2],
    })
    .unwrap();
    let mut history = vec![modal_coordinate(j, &sim.state().positions, &rest)];
    let mut max_iterations = 0;
    for step in 1..=steps {
        let stats = sim.step().unwrap();
        assert!(stats.converged, "{scheme:?} step {step}: {stats:?}");
        max_iterations = max_iterations.max(stats.iterations);
        let positions = &sim.state().positions;
        let q = modal_coordinate(j, positions, &rest);
        // Other modes and transverse motion stay at round-off: the
        // Laplacian is the stiffness matrix, whose eigenvectors these are.
        let off_mode = (1..=N)
            .map(|i| {
                let p = positions[i] - rest[i];
                (p.x - q * shape(j, i)).abs().max(p.y.abs()).max(p.z.abs())
            })
            .fold(0.0, f64::max);
        assert!(
            off_mode <= AMPLITUDE * relative_roundoff(step, dt, AMPLITUDE),
            "{scheme:?} step {step}: left mode {j} by {off_mode:e} m"
        );
        history.push(q);
    }
    eprintln!("  ({scheme:?}, mode {j}: at most {max_iterations} iterations per step)");
    history
}

/// Times (s) at which the linearly interpolated samples cross zero.
fn zero_crossings(q: &[f64], dt: f64) -> Vec<f64> {
    q.windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] * w[1] < 0.0)
        .map(|(n, w)| (n as f64 + w[0] / (w[0] - w[1])) * dt)
        .collect()
}

/// `(ln |mu|, arg mu)` per step measured from `q_n = Re(C mu^n)` over
/// `q[first - 1 ..= last + 1]`, with `roundoff` the error of `q` relative
/// to its smallest amplitude in that window; returns the two estimates and
/// their error bounds.
///
/// `|mu|`: the Casoratian `E_n = q_n^2 - q_{n-1} q_{n+1}` equals
/// `|C|^2 |mu|^{2n} sin^2(arg mu)` exactly, so
/// `ln |mu| = ln(E_last/E_first)/(2 (last - first))`. An error `eps a` in
/// each `q` moves each product by at most `2 eps a^2`, so `E` by
/// `4 eps / sin^2(arg mu)` relative, and `ln |mu|` by twice that (two ends)
/// over `2 (last - first)`.
///
/// `arg mu`: the recurrence `q_{n+1} + |mu|^2 q_{n-1} = 2 |mu| cos(arg mu) q_n`
/// is exact; summed against `q_n` it gives
/// `cos(arg mu) = sum q_n (q_{n+1} + |mu|^2 q_{n-1}) / (2 |mu| sum q_n^2)`.
/// Each term's error is at most `(3 eps + 2 d) a^2` (`d` the error of
/// `ln |mu|`), and over whole periods `sum q_n^2` is at least a third of
/// `sum a^2` (it is half of it for a sinusoid, less the decay within a
/// period), so `cos` errs by at most `3 (3 eps + 2 d)/(2 |mu|)`, and the angle
/// by that over `sin(arg mu)`.
struct Rotation {
    log_modulus: f64,
    log_modulus_error: f64,
    angle: f64,
    angle_error: f64,
}

impl Rotation {
    fn measure(q: &[f64], first: usize, last: usize, roundoff: f64) -> Self {
        let casoratian = |n: usize| q[n] * q[n] - q[n - 1] * q[n + 1];
        let steps = (last - first) as f64;
        let log_modulus = (casoratian(last) / casoratian(first)).ln() / (2.0 * steps);
        let modulus = log_modulus.exp();
        let (mut cross, mut square) = (0.0, 0.0);
        for n in first..=last {
            cross += q[n] * (q[n + 1] + modulus * modulus * q[n - 1]);
            square += q[n] * q[n];
        }
        let cosine = cross / (2.0 * modulus * square);
        let angle = cosine.acos();
        let sin2 = angle.sin().powi(2);
        let log_modulus_error = 2.0 * 4.0 * roundoff / sin2 / (2.0 * steps);
        let cosine_error = 3.0 * (3.0 * roundoff + 2.0 * log_modulus_error) / (2.0 * modulus);
        Self {
            log_modulus,
            log_modulus_error,
            angle,
            angle_error: cosine_error / angle.sin(),
        }
    }
}

/// The damping ratio of a discrete rotation `mu = exp(l + i t)` per step:
/// the continuous `zeta` with the same decrement per period,
/// `-l / sqrt(l^2 + t^2)`.
fn damping_ratio(log_modulus: f64, angle: f64) -> f64 {
    -log_modulus / log_modulus.hypot(angle)
}

/// The exact per-step eigenvalue of `scheme` for `y' = lambda y`.
fn discrete_eigenvalue(scheme: Scheme, h_lambda: Complex<f64>) -> Complex<f64> {
    let one = Complex::new(1.0, 0.0);
    match scheme {
        Scheme::ImplicitMidpoint => (one + h_lambda / 2.0) / (one - h_lambda / 2.0),
        Scheme::BackwardEuler => one / (one - h_lambda),
        Scheme::Bdf2 => (2.0 * one + (one + 2.0 * h_lambda).sqrt()) / (3.0 * one - 2.0 * h_lambda),
    }
}

#[test]
fn implicit_midpoint_frequencies_match_the_cayley_rotation() {
    eprintln!(
        "mode | omega_j (rad/s) | h omega | predicted 2 atan(h omega/2)/h | measured | rel. error vs predicted | tolerance | measured/omega - 1"
    );
    for j in 1..=3 {
        let omega = omega(j);
        let dt = 0.05 / omega;
        let theta = 2.0 * (0.5 * dt * omega).atan();
        let predicted = theta / dt;
        // Ten periods, and a step more so the last crossing is sampled.
        let steps = (10.0 * 2.0 * PI / theta).ceil() as usize + 1;
        let q = modal_history(Scheme::ImplicitMidpoint, Box::new(NoDamping), j, dt, steps);
        let crossings = zero_crossings(&q, dt);
        let span = crossings[crossings.len() - 1] - crossings[0];
        let measured = PI * (crossings.len() - 1) as f64 / span;
        // From zero velocity the map gives exactly `q_n = a cos(n theta)`
        // (its first step is `cos theta`), i.e. `cos(Omega t)` sampled, with
        // `Omega = theta/h`. Linear interpolation near a zero of
        // `sin(Omega tau)` misses its cubic term: with the zero `a` after one
        // sample and `b` before the next (`a + b = h`) the line is off by
        // `Omega^3 a b |b - a|/6 <= Omega^3 h^3/(36 sqrt 3)` there, so the
        // crossing time by `Omega^2 h^3/(36 sqrt 3)`; round-off `eps a` in
        // `q` moves it by `eps/Omega`. Two crossings bound the span.
        let interpolation = predicted.powi(2) * dt.powi(3) / (36.0 * 3f64.sqrt());
        let roundoff = relative_roundoff(steps, dt, AMPLITUDE) / predicted;
        let tolerance = 2.0 * (interpolation + roundoff) / span;
        let error = (measured - predicted) / predicted;
        let versus_continuous = measured / omega - 1.0;
        eprintln!(
            "{j} | {omega:.4} | {:.3} | {predicted:.6} | {measured:.6} | {error:.1e} | {tolerance:.1e} | {versus_continuous:.3e}",
            dt * omega
        );
        assert!(
            error.abs() <= tolerance,
            "mode {j}: measured {measured} rad/s, predicted {predicted}: {error:e} > {tolerance:e}"
        );
        // The test resolves implicit midpoint's own frequency error
        // (`-(h omega)^2/12 = -2.1e-4`): the continuous `omega_j` fails it.
        assert!(versus_continuous.abs() > 10.0 * tolerance);
    }
}

#[test]
fn laplacian_damping_is_rayleigh_damping_on_the_axial_chain() {
    eprintln!(
        "a1 (1/s) | a2 (s) | mode | zeta continuous | zeta discrete (IM) | zeta measured | ln|mu| measured - exact | tolerance | zeta measured/continuous - 1"
    );
    for (a1, a2) in [(1.0, 1e-3), (5.0, 1e-4)] {
        for j in [1, 3] {
            let omega = omega(j);
            let dt = 0.05 / omega;
            let zeta = a1 / (2.0 * omega) + a2 * omega / 2.0;
            let lambda = Complex::new(-zeta * omega, omega * (1.0 - zeta * zeta).sqrt());
            let mu = discrete_eigenvalue(Scheme::ImplicitMidpoint, lambda * dt);
            // Five periods: the amplitude falls by `exp(-10 pi zeta)`, at
            // least to 0.1 for these `zeta <= 0.07`.
            let steps = (5.0 * 2.0 * PI / mu.arg()).ceil() as usize;
            let damping = Box::new(LaplacianDamping::new(a2, a1, false).unwrap());
            let q = modal_history(Scheme::ImplicitMidpoint, damping, j, dt, steps);
            let smallest = AMPLITUDE * mu.norm().powi(steps as i32);
            let roundoff = relative_roundoff(steps, dt, smallest);
            let measured = Rotation::measure(&q, 1, steps - 1, roundoff);
            let log_error = measured.log_modulus - mu.norm().ln();
            let angle_error = measured.angle - mu.arg();
            let zeta_discrete = damping_ratio(mu.norm().ln(), mu.arg());
            let zeta_measured = damping_ratio(measured.log_modulus, measured.angle);
            eprintln!(
                "{a1} | {a2} | {j} | {zeta:.6} | {zeta_discrete:.6} | {zeta_measured:.6} | {log_error:.1e} | {:.1e} | {:.3e}",
                measured.log_modulus_error,
                zeta_measured / zeta - 1.0
            );
            assert!(
                log_error.abs() <= measured.log_modulus_error,
                "a1 {a1}, a2 {a2}, mode {j}: ln|mu| off by {log_error:e}"
            );
            assert!(
                angle_error.abs() <= measured.angle_error,
                "a1 {a1}, a2 {a2}, mode {j}: arg mu off by {angle_error:e} > {:e}",
                measured.angle_error
            );
            // The discrete decay differs from the continuous one by about
            // `zeta (h omega)^3/4` per step (the `z^3/12` term of the Cayley
            // map); the check resolves that difference: the continuous
            // `-zeta omega h` fails it.
            let continuous = -zeta * omega * dt;
            let gap = (continuous - mu.norm().ln()).abs();
            eprintln!("    continuous vs discrete ln|mu| per step: {gap:.1e}");
            assert!(gap > measured.log_modulus_error);
        }
    }
}

#[test]
fn numerical_damping_of_each_integrator_matches_its_discrete_eigenvalues() {
    // Mode 2 at h omega = 0.1 for 600 steps (about 9.5 periods): backward
    // Euler loses `exp(-3)` of the amplitude, enough to stay far above
    // round-off, and BDF-2's `(h omega)^4/4` per step adds up to 1.5e-2.
    let j = 2;
    let omega = omega(j);
    let dt = 0.1 / omega;
    let steps = 600;
    // BDF-2's parasitic root is about 1/3: after 100 steps its part is
    // below 1e-47 of the amplitude, so the window starts there.
    let first = 100;
    let y = dt * omega;
    eprintln!(
        "integrator | h omega | -ln|mu| exact | -ln|mu| measured | difference | tolerance | small-h estimate | zeta_num measured | arg mu measured/exact - 1"
    );
    for scheme in SCHEMES {
        let mu = discrete_eigenvalue(scheme, Complex::new(0.0, y));
        let q = modal_history(scheme, Box::new(NoDamping), j, dt, steps);
        let smallest = AMPLITUDE * mu.norm().powi(steps as i32);
        let measured =
            Rotation::measure(&q, first, steps - 1, relative_roundoff(steps, dt, smallest));
        let exact = -mu.norm().ln();
        let estimate = match scheme {
            Scheme::BackwardEuler => y * y / 2.0,
            Scheme::ImplicitMidpoint => 0.0,
            Scheme::Bdf2 => y.powi(4) / 4.0,
        };
        let difference = -measured.log_modulus - exact;
        let zeta = damping_ratio(measured.log_modulus, measured.angle);
        eprintln!(
            "{scheme:?} | {y} | {exact:.6e} | {:.6e} | {difference:.1e} | {:.1e} | {estimate:.6e} | {zeta:.3e} | {:.1e}",
            -measured.log_modulus,
            measured.log_modulus_error,
            measured.angle / mu.arg() - 1.0
        );
        assert!(
            difference.abs() <= measured.log_modulus_error,
            "{scheme:?}: -ln|mu| measured {} vs exact {exact}",
            -measured.log_modulus
        );
        assert!(
            (measured.angle - mu.arg()).abs() <= measured.angle_error,
            "{scheme:?}: arg mu measured {} vs exact {}",
            measured.angle,
            mu.arg()
        );
    }
}
