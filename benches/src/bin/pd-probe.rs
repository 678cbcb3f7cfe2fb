//! `pd-probe`: one measurement per process, one JSON line on stdout.
//! `cargo xtask bench-report` and `cargo xtask cpp-compare` build it in
//! release mode and run it once per measurement, so that each run's peak
//! memory (`VmHWM`) is its own.
//!
//! ```text
//! pd-probe step     [beam options] [--mesh BASE] [--model M] [--integrator be|im] [--steps N]
//! pd-probe overhead [beam options] [--integrator be|im] [--rounds R] [--warmup W]
//! pd-probe phases   [beam options] [--mesh BASE] [--model M] [--reps R] [--evict-mib M] [--idle-us U] [--parts P]
//! pd-probe accuracy [beam options] [--integrator be|im] [--time T] [--iters-list 1,2,...]
//! pd-probe bandwidth [--mib M] [--reps R] [--threads T]
//! pd-probe cache-scaling [--mib M] [--reps R]
//! pd-probe methods  [beam options] [--mesh BASE] [--integrator be|im|bdf2] [--model M] [--steps N] [--budgets 1,2,...]
//!                   [--methods local-global,anderson,...] [--window W] [--start S] [--cheb-rho R|auto]
//!                   [--predicted anderson,lbfgs:linear,...]   (those methods again with a predictor, default extrapolated)
//! pd-probe accuracy-target --scene beam|strip|mesh|contact-stack [--cells NX,NY,NZ] [--mesh BASE]
//!                   [--targets 0.01,0.001] [--warmup W] [--steps N]
//! beam options: --cells NX,NY,NZ --iters K --threads T --dt H --stiffness PA --soft-clamp
//! ```
//!
//! `step` and `phases` take `--cloth NX,NZ [--bending D] [--limits MIN,MAX]`
//! instead of a beam or mesh: the cloth sheet of `pd_benches::Sheet` with
//! that many cells (triangle strain only, or with bending of rigidity `D`
//! in N m; with stretch limits `[MIN, MAX]` on every triangle), stepped
//! with the beam options' `--iters`, `--threads` and `--dt` (undamped,
//! backward Euler); the output then also has `n_triangles`.

use std::process::ExitCode;
use std::time::Instant;

