//! What an integrator does to one damped mode: the modal equation
//! `q'' + c q' + omega^2 q = 0` (`c = a1 + a2 phi^T D phi`, 1/s) stepped by
//! the integrator's own global step (docs/design/formulation.md, "The
//! global step", here a scalar:
//! `(x - y)/h^2 + c1 c2 omega^2 (x_n + c2 (x - x_n)) + c1 c2 gamma c (x -
//! x_hat) = 0`) and velocity update. The step is linear in the state
//! (`(q_n, v_n)`, and `(q_{n-1}, v_{n-1})` for a multistep method), so its
//! matrix comes from stepping the unit states; its two largest eigenvalues
//! `mu_1, mu_2` (the principal roots; a multistep method's parasitic roots
//! are smaller) give the equivalent continuous roots `s_i = ln(mu_i)/h` and
//! the damping ratio `zeta = -Re(s_1 + s_2) / (2 sqrt|s_1 s_2|)` the user
//! sees, numerical damping included.

use nalgebra::{Complex, DMatrix};
use pd_integrators::{History, Integrator, Point, StepTargets};

/// How a mode decays and turns under an integrator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscreteMode {
    /// The damping ratio of the discrete motion (1 = critical).
    pub damping_ratio: f64,
    /// The angular frequency of the discrete motion, `sqrt|s_1 s_2|`, rad/s
    /// (the undamped natural frequency of the continuous equation with the
    /// same roots).
    pub omega: f64,
    /// The largest `|mu|`: the factor per step by which the mode's amplitude
    /// shrinks.
    pub spectral_radius: f64,
}

/// The discrete damping of a mode of angular frequency `omega` (rad/s) with
/// modal damping coefficient `c` (1/s) under the integrators `make` builds
/// (a fresh one per unit state), at step `h` (s).
pub fn discrete_mode(
    make: &dyn Fn() -> Box<dyn Integrator>,
    h: f64,
    omega: f64,
    c: f64,
) -> DiscreteMode {
    let previous = History {
        states: vec![(vec![Point::zeros()], vec![Point::zeros()])],
    };
    let multistep = make().restore_history(&previous, 1).is_ok();
    let size = if multistep { 4 } else { 2 };
    let mut matrix = DMatrix::<f64>::zeros(size, size);
    for column in 0..size {
        let mut unit = [0.0; 4];
        unit[column] = 1.0;
        let mut integrator = make();
        if multistep {
            let history = History {
                states: vec![(
                    vec![Point::new(unit[2], 0.0, 0.0)],
                    vec![Point::new(unit[3], 0.0, 0.0)],
                )],
            };
            // Accepted above for the same length.
            let _ = integrator.restore_history(&history, 1);
        }
        let (x_n, v_n) = (
            [Point::new(unit[0], 0.0, 0.0)],
            [Point::new(unit[1], 0.0, 0.0)],
        );
        let k = integrator.coefficients(h);
        let mut targets = StepTargets::with_len(1);
        integrator.prepare(h, &x_n, &v_n, Point::zeros(), &mut targets);
        let (dy, da) = (
            targets.inertial_displacement[0].x,
            targets.anchor_displacement[0].x,
        );
        let damping = k.c1 * k.c2 * k.gamma * c;
        let d = (dy / (h * h) - k.c1 * k.c2 * omega * omega * unit[0] + damping * da)
            / (1.0 / (h * h) + k.c1 * k.c2 * k.c2 * omega * omega + damping);
        let x = [Point::new(unit[0] + d, 0.0, 0.0)];
        let mut v = [Point::zeros()];
        integrator.finish(h, &x_n, &v_n, &x, &mut v);
        matrix[(0, column)] = x[0].x;
        matrix[(1, column)] = v[0].x;
        if multistep {
            matrix[(2, column)] = unit[0];
            matrix[(3, column)] = unit[1];
        }
    }
    let mut roots: Vec<Complex<f64>> = matrix.complex_eigenvalues().iter().copied().collect();
    roots.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
    let s: Vec<Complex<f64>> = roots[..2].iter().map(|mu| mu.ln() / h).collect();
    let product = (s[0] * s[1]).norm().sqrt();
    DiscreteMode {
        damping_ratio: -(s[0] + s[1]).re / (2.0 * product),
        omega: product,
        spectral_radius: roots[0].norm(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pd_integrators::{BackwardEuler, Bdf2, ImplicitMidpoint};

    /// The damping ratio and frequency of the continuous roots `ln(mu)/h`
    /// of a conjugate pair `mu`.
    fn from_root(mu: Complex<f64>, h: f64) -> (f64, f64) {
        let s = mu.ln() / h;
        (-s.re / s.norm(), s.norm())
    }

    /// The continuous root `lambda` of `q'' + c q' + omega^2 q = 0` with
    /// positive imaginary part (under-damped).
    fn lambda(omega: f64, c: f64) -> Complex<f64> {
        Complex::new(-c / 2.0, (omega * omega - c * c / 4.0).sqrt())
    }

    // Each map is exact for the scalar equation (docs/design/validation.md 1-3), so
    // the computed roots match the closed forms up to the eigensolver's
    // round-off, about u |A| with |A| <= 2 + 2/h = 202 here (velocity rows
    // hold 1/h), i.e. 5e-14 absolute in mu. The damping ratio is
    // ln|mu| / |ln mu|, and |ln|mu|| is about 8e-3, which amplifies that by
    // 1/8e-3 = 125: 6e-12 relative. 1e-10 leaves a factor 15.
    const TOLERANCE: f64 = 1e-10;

    #[test]
    fn implicit_midpoint_is_the_cayley_map() {
        let (h, omega, c) = (0.02, 30.0, 1.5);
        let found = discrete_mode(&|| Box::new(ImplicitMidpoint::new()), h, omega, c);
        let l = lambda(omega, c) * h / 2.0;
        let (zeta, w) = from_root(
            (Complex::new(1.0, 0.0) + l) / (Complex::new(1.0, 0.0) - l),
            h,
        );
        assert!(
            (found.damping_ratio - zeta).abs() <= TOLERANCE * zeta,
            "{found:?} vs {zeta}"
        );
        assert!((found.omega - w).abs() <= TOLERANCE * w);
        // Undamped: no numerical damping at all.
        let undamped = discrete_mode(&|| Box::new(ImplicitMidpoint::new()), h, omega, 0.0);
        assert!(undamped.damping_ratio.abs() <= 1e-12, "{undamped:?}");
    }

    #[test]
    fn backward_euler_and_bdf2_match_their_roots() {
        let (h, omega, c) = (0.01, 40.0, 0.8);
        let l = lambda(omega, c) * h;
        let one = Complex::new(1.0, 0.0);
        let be = discrete_mode(&|| Box::new(BackwardEuler::new()), h, omega, c);
        let (zeta, w) = from_root(one / (one - l), h);
        assert!(
            (be.damping_ratio - zeta).abs() <= TOLERANCE * zeta,
            "{be:?} vs {zeta}"
        );
        assert!((be.omega - w).abs() <= TOLERANCE * w);
        let bdf2 = discrete_mode(&|| Box::new(Bdf2::new()), h, omega, c);
        let mu = (2.0 * one + (one + 2.0 * l).sqrt()) / (3.0 * one - 2.0 * l);
        let (zeta, w) = from_root(mu, h);
        assert!(
            (bdf2.damping_ratio - zeta).abs() <= TOLERANCE * zeta,
            "{bdf2:?} vs {zeta}"
        );
        assert!((bdf2.omega - w).abs() <= TOLERANCE * w);
    }
}
