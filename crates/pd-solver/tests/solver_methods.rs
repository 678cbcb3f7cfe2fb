//! Every iteration method, run to convergence, reaches the step solution
//! Newton's method finds (per integrator, with and without Laplacian
//! damping); the methods keep the momentum and the thread-count
//! determinism properties of plain local-global PD.

mod common;

use common::{SCHEMES, Scheme, clamped_beam};
use pd_damping::{Damping, LaplacianDamping, NoDamping};
use pd_mesh::Point;
use pd_solver::{Predictor, Settings, Simulation, SolverMethod, SolverSpec, SpectralRadius};

fn damping(laplacian: bool) -> Box<dyn Damping> {
    if laplacian {
        Box::new(LaplacianDamping::new(0.02, 0.0, false).unwrap())
    } else {
        Box::new(NoDamping)
    }
}

fn spec(method: SolverMethod) -> SolverSpec {
    SolverSpec {
        method,
        window: 5,
        rho: SpectralRadius::Auto,
        start: SolverSpec::default().start,
    }
}

/// A 1 x 0.2 x 0.2 m beam, 1e6 Pa, clamped at x = 0, sagging under gravity
/// for `steps` steps of 10 ms with `method` at `tolerance`.
fn run(
    scheme: Scheme,
    laplacian: bool,
    method: SolverMethod,
    tolerance: f64,
    iterations: usize,
    steps: usize,
) -> (Vec<Point>, Vec<usize>) {
    let (model, _) = clamped_beam([10, 2, 2], [1.0, 0.2, 0.2], 7, 1e6);
    let settings = Settings {
        dt: 0.01,
        iterations,
        tolerance,
        ..Settings::default()
    };
    let mut sim =
        Simulation::new(model, scheme.integrator(), damping(laplacian), settings).unwrap();
    sim.set_position_solver(spec(method).create().unwrap());
    let stats = sim.run(steps).unwrap();
    (
        sim.state().positions.clone(),
        stats.iter().map(|s| s.iterations).collect(),
    )
}

fn mass_free_error(a: &[Point], b: &[Point]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt()
}

/// The accelerated methods, run to a relative residual of 1e-9 (3 steps),
/// end where Newton run to 1e-12 ends.
///
/// Tolerance: a residual `r = |G(x) - x|_M` of a map contracting at rate
/// `rho` leaves an error `<= r / (1 - rho)`; plain PD needs up to 207
/// iterations for 1e-9 here, so `rho` is about `1 - 1/10` to `1 - 1/100`
/// and each step's error is at most ~100 times the tolerance of the
/// displacement; 3 steps and a factor 3 of margin give `1e-9 * 100 * 3 * 3`
/// ~ 1e-6 of the motion. Measured: at most 1.4e-8 (plain PD, BDF-2), so the
/// bound has a margin of 70; the control shows that 3 plain iterations a
/// step miss it by far.
#[test]
fn every_method_converges_to_newtons_solution() {
    for scheme in SCHEMES {
        for laplacian in [false, true] {
            let (reference, _) = run(scheme, laplacian, SolverMethod::Newton, 1e-12, 50, 3);
            let (start, _) = run(scheme, laplacian, SolverMethod::LocalGlobal, 0.0, 1, 0);
            let motion = mass_free_error(&reference, &start);
            assert!(
                motion > 1e-2,
                "{scheme:?}: the beam barely moves ({motion} m)"
            );
            for method in [
                SolverMethod::LocalGlobal,
                SolverMethod::Anderson,
                SolverMethod::Chebyshev,
                SolverMethod::Lbfgs,
            ] {
                let (x, its) = run(scheme, laplacian, method, 1e-9, 20000, 3);
                let relative = mass_free_error(&x, &reference) / motion;
                assert!(
                    relative < 1e-6,
                    "{scheme:?} laplacian {laplacian} {method:?}: error {relative:e} of the \
                     motion after {its:?} iterations"
                );
            }
            // The control: 3 plain iterations a step are far from converged.
            let (x, _) = run(scheme, laplacian, SolverMethod::LocalGlobal, 0.0, 3, 3);
            let relative = mass_free_error(&x, &reference) / motion;
            assert!(
                relative > 1e-5,
                "{scheme:?}: 3 iterations already at {relative:e}"
            );
        }
    }
}