use pd_benches::schema::{
    Accuracy, AccuracyRow, Bandwidth, CacheScaling, Overhead, OverheadModel, Phases, Step,
};
use pd_benches::{Beam, Clamp, Options, Sheet, damping_models, peak_memory_bytes};
use pd_damping::registry::UNDAMPED;
use pd_io::stats::median;
use pd_mesh::Point;
use pd_solver::Simulation;
use serde_json::Value;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(value) => {
            println!("{value}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("pd-probe: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The options of the beam and of the cloth sheet a probe runs.
trait ProbeOptions {
    /// The beam of `--cells`, `--iters`, `--threads`, `--dt`, ...
    fn beam(&self) -> Result<Beam, String>;
    fn sheet(&self) -> Result<Option<Sheet>, String>;
}

impl ProbeOptions for Options<'_> {
    fn beam(&self) -> Result<Beam, String> {
        let defaults = Beam::default();
        let cells = self.list("--cells", &defaults.cells)?;
        let cells: [usize; 3] = cells
            .try_into()
            .map_err(|_| "--cells needs three counts NX,NY,NZ".to_string())?;
        Ok(Beam {
            cells,
            iterations: self.parse("--iters", defaults.iterations)?,
            threads: self.parse("--threads", defaults.threads)?,
            dt: self.parse("--dt", defaults.dt)?,
            stiffness: self.parse("--stiffness", defaults.stiffness)?,
            density: self.parse("--rho", defaults.density)?,
            clamp: if self.flag("--soft-clamp") {
                Clamp::SoftLikeReference
            } else {
                Clamp::Fixed
            },
            ..defaults
        })
    }

    /// The cloth sheet of `--cloth NX,NZ [--bending D] [--limits MIN,MAX]`,
    /// if asked for.
    fn sheet(&self) -> Result<Option<Sheet>, String> {
        if self.value("--cloth").is_none() {
            return Ok(None);
        }
        let cells = self.list("--cloth", &[])?;
        let cells: [usize; 2] = cells
            .try_into()
            .map_err(|_| "--cloth needs two counts NX,NZ".to_string())?;
        let bending = match self.value("--bending") {
            None => None,
            Some(_) => Some(self.parse("--bending", 0.0)?),
        };
        let limits = match self.value("--limits") {
            None => None,
            Some(text) => {
                let bounds: Vec<f64> = text
                    .split(',')
                    .map(|p| p.trim().parse())
                    .collect::<Result<_, _>>()
                    .map_err(|_| format!("--limits: cannot parse {text:?}"))?;
                let [min, max]: [f64; 2] = bounds
                    .try_into()
                    .map_err(|_| "--limits needs two numbers MIN,MAX".to_string())?;
                Some((min, max))
            }
        };
        Ok(Some(Sheet {
            cells,
            bending,
            limits,
            ..Sheet::default()
        }))
    }
}

/// The number of triangles of a cloth run, `None` for a beam or mesh run
/// (whose output has no `n_triangles`).
fn triangles(sim: &Simulation, cloth: bool) -> Option<usize> {
    cloth.then(|| sim.model().bodies()[0].mesh.triangles().len())
}

/// A probe's typed output as the JSON value printed.
fn output(value: &impl serde::Serialize) -> Result<Value, String> {
    serde_json::to_value(value).map_err(|e| e.to_string())
}

/// Every option some probe reads: anything else is a typo.
const KNOWN: &[&str] = &[
    "--bending",
    "--budgets",
    "--cells",
    "--cheb-rho",
    "--cloth",
    "--dt",
    "--evict-mib",
    "--factor-reps",
    "--idle-us",
    "--integrator",
    "--iters",
    "--iters-list",
    "--limits",
    "--mesh",
    "--methods",
    "--mib",
    "--model",
    "--newton-budgets",
    "--parts",
    "--predicted",
    "--reference-max-iters",
    "--reference-tolerance",
    "--reps",
    "--rho",
    "--rounds",
    "--scene",
    "--side-cells",
    "--soft-clamp",
    "--start",
    "--steps",
    "--stiffness",
    "--targets",
    "--threads",
    "--time",
    "--warmup",
    "--window",
];

fn run(args: &[String]) -> Result<Value, String> {
    let options = Options::new(args);
    options.only(KNOWN)?;
    let beam = options.beam()?;
    match args.first().map(String::as_str) {
        Some("step") => step(&options, &beam),
        Some("overhead") => overhead(&options, &beam),
        Some("phases") => phases(&options, &beam),
        Some("accuracy") => accuracy(&options, &beam),
        Some("bandwidth") => bandwidth(&options),
        Some("cache-scaling") => cache_scaling(&options),
        Some("methods") => methods(&options, &beam),
        Some("accuracy-target") => accuracy_target(&options, &beam),
        Some("contact") => pd_benches::contact::measure(
            options.parse("--side-cells", 4usize)?,
            options.parse("--warmup", 20usize)?,
            options.parse("--steps", 100usize)?,
        ),
        _ => Err(
            "usage: pd-probe step|overhead|phases|accuracy|bandwidth|cache-scaling|methods|contact|accuracy-target [options] (see the source)"
                .into(),
        ),
    }
}

/// Streaming read bandwidth: the best of `--reps` sums of a `--mib` MiB
/// array of f64 (far larger than the caches), in bytes per second. A
/// triangular solve streams its factor much like this read, so this is the
/// bound `cargo xtask bench-report` compares solves with. With
/// `--threads T` (default 1), T threads each sum one contiguous T-th of
/// the array at once, timed from before the first starts to after the last
/// ends: the bandwidth T cores get together, the bound for a T-thread
/// solve reading the same bytes.
fn bandwidth(options: &Options<'_>) -> Result<Value, String> {
    let mib: usize = options.parse("--mib", 512)?;
    let reps: usize = options.parse("--reps", 7)?;
    let threads: usize = options.parse("--threads", 1)?;
    if threads == 0 {
        return Err("--threads: must be at least 1".into());
    }
    let len = mib * 1024 * 1024 / 8;
    let data: Vec<f64> = (0..len).map(|i| (i % 7) as f64).collect();
    // Whole groups of eight per thread (the last takes the rest).
    let part = len / threads / 8 * 8;
    let mut best = f64::INFINITY;
    let mut checksum = 0.0;
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        let total: f64 = if threads == 1 {
            sum_streaming(&data)
        } else {
            std::thread::scope(|scope| {
                let handles: Vec<_> = (0..threads)
                    .map(|i| {
                        let end = if i + 1 == threads {
                            len
                        } else {
                            (i + 1) * part
                        };
                        let slice = &data[i * part..end];
                        scope.spawn(move || sum_streaming(slice))
                    })
                    .collect();
                handles
                    .into_iter()
                    .map(|h| h.join().unwrap_or(f64::NAN))
                    .sum()
            })
        };
        checksum += std::hint::black_box(total);
        best = best.min(t.elapsed().as_secs_f64());
    }
    output(&Bandwidth {
        bytes: len * 8,
        reps,
        threads,
        best_seconds: best,
        bytes_per_second: (len * 8) as f64 / best,
        checksum,
    })
}

