//! The cost of the modal analysis against one factorisation, on the
//! 19 440-dof clamped beam (`80 x 8 x 8` cells) of docs/design/damping.md, phase by
//! phase, for block Lanczos (the default) and subspace iteration. Ignored:
//! a timing, not a check (run it with `--ignored --nocapture` on a quiet
//! machine; the numbers recorded in docs/design/damping.md say how loaded theirs
//! was). Each method runs on one thread, so that the thread's CPU time
//! (`/proc/thread-self/schedstat`) covers the whole analysis: less sensitive
//! to other processes than the wall clock. `PD_MODES_BEAM=40,4,4` picks
//! another mesh and `PD_MODES_METHOD=lanczos` (or `subspace`) one method
//! alone (for `valgrind --tool=callgrind` instruction counts).

mod common;

use pd_damping::NoDamping;
use pd_integrators::ImplicitMidpoint;
use pd_modes::Method;
use pd_solver::{Settings, Simulation};

/// CPU seconds the calling thread has run, if the kernel says.
fn thread_cpu_seconds() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let nanoseconds: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(nanoseconds * 1e-9)
}

#[test]
#[ignore = "timing: run by hand"]
fn modes_cost_against_one_factorisation() {
    let cells: Vec<usize> = std::env::var("PD_MODES_BEAM")
        .ok()
        .map(|s| s.split(',').map(|c| c.trim().parse().unwrap()).collect())
        .unwrap_or_else(|| vec![80, 8, 8]);
    let model = common::beam([1.0, 0.1, 0.1], [cells[0], cells[1], cells[2]]);
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let methods: &[Method] = match std::env::var("PD_MODES_METHOD").as_deref() {
        Ok("lanczos") => &[Method::Lanczos],
        Ok("subspace") => &[Method::Subspace],
        _ => &[Method::Lanczos, Method::Subspace],
    };
    for &method in methods {
        let (analysis, cpu) = one_thread.install(|| {
            let before = thread_cpu_seconds();
            let analysis = pd_modes::elastic_modes_by(&model, 6, method).unwrap();
            let cpu = thread_cpu_seconds().zip(before).map(|(b, a)| b - a);
            (analysis, cpu)
        });
        let p = analysis.phases;
        println!(
            "{} dofs, {} on 1 thread: {} iterations, {} solved columns, {} restarts; \
             analysis {:.3} s wall, {} CPU; phases (wall, s): assembly {:.3}, rigid basis \
             {:.3}, factorisation {:.3}, solves {:.3}, orthonormalisation {:.3}, \
             Rayleigh-Ritz {:.3}, shapes and quotients {:.3}; analysis / factorisation {:.2}; \
             frequencies {:?} Hz",
            analysis.dofs,
            analysis.method,
            analysis.iterations,
            analysis.solved_columns,
            analysis.restarts,
            analysis.seconds,
            cpu.map_or("?".into(), |c| format!("{c:.3} s")),
            p.assembly,
            p.rigid_basis,
            p.factorisation,
            p.solves,
            p.orthonormalisation,
            p.rayleigh_ritz,
            p.quotients,
            analysis.seconds / p.factorisation,
            analysis
                .modes
                .iter()
                .map(|m| m.frequency_hz())
                .collect::<Vec<_>>()
        );
    }
    if std::env::var("PD_MODES_METHOD").is_ok() {
        return;
    }
    let analysis = pd_modes::elastic_modes(&model, 6).unwrap();
    let sim = Simulation::new(
        model,
        Box::new(ImplicitMidpoint),
        Box::new(NoDamping),
        Settings::default(),
    )
    .unwrap();
    println!(
        "default ({}, both threads): analysis {:.3} s wall, of which symbolic + numeric \
         factorisation of the 3n system {:.3} s; the PD scalar factorisation {:.3} s",
        analysis.method,
        analysis.seconds,
        analysis.factor_seconds,
        sim.setup_stats().factor_seconds,
    );
}
