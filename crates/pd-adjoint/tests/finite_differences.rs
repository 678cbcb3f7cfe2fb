//! The adjoint gradient against central finite differences of the same loss,
//! for every parameter kind and every integrator, on a clamped beam of 28
//! vertices (tet strain, springs and two attachments: three constraint
//! groups) swinging and sagging for 20 steps of 10 ms.
//!
//! Each finite difference is taken at two step sizes, `eps` and `eps / 2`.
//! A central difference's error is `C eps^2` (plus the forward run's
//! round-off and stopping error over `eps`), so the half-step value is off
//! by about `|D(eps) - D(eps/2)| / 3`; the test accepts the adjoint value
//! when it is within 1% of the half-step difference or within that
//! difference's own error bound, taken generously as the whole gap
//! `|D(eps) - D(eps/2)|` plus the stopping error's share (the forward run
//! converged to 1e-12 of each step's displacement, over `eps`).

use pd_adjoint::{
    AdjointOptions, Loss, LossGradient, Parameter, ParameterGradient, ProbeLoss, loss_and_gradient,
};
use pd_damping::LaplacianDamping;
use pd_integrators::{BackwardEuler, Bdf2, ImplicitMidpoint, Integrator};
use pd_mesh::{Point, VertexSelection, generators};
use pd_solver::{Model, Settings, Simulation, State};

const STEPS: usize = 20;

/// Everything the scene depends on.
#[derive(Debug, Clone)]
struct Scene {
    integrator: &'static str,
    a1: f64,
    a2: f64,
    /// The Caughey series' `a3, a4, ...` (empty: plain Laplacian damping).
    series: Vec<f64>,
    strain: f64,
    springs: f64,
    attachments: f64,
    density: f64,
    gravity: Point,
    /// Added to the initial positions and velocities.
    dx0: Vec<Point>,
    dv0: Vec<Point>,
}

const VERTICES: usize = 28;

impl Scene {
    fn new(integrator: &'static str) -> Self {
        Self {
            integrator,
            a1: 0.5,
            a2: 0.01,
            series: Vec::new(),
            strain: 2e4,
            springs: 300.0,
            attachments: 50.0,
            density: 1000.0,
            gravity: Point::new(0.3, -9.81, 0.5),
            dx0: vec![Point::zeros(); VERTICES],
            dv0: vec![Point::zeros(); VERTICES],
        }
    }

    fn simulation(&self) -> Simulation {
        let beam = generators::box_tets([1.0, 0.2, 0.2], [6, 1, 1]).unwrap();
        assert_eq!(beam.num_vertices(), VERTICES);
        let clamp = VertexSelection::Box {
            min: [-1.0; 3],
            max: [1e-9, 1.0, 1.0],
        }
        .resolve(&beam)
        .unwrap();
        let masses = beam.lumped_masses(self.density).unwrap();
        let mut model = Model::new();
        let body = model.add_body(beam, masses).unwrap();
        model.add_tet_strain(body, self.strain, None).unwrap();
        model.add_springs(body, self.springs).unwrap();
        // Two corners of the free end, held softly where they rest.
        model
            .add_attachments(body, &[20, 27], self.attachments)
            .unwrap();
        model.fix_vertices(body, &clamp).unwrap();
        let rest = model.rest_positions().to_vec();
        let settings = Settings {
            dt: 0.01,
            gravity: self.gravity,
            ..Settings::default()
        };
        let integrator: Box<dyn Integrator> = match self.integrator {
            "backward-euler" => Box::new(BackwardEuler),
            "implicit-midpoint" => Box::new(ImplicitMidpoint),
            _ => Box::new(Bdf2::new()),
        };
        let damping = if self.series.is_empty() {
            LaplacianDamping::new(self.a2, self.a1, false).unwrap()
        } else {
            LaplacianDamping::with_series(self.a2, self.a1, false, &self.series).unwrap()
        };
        let mut sim = Simulation::new(model, integrator, Box::new(damping), settings).unwrap();
        // An upward swing growing along the beam, and a twist, so that the
        // run bends and stretches the beam in every direction.
        let positions = rest.iter().zip(&self.dx0).map(|(x, d)| x + d).collect();
        let velocities = rest
            .iter()
            .zip(&self.dv0)
            .map(|(x, d)| Point::new(0.1 * x.y, 1.5 * x.x, -0.8 * x.x + 0.5 * x.y) + d)
            .collect();
        sim.set_state(State {
            positions,
            velocities,
        })
        .unwrap();
        sim
    }
}

/// Targets: the rest positions of three probes, lifted and shifted.
fn probe_loss() -> ProbeLoss {
    let beam = generators::box_tets([1.0, 0.2, 0.2], [6, 1, 1]).unwrap();
    let vertices = vec![6, 13, 27];
    let targets = (1..=STEPS)
        .map(|s| {
            vertices
                .iter()
                .map(|&v| beam.vertices()[v] + Point::new(0.01, 0.002 * s as f64, -0.01))
                .collect()
        })
        .collect();
    ProbeLoss { vertices, targets }
}