/// Anderson reaches the tolerance in fewer than half the iterations of
/// plain PD, L-BFGS and Chebyshev in fewer than three quarters and three
/// fifths (measured over the three steps at 1e-6: Anderson 0.28 to 0.46 of
/// plain PD's count, L-BFGS 0.37 to 0.54, Chebyshev with its default
/// `start` and `rho = "auto"` 0.51 to 0.53 (0.42 to 0.51 with the estimate
/// made once from the first step's first 10 plain iterations, which these
/// three steps, mostly the first, favour; docs/design/solver.md, "Chebyshev's
/// `rho` from every step"); Chebyshev on Wang's symmetric
/// interval with `start = 10`, before docs/design/solver.md's "Chebyshev on the
/// map's own spectrum", needed 0.70 to 0.81 at 1e-9).
#[test]
fn accelerated_methods_need_fewer_iterations() {
    for scheme in SCHEMES {
        let (_, plain) = run(scheme, false, SolverMethod::LocalGlobal, 1e-6, 20000, 3);
        let plain: usize = plain.iter().sum();
        for method in [
            SolverMethod::Anderson,
            SolverMethod::Lbfgs,
            SolverMethod::Chebyshev,
        ] {
            let (_, accelerated) = run(scheme, false, method, 1e-6, 20000, 3);
            let accelerated: usize = accelerated.iter().sum();
            let bound = match method {
                SolverMethod::Anderson => plain / 2,
                SolverMethod::Chebyshev => plain * 3 / 5,
                _ => plain * 3 / 4,
            };
            assert!(
                accelerated < bound,
                "{scheme:?} {method:?}: {accelerated} iterations, plain {plain}"
            );
        }
    }
}

/// A free, spinning, deformed box without gravity: every method keeps the
/// linear momentum. Each local-global iterate has the momentum of the
/// inertial target (the elastic forces sum to zero), and every method
/// combines iterates affinely (Anderson, Chebyshev) or moves along
/// `H^{-1} A w` with `w` a difference of iterates (Newton; `H`'s and `A`'s
/// rows sum to `M/h^2` times the vector), so the momentum is kept to
/// round-off: `u` times the momentum scale times the number of terms, with
/// a factor 1e3 for the iterations' accumulation.
#[test]
fn every_method_keeps_linear_momentum() {
    for method in [
        SolverMethod::Anderson,
        SolverMethod::Chebyshev,
        SolverMethod::Lbfgs,
        SolverMethod::Newton,
    ] {
        for scheme in SCHEMES {
            let mesh = common::jittered_box([3, 2, 2], [0.6, 0.3, 0.3], 0.1, 3);
            let masses = mesh.lumped_masses(500.0).unwrap();
            let total: f64 = masses.iter().sum();
            let mut model = pd_solver::Model::new();
            let body = model.add_body(mesh, masses).unwrap();
            model.add_tet_strain(body, 1e5, None).unwrap();
            let settings = Settings {
                dt: 0.01,
                iterations: 15,
                gravity: Point::zeros(),
                ..Settings::default()
            };
            let mut sim =
                Simulation::new(model, scheme.integrator(), damping(true), settings).unwrap();
            sim.set_position_solver(spec(method).create().unwrap());
            sim.add_rigid_velocity(0, Point::new(0.5, -0.2, 0.1), Point::new(1.0, 3.0, -2.0))
                .unwrap();
            let p0 = sim.linear_momentum();
            sim.run(10).unwrap();
            let scale = total * 3.0;
            let drift = (sim.linear_momentum() - p0).norm();
            assert!(
                drift < 1e3 * common::U * scale,
                "{method:?} {scheme:?}: momentum drifted by {drift:e}"
            );
        }
    }
}

/// Every method gives bit-identical results on 1 and 2 threads, with
/// either predictor (BDF-2: the extrapolated start is used from step 3).
#[test]
fn every_method_is_thread_count_independent() {
    let methods = [
        SolverMethod::Anderson,
        SolverMethod::Chebyshev,
        SolverMethod::Lbfgs,
        SolverMethod::Newton,
    ];
    let predictors = [Predictor::Inertial, Predictor::Extrapolated];
    for (method, predictor) in predictors
        .into_iter()
        .flat_map(|p| methods.into_iter().map(move |m| (m, p)))
    {
        let runs: Vec<Vec<Point>> = [1, 2]
            .into_iter()
            .map(|threads| {
                let (model, _) = clamped_beam([10, 2, 2], [1.0, 0.2, 0.2], 7, 1e6);
                let settings = Settings {
                    dt: 0.01,
                    iterations: 12,
                    tolerance: 1e-7,
                    threads,
                    ..Settings::default()
                };
                let mut sim =
                    Simulation::new(model, Scheme::Bdf2.integrator(), damping(true), settings)
                        .unwrap();
                sim.set_position_solver(spec(method).create().unwrap());
                sim.set_predictor(predictor);
                sim.run(4).unwrap();
                sim.state().positions.clone()
            })
            .collect();
        for (a, b) in runs[0].iter().zip(&runs[1]) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "{method:?} {predictor:?}");
            }
        }
    }
}