/// How a plain read loop over a working set of `--mib` MiB (default 16)
/// scales from 1 to 2 threads when it is read again and again, as the
/// local step reads its elements in every iteration: each thread sums its
/// contiguous half (or the whole, alone) `--reps` times (default enough
/// for about 2 GB) without leaving the thread, the best of 5 trials. No
/// state is shared, so above 2 the speed-up is the caches (two cores
/// holding more of the set than one), not parallel work. `cargo xtask
/// bench-report` runs it at the local step's working set beside its noise
/// check (docs/design/performance.md, "Two cores cache more than one").
fn cache_scaling(options: &Options<'_>) -> Result<Value, String> {
    let mib: usize = options.parse("--mib", 16)?;
    if mib == 0 {
        return Err("--mib: must be at least 1".into());
    }
    let reps: usize = options.parse("--reps", (2048 / mib).max(4))?;
    let len = mib * 1024 * 1024 / 8 / 16 * 16;
    let data: Vec<f64> = (0..len).map(|i| (i % 7) as f64).collect();
    let repeated = |part: &[f64]| {
        let mut total = 0.0;
        for _ in 0..reps {
            total += sum_streaming(std::hint::black_box(part));
        }
        total
    };
    let mut best = [f64::INFINITY; 2];
    let mut checksum = 0.0;
    for _ in 0..5 {
        let t = Instant::now();
        checksum += std::hint::black_box(repeated(&data));
        best[0] = best[0].min(t.elapsed().as_secs_f64());
        let (a, b) = data.split_at(len / 2);
        let t = Instant::now();
        let (x, y) = std::thread::scope(|scope| {
            let other = scope.spawn(|| repeated(b));
            let mine = repeated(a);
            (mine, other.join().unwrap_or(f64::NAN))
        });
        checksum += std::hint::black_box(x + y);
        best[1] = best[1].min(t.elapsed().as_secs_f64());
    }
    let bytes = (len * 8 * reps) as f64;
    output(&CacheScaling {
        mib,
        reps,
        bytes_per_second_1_thread: bytes / best[0],
        bytes_per_second_2_threads: bytes / best[1],
        speedup: best[0] / best[1],
        checksum,
    })
}

/// The sum of `data` in eight independent sums, so that the adds never
/// limit the read.
fn sum_streaming(data: &[f64]) -> f64 {
    let mut sums = [0.0f64; 8];
    let chunks = data.chunks_exact(8);
    let rest: f64 = chunks.remainder().iter().sum();
    for chunk in chunks {
        for (s, x) in sums.iter_mut().zip(chunk) {
            *s += x;
        }
    }
    sums.iter().sum::<f64>() + rest
}

fn ms(seconds: f64) -> f64 {
    seconds * 1e3
}

/// Solves timed after the steps of `pd-probe step` (`solve_ms_median`).
const SOLVE_REPS: usize = 10;