fn run(scene: &Scene, loss: &dyn Loss, parameters: &[Parameter]) -> LossGradient {
    let options = AdjointOptions {
        forward_tolerance: 1e-12,
        ..AdjointOptions::default()
    };
    loss_and_gradient(scene.simulation(), STEPS, loss, parameters, &options).unwrap()
}

/// Central differences of the loss along `perturb` at `eps` and `eps / 2`.
fn central(scene: &Scene, eps: f64, perturb: &dyn Fn(&mut Scene, f64)) -> (f64, f64) {
    let loss = probe_loss();
    let at = |t: f64| {
        let mut s = scene.clone();
        perturb(&mut s, t);
        run(&s, &loss, &[]).loss
    };
    let d1 = (at(eps) - at(-eps)) / (2.0 * eps);
    let d2 = (at(eps / 2.0) - at(-eps / 2.0)) / eps;
    (d1, d2)
}

/// Checks `adjoint` against the central differences, as the module
/// documentation explains.
fn check(what: &str, adjoint: f64, (d1, d2): (f64, f64), loss: f64, eps: f64) {
    // The forward run stops at 1e-12 of a step's displacement; the loss's
    // resulting error is at most about 1e-12 of the loss itself, and a
    // difference over 2 eps multiplies it by 1/eps.
    let stopping = 1e-12 * loss / eps;
    let bound = (d1 - d2).abs() + stopping;
    let error = (adjoint - d2).abs();
    println!(
        "{what}: adjoint {adjoint:.9e}, fd {d2:.9e} (eps {eps:e}: {d1:.9e}), error {error:.2e}, bound {bound:.2e}"
    );
    assert!(
        error <= 0.01 * d2.abs() || error <= bound,
        "{what}: adjoint {adjoint:e} against finite differences {d2:e} (eps {eps:e}: {d1:e})"
    );
    // A check that cannot fail is no check: the derivative is not zero.
    assert!(
        d2.abs() > 10.0 * bound,
        "{what}: the derivative {d2:e} is lost in the noise {bound:e}"
    );
}

fn scalar(g: &ParameterGradient) -> f64 {
    match g {
        ParameterGradient::Scalar(v) => *v,
        ParameterGradient::Points(_) => panic!("a scalar gradient was expected"),
    }
}

fn points(g: &ParameterGradient) -> &[Point] {
    match g {
        ParameterGradient::Points(p) => p,
        ParameterGradient::Scalar(_) => panic!("a vector gradient was expected"),
    }
}

/// A fixed pseudo-random direction, one point per vertex, entries in
/// [-1, 1].
fn direction(seed: u64) -> Vec<Point> {
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    (0..VERTICES)
        .map(|_| Point::new(next(), next(), next()))
        .collect()
}

