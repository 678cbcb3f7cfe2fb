//! The cost of the modal analysis against one factorisation, on the
//! 19 440-dof clamped beam (`80 x 8 x 8` cells) of docs/damping.md. Ignored:
//! a timing, not a check (run it with `--ignored --nocapture` on a quiet
//! machine; the numbers recorded in docs/damping.md say how loaded theirs
//! was).

mod beam_modes;

use pd_damping::NoDamping;
use pd_integrators::ImplicitMidpoint;
use pd_solver::{Settings, Simulation, modes};

#[test]
#[ignore = "timing: run by hand"]
fn modes_cost_against_one_factorisation() {
    let model = beam_modes::beam([1.0, 0.1, 0.1], [80, 8, 8]);
    let analysis = modes::elastic_modes(&model, 6).unwrap();
    let sim = Simulation::new(
        model,
        Box::new(ImplicitMidpoint),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap();
    let pd_factor = sim.setup_stats().factor_seconds;
    println!(
        "{} dofs, {}: {} iterations, analysis {:.3} s of which symbolic + numeric \
         factorisation of the 3n system {:.3} s; the PD scalar factorisation {:.3} s; \
         frequencies {:?} Hz",
        analysis.dofs,
        analysis.method,
        analysis.iterations,
        analysis.seconds,
        analysis.factor_seconds,
        pd_factor,
        analysis
            .modes
            .iter()
            .map(|m| m.frequency_hz())
            .collect::<Vec<_>>()
    );
}
