//! The three runs of the stability map's method axis
//! (`docs/reports/stability-methods.md`) where plain local-global PD completed and an
//! accelerated method was stopped by the divergence check: the stability
//! map's clamped beam (1 x 0.25 x 0.25 m, 2 x 1 x 1 cells, density 1
//! kg/m^3), implicit midpoint, `dt = 0.1` s, 10 iterations a step, from
//! rest, 100 steps.

use pd_io::scene::{Scene, Syntax};
use pd_solver::{SolverError, SolverMethod};

/// The stability map's beam (`xtask/src/stability.rs`, `BEAM`) with the
/// method axis' parameters.
fn simulation(method: SolverMethod, stiffness: f64, drag: bool) -> pd_solver::Simulation {
    let damping = if drag {
        "[damping]\nmodel = \"ether-drag\"\nrate = 1000.0\n"
    } else {
        ""
    };
    let text = format!(
        "[simulation]\ndt = 0.1\nsteps = 100\nintegrator = \"implicit-midpoint\"\n\
         iterations = 10\nthreads = 1\n\n[solver]\nmethod = \"{}\"\n\n{damping}\n\
         [[body]]\nmesh = {{ generator = \"box\", size = [1.0, 0.25, 0.25], cells = [2, 1, 1] }}\n\
         density = 1.0\nconstraints = [ {{ kind = \"tet-strain\", stiffness = {stiffness:e} }} ]\n\
         fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] }} }}\n",
        method.name()
    );
    let scene = Scene::parse(&text, Syntax::Toml, std::path::Path::new("case.toml")).unwrap();
    scene.build().unwrap()
}

/// Runs 100 steps; returns the total energy after each completed step (J)
/// and the step at which the divergence check stopped the run, if it did.
fn run(method: SolverMethod, stiffness: f64, drag: bool) -> (Vec<f64>, Option<usize>) {
    let mut sim = simulation(method, stiffness, drag);
    let mut energies = Vec::new();
    for _ in 0..100 {
        match sim.step() {
            Ok(_) => energies.push(sim.energies().total()),
            Err(SolverError::Diverged { step, .. }) => return (energies, Some(step)),
            Err(e) => panic!("{method:?}: {e}"),
        }
    }
    (energies, None)
}

const CASES: [(SolverMethod, f64, bool); 3] = [
    (SolverMethod::Anderson, 1e6, false),
    (SolverMethod::Anderson, 1e9, true),
    (SolverMethod::Lbfgs, 1e9, true),
];

/// Each case completes its 100 steps, and its total energy never rises
/// above the larger of plain PD's highest value in the same case and the
/// initial energy plus one energy scale.
///
/// Before the end-of-step check (src/step/ray.rs) the three runs stopped at
/// steps 82, 81 and 38 with energies growing from about 1 J to 650 J, while
/// plain PD stayed between 0.08 and 1.1 J (stiffness 1e6 Pa) and at 279 J
/// (1e9 Pa with drag). With it, both methods keep the initial energy
/// 0.0766 J to four digits, as Newton's method does; the bound is plain
/// PD's own behaviour, so it leaves room for round-off and for legitimate
/// fluctuations of an unconverged midpoint step.
#[test]
fn accelerated_methods_do_not_diverge_where_plain_pd_does_not() {
    for (method, stiffness, drag) in CASES {
        let (plain, stop) = run(SolverMethod::LocalGlobal, stiffness, drag);
        assert_eq!(stop, None, "the control: plain PD completes");
        let sim = simulation(SolverMethod::LocalGlobal, stiffness, drag);
        let initial = sim.energies().total();
        let bound = plain
            .iter()
            .copied()
            .fold(initial + sim.energy_scale(), f64::max);
        let (energies, stop) = run(method, stiffness, drag);
        assert_eq!(
            stop, None,
            "{method:?}, {stiffness:e} Pa, drag {drag}: stopped by the divergence check"
        );
        let highest = energies.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(
            highest <= bound,
            "{method:?}, {stiffness:e} Pa, drag {drag}: energy up to {highest:e} J above {bound:e} J"
        );
    }
}

/// Prints each case's energy trajectory for every method
/// (`cargo test -p pd-solver --test method_divergence -- --ignored --nocapture`).
#[test]
#[ignore = "a probe: prints trajectories"]
fn print_trajectories() {
    for (stiffness, drag) in [(1e6, false), (1e9, true)] {
        for method in SolverMethod::ALL {
            let (energies, stop) = run(method, stiffness, drag);
            let samples: Vec<String> = energies
                .iter()
                .enumerate()
                .filter(|(i, _)| i % 5 == 4 || *i < 5)
                .map(|(i, e)| format!("{}:{e:.3e}", i + 1))
                .collect();
            eprintln!(
                "stiffness {stiffness:e} drag {drag} {method:?}: stopped {stop:?}\n  {}",
                samples.join(" ")
            );
        }
    }
}
