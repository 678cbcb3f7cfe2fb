//! The three runs of the predictor's stability subset
//! (`docs/reports/stability-methods-predictor-linear-implicit-midpoint.md`) where
//! plain local-global PD started at `y` completed and plain local-global PD
//! started at the `linear` predictor was stopped by the divergence check:
//! the stability map's clamped beam (1 x 0.25 x 0.25 m, 2 x 1 x 1 cells),
//! implicit midpoint, `dt = 0.1` s, 10 iterations a step, from rest, 100
//! steps (docs/design/solver.md, "A better start: predictors").

use pd_io::scene::{Scene, Syntax};
use pd_solver::SolverError;

/// The stability map's beam (`xtask/src/stability.rs`, `BEAM`) with the
/// method axis' parameters, started at `predictor`.
fn simulation(predictor: &str, stiffness: f64, density: f64, drag: bool) -> pd_solver::Simulation {
    let damping = if drag {
        "[damping]\nmodel = \"ether-drag\"\nrate = 1000.0\n"
    } else {
        ""
    };
    let text = format!(
        "[simulation]\ndt = 0.1\nsteps = 100\nintegrator = \"implicit-midpoint\"\n\
         iterations = 10\nthreads = 1\n\n[solver]\nmethod = \"local-global\"\n\
         predictor = \"{predictor}\"\n\n{damping}\n\
         [[body]]\nmesh = {{ generator = \"box\", size = [1.0, 0.25, 0.25], cells = [2, 1, 1] }}\n\
         density = {density:e}\nconstraints = [ {{ kind = \"tet-strain\", stiffness = {stiffness:e} }} ]\n\
         fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] }} }}\n"
    );
    let scene = Scene::parse(&text, Syntax::Toml, std::path::Path::new("case.toml")).unwrap();
    scene.build().unwrap()
}

/// Runs 100 steps; returns the total energy after each completed step (J)
/// and the step at which the divergence check stopped the run, if it did.
fn run(predictor: &str, (stiffness, density, drag): (f64, f64, bool)) -> (Vec<f64>, Option<usize>) {
    let mut sim = simulation(predictor, stiffness, density, drag);
    let mut energies = Vec::new();
    for _ in 0..100 {
        match sim.step() {
            Ok(_) => energies.push(sim.energies().total()),
            Err(SolverError::Diverged { step, .. }) => return (energies, Some(step)),
            Err(e) => panic!("{predictor}: {e}"),
        }
    }
    (energies, None)
}

/// (stiffness in Pa, density in kg/m^3, ether drag at 1000 1/s).
const CASES: [(f64, f64, bool); 3] = [(1e6, 1.0, false), (1e9, 1e5, false), (1e9, 1.0, true)];

/// Each case completes its 100 steps with the linear predictor, and its
/// total energy never rises above the larger of plain PD's (started at `y`)
/// highest value in the same case and the initial energy plus one energy
/// scale.
///
/// Before plain PD ran implicit midpoint's end-of-step check on predicted
/// steps (src/step/iteration.rs, src/step/ray.rs) the three runs stopped at
/// steps 17, 31 and 7, the energy growing with a period of two steps. The
/// bound is plain PD's own behaviour from `y` (the stability map's rule is
/// only "completes where plain PD completes"), with one energy scale of
/// room for an unconverged midpoint step's legitimate fluctuations, as in
/// `tests/method_divergence.rs`.
#[test]
fn plain_pd_from_the_linear_predictor_does_not_diverge_where_it_does_not_from_y() {
    for case in CASES {
        let (plain, stop) = run("inertial", case);
        assert_eq!(
            stop, None,
            "{case:?}: the control, plain PD from y, completes"
        );
        let (stiffness, density, drag) = case;
        let sim = simulation("inertial", stiffness, density, drag);
        let bound = plain
            .iter()
            .copied()
            .fold(sim.energies().total() + sim.energy_scale(), f64::max);
        let (energies, stop) = run("linear", case);
        assert_eq!(stop, None, "{case:?}: stopped by the divergence check");
        let highest = energies.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(
            highest <= bound,
            "{case:?}: energy up to {highest:e} J above {bound:e} J"
        );
    }
}
