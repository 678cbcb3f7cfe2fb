//! `cargo xtask stability --only contact`: the contact axis of the stability
//! map, on its own, written to `docs/reports/stability-contact.md`.
//!
//! Same rule as the map (`stability.rs`): a run completes (finite state and
//! energies, total energy never above the divergence bound) or stops with
//! `SolverError::Diverged`; a run that completes exploded, a panic, a
//! non-finite value after an `Ok` step or another error is a bug and fails
//! the command. A completed run is "completed sane" unless it created
//! energy where it should only dissipate (the run summary's energy
//! warning, `stability::energy_rule`): then it counts as "energy created".
//! Contact adds one more rule: no free vertex ends a completed step more
//! than 1 mm behind the floor (tunnelling; the final projection puts every
//! contact vertex on it).
//!
//! Matrix: a 0.2 m cube (2 cells across, 48 tets) dropped on a floor, alone
//! ("drop") or onto a second cube resting on the floor with `bodies = true`
//! ("stack"), the same with `self = true` as well ("stack-self": the crushed
//! soft cubes fold onto themselves); drop height 0.01, 1, 100 m; tet-strain stiffness 1e3, 1e6,
//! 1e9 Pa; friction 0, 0.5, 10; time step 1e-4, 1e-2, 0.1 s; the three
//! integrators; no damping and Laplacian damping (0.01 s). 1000 kg/m^3, 20
//! iterations, thickness 1 mm, 100 steps. Runs in the dev profile (opt-level
//! 2): no release build needed.

use std::fmt::Write as _;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use pd_integrators::registry;
use pd_io::recorder::{AccuracyWatch, EnergyCreated, MetricsRow};
use pd_io::scene::{Scene, Syntax};
use pd_solver::SolverError;

const STEPS: usize = 100;
const HEIGHTS: [f64; 3] = [0.01, 1.0, 100.0];
const STIFFNESS: [f64; 3] = [1e3, 1e6, 1e9];
const FRICTION: [f64; 3] = [0.0, 0.5, 10.0];
const DT: [f64; 3] = [1e-4, 1e-2, 0.1];
const DAMPING: [&str; 2] = ["none", "laplacian"];
const BODIES: [&str; 3] = ["drop", "stack", "stack-self"];
/// How far behind the floor a vertex may end a step, m (the thickness is
/// 1 mm and the projection leaves round-off only; 1 mm is a tunnelled
/// vertex, not round-off).
const BEHIND: f64 = 1e-3;

#[derive(Debug, Clone, Copy)]
struct Case {
    body: usize,
    height: f64,
    stiffness: f64,
    friction: f64,
    dt: f64,
    integrator: usize,
    damping: usize,
}

enum Ending {
    /// `energy`: the energy the run created, as its summary's accuracy
    /// watch measures it (`None` where the setting need not dissipate);
    /// `crossed`: whether the watch's figure was above the warning at the
    /// end of some step (what a check that stopped runs mid-run would
    /// have read).
    Completed {
        contacts: usize,
        penetration: f64,
        energy: Option<EnergyCreated>,
        crossed: bool,
    },
    Diverged,
    Bug(String),
}

impl Ending {
    /// Whether the run completed but created energy where it should only
    /// dissipate: the run summary's energy warning.
    fn created_energy(&self) -> bool {
        matches!(self, Self::Completed { energy: Some(e), .. } if e.warns())
    }
}

fn cases() -> Vec<Case> {
    let mut cases = Vec::new();
    for body in 0..BODIES.len() {
        for &height in &HEIGHTS {
            for &stiffness in &STIFFNESS {
                for &friction in &FRICTION {
                    for &dt in &DT {
                        for integrator in 0..registry::entries().len() {
                            for damping in 0..DAMPING.len() {
                                cases.push(Case {
                                    body,
                                    height,
                                    stiffness,
                                    friction,
                                    dt,
                                    integrator,
                                    damping,
                                });
                            }
                        }
                    }
                }
            }
        }
    }
    cases
}

fn scene_text(case: &Case) -> String {
    let damping = match DAMPING[case.damping] {
        "none" => "model = \"none\"".to_string(),
        _ => "model = \"laplacian\"\nstiffness = 0.01".to_string(),
    };
    let cube = |translate: [f64; 3]| {
        format!(
            "[[body]]\nmesh = {{ generator = \"box\", size = [0.2, 0.2, 0.2], cells = [2, 2, 2] }}\n\
             density = 1000.0\nconstraints = [ {{ kind = \"tet-strain\", stiffness = {:e} }} ]\n\
             translate = [{:?}, {:?}, {:?}]\n",
            case.stiffness, translate[0], translate[1], translate[2]
        )
    };
    let (bodies, contact) = if BODIES[case.body].starts_with("stack") {
        let bottom = cube([-0.1, 0.001, -0.1]);
        let top = cube([-0.07, 0.201 + case.height, -0.12]);
        let self_contact = if BODIES[case.body] == "stack-self" {
            "self = true\n"
        } else {
            ""
        };
        (
            format!("{bottom}\n{top}"),
            format!(
                "bodies = true\n{self_contact}friction = {:?}\n",
                case.friction
            ),
        )
    } else {
        (cube([-0.1, 0.001 + case.height, -0.1]), String::new())
    };
    format!(
        "[simulation]\ndt = {:?}\nsteps = {STEPS}\ngravity = [0.0, -9.81, 0.0]\n\
         integrator = \"{}\"\niterations = 20\nthreads = 1\n\n[damping]\n{damping}\n\n\
         [[collider]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\n\
         friction = {:?}\n\n[contact]\nthickness = 0.001\n{contact}\n{bodies}",
        case.dt,
        registry::entries()[case.integrator].name,
        case.friction
    )
}