fn check_all(integrator: &'static str) {
    let scene = Scene::new(integrator);
    let parameters = [
        Parameter::DampingMass,
        Parameter::DampingStiffness,
        Parameter::ConstraintStiffness {
            body: 0,
            constraint: 0,
        },
        Parameter::ConstraintStiffness {
            body: 0,
            constraint: 1,
        },
        Parameter::Density { body: 0 },
        Parameter::InitialPositions,
        Parameter::ConstraintStiffness {
            body: 0,
            constraint: 2,
        },
        Parameter::InitialVelocities,
        Parameter::ExternalForce,
    ];
    let result = run(&scene, &probe_loss(), &parameters);
    println!(
        "{integrator}: loss {:e}, adjoint iterations {}, fallback steps {}, residual {:e}, retries {}, unconverged {}",
        result.loss,
        result.adjoint_iterations,
        result.fallback_steps,
        result.adjoint_residual,
        result.forward_retries,
        result.unconverged_steps
    );
    assert_eq!(result.unconverged_steps, 0, "the forward run must converge");
    let loss = result.loss;
    let g = &result.gradients;
    // Step sizes: about 1e-3 of each parameter's value (or scale), where
    // the eps^2 truncation error and the stopping error over eps are both
    // small.
    let eps = 1e-3 * scene.a1;
    check(
        "a1",
        scalar(&g[0]),
        central(&scene, eps, &|s, t| s.a1 += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.a2;
    check(
        "a2",
        scalar(&g[1]),
        central(&scene, eps, &|s, t| s.a2 += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.strain;
    check(
        "tet-strain stiffness",
        scalar(&g[2]),
        central(&scene, eps, &|s, t| s.strain += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.springs;
    check(
        "spring stiffness",
        scalar(&g[3]),
        central(&scene, eps, &|s, t| s.springs += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.attachments;
    check(
        "attachment stiffness",
        scalar(&g[6]),
        central(&scene, eps, &|s, t| s.attachments += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.density;
    check(
        "density",
        scalar(&g[4]),
        central(&scene, eps, &|s, t| s.density += t),
        loss,
        eps,
    );
    // Vector parameters: the directional derivative along a fixed
    // pseudo-random direction (every vertex, fixed ones included for the
    // positions, every component).
    let d = direction(1);
    let along: f64 = points(&g[5]).iter().zip(&d).map(|(a, b)| a.dot(b)).sum();
    let eps = 1e-5;
    check(
        "initial positions",
        along,
        central(&scene, eps, &|s, t| {
            s.dx0 = d.iter().map(|d| d * t).collect();
        }),
        loss,
        eps,
    );
    let d = direction(2);
    let along: f64 = points(&g[7]).iter().zip(&d).map(|(a, b)| a.dot(b)).sum();
    let eps = 1e-4;
    check(
        "initial velocities",
        along,
        central(&scene, eps, &|s, t| {
            s.dv0 = d.iter().map(|d| d * t).collect();
        }),
        loss,
        eps,
    );
    let gravity = points(&g[8]);
    assert_eq!(gravity.len(), 1);
    for (axis, &component) in gravity[0].iter().enumerate() {
        let eps = 1e-3;
        check(
            &format!("gravity[{axis}]"),
            component,
            central(&scene, eps, &|s, t| s.gravity[axis] += t),
            loss,
            eps,
        );
    }
}

#[test]
fn backward_euler_gradients_match_finite_differences() {
    check_all("backward-euler");
}

#[test]
fn implicit_midpoint_gradients_match_finite_differences() {
    check_all("implicit-midpoint");
}

#[test]
fn bdf2_gradients_match_finite_differences() {
    check_all("bdf2");
}

/// The Caughey series `a1 M + a2 L_d + a3 L_d M^-1 L_d + a4 L_d (M^-1
/// L_d)^2`: the gradient with respect to each coefficient, a term the
/// series does not have (`a5`, zero), and the parameters the series' powers
/// depend on (the constraint weights through `L_d`, the density through
/// `M^-1`).
fn check_series(integrator: &'static str) {
    let mut scene = Scene::new(integrator);
    // Each term matters in the loss: a_k dloss/da_k is 30% of the loss for
    // a2, 2.5% for a3 and 0.4% for a4 (measured, backward Euler).
    scene.series = vec![5e-7, 2e-11];
    let parameters = [
        Parameter::DampingMass,
        Parameter::DampingStiffness,
        Parameter::DampingSeries(0),
        Parameter::DampingSeries(1),
        Parameter::DampingSeries(2),
        Parameter::ConstraintStiffness {
            body: 0,
            constraint: 0,
        },
        Parameter::ConstraintStiffness {
            body: 0,
            constraint: 1,
        },
        Parameter::Density { body: 0 },
    ];
    let result = run(&scene, &probe_loss(), &parameters);
    println!(
        "{integrator} with a series: loss {:e}, adjoint iterations {}, fallback steps {}, residual {:e}",
        result.loss, result.adjoint_iterations, result.fallback_steps, result.adjoint_residual
    );
    assert_eq!(result.unconverged_steps, 0, "the forward run must converge");
    let loss = result.loss;
    let g = &result.gradients;
    let eps = 1e-3 * scene.a1;
    check(
        "a1",
        scalar(&g[0]),
        central(&scene, eps, &|s, t| s.a1 += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.a2;
    check(
        "a2",
        scalar(&g[1]),
        central(&scene, eps, &|s, t| s.a2 += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.series[0];
    check(
        "a3",
        scalar(&g[2]),
        central(&scene, eps, &|s, t| s.series[0] += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.series[1];
    check(
        "a4",
        scalar(&g[3]),
        central(&scene, eps, &|s, t| s.series[1] += t),
        loss,
        eps,
    );
    // a5 is zero: a step 1e-3 a4 / (1e4 1/s^2), a scale a4's term has
    // at an eigenvalue s = 1e4 1/s^2 of M^-1 L_d, taken on both sides (the
    // series stays positive: the forward run would refuse it otherwise).
    let eps = 1e-3 * scene.series[1] / 1e4;
    check(
        "a5 (absent)",
        scalar(&g[4]),
        central(&scene, eps, &|s, t| {
            s.series.resize(3, 0.0);
            s.series[2] += t;
        }),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.strain;
    check(
        "tet-strain stiffness",
        scalar(&g[5]),
        central(&scene, eps, &|s, t| s.strain += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.springs;
    check(
        "spring stiffness",
        scalar(&g[6]),
        central(&scene, eps, &|s, t| s.springs += t),
        loss,
        eps,
    );
    let eps = 1e-3 * scene.density;
    check(
        "density",
        scalar(&g[7]),
        central(&scene, eps, &|s, t| s.density += t),
        loss,
        eps,
    );
}

#[test]
fn backward_euler_series_gradients_match_finite_differences() {
    check_series("backward-euler");
}

#[test]
fn implicit_midpoint_series_gradients_match_finite_differences() {
    check_series("implicit-midpoint");
}

#[test]
fn bdf2_series_gradients_match_finite_differences() {
    check_series("bdf2");
}