/// `steps` steps from rest; medians of the step and of its phases, like the
/// C++ reference's `run`; then the median and the fastest of
/// [`SOLVE_REPS`] solves alone.
fn step(options: &Options<'_>, beam: &Beam) -> Result<Value, String> {
    let model = options.value("--model").unwrap_or(UNDAMPED);
    let integrator = options.value("--integrator").unwrap_or("be");
    let steps: usize = options.parse("--steps", 10)?;
    let sheet = options.sheet()?;
    let sim = match &sheet {
        Some(sheet) => sheet.simulation(&beam.settings())?,
        None => {
            let mesh = match options.value("--mesh") {
                Some(base) => pd_io::tetgen::read_tetgen_base(std::path::Path::new(base))
                    .map_err(|e| e.to_string())?,
                None => beam.mesh()?,
            };
            beam.simulation_on(mesh, model, integrator)?
        }
    };
    let mesh = &sim.model().bodies()[0].mesh;
    let (n_verts, n_tets) = (mesh.num_vertices(), mesh.tets().len());
    let setup = sim.setup_stats();
    // The peak so far is the setup's (mesh, model, operators, analysis,
    // first factorisation); `peak_bytes` below adds the steps.
    let setup_peak_bytes = peak_memory_bytes();
    let mut sim = sim;
    let stats = sim.run(steps).map_err(|e| e.to_string())?;
    let pick = |f: fn(&pd_solver::StepStats) -> f64| -> f64 {
        ms(median(&stats.iter().map(f).collect::<Vec<_>>()))
    };
    // The solve alone (no right-hand side assembly), per iteration: what
    // the bench report's limits section compares with the streaming bound.
    let mut solves = Vec::with_capacity(SOLVE_REPS);
    for _ in 0..SOLVE_REPS {
        let t = Instant::now();
        sim.profile_solve().map_err(|e| e.to_string())?;
        solves.push(ms(t.elapsed().as_secs_f64()));
    }
    // The right-hand side `B p` and the solve, per iteration: minus the
    // solve alone, the right-hand side's share (docs/design/performance.md).
    let mut rhs_and_solves = Vec::with_capacity(SOLVE_REPS);
    for _ in 0..SOLVE_REPS {
        let t = Instant::now();
        sim.profile_global_solve().map_err(|e| e.to_string())?;
        rhs_and_solves.push(ms(t.elapsed().as_secs_f64()));
    }
    let positions = &sim.state().positions;
    let centroid = positions.iter().sum::<Point>() / positions.len() as f64;
    let min_y = positions.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    // What one local pass reads and writes: every element and its 3 x 3
    // projection, and the positions (the bench report's cache control).
    let local_bytes = n_tets
        * (std::mem::size_of::<pd_constraints::TetStrain>() + 9 * std::mem::size_of::<f64>())
        + n_verts * std::mem::size_of::<Point>();
    output(&Step {
        n_verts,
        n_tets,
        n_triangles: triangles(&sim, sheet.is_some()),
        local_bytes,
        n_free: sim.num_free_vertices(),
        nnz_l_factor: sim.factor_len(),
        nnz_l_exact: sim.factor_nnz(),
        symbolic_ms: ms(setup.analysis_seconds),
        factor_ms: ms(setup.analysis_seconds + setup.factor_seconds),
        numeric_factor_ms: ms(setup.factor_seconds),
        step_ms_median: pick(|s| s.total_seconds),
        local_ms_median: pick(|s| s.local_seconds),
        global_ms_median: pick(|s| s.global_seconds),
        solve_ms_median: median(&solves),
        solve_ms_min: solves.iter().copied().fold(f64::INFINITY, f64::min),
        rhs_and_solve_ms_median: median(&rhs_and_solves),
        steps,
        iters: beam.iterations,
        threads: beam.threads,
        model: model.into(),
        integrator: integrator.into(),
        centroid: [centroid.x, centroid.y, centroid.z],
        min_y,
        kinetic_energy: sim.energies().kinetic,
        peak_bytes: peak_memory_bytes(),
        setup_peak_bytes,
        state_hash: state_hash(sim.state()),
    })
}

/// FNV-1a over the bits of every position and velocity, as hex: two runs
/// with the same hash ended in the same state bit for bit (how a change
/// that must not move results is checked, e.g. a memory saving).
fn state_hash(state: &pd_solver::State) -> String {
    format!("{:016x}", pd_benches::state_hash(state))
}