fn run_case(case: &Case) -> Ending {
    let outcome = catch_unwind(AssertUnwindSafe(|| -> Result<Ending, String> {
        let text = scene_text(case);
        let scene = Scene::parse(&text, Syntax::Toml, Path::new("contact-stability.toml"))
            .map_err(|e| e.to_string())?;
        let mut sim = scene.build().map_err(|e| e.to_string())?;
        let initial = sim.energies().total();
        let scale = sim.energy_scale();
        let bound = sim.settings().divergence_energy_factor;
        let mut last = (0, 0.0);
        // The rows a run records, for the energy created (row 0: the start).
        let mut watch = AccuracyWatch::default();
        watch.observe(&MetricsRow::of(&sim, None));
        let mut crossed = false;
        for _ in 0..STEPS {
            match sim.step() {
                Ok(stats) => {
                    let row = MetricsRow::of(&sim, Some(&stats));
                    let energy = row.total;
                    let state = sim.state();
                    let finite = (state.positions.iter().chain(&state.velocities))
                        .all(|p| p.iter().all(|c| c.is_finite()));
                    if !finite || !energy.is_finite() {
                        return Ok(Ending::Bug(format!(
                            "non-finite output after step {}",
                            sim.steps()
                        )));
                    }
                    if (energy - initial) / scale > bound {
                        return Ok(Ending::Bug(format!(
                            "completed step {} exploded: energy {energy:.3e} J",
                            sim.steps()
                        )));
                    }
                    let low = state.positions.iter().map(|p| p.y).fold(f64::MAX, f64::min);
                    if low < -BEHIND {
                        return Ok(Ending::Bug(format!(
                            "step {}: a vertex at y = {low:.3e} m, behind the floor",
                            sim.steps()
                        )));
                    }
                    watch.observe(&row);
                    crossed |= watch.energy_created(&sim).is_some_and(|e| e.warns());
                    last = (stats.contacts, stats.penetration);
                }
                Err(SolverError::Diverged { .. }) => return Ok(Ending::Diverged),
                Err(e) => return Ok(Ending::Bug(e.to_string())),
            }
        }
        Ok(Ending::Completed {
            contacts: last.0,
            penetration: last.1,
            energy: watch.energy_created(&sim),
            crossed,
        })
    }));
    match outcome {
        Ok(Ok(ending)) => ending,
        Ok(Err(setup)) => Ending::Bug(format!("setup failed: {setup}")),
        Err(_) => Ending::Bug("panic".into()),
    }
}

/// Runs the contact matrix on every core and writes
/// `docs/reports/stability-contact.md`.
pub fn run(root: &Path) -> Result<PathBuf, String> {
    let cases = cases();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    eprintln!("{} contact runs on {threads} threads", cases.len());
    let started = std::time::Instant::now();
    let next = Mutex::new(0usize);
    let results = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    let index = {
                        let mut next = next.lock().expect("no thread panics holding it");
                        *next += 1;
                        *next - 1
                    };
                    let Some(case) = cases.get(index) else { break };
                    let ending = run_case(case);
                    (results.lock().expect("no thread panics holding it")).push((index, ending));
                }
            });
        }
    });
    let mut results = results.into_inner().expect("threads joined");
    results.sort_by_key(|(i, _)| *i);
    let seconds = started.elapsed().as_secs_f64();
    let text = report(&cases, &results, seconds, threads);
    let path = root.join("docs/reports/stability-contact.md");
    std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    let bugs = results
        .iter()
        .filter(|(_, e)| matches!(e, Ending::Bug(_)))
        .count();
    if bugs > 0 {
        return Err(format!("{bugs} bugs; see {}", path.display()));
    }
    Ok(path)
}

/// Counts per value of one axis: completed sane, energy created, stopped,
/// bugs.
fn axis<T: std::fmt::Debug>(
    out: &mut String,
    name: &str,
    values: &[T],
    of: impl Fn(&Case) -> usize,
    cases: &[Case],
    results: &[(usize, Ending)],
) {
    let _ = writeln!(
        out,
        "\n| {name} | completed sane | energy created | stopped (diverged) | bugs | deepest left at the end (m) |\n|---|---|---|---|---|---|"
    );
    for (k, value) in values.iter().enumerate() {
        let (mut sane, mut created, mut stopped, mut bugs, mut deepest) = (0, 0, 0, 0, 0.0_f64);
        for (i, ending) in results {
            if of(&cases[*i]) != k {
                continue;
            }
            match ending {
                Ending::Completed { penetration, .. } => {
                    if ending.created_energy() {
                        created += 1;
                    } else {
                        sane += 1;
                    }
                    deepest = deepest.max(*penetration);
                }
                Ending::Diverged => stopped += 1,
                Ending::Bug(_) => bugs += 1,
            }
        }
        let _ = writeln!(
            out,
            "| {value:?} | {sane} | {created} | {stopped} | {bugs} | {deepest:.1e} |"
        );
    }
}

