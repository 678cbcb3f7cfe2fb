//! The step's error estimate (`StepStats::estimated_error`) against the true
//! relative error: each step of a 10-iteration run is solved again to
//! convergence (Newton, relative residual 1e-12) from the same state, and
//! `|x - x*|_M / |y - x*|_M` is compared with the estimate
//! (docs/design/solver.md, "How far from converged").

mod common;

use common::clamped_beam;
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation, SolverMethod, SolverSpec, State, StepStats};

const DT: f64 = 0.01;

/// The cloth strip: 0.3 x 0.05 m, 30 x 5 quads, 0.2 kg/m^2,
/// `triangle-strain` 1e5 N/m, `bending` 0.5 N m, clamped along its x = 0
/// short edge.
fn strip() -> Model {
    let mesh = generators::cloth([0.3, 0.05], [30, 5]).unwrap();
    let masses = mesh.lumped_masses(0.2).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_triangle_strain(body, 1e5, None).unwrap();
    model.add_bending(body, 0.5).unwrap();
    let clamp: Vec<usize> = (0..model.num_vertices())
        .filter(|&v| model.rest_positions()[v].x < 1e-9)
        .collect();
    model.fix_vertices(body, &clamp).unwrap();
    model
}

/// The solver tests' beam (1 x 0.2 x 0.2 m, 1e6 Pa, clamped at x = 0).
fn beam() -> Model {
    clamped_beam([10, 2, 2], [1.0, 0.2, 0.2], 7, 1e6).0
}

/// Undamped backward Euler (the builder's defaults) with `method`.
fn simulation(model: Model, method: SolverMethod, tolerance: f64, iterations: usize) -> Simulation {
    let settings = Settings {
        dt: DT,
        iterations,
        tolerance,
        ..Settings::default()
    };
    let spec = SolverSpec {
        method,
        ..SolverSpec::default()
    };
    Simulation::builder(model)
        .settings(settings)
        .solver(spec)
        .build()
        .unwrap()
}

/// One step of `sim` and the same step solved to convergence by
/// `reference` from the same state: the step's statistics and its true
/// relative error `|x - x*|_M / |y - x*|_M`.
fn step_against_reference(sim: &mut Simulation, reference: &mut Simulation) -> (StepStats, f64) {
    let start: State = sim.state().clone();
    let gravity = sim.settings().gravity;
    // Backward Euler's inertial prediction, no damping: y = x + h v + h^2 g.
    let y: Vec<Point> = (start.positions.iter().zip(&start.velocities))
        .map(|(x, v)| x + v * DT + gravity * (DT * DT))
        .collect();
    reference.set_state(start).unwrap();
    reference.step().unwrap();
    let stats = sim.step().unwrap();
    let exact = &reference.state().positions;
    let model = sim.model();
    let truth = model.mass_distance(&sim.state().positions, exact) / model.mass_distance(&y, exact);
    (stats, truth)
}

/// Per step: (estimated, true) relative error of `steps` steps of `method`
/// at 10 iterations, undamped backward Euler.
fn estimates_and_truth(
    model: fn() -> Model,
    method: SolverMethod,
    steps: usize,
) -> Vec<(f64, f64)> {
    let mut sim = simulation(model(), method, 0.0, 10);
    let mut reference = simulation(model(), SolverMethod::Newton, 1e-12, 100);
    (0..steps)
        .map(|_| {
            let (stats, truth) = step_against_reference(&mut sim, &mut reference);
            (stats.estimated_error, truth)
        })
        .collect()
}

/// How often and by how much the estimate falls below the truth, over the
/// steps whose true error is above 1e-6 (below, Newton's steps sit at the
/// reference's own round-off): (steps counted, steps below half the true
/// error, smallest and largest ratio estimate / truth).
fn under_reporting(pairs: &[(f64, f64)]) -> (usize, usize, f64, f64) {
    let counted: Vec<f64> = pairs
        .iter()
        .filter(|(_, t)| *t > 1e-6)
        .map(|(e, t)| e / t)
        .collect();
    let below = counted.iter().filter(|r| **r < 0.5).count();
    let worst = counted.iter().copied().fold(f64::INFINITY, f64::min);
    let most = counted.iter().copied().fold(0.0, f64::max);
    (counted.len(), below, worst, most)
}