/// Every damping model stepped from one common state, the models' steps
/// interleaved round by round so that drift in the machine's speed hits all
/// models alike; the median per model and its ratio to `none`.
fn overhead(options: &Options<'_>, beam: &Beam) -> Result<Value, String> {
    let integrator = options.value("--integrator").unwrap_or("be");
    let rounds: usize = options.parse("--rounds", 15)?;
    let warmup: usize = options.parse("--warmup", 10)?;
    let models = damping_models();
    let mut sims: Vec<Simulation> = models
        .iter()
        .map(|m| beam.simulation(m, integrator))
        .collect::<Result<_, _>>()?;
    // A deformed, moving state: the undamped beam after `warmup` steps.
    sims[0].run(warmup).map_err(|e| e.to_string())?;
    let start = sims[0].state().clone();
    let mut samples = vec![Vec::with_capacity(rounds); sims.len()];
    for _ in 0..rounds {
        for (sim, samples) in sims.iter_mut().zip(&mut samples) {
            sim.set_state(start.clone()).map_err(|e| e.to_string())?;
            let t = Instant::now();
            sim.step().map_err(|e| e.to_string())?;
            samples.push(ms(t.elapsed().as_secs_f64()));
        }
    }
    let none = median(&samples[0]);
    let models: Vec<OverheadModel> = models
        .iter()
        .zip(samples)
        .map(|(name, s)| OverheadModel {
            model: (*name).into(),
            median_ms: median(&s),
            ratio_to_none: median(&s) / none,
            min_ms: s.iter().copied().fold(f64::INFINITY, f64::min),
            samples_ms: s,
        })
        .collect();
    output(&Overhead {
        integrator: integrator.into(),
        n_verts: sims[0].model().num_vertices(),
        iters: beam.iterations,
        threads: beam.threads,
        rounds,
        models,
    })
}

/// The phases alone, each repeated `reps` times: local step, global solve
/// (right-hand side and solve), numeric factorisation.
fn phases(options: &Options<'_>, beam: &Beam) -> Result<Value, String> {
    let model = options.value("--model").unwrap_or(UNDAMPED);
    let reps: usize = options.parse("--reps", 10)?;
    let factor_reps: usize = options.parse("--factor-reps", 3)?;
    // Diagnostics of the local step's 2-thread speed-up: before
    // each timed repetition (untimed), stream `--evict-mib` MiB on this
    // thread (the global solve's factor evicts the L3 so in a step) and/or
    // sleep `--idle-us` microseconds (rayon's idle workers fall asleep
    // during a step's sequential parts). 0 = off, the default.
    let evict_mib: usize = options.parse("--evict-mib", 0)?;
    let idle_us: u64 = options.parse("--idle-us", 0)?;
    let mut evict = vec![1.0f64; evict_mib * 1024 * 1024 / 8];
    let mut between = || {
        for x in evict.iter_mut() {
            *x = std::hint::black_box(*x + 1.0);
        }
        if idle_us > 0 {
            std::thread::sleep(std::time::Duration::from_micros(idle_us));
        }
    };
    let sheet = options.sheet()?;
    let mut sim = match (&sheet, options.value("--mesh")) {
        (Some(sheet), _) => sheet.simulation(&beam.settings())?,
        (None, Some(base)) => {
            let mesh = pd_io::tetgen::read_tetgen_base(std::path::Path::new(base))
                .map_err(|e| e.to_string())?;
            beam.simulation_on(mesh, model, "be")?
        }
        (None, None) => beam.simulation(model, "be")?,
    };
    sim.run(2).map_err(|e| e.to_string())?;
    let mut time = |reps: usize, f: &mut dyn FnMut() -> Result<(), String>| {
        let mut samples = Vec::with_capacity(reps);
        for _ in 0..reps {
            between();
            let t = Instant::now();
            f()?;
            samples.push(ms(t.elapsed().as_secs_f64()));
        }
        Ok::<f64, String>(median(&samples))
    };
    let local = time(reps, &mut || {
        sim.profile_local_step();
        Ok(())
    })?;
    let parts = part_costs(&sim, options.parse("--parts", 0)?, reps);
    let global = time(reps, &mut || {
        sim.profile_global_solve().map_err(|e| e.to_string())
    })?;
    let factor = time(factor_reps, &mut || {
        sim.profile_factorise().map_err(|e| e.to_string())
    })?;
    output(&Phases {
        n_verts: sim.model().num_vertices(),
        n_tets: sim.model().bodies()[0].mesh.tets().len(),
        n_triangles: triangles(&sim, sheet.is_some()),
        threads: beam.threads,
        model: model.into(),
        evict_mib,
        idle_us,
        local_ms_median: local,
        local_part_ns_per_tet_min: parts,
        global_solve_ms_median: global,
        numeric_factor_ms_median: factor,
        nnz_l_factor: sim.factor_len(),
        peak_bytes: peak_memory_bytes(),
    })
}

