//! Damping by ratio through the scene file (`[damping] ratio`, `ratios`,
//! `modes`): the coefficients fitted from the modes give the asked ratios in
//! the simulation, measured from the motion.
//!
//! **Measuring a ratio.** A scene is released from rest displaced along an
//! elastic mode `phi` (mass-normalised), and the modal coordinate
//! `q_n = phi^T M (x_n - X)` is recorded. Implicit midpoint is, for a
//! linear system, the trapezoidal (Cayley) map of the continuous equation, so
//! `q_n` of one decoupled mode obeys the two-term recurrence
//! `q_{n+1} = a q_n + b q_{n-1}` whose roots `mu` are the Cayley images of
//! the continuous roots `lambda`; the test fits `a, b` by least squares,
//! inverts the map, `lambda = (2/h)(mu - 1)/(mu + 1)`, and reads
//! `zeta = -Re(lambda) / |lambda|`: the continuous ratio, with the
//! integrator's frequency warping undone exactly.

use std::path::Path;

use nalgebra::{Complex, Matrix2, Vector2};
use pd_io::scene::{Scene, Syntax};
use pd_mesh::Point;
use pd_solver::{Simulation, State};

fn scene(text: &str) -> Scene {
    Scene::parse(text, Syntax::Toml, Path::new("ratio.toml")).unwrap()
}

/// The spring chain of `docs/design/validation.md` 1 (10 free vertices of 0.01 kg,
/// springs of 100 N/m, both ends fixed), implicit midpoint at `dt`.
fn chain(dt: f64, damping: &str) -> String {
    format!(
        "[simulation]\ndt = {dt}\nsteps = 1\ngravity = [0.0, 0.0, 0.0]\n\
         integrator = \"implicit-midpoint\"\niterations = 100\ntolerance = 1e-12\n\n\
         [damping]\nmodel = \"laplacian\"\n{damping}\n\n[[body]]\n\
         mesh = {{ generator = \"chain\", points = 12, length = 1.1 }}\nvertex_mass = 0.01\n\
         constraints = [ {{ kind = \"spring\", stiffness = 100.0 }} ]\n\
         fixed = {{ vertices = [0, 11] }}\n"
    )
}

/// A clamped beam 1 m x 0.1 m x 0.1 m of 10 x 1 x 1 cells (120 free dofs),
/// `E = 1 MPa`, `rho = 1000 kg/m^3`, implicit midpoint at `dt`.
fn beam(dt: f64, integrator: &str, damping: &str) -> String {
    format!(
        "[simulation]\ndt = {dt}\nsteps = 1\ngravity = [0.0, 0.0, 0.0]\n\
         integrator = \"{integrator}\"\niterations = 5000\ntolerance = 1e-10\n\n\
         [damping]\n{damping}\n\n[[body]]\n\
         mesh = {{ generator = \"box\", size = [1.0, 0.1, 0.1], cells = [10, 1, 1] }}\n\
         density = 1000.0\nconstraints = [ {{ kind = \"tet-strain\", stiffness = 1.0e6 }} ]\n\
         fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [1e-9, 1.0, 1.0] }} }}\n"
    )
}

/// Releases `sim` from rest displaced by `amplitude phi` and returns the
/// modal coordinates `q_0..q_steps`.
fn release(sim: &mut Simulation, phi: &[Point], amplitude: f64, steps: usize) -> Vec<f64> {
    let rest = sim.model().rest_positions().to_vec();
    let masses = sim.model().masses().to_vec();
    let positions = rest
        .iter()
        .zip(phi)
        .map(|(x, p)| x + p * amplitude)
        .collect();
    sim.set_state(State {
        positions,
        velocities: vec![Point::zeros(); rest.len()],
    })
    .unwrap();
    let q = |sim: &Simulation| -> f64 {
        let x = &sim.state().positions;
        (0..rest.len())
            .map(|i| masses[i] * phi[i].dot(&(x[i] - rest[i])))
            .sum()
    };
    let mut out = vec![q(sim)];
    for _ in 0..steps {
        sim.step().unwrap();
        out.push(q(sim));
    }
    out
}