/// A named scene's model.
type Scene = (&'static str, fn() -> Model);

fn scenes() -> [Scene; 2] {
    [("beam", beam), ("strip", strip)]
}

/// At 10 iterations a step, 30 steps of backward Euler: plain local-global
/// PD on the beam and the cloth strip, Chebyshev and L-BFGS on the beam
/// never report below half the true error, and plain PD not above 4 times
/// it (a useful figure, not a blanket bound).
///
/// Why half holds for plain PD: the error left after iteration `K` is the
/// sum of the changes still to come; the estimate's rate `sqrt(r_max)`
/// halves the observed distance of the largest recent ratio to 1, which
/// covers the slow modes the observed ratio under-weighs as long as the
/// asymptotic rate's distance to 1 is at least half the observed one
/// (measured: the rate that gives the true error lay at 0.85 to 0.93 where
/// the ratios were 0.70 to 0.86; step/estimate.rs). Why 4: a sequence that
/// is already geometric is over-reported by `(1 + rho) / rho`, at most
/// about 2.4 for ratios above 0.5, and the margin to 4 covers the steps
/// where the ratios fall (measured largest: 1.75 on the beam, 0.97 on the
/// strip). The test can fail: the truth is far from zero (asserted), and
/// Anderson's estimate, whose ratios are mostly its accelerated rate, reports below
/// half on most beam steps (the measured test below).
#[test]
fn the_estimate_is_within_half_and_four_times_the_true_error() {
    let checked = [
        ("beam", SolverMethod::LocalGlobal),
        ("strip", SolverMethod::LocalGlobal),
        ("beam", SolverMethod::Chebyshev),
        ("beam", SolverMethod::Lbfgs),
    ];
    for (name, model) in scenes() {
        for (_, method) in checked.iter().filter(|(n, _)| *n == name) {
            let pairs = estimates_and_truth(model, *method, 30);
            let (counted, below, worst, most) = under_reporting(&pairs);
            let largest = pairs.iter().map(|p| p.1).fold(0.0, f64::max);
            eprintln!(
                "{name} {method:?}: {below} of {counted} below half, ratio {worst:.3} to {most:.3}, largest true {largest:.3e}"
            );
            assert!(
                largest > 1e-3,
                "{name}: the step is already converged ({largest:e})"
            );
            assert_eq!(counted, 30, "{name} {method:?}: {pairs:?}");
            assert_eq!(below, 0, "{name} {method:?}: {pairs:?}");
            if *method == SolverMethod::LocalGlobal {
                assert!(most <= 4.0, "{name}: over-reports by {most}: {pairs:?}");
            }
        }
    }
}

/// Every method on both scenes: the measured under-reporting (printed with
/// `--nocapture`; docs/design/solver.md, "How far from converged", has the
/// table). Each method's estimate is in [0, 1] on every step, and above
/// 0.1 wherever the true error is above 0.5.
#[test]
fn the_estimate_of_every_method_is_measured() {
    for (name, model) in scenes() {
        for method in SolverMethod::ALL {
            let pairs = estimates_and_truth(model, method, 30);
            assert!(
                pairs.iter().all(|(e, _)| (0.0..=1.0).contains(e)),
                "{name} {method:?}: {pairs:?}"
            );
            // Where a step is far from converged (more than half its
            // correction left), every method's estimate is above the
            // warning threshold of `pd run` (0.1).
            assert!(
                pairs.iter().all(|(e, t)| *t <= 0.5 || *e > 0.1),
                "{name} {method:?}: {pairs:?}"
            );
            let (counted, below, worst, most) = under_reporting(&pairs);
            let largest = pairs.iter().map(|p| p.1).fold(0.0, f64::max);
            eprintln!(
                "{name} {method:?}: {below} of {counted} below half, ratio {worst:.3} to {most:.3}, largest true {largest:.3e}"
            );
        }
    }
}

/// `Settings::accuracy`: each step of the beam stops once its estimate is
/// at most the target, and its true error is then at most twice the target
/// (the estimate reports at least half the truth for plain PD, the test
/// above), within the iteration cap. (Plain PD on the strip does not reach
/// 1% within 10,000 iterations: its estimate then says 0.027, and the step
/// reports `converged: false`.)
#[test]
fn an_accuracy_target_bounds_the_true_error() {
    let target = 1e-3;
    let settings = Settings {
        dt: DT,
        iterations: 10_000,
        accuracy: target,
        ..Settings::default()
    };
    let mut sim = Simulation::builder(beam())
        .settings(settings)
        .build()
        .unwrap();
    let mut reference = simulation(beam(), SolverMethod::Newton, 1e-12, 100);
    for _ in 0..10 {
        let (stats, truth) = step_against_reference(&mut sim, &mut reference);
        assert!(
            stats.converged && stats.estimated_error <= target,
            "{stats:?}"
        );
        assert!(
            stats.iterations > 10 && stats.iterations < 10_000,
            "{stats:?}"
        );
        assert!(truth <= 2.0 * target, "true error {truth}: {stats:?}");
    }
}

/// A target outside (0, 1), or with a tolerance, is refused naming
/// `accuracy`.
#[test]
fn bad_accuracy_targets_are_refused() {
    for (accuracy, tolerance) in [(-0.1, 0.0), (1.0, 0.0), (f64::NAN, 0.0), (0.01, 1e-6)] {
        let settings = Settings {
            accuracy,
            tolerance,
            ..Settings::default()
        };
        match settings.validate() {
            Err(pd_solver::SolverError::InvalidSetting { field, .. }) => {
                assert_eq!(field, "accuracy")
            }
            other => panic!("{accuracy} {tolerance}: {other:?}"),
        }
    }
}