/// With `--parts P` (diagnostic): the first constraint block
/// (the tet strain of a beam or mesh, the triangle strain of a `--cloth`
/// sheet) cut into `P` equal contiguous parts,
/// each projected on this thread alone `reps` times; the fastest pass per
/// part in ns per constraint. Unequal parts would show a load imbalance of
/// a fixed split (rayon's chunks are stolen, so they balance whatever the
/// costs). Empty without the option.
fn part_costs(sim: &Simulation, parts: usize, reps: usize) -> Vec<f64> {
    let blocks = sim.model().constraint_blocks();
    let Some(block) = blocks.first().filter(|_| parts > 0) else {
        return Vec::new();
    };
    let q = &sim.state().positions;
    let rows = block.rows_per_constraint();
    let mut out = vec![Point::zeros(); block.len() * rows];
    (0..parts)
        .map(|p| {
            let (first, last) = (block.len() * p / parts, block.len() * (p + 1) / parts);
            let mine = &mut out[first * rows..last * rows];
            let mut best = f64::INFINITY;
            for _ in 0..reps.max(1) {
                let t = Instant::now();
                block.project_range(q, first, mine);
                best = best.min(t.elapsed().as_secs_f64());
            }
            best * 1e9 / (last - first).max(1) as f64
        })
        .collect()
}

/// Total energy (kinetic + elastic + gravitational), J.
fn total_energy(sim: &Simulation) -> f64 {
    sim.energies().total()
}

/// For each iteration count: the state after simulated time `--time`
/// against a reference solved to a tight tolerance with the same integrator
/// and step; position error relative to the body's diagonal, energy error
/// relative to `m g L` (total weight times the body's diagonal); the median
/// time per step.
fn accuracy(options: &Options<'_>, beam: &Beam) -> Result<Value, String> {
    let integrator = options.value("--integrator").unwrap_or("be");
    let model = options.value("--model").unwrap_or(UNDAMPED);
    let time: f64 = options.parse("--time", 0.5)?;
    let reference_tolerance: f64 = options.parse("--reference-tolerance", 1e-9)?;
    let reference_max: usize = options.parse("--reference-max-iters", 2000)?;
    let counts = options.list("--iters-list", &[1, 2, 3, 5, 10, 20, 50])?;
    let steps = (time / beam.dt).round() as usize;
    let mesh = beam.mesh()?;
    let diagonal = beam.size.iter().map(|s| s * s).sum::<f64>().sqrt();

    let mut reference = Simulation::new(
        beam.model_on(mesh.clone())?,
        pd_benches::integrator(integrator)?,
        pd_benches::damping(model)?,
        pd_solver::Settings {
            iterations: reference_max,
            tolerance: reference_tolerance,
            ..beam.settings()
        },
    )
    .map_err(|e| e.to_string())?;
    let t = Instant::now();
    let reference_stats = reference.run(steps).map_err(|e| e.to_string())?;
    let reference_seconds = t.elapsed().as_secs_f64();
    let unconverged = reference_stats.iter().filter(|s| !s.converged).count();
    let mean_reference_iterations =
        reference_stats.iter().map(|s| s.iterations).sum::<usize>() as f64 / steps.max(1) as f64;
    let weight: f64 = reference.model().masses().iter().sum::<f64>() * 9.81;
    let energy_scale = weight * diagonal;
    let reference_energy = total_energy(&reference);

    let mut rows = Vec::new();
    for &iterations in &counts {
        let run_beam = Beam {
            iterations,
            ..beam.clone()
        };
        let mut sim = run_beam.simulation_on(mesh.clone(), model, integrator)?;
        let (error, energy_error, step_ms, diverged) = match sim.run(steps) {
            Ok(stats) => {
                let error = sim
                    .state()
                    .positions
                    .iter()
                    .zip(&reference.state().positions)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                let step_ms = ms(median(
                    &stats.iter().map(|s| s.total_seconds).collect::<Vec<_>>(),
                ));
                (
                    error / diagonal,
                    (total_energy(&sim) - reference_energy).abs() / energy_scale,
                    step_ms,
                    false,
                )
            }
            Err(_) => (f64::NAN, f64::NAN, f64::NAN, true),
        };
        rows.push(AccuracyRow {
            iters: iterations,
            position_error_rel: error,
            energy_error_rel: energy_error,
            step_ms_median: step_ms,
            diverged,
        });
    }
    output(&Accuracy {
        integrator: integrator.into(),
        model: model.into(),
        n_verts: reference.model().num_vertices(),
        time,
        dt: beam.dt,
        steps,
        reference_tolerance,
        reference_unconverged_steps: unconverged,
        reference_mean_iterations: mean_reference_iterations,
        reference_seconds,
        energy_scale_joule: energy_scale,
        rows,
    })
}