/// The spec refuses what it cannot run, naming the field.
#[test]
fn spec_validation_names_the_field() {
    let field = |spec: SolverSpec| match spec.create() {
        Err(pd_solver::SolverError::InvalidSetting { field, .. }) => field,
        other => panic!("expected an invalid setting, got {other:?}"),
    };
    let base = spec(SolverMethod::Anderson);
    assert_eq!(field(SolverSpec { window: 0, ..base }), "window");
    assert_eq!(field(SolverSpec { start: 1, ..base }), "start");
    assert_eq!(
        field(SolverSpec {
            rho: SpectralRadius::Fixed(1.0),
            ..base
        }),
        "rho"
    );
    assert!(SolverSpec::default().create().is_ok());
}

/// Newton and L-BFGS refuse lagged damping, saying why.
#[test]
fn newton_and_lbfgs_refuse_lagged_damping() {
    for method in [SolverMethod::Newton, SolverMethod::Lbfgs] {
        let (model, _) = clamped_beam([4, 1, 1], [1.0, 0.2, 0.2], 7, 1e6);
        let damping = Box::new(pd_damping::RayleighLagged::new(0.01, 0.0).unwrap());
        let mut sim = Simulation::new(
            model,
            Scheme::BackwardEuler.integrator(),
            damping,
            Settings::default(),
        )
        .unwrap();
        sim.set_position_solver(spec(method).create().unwrap());
        // Refused before the first step, and again by the step itself.
        let early = sim.check_position_solver().unwrap_err().to_string();
        let error = sim.step().unwrap_err().to_string();
        assert_eq!(early, error);
        assert!(
            error.contains(method.name()) && error.contains("lagged"),
            "{error}"
        );
        assert_eq!(sim.steps(), 0);
    }
}

/// Methods built directly, not through a checked `SolverSpec`: a spectral
/// radius outside (0, 1) is refused before the first step, and a huge
/// window is capped instead of allocating `window^2` values.
#[test]
fn directly_built_methods_check_their_parameters() {
    let beam = || {
        let (model, _) = clamped_beam([4, 1, 1], [1.0, 0.2, 0.2], 7, 1e6);
        Simulation::new(
            model,
            Scheme::BackwardEuler.integrator(),
            Box::new(NoDamping),
            Settings::default(),
        )
        .unwrap()
    };
    for rho in [f64::NAN, 0.0, 1.0, 1.5, -1.0] {
        let mut sim = beam();
        sim.set_position_solver(Box::new(pd_solver::Chebyshev::new(
            SpectralRadius::Fixed(rho),
            2,
        )));
        let early = sim.check_position_solver().unwrap_err().to_string();
        assert!(early.contains("rho"), "{rho}: {early}");
        assert_eq!(sim.step().unwrap_err().to_string(), early);
    }
    let mut sim = beam();
    sim.set_position_solver(Box::new(pd_solver::Chebyshev::new(
        SpectralRadius::Fixed(0.9),
        2,
    )));
    sim.step().unwrap();
    for method in [
        Box::new(pd_solver::Anderson::new(100_000_000)) as Box<dyn pd_solver::PositionSolver>,
        Box::new(pd_solver::Lbfgs::new(100_000_000)),
    ] {
        let mut sim = beam();
        sim.set_position_solver(method);
        sim.step().unwrap();
    }
}

/// An empty model is called empty, not "every vertex is fixed".
#[test]
fn an_empty_model_says_it_has_no_vertices() {
    let error = Simulation::new(
        pd_solver::Model::new(),
        Scheme::BackwardEuler.integrator(),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(error.contains("no vertices"), "{error}");
}

/// A rigid velocity for a body that does not exist, or that is not finite
/// (or overflows a vertex's velocity), is refused and changes nothing; it
/// used to be ignored, or to fail the next step as a "position that is not
/// finite".
#[test]
fn a_bad_rigid_velocity_is_refused() {
    let (model, _) = clamped_beam([4, 1, 1], [1.0, 0.2, 0.2], 7, 1e6);
    let mut sim = Simulation::new(
        model,
        Scheme::BackwardEuler.integrator(),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap();
    let before = sim.checkpoint();
    let v = Point::new(1.0, 0.0, 0.0);
    for (body, linear, angular, what) in [
        (1, v, Point::zeros(), "1 bodies"),
        (
            0,
            Point::new(f64::NAN, 0.0, 0.0),
            Point::zeros(),
            "not finite",
        ),
        (
            0,
            Point::zeros(),
            Point::new(0.0, f64::INFINITY, 0.0),
            "not finite",
        ),
        (
            0,
            Point::new(f64::MAX, 0.0, 0.0),
            Point::new(0.0, 0.0, f64::MAX),
            "vertex",
        ),
    ] {
        let error = sim.add_rigid_velocity(body, linear, angular).unwrap_err();
        assert!(error.to_string().contains(what), "{error}");
        assert_eq!(sim.checkpoint(), before);
    }
    sim.add_rigid_velocity(0, v, Point::zeros()).unwrap();
    sim.step().unwrap();
}