/// The step's roots `mu` of the least-squares recurrence of `q` (skipping
/// the first `skip` steps).
fn step_roots(q: &[f64], skip: usize) -> [Complex<f64>; 2] {
    let (mut normal, mut rhs) = (Matrix2::zeros(), Vector2::zeros());
    for n in skip + 1..q.len() - 1 {
        let row = Vector2::new(q[n], q[n - 1]);
        normal += row * row.transpose();
        rhs += row * q[n + 1];
    }
    let ab = normal.lu().solve(&rhs).unwrap();
    let (a, b) = (Complex::new(ab[0], 0.0), Complex::new(ab[1], 0.0));
    let root = (a * a + 4.0 * b).sqrt();
    [(a + root) / 2.0, (a - root) / 2.0]
}

/// The continuous damping ratio behind implicit midpoint's roots.
fn midpoint_ratio(q: &[f64], dt: f64) -> f64 {
    let mu = step_roots(q, 0)[0];
    let one = Complex::new(1.0, 0.0);
    let lambda = (mu - one) / (mu + one) * (2.0 / dt);
    -lambda.re / lambda.norm()
}

/// The decay rate `-ln|mu| / h` (1/s) the motion shows.
fn decay_rate(q: &[f64], dt: f64) -> f64 {
    -step_roots(q, 0)[0].norm().ln() / dt
}

#[test]
fn two_mode_fit_reproduces_both_ratios_on_the_spring_chain() {
    let dt = 0.001;
    let s = scene(&chain(dt, "ratios = [0.02, 0.05]\nmodes = [1, 3]"));
    let mut sim = s.build().unwrap();
    let analysis = pd_modes::elastic_modes(sim.model(), 3).unwrap();
    let d = sim.damping_matrix();
    assert!(d.mass > 0.0 && d.damping_laplacian > 0.0, "{d:?}");
    for (mode, target) in [(0, 0.02), (2, 0.05)] {
        // 0.01 m along the axis keeps every spring far from inverting: the
        // chain stays exactly linear (docs/design/validation.md 1).
        let q = release(&mut sim, &analysis.modes[mode].shape, 0.01, 600);
        let zeta = midpoint_ratio(&q, dt);
        // On the chain L_d = K shares the modes, so the fit is exact and the
        // only errors are the 1e-12 solve and round-off, far below the 1%
        // asserted here.
        println!("mode {}: zeta {zeta} (asked {target})", mode + 1);
        assert!(
            (zeta - target).abs() <= 0.01 * target,
            "mode {}: {zeta}",
            mode + 1
        );
    }
}

#[test]
fn ratio_mistakes_are_clear_errors() {
    let parse =
        |damping: &str| Scene::parse(&chain(0.01, damping), Syntax::Toml, Path::new("r.toml"));
    let both = parse("stiffness = 0.01\nratio = 0.05")
        .unwrap_err()
        .to_string();
    assert!(
        both.contains("damping.stiffness") && both.contains("not both"),
        "{both}"
    );
    let pair = parse("ratios = [0.05]\nmodes = [1, 2]")
        .unwrap_err()
        .to_string();
    assert!(pair.contains("ratios") && pair.contains("two"), "{pair}");
    let lone = parse("ratios = [0.01, 0.02]").unwrap_err().to_string();
    assert!(lone.contains("damping.modes"), "{lone}");
    // The chain has 10 elastic modes along its axis (20 sideways mechanisms).
    let far = scene(&chain(0.01, "ratio = 0.05\nmode = 11"))
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        far.contains("damping.mode") && far.contains("only 10"),
        "{far}"
    );
    // A ratio whose stiffness overflows says so (it used to read as a
    // negative stiffness and a too large mass of 0).
    let huge = scene(&chain(0.01, "ratio = 1e308"))
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        huge.contains("damping.ratio") && huge.contains("smaller ratio"),
        "{huge}"
    );
}