/// Error against cost per step for every iteration method
/// (`pd_benches::methods`).
fn methods(options: &Options<'_>, beam: &Beam) -> Result<Value, String> {
    use pd_solver::{SolverMethod, SolverSpec};
    let defaults = SolverSpec::default();
    let mesh = match options.value("--mesh") {
        Some(base) => pd_io::tetgen::read_tetgen_base(std::path::Path::new(base))
            .map_err(|e| e.to_string())?,
        None => beam.mesh()?,
    };
    let plan = pd_benches::methods::MethodsPlan {
        integrator: options.value("--integrator").unwrap_or("be").into(),
        damping: options.value("--model").unwrap_or(UNDAMPED).into(),
        steps: options.parse("--steps", 20)?,
        budgets: options.list("--budgets", &[1, 2, 3, 5, 10, 20, 50])?,
        newton_budgets: options.list("--newton-budgets", &[1, 2, 3, 5])?,
        reference_tolerance: options.parse("--reference-tolerance", 1e-10)?,
        methods: match options.value("--methods") {
            None => pd_benches::methods::MethodsPlan::ALL_METHODS.to_vec(),
            Some(text) => text
                .split(',')
                .map(|name| {
                    SolverMethod::parse(name.trim())
                        .ok_or_else(|| format!("--methods: unknown method {name:?}"))
                })
                .collect::<Result<_, _>>()?,
        },
        parameters: SolverSpec {
            window: options.parse("--window", defaults.window)?,
            start: options.parse("--start", defaults.start)?,
            rho: options.spectral_radius("--cheb-rho")?,
            ..defaults
        },
        predicted: match options.value("--predicted") {
            None => Vec::new(),
            Some(text) => text
                .split(',')
                .map(|item| {
                    let (name, predictor) = item
                        .trim()
                        .split_once(':')
                        .unwrap_or((item.trim(), "extrapolated"));
                    let method = SolverMethod::parse(name)
                        .ok_or_else(|| format!("--predicted: unknown method {name:?}"))?;
                    let predictor = parse_predictor(predictor)
                        .ok_or_else(|| format!("--predicted: unknown predictor {predictor:?}"))?;
                    Ok::<_, String>((method, predictor))
                })
                .collect::<Result<_, _>>()?,
        },
    };
    pd_benches::methods::measure(beam, &mesh, &plan)
}

/// A predictor name, or `fittedK/M` for the fitted predictor of order `K`
/// over `M` steps (`fitted` alone: the default order and steps).
fn parse_predictor(text: &str) -> Option<pd_solver::Predictor> {
    let Some((k, m)) = text.strip_prefix("fitted").and_then(|t| t.split_once('/')) else {
        return pd_solver::Predictor::parse(text);
    };
    Some(pd_solver::Predictor::Fitted {
        order: k
            .parse()
            .ok()
            .filter(|k| (1..=pd_solver::Predictor::MAX_ORDER).contains(k))?,
        equations: m
            .parse()
            .ok()
            .filter(|m| *m <= pd_solver::Predictor::MAX_EQUATIONS)?,
    })
    .filter(
        |p| matches!(p, pd_solver::Predictor::Fitted { order, equations } if equations >= order),
    )
}

/// `accuracy-target`: each accuracy target of `--targets` on the scene of
/// `--scene` (`pd_benches::accuracy_target`): the bench beam of `--cells`,
/// the cloth strip, the TetGen mesh of `--mesh` hanging, or the bundled
/// contact stack.
fn accuracy_target(options: &Options<'_>, beam: &Beam) -> Result<Value, String> {
    use pd_benches::accuracy_target::{TargetPlan, TargetScene};
    let scene = match options.value("--scene") {
        Some("beam") => TargetScene::Beam { cells: beam.cells },
        Some("strip") => TargetScene::Strip,
        Some("mesh") => TargetScene::Hanging {
            mesh: options
                .value("--mesh")
                .ok_or("--scene mesh needs --mesh BASE")?
                .into(),
        },
        Some("contact-stack") => TargetScene::ContactStack,
        other => {
            return Err(format!(
                "--scene: expected beam, strip, mesh or contact-stack, got {other:?}"
            ));
        }
    };
    pd_benches::accuracy_target::measure(&TargetPlan {
        scene,
        targets: options.list("--targets", &[1e-2, 1e-3])?,
        warmup: options.parse("--warmup", 3)?,
        steps: options.parse("--steps", 20)?,
    })
}