fn report(cases: &[Case], results: &[(usize, Ending)], seconds: f64, threads: usize) -> String {
    let mut out = String::new();
    let integrators = registry::names();
    let completed = results
        .iter()
        .filter(|(_, e)| matches!(e, Ending::Completed { .. }))
        .count();
    let resting = results
        .iter()
        .filter(|(_, e)| matches!(e, Ending::Completed { contacts, .. } if *contacts > 0))
        .count();
    let stopped = results
        .iter()
        .filter(|(_, e)| matches!(e, Ending::Diverged))
        .count();
    let created = results.iter().filter(|(_, e)| e.created_energy()).count();
    // Runs a check at every step would have stopped that end below the
    // warning: the transients the end-of-run figure does not confirm.
    let transient = results
        .iter()
        .filter(|(_, e)| {
            matches!(e, Ending::Completed { crossed: true, .. }) && !e.created_energy()
        })
        .count();
    let machine = crate::bench_report::machine();
    let _ = writeln!(
        out,
        "# Stability with contact\n\n\
         Generated by `cargo xtask stability --only contact` ({} runs of {STEPS} steps, \
         {seconds:.0} s on {threads} threads, CPU {cpu} with {cores} logical cores, {profile} \
         profile; the time is not a benchmark). Do not edit by hand: the matrix and the rules \
         are in `xtask/src/stability_contact.rs`.\n\n\
         The rule of `docs/reports/stability.md`: every run completes (finite state and energies, \
         total energy never above the divergence bound) or stops with the solver's divergence \
         error; one more for contact: no vertex ends a completed step more than 1 mm behind the \
         floor. Anything else is a bug and fails the command.\n\n\
         {rule}\n\n\
         Matrix: a 0.2 m cube (2 cells across) dropped on a floor plane, alone (drop) or onto a \
         second one resting on the floor with `bodies = true` (stack), and the same with \
         `self = true` as well (stack-self); drop height {HEIGHTS:?} m; \
         tet-strain stiffness {STIFFNESS:?} Pa; friction (floor and between bodies) \
         {FRICTION:?}; time step {DT:?} s; {integrators:?}; damping {DAMPING:?} (Laplacian \
         0.01 s); 1000 kg/m^3, 20 iterations, thickness 1 mm.\n\n\
         **{} completed sane**, **{created} energy created** ({completed} completed, {resting} \
         with contacts active at the end), **{stopped} stopped by the divergence error**, \
         **{} bugs**. \"Deepest left\" is the last step's `penetration` (what the iterations \
         left below the thickness, before the projection) over the completed runs.\n\n\
         {transient} completed runs created more than the warning's share of energy at the end \
         of some step but not at the end of the run: the largest kinetic plus elastic energy \
         grew after, so a check that stopped a run at the first such step would have stopped \
         them, and the energy-created heading does not count them.",
        cases.len(),
        completed - created,
        results.len() - completed - stopped,
        profile = crate::stability::profile_name(),
        cpu = machine.cpu,
        cores = machine.logical_cores,
        rule = crate::stability::energy_rule(),
    );
    axis(&mut out, "body", &BODIES, |c| c.body, cases, results);
    let index = |values: &[f64], v: f64| values.iter().position(|x| *x == v).unwrap_or(0);
    axis(
        &mut out,
        "drop height (m)",
        &HEIGHTS,
        |c| index(&HEIGHTS, c.height),
        cases,
        results,
    );
    axis(
        &mut out,
        "stiffness (Pa)",
        &STIFFNESS,
        |c| index(&STIFFNESS, c.stiffness),
        cases,
        results,
    );
    axis(
        &mut out,
        "friction",
        &FRICTION,
        |c| index(&FRICTION, c.friction),
        cases,
        results,
    );
    axis(
        &mut out,
        "time step (s)",
        &DT,
        |c| index(&DT, c.dt),
        cases,
        results,
    );
    axis(
        &mut out,
        "integrator",
        &integrators,
        |c| c.integrator,
        cases,
        results,
    );
    axis(&mut out, "damping", &DAMPING, |c| c.damping, cases, results);
    let bugs: Vec<_> = results
        .iter()
        .filter_map(|(i, e)| match e {
            Ending::Bug(message) => Some((cases[*i], message)),
            _ => None,
        })
        .collect();
    if !bugs.is_empty() {
        let _ = writeln!(out, "\n## Bugs\n");
        for (case, message) in bugs {
            let _ = writeln!(out, "- {case:?}: {message}");
        }
    }
    out
}