/// The beam's first mode released at `1e-3 L` and recorded for `periods`
/// periods: its modal coordinate, the mode, and `sim`.
fn beam_history(dt: f64, integrator: &str, damping: &str, periods: f64) -> (Vec<f64>, f64) {
    let mut sim = scene(&beam(dt, integrator, damping)).build().unwrap();
    let analysis = pd_modes::elastic_modes(sim.model(), 1).unwrap();
    let mode = &analysis.modes[0];
    let largest = mode.shape.iter().map(|p| p.norm()).fold(0.0, f64::max);
    let steps = (periods * std::f64::consts::TAU / (mode.omega * dt)).round() as usize;
    let q = release(&mut sim, &mode.shape, 1e-3 / largest, steps);
    (q, mode.omega)
}

#[test]
fn clamped_beam_gets_its_ratio_with_implicit_midpoint() {
    let zeta = 0.05;
    let damping = format!("model = \"laplacian\"\nratio = {zeta}");
    // h omega_1 = 0.1 (omega_1 = 5.799 rad/s on this mesh).
    let dt = 0.1 / 5.798936;
    let (q, _) = beam_history(dt, "implicit-midpoint", &damping, 2.0);
    let measured = midpoint_ratio(&q, dt);
    println!("beam: zeta {measured} (asked {zeta})");
    // Tolerance. The fit makes the first mode's own coefficient
    // a1 + a2 phi_1^T L_d phi_1 = 2 zeta omega_1 exactly; what it cannot
    // control is that L_d is not diagonal in the modes: c_1j = a2 phi_1^T L_d
    // phi_j couples mode 1 to the others, and second-order perturbation of
    // the quadratic eigenproblem moves the root by about
    // sum_j c_1j^2 omega_1^2 / (omega_j^2 - omega_1^2) / (2 omega_1) in
    // frequency and by c_1j^2 c_jj omega_1^2 / (omega_j^2 - omega_1^2)^2 / 2
    // in decay rate. Here omega_j >= 5.8 rad/s for the pair mode (which
    // does not couple, c_12 = 0 by the section's symmetry) and >= 33 rad/s
    // for the rest, so the relative error of zeta is of order
    // (c_1j/omega_j)^2 <= (2 zeta omega_1 / omega_2)^2 ~ 3e-4 per coupled
    // mode; with the ~10 modes that couple noticeably, 5e-3. The amplitude
    // 1e-3 L shifts the frequency by ~1e-6 (geometric nonlinearity,
    // docs/design/validation.md 4a) and the 1e-10 solve tolerance adds less. The
    // test allows 2%, four times that estimate.
    assert!((measured - zeta).abs() <= 0.02 * zeta, "{measured}");
}

#[test]
fn ratio_decay_does_not_depend_on_the_time_step_with_implicit_midpoint() {
    let zeta = 0.05;
    let damping = format!("model = \"laplacian\"\nratio = {zeta}");
    let mut rates = Vec::new();
    for dt in [0.002, 0.02] {
        let (q, omega) = beam_history(dt, "implicit-midpoint", &damping, 1.5);
        let rate = decay_rate(&q, dt);
        println!(
            "dt {dt}: decay rate {rate} 1/s (zeta omega = {})",
            zeta * omega
        );
        rates.push((rate, omega, dt));
    }
    // Implicit midpoint adds no numerical damping; its Cayley map shrinks
    // the decay rate zeta omega to zeta omega / (1 + (h omega / 2)^2), so the
    // two rates differ by (h omega / 2)^2 = 3.4e-3 at dt = 0.02 (and 3e-5 at
    // 0.002); mode coupling is the same at both steps. Allow 1%.
    let (fine, coarse) = (rates[0].0, rates[1].0);
    assert!((fine - coarse).abs() <= 0.01 * fine, "{fine} vs {coarse}");
    // Both are the asked zeta omega_1, to the coupling estimate above.
    assert!((fine - zeta * rates[0].1).abs() <= 0.02 * fine, "{fine}");
}
