//! `[simulation] accuracy = 0.01` against converged references
//! (docs/design/solver.md, "How far from converged"): the scene is run once
//! with the accuracy target and no `[solver]` method (the contract under
//! test), and once converged by other means (Newton stopped by a residual
//! tolerance, or the modal analysis of `pd modes`), never by the error
//! estimate itself; what is compared is physics read from the motion (a
//! static sag, a frequency, a damping ratio, the energy balance).
//!
//! The scenes are scene-file text built with [`Scene::parse`], as `pd run`
//! builds them; `summary.json`'s `accuracy` object and warnings come from
//! the recorder's own [`AccuracyWatch`] fed each step's [`MetricsRow`].
//! Run with `--nocapture` to see the measured figures and times.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Instant;

use pd::io::recorder::{AccuracyWatch, MetricsRow};
use pd::io::scene::{Scene, Syntax};
use pd::io::tetgen::read_tetgen_base;
use pd::prelude::*;

/// What a run of a scene leaves to compare.
struct Run {
    /// `probe` of the state after each step, row 0 the initial state.
    probe: Vec<f64>,
    /// (kinetic, elastic, total) energy after each step, J, row 0 the
    /// initial state: read from the simulation, not from the recorder.
    energies: Vec<(f64, f64, f64)>,
    /// (step, iterations, estimated error) of each step whose iterations
    /// did not meet the target (or the tolerance).
    unconverged: Vec<(usize, usize, f64)>,
    /// The recorder's view of the run (`summary.json`'s `accuracy`).
    watch: AccuracyWatch,
    /// The simulation at the end.
    sim: Simulation,
    /// Wall time, building included, s.
    seconds: f64,
}

impl Run {
    /// Builds the scene `text` (relative paths against `source`'s folder)
    /// and runs its `steps`, recording `probe` after each step.
    fn of(text: &str, source: &Path, probe: fn(&Simulation) -> f64) -> Self {
        let clock = Instant::now();
        let scene = Scene::parse(text, Syntax::Toml, source).unwrap();
        let mut sim = scene.build().unwrap();
        let mut watch = AccuracyWatch::default();
        watch.observe(&MetricsRow::of(&sim, None));
        let energy = |sim: &Simulation| {
            let e = sim.energies();
            (e.kinetic, e.elastic, e.total())
        };
        let (mut values, mut energies) = (vec![probe(&sim)], vec![energy(&sim)]);
        let mut unconverged = Vec::new();
        for step in 1..=scene.steps {
            let stats = sim.step().unwrap();
            watch.observe(&MetricsRow::of(&sim, Some(&stats)));
            values.push(probe(&sim));
            energies.push(energy(&sim));
            if !stats.converged {
                unconverged.push((step, stats.iterations, stats.estimated_error));
            }
        }
        Self {
            probe: values,
            energies,
            unconverged,
            watch,
            sim,
            seconds: clock.elapsed().as_secs_f64(),
        }
    }

    /// The summary's `energy_created_j` (J).
    fn energy_created(&self) -> f64 {
        self.watch.summary(&self.sim)["energy_created_j"]
            .as_f64()
            .unwrap()
    }

    /// The largest rise of the total energy between two states of the run,
    /// `max_(m < n) (E_n - E_m)` (J), and the largest kinetic plus elastic
    /// energy (J), from the energies recorded here (pair by pair: no
    /// running minimum shared with the recorder).
    fn energy_rise(&self) -> (f64, f64) {
        let totals: Vec<f64> = self.energies.iter().map(|e| e.2).collect();
        let rise = (0..totals.len())
            .flat_map(|n| totals[..n].iter().map(move |m| (n, m)))
            .map(|(n, m)| totals[n] - m)
            .fold(0.0, f64::max);
        let largest = self.energies.iter().map(|e| e.0 + e.1).fold(0.0, f64::max);
        (rise, largest)
    }

    /// A line for `--nocapture`.
    fn describe(&self, name: &str) -> String {
        format!(
            "{name}: {:.1} s, {}, {} of {} steps short of the target or tolerance (the first: \
             {:?}), accuracy {}",
            self.seconds,
            self.sim.position_solver_name(),
            self.unconverged.len(),
            self.sim.steps(),
            &self.unconverged[..self.unconverged.len().min(3)],
            self.watch.summary(&self.sim)
        )
    }
}

/// The downward displacement (m) of the free end: the mean over the
/// vertices of largest rest x of `rest y - y`.
fn tip_sag(sim: &Simulation) -> f64 {
    let rest = sim.model().rest_positions();
    let end = rest.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max);
    let (sum, count) = (rest.iter().zip(&sim.state().positions))
        .filter(|(r, _)| r.x > end - 1e-9)
        .fold((0.0, 0.0), |(s, c), (r, p)| (s + r.y - p.y, c + 1.0));
    sum / count
}

/// The relative difference `a / b - 1`.
fn relative(a: f64, b: f64) -> f64 {
    a / b - 1.0
}

/// The accuracy contract: a target of 1%, no method named.
const ACCURACY: &str = "accuracy = 0.01";

/// The energy created, as a fraction of the largest kinetic plus elastic
/// energy, at which `pd run` warns (docs/guide/03-accuracy-and-solvers.md).
const ENERGY_WARNING: f64 = 0.01;

/// The converged reference: Newton, stopped once a Newton step changes the
/// positions by at most 1e-6 of the step's displacement (a step that
/// converges quadratically from there is at round-off after one more), or
/// after 10 iterations (a body at rest barely moves in a step, so its
/// relative tolerance can stay out of reach: the strip's steps at rest end
/// there, with Newton's own estimate below 3e-9).
const NEWTON: (&str, &str) = (
    "[solver]\nmethod = \"newton\"",
    "tolerance = 1e-6\niterations = 10",
);

/// The cloth strip: 0.3 x 0.05 m, 30 x 5 quads, `triangle-strain` 1e5 N/m,
/// `bending` 0.5 N m, 0.2 kg/m^2, clamped along its x = 0 edge (two fixed
/// vertex lines, x <= 0.01 m: one line alone is a hinge for the plate
/// bending energy, docs/design/cloth.md), backward Euler, dt 0.01 s,
/// ether drag 2/s, 3 s.
fn strip(solver: &str, simulation: &str) -> String {
    format!(
        r#"[simulation]
dt = {DT}
steps = 300
integrator = "backward-euler"
threads = 1
{simulation}

[damping]
model = "ether-drag"
rate = 2.0

[[body]]
mesh = {{ generator = "cloth", size = [0.3, 0.05], cells = [30, 5] }}
density = 0.2
constraints = [
  {{ kind = "triangle-strain", stiffness = 1.0e5 }},
  {{ kind = "bending", stiffness = 0.5 }},
]
fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.0101, 1.0, 1.0] }} }}

{solver}
"#
    )
}

/// The strip's tip sag at 3 s with `accuracy = 0.01` is within 5% of
/// Newton's.
///
/// Why 5%: the run settles where a step from rest, started at its
/// inertial prediction `y = x_s + h^2 g`, returns `x_s`. If the step
/// leaves a remainder `r` (`|r|_M <= e |y - x*|_M`, `e` its true relative
/// error), mode `i` of the linearised strip (M-orthonormal, `omega_i`)
/// settles at `s_i = (g_i + (1 + (omega_i h)^2) r_i / h^2) / omega_i^2`
/// instead of `g_i / omega_i^2` (backward Euler), and `|y - x*|_M` is
/// about `h^2 |g|_M` at rest, so the first mode's sag, which carries the
/// tip's, is off by at most `e (1 + (omega_1 h)^2) |g|_M / g_1`. Here
/// `omega_1` is about 66 rad/s (the clamped plate,
/// `1.875^2 sqrt(D / (rho_A L^4))` with the free length 0.29 m), so
/// `(omega_1 h)^2 = 0.44`, and `|g|_M / g_1` is `1 / sqrt(0.61)` (the first
/// cantilever mode's share of the mass): the bound is `1.8 e`, 1.8% at
/// `e = 1%`, 3.7% if the true error is twice the estimate (plain PD's
/// estimate was never below half the truth, tests/accuracy_estimate.rs in
/// pd-solver). 5% is above that and far below what an unconverged run is
/// off by: plain PD at its default 10 iterations sags 57.7 mm, 15.5 times
/// the reference (measured), so the test can fail.
///
/// Measured (dev profile, 2-core shared machine): reference 3.7121 mm,
/// accuracy run 3.7473 mm (+0.95%) at a median of 1,883 plain iterations a
/// step; the accuracy run takes 100 to 250 s with the machine's load (plain
/// local-global: no method is chosen for an `accuracy` scene yet), the
/// reference 10 s.
#[test]
fn cloth_strip_sag_with_accuracy_is_within_5_percent_of_newton() {
    let source = Path::new("strip.toml");
    let reference = Run::of(&strip(NEWTON.0, NEWTON.1), source, tip_sag);
    let accurate = Run::of(&strip("", ACCURACY), source, tip_sag);
    let (expected, sag) = (
        *reference.probe.last().unwrap(),
        *accurate.probe.last().unwrap(),
    );
    eprintln!("{}", reference.describe("strip, Newton"));
    eprintln!("{}", accurate.describe("strip, accuracy 0.01"));
    eprintln!(
        "strip tip sag: Newton {:.4} mm, accuracy 0.01 {:.4} mm ({:+.2}%)",
        1e3 * expected,
        1e3 * sag,
        100.0 * relative(sag, expected)
    );
    // The reference is the clamped strip: the plate estimate
    // rho_A g L^4 / (8 D) is 3.5 mm (free length 0.29 m) to 4.0 mm (0.3 m).
    // Both runs are at rest: over the last half second the tip moves by
    // less than 0.1% of its sag (drag and backward Euler have damped the
    // swing; measured: unchanged in 5 digits from 0.6 s on).
    assert!((3e-3..4.5e-3).contains(&expected), "{expected}");
    for run in [&reference, &accurate] {
        let end = *run.probe.last().unwrap();
        let late = &run.probe[250..];
        assert!(
            late.iter().all(|v| (v - end).abs() < 1e-3 * end),
            "{late:?}"
        );
    }
    assert!(
        relative(sag, expected).abs() <= 0.05,
        "tip sag {sag} m with accuracy 0.01 against {expected} m converged"
    );
}

/// The stiff beam: 1 x 0.05 x 0.1 m (bending in its 0.05 m direction,
/// along gravity), 20 x 2 x 4 cells, 1e8 Pa tet strain, 1000 kg/m^3,
/// clamped at x = 0, implicit midpoint, Laplacian damping of ratio 0.05 on
/// its lowest mode, dt 0.01 s, released straight from rest, 4 s.
fn beam(solver: &str, simulation: &str) -> String {
    midpoint_damped(400, simulation)
        + &format!(
            r#"[[body]]
mesh = {{ generator = "box", size = [1.0, 0.05, 0.1], cells = [20, 2, 4] }}
density = 1000.0
constraints = [ {{ kind = "tet-strain", stiffness = 1.0e8 }} ]
fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] }} }}

{solver}
"#
        )
}

/// The `[simulation]` and `[damping]` tables of the beam, the drop and the
/// free fall: `steps` of implicit midpoint at [`DT`] on one thread with
/// `simulation`'s iteration settings, and Laplacian damping of ratio 0.05
/// on the lowest elastic mode.
fn midpoint_damped(steps: usize, simulation: &str) -> String {
    midpoint_damped_at(DT, steps, simulation)
}

/// [`midpoint_damped`] at time step `dt` (s).
fn midpoint_damped_at(dt: f64, steps: usize, simulation: &str) -> String {
    format!(
        "[simulation]\ndt = {dt}\nsteps = {steps}\nintegrator = \"implicit-midpoint\"\n\
         threads = 1\n{simulation}\n\n[damping]\nmodel = \"laplacian\"\nratio = 0.05\n\n"
    )
}

/// The time step of every scene here but the finer armadillo drop, s.
const DT: f64 = 0.01;

/// The oscillation of the beam's tip about its static sag, read from the
/// tip trajectory alone.
#[derive(Debug, Clone, Copy)]
struct Oscillation {
    /// The static sag: the mean tip sag over the last second, m.
    sag: f64,
    /// The frequency of the damped motion, from its zero crossings, Hz.
    frequency: f64,
    /// The damping ratio, from the decay of its extremes.
    ratio: f64,
}

/// The window of the trajectory the frequency and the decay are read
/// from, s: after the release's first swing, and while the amplitude
/// (1.4 mm or more at 2 s, 7% of the sag) is far above the jitter an
/// accuracy-driven run leaves about its rest state (0.05-0.1 mm, seen from
/// 2.7 s on at 1%).
const WINDOW: (f64, f64) = (0.2, 2.0);

impl Oscillation {
    /// Reads `sag` (one value per step of [`DT`], row 0 the release).
    fn of(sag: &[f64]) -> Self {
        let last = (1.0 / DT).round() as usize;
        let rest = sag[sag.len() - last..].iter().sum::<f64>() / last as f64;
        let q: Vec<f64> = sag.iter().map(|s| s - rest).collect();
        let window = (WINDOW.0 / DT) as usize..(WINDOW.1 / DT) as usize;
        // Zero crossings, interpolated linearly: half a period apart.
        let crossings: Vec<(f64, f64)> = window
            .clone()
            .filter(|&n| q[n] * q[n + 1] < 0.0)
            .map(|n| (n as f64 + q[n] / (q[n] - q[n + 1])) * DT)
            .enumerate()
            .map(|(k, t)| (k as f64, t))
            .collect();
        let frequency = 0.5 / line_slope(&crossings);
        // Extremes, each refined by the parabola through its three
        // samples: ln |q| falls by zeta omega per second.
        let extremes: Vec<(f64, f64)> = window
            .filter(|&n| q[n].abs() > q[n - 1].abs() && q[n].abs() >= q[n + 1].abs())
            .filter(|&n| q[n - 1] * q[n] > 0.0 && q[n] * q[n + 1] > 0.0)
            .map(|n| {
                let (a, b, c) = (q[n - 1], q[n], q[n + 1]);
                let shift = 0.5 * (a - c) / (a - 2.0 * b + c);
                let peak = b - 0.25 * (a - c) * shift;
                ((n as f64 + shift) * DT, peak.abs().ln())
            })
            .collect();
        let decay = -line_slope(&extremes);
        let damped = std::f64::consts::TAU * frequency;
        Self {
            sag: rest,
            frequency,
            ratio: decay / decay.hypot(damped),
        }
    }
}

/// The slope of the least-squares line through `points`.
fn line_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p.0 / n, y + p.1 / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(sxy, sxx), p| {
        (sxy + (p.0 - mx) * (p.1 - my), sxx + (p.0 - mx) * (p.0 - mx))
    });
    sxy / sxx
}

/// What the beam's two runs and `pd modes` give.
#[derive(Debug)]
struct BeamRuns {
    /// Newton's run, read as an [`Oscillation`].
    reference: Oscillation,
    /// The run with `accuracy = 0.01`.
    accurate: Oscillation,
    /// What `pd modes` predicts for mode 1 at the scene's `dt`: the
    /// frequency of the damped discrete motion (Hz) and its damping ratio.
    predicted: (f64, f64),
}

/// The beam's runs, made once for the tests that read them.
fn beam_runs() -> &'static BeamRuns {
    static RUNS: OnceLock<BeamRuns> = OnceLock::new();
    RUNS.get_or_init(|| {
        let source = Path::new("beam.toml");
        let reference = Run::of(&beam(NEWTON.0, NEWTON.1), source, tip_sag);
        let accurate = Run::of(&beam("", ACCURACY), source, tip_sag);
        eprintln!("{}", reference.describe("beam, Newton"));
        eprintln!("{}", accurate.describe("beam, accuracy 0.01"));
        let runs = BeamRuns {
            reference: Oscillation::of(&reference.probe),
            accurate: Oscillation::of(&accurate.probe),
            predicted: mode_one(&accurate.sim),
        };
        eprintln!(
            "beam: Newton {:?}, accuracy 0.01 {:?}, pd modes (frequency Hz, ratio) {:?}",
            runs.reference, runs.accurate, runs.predicted
        );
        runs
    })
}

/// Mode 1 as `pd modes` reports it (crates/pd-cli/src/modes.rs): the
/// lowest elastic mode at rest, its modal damping `c` under the scene's
/// damping, and the discrete root of the scene's integrator at its `dt`
/// (`discrete_frequency_hz`, `damping_ratio`). The motion's frequency is
/// the damped one, `omega sqrt(1 - zeta^2)`.
fn mode_one(sim: &Simulation) -> (f64, f64) {
    let analysis = pd::modes::elastic_modes(sim.model(), 1).unwrap();
    let mode = &analysis.modes[0];
    let d = sim.damping_matrix();
    let c = d.mass
        + d.damping_laplacian * mode.laplacian_quotient
        + d.lagged_stiffness * mode.omega * mode.omega;
    let make = || -> Box<dyn Integrator> { Box::new(ImplicitMidpoint) };
    let discrete = pd::modes::discrete_mode(&make, sim.settings().dt, mode.omega, c);
    let ratio = discrete.damping_ratio;
    let damped = discrete.omega * (1.0 - ratio * ratio).sqrt();
    (damped / std::f64::consts::TAU, ratio)
}

/// (a) The beam's static sag with `accuracy = 0.01` is within 5% of
/// Newton's.
///
/// Why 5%: as for the strip (above), with implicit midpoint's force at the
/// midpoint: a step from rest `x_s` with prediction `y = x_s + h^2 g / 2`
/// that leaves a remainder `r` settles mode `i` at
/// `s_i = (g_i + 2 (1 + (omega_i h)^2 / 4) r_i / h^2) / omega_i^2`, and
/// `|y - x*|_M` is about `h^2 |g|_M / 2`, so the first mode's sag is off by
/// at most `e (1 + (omega_1 h)^2 / 4) |g|_M / g_1 = 1.3 e` (`omega_1 h =
/// 0.27`; the first mode holds 61% of the mass): 1.3% at `e = 1%`, 2.6% if
/// the truth is twice the estimate. The mean over the last second leaves
/// the remaining swing (0.1-0.3 mm, under 1.5% of the sag, averaged over
/// four periods) out to better than 0.1%. Measured: Newton 20.109 mm,
/// accuracy 0.01 20.044 mm (-0.32%); plain PD at 30 iterations 19.427 mm
/// (-3.4%), at 10 iterations 19.010 mm (-5.5%: the test can fail).
#[test]
fn beam_sag_with_accuracy_is_within_5_percent_of_newton() {
    let runs = beam_runs();
    let error = relative(runs.accurate.sag, runs.reference.sag);
    eprintln!("beam sag: {:+.2}% against Newton", 100.0 * error);
    // The reference sags as a clamped beam of this mesh should: gravity
    // over mode 1, g / omega_1^2 = 13 mm, times the tip's share of a
    // uniform load's deflection against mode 1's (about 1.5).
    assert!((0.015..0.025).contains(&runs.reference.sag), "{runs:?}");
    assert!(error.abs() <= 0.05, "sag off by {error}");
}

/// (b) The beam's frequency and damping ratio measured from its motion with
/// `accuracy = 0.01` are within 3% and 10% of what `pd modes` predicts for
/// mode 1 at the scene's `dt`.
///
/// The prediction includes implicit midpoint's own period elongation at
/// this `dt`, `(omega h)^2 / 12 = 0.6%` (`omega_1 h = 0.27`), and its
/// damping ratio of the discrete motion (0.0494 for the 0.05 asked). The
/// converged run checks the measurement: it must match the prediction to
/// 1% and 3% (measured 0.08% and 0.10%: the geometric nonlinearity of a
/// 2% sag and a 1.7% amplitude, the sampling at 23 steps a period and the
/// weakly excited higher modes are all below that).
///
/// Why 3% and 10% for the accuracy run: a step that leaves a fraction
/// `e_1` of mode 1's correction undone applies `1 - e_1` of its elastic
/// impulse, which lowers the frequency by about `e_1 / 2`; 3% allows
/// `e_1` up to 6%, six times the target, and is far below the 18% of a
/// 30-iteration run. The damping ratio is read from a decay of 2.7% of the
/// energy a step, against which the energy an unconverged implicit-midpoint
/// step adds or removes (docs/design/solver.md, "The end-of-step check") is
/// not small: 10% is six times what the accuracy run shows and below the
/// 12% of a 30-iteration run. Measured: prediction 4.3217 Hz, 0.0494;
/// Newton 4.3250 Hz, 0.0493; accuracy 0.01 4.2965 Hz (-0.58%), 0.0502
/// (+1.6%); plain PD at 30 iterations 3.550 Hz (-18%), 0.0435 (-12%), and
/// even at 100 iterations, whose median estimate is 0.008 (largest 0.32),
/// 4.181 Hz (-3.3%), 0.0488 (-1.1%).
/// Both beam tests share one pair of runs: 35 s under load, 25 s idle.
#[test]
fn beam_frequency_and_ratio_with_accuracy_match_pd_modes() {
    let runs = beam_runs();
    let (frequency, ratio) = runs.predicted;
    let report = |o: &Oscillation| (relative(o.frequency, frequency), relative(o.ratio, ratio));
    let (reference, accurate) = (report(&runs.reference), report(&runs.accurate));
    eprintln!(
        "beam against pd modes ({frequency:.4} Hz, {ratio:.4}): Newton {:+.2}% / {:+.2}%, accuracy 0.01 {:+.2}% / {:+.2}%",
        100.0 * reference.0,
        100.0 * reference.1,
        100.0 * accurate.0,
        100.0 * accurate.1
    );
    assert!(
        reference.0.abs() <= 0.01 && reference.1.abs() <= 0.03,
        "the measurement itself is off: {runs:?}"
    );
    assert!(accurate.0.abs() <= 0.03, "frequency off by {}", accurate.0);
    assert!(
        accurate.1.abs() <= 0.10,
        "damping ratio off by {}",
        accurate.1
    );
}

/// The folder of the TetGen armadillo (`../shared/meshes/armadillo` beside
/// the repository, as pd-linalg's fixtures find it), or `None` with a line
/// saying the test is skipped.
fn armadillo_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/meshes/armadillo");
    let present = ["node", "ele"]
        .iter()
        .all(|e| dir.join("armadillo").with_extension(e).is_file());
    if !present {
        println!(
            "armadillo drop skipped: {}/armadillo.node and .ele not found",
            dir.display()
        );
    }
    present.then_some(dir)
}

/// The drop's length: the body lands at 0.35 s (a 0.6 m fall) and
/// rebounds; with 10 plain iterations the total energy has risen from its
/// minimum at landing by 12% of the largest kinetic plus elastic energy by
/// 0.6 s and by 62.5% by 0.8 s (measured).
const DROP_STEPS: usize = 80;

/// The armadillo (14,779 vertices, `tet-strain` 2e5 Pa, 1000 kg/m^3,
/// 122 kg) at rest above a plane with friction 0.5, implicit midpoint,
/// Laplacian damping of ratio 0.05, time step `dt` (s), to 0.8 s. Gravity
/// is -y and the mesh spans y in [-0.445, 0.419] m (x in [-0.628, 0.719],
/// z in [0, 0.565]): the plane `y = const` lies 0.6 m below its lowest
/// vertex.
fn armadillo_at(dir: &Path, dt: f64, simulation: &str) -> String {
    let mesh = read_tetgen_base(&dir.join("armadillo")).unwrap();
    let lowest = mesh
        .vertices()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    let plane = lowest - 0.6;
    let steps = (DROP_STEPS as f64 * DT / dt).round() as usize;
    midpoint_damped_at(dt, steps, simulation)
        + &format!(
            r#"[[collider]]
shape = "plane"
point = [0.0, {plane}, 0.0]
normal = [0.0, 1.0, 0.0]
friction = 0.5

[[body]]
mesh = {{ file = "armadillo.node" }}
density = 1000.0
constraints = [ {{ kind = "tet-strain", stiffness = 2.0e5 }} ]
"#
        )
}

/// The lowest y of any vertex, m.
fn lowest(sim: &Simulation) -> f64 {
    sim.state()
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min)
}

/// Runs the drop with `simulation`'s settings and reports its energies.
fn drop(simulation: &str) -> Option<Run> {
    drop_at(DT, simulation)
}

/// [`drop`] at time step `dt` (s).
fn drop_at(dt: f64, simulation: &str) -> Option<Run> {
    let dir = armadillo_dir()?;
    let run = Run::of(
        &armadillo_at(&dir, dt, simulation),
        &dir.join("drop.toml"),
        lowest,
    );
    let (rise, largest) = run.energy_rise();
    eprintln!("{}", run.describe("armadillo drop"));
    eprintln!(
        "armadillo drop: largest rise of the total energy {rise:.3e} J ({:.2}% of the largest \
         kinetic plus elastic energy, {largest:.3e} J); summary energy_created_j {:.3e} J; \
         warnings {:?}",
        100.0 * rise / largest,
        run.energy_created(),
        run.watch.warnings(&run.sim)
    );
    // It fell the 0.6 m onto the plane.
    let fall = run.probe[0] - run.probe.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(fall > 0.59, "{:?}", run.probe);
    Some(run)
}

/// (a) With `accuracy = 0.01` the drop creates no energy beyond 1% of its
/// largest kinetic plus elastic energy, by the summary and by the energies
/// recorded here.
///
/// Why 1%: a damping model, friction and inelastic contact only
/// dissipate, and implicit midpoint conserves the energy of quadratic
/// elastic energies, so the converged run's total should not rise (this
/// drop's does, below: its strain energy is far from quadratic); an
/// unconverged implicit-midpoint step changes the total by
/// `2 grad g(x) . (x - x_n)` (docs/design/solver.md, "The end-of-step
/// check"), which a 1% error keeps to a small fraction of a step's energy;
/// 1% is the figure at which `pd run` warns (its 10-iteration run does).
///
/// Ignored: it takes minutes (103-150 s in release on the loaded 2-core
/// machine, 53-60 s of CPU; the dev profile is several times slower), and it
/// fails, for a reason that is the integrator's, not the solve's.
/// Measured (80 steps, local-global, the only method that runs colliders;
/// the collider contacts solved against the Delassus operator,
/// docs/design/contact.md, "Friction with an accuracy target"): every step
/// meets the target (median 24 iterations, 4,038 in all), and the run
/// creates 14.5 J, 1.43% of its largest kinetic plus elastic energy
/// (1,013 J), at the rebound (steps 50-51). The same run at `accuracy =
/// 0.001` creates 14.8 J: it is the converged implicit-midpoint
/// trajectory's own energy error with the corotational strain of the
/// squashed body, not the steps' error; at dt 0.005 s the drop creates
/// none (to 0.8 s), at 0.0075 s 0.14%, at 0.00875 s 2.01%: the figure
/// follows where the steps fall in the body's wobble (docs/design/contact.md,
/// "The case that needs it"), and `pd run`'s warning names `dt`, not the
/// iterations, when every step met its target.
#[test]
#[ignore = "minutes, and fails: the converged implicit-midpoint drop creates 1.43% at dt 0.01 s (every step meets the target; 1.46% at accuracy 0.001; none at dt 0.005 s, the test below)"]
fn armadillo_drop_with_accuracy_creates_no_energy() {
    let Some(run) = drop(ACCURACY) else { return };
    let (rise, largest) = run.energy_rise();
    let created = run.energy_created();
    assert!(created <= ENERGY_WARNING * largest, "created {created} J");
    assert!(rise <= ENERGY_WARNING * largest, "created {rise} J");
}

/// (a') The same drop at half the time step (dt 0.005 s, 160 steps to the
/// same 0.8 s) with `accuracy = 0.01` creates no energy beyond 1%, with the
/// bound of (a). Ignored: minutes (about 100 s in release).
#[test]
#[ignore = "minutes: 160 steps of the 14,779-vertex armadillo in contact"]
fn armadillo_drop_with_accuracy_at_half_the_step_creates_no_energy() {
    let Some(run) = drop_at(DT / 2.0, ACCURACY) else {
        return;
    };
    let (rise, largest) = run.energy_rise();
    assert!(run.unconverged.is_empty(), "{:?}", run.unconverged);
    assert!(rise <= ENERGY_WARNING * largest, "created {rise} J");
    assert!(run.watch.warnings(&run.sim).is_empty());
}

/// (a'') At dt 0.01 s, where every step meets `accuracy = 0.01` and the
/// run still creates energy (a), the warning says the energy is the time
/// step's and names `dt`, not the iterations. Ignored: minutes.
#[test]
#[ignore = "minutes: 80 steps of the 14,779-vertex armadillo in contact"]
fn armadillo_drop_with_accuracy_warns_that_the_energy_is_the_time_steps() {
    let Some(run) = drop(ACCURACY) else { return };
    let (rise, largest) = run.energy_rise();
    assert!(run.unconverged.is_empty(), "{:?}", run.unconverged);
    assert!(rise > ENERGY_WARNING * largest, "{rise} J of {largest} J");
    let warnings = run.watch.warnings(&run.sim);
    assert!(
        warnings.len() == 1
            && warnings[0].contains("the energy is the time step's")
            && warnings[0].contains("halve `dt`"),
        "{warnings:?}"
    );
}

/// (b) At a fixed 10 iterations (no accuracy) the drop warns that it
/// created energy, and the energies recorded here agree that it did.
/// Measured: the total goes from 69.3 J to about -96 J after landing
/// (0.55 s), then up to 859 J at 0.8 s (973 J created, 62.5% of the
/// largest kinetic plus elastic energy, 1,556 J); 48 s on the loaded
/// machine (0.55 s a step, 29 ms idle).
#[test]
fn armadillo_drop_at_10_iterations_warns_of_energy_created() {
    let Some(run) = drop("iterations = 10") else {
        return;
    };
    let (rise, largest) = run.energy_rise();
    assert!(rise > ENERGY_WARNING * largest, "{rise} J of {largest} J");
    assert!(
        (run.energy_created() - rise).abs() <= 1e-9 * largest,
        "the summary's {} J against {rise} J",
        run.energy_created()
    );
    let warnings = run.watch.warnings(&run.sim);
    assert!(
        warnings.iter().any(|w| w.contains("J of energy")),
        "{warnings:?}"
    );
}

/// A body in free fall (at rest, so each step is a rigid translation and
/// its correction `y -> x*` is zero) with `accuracy = 0.01`, under the
/// automatic choice and under every method named: each step should stop
/// within a few iterations, as a step that does not move does (at once);
/// 100 is generous.
///
/// The iterates' changes are round-off (relative residual 1e-16 to
/// 1e-14), which do not shrink: read by the contraction rule alone, the
/// estimate stayed near 1 and a step stopped only if round-off happened to
/// give an exact zero change (this cube's 10 steps took 40 to 10,000
/// iterations). A change below `ROUNDOFF` (1e-12) of the step's
/// displacement counts as converged (step/estimate.rs), and so it ends the
/// plain iterations that measure the contraction L-BFGS and Newton need
/// in their first step (without that, their first step ran all 1,000,
/// and the automatic choice, which picks by timing, picked L-BFGS on a
/// loaded machine).
#[test]
fn a_free_fall_reaches_the_accuracy_target() {
    for method in [
        "",
        "local-global",
        "anderson",
        "chebyshev",
        "lbfgs",
        "newton",
    ] {
        let solver = if method.is_empty() {
            String::new()
        } else {
            format!("[solver]\nmethod = \"{method}\"\n\n")
        };
        let text = midpoint_damped(10, ACCURACY)
            + &solver
            + "[[body]]\nmesh = { generator = \"box\", size = [0.2, 0.2, 0.2], cells = [3, 3, 3] }\n\
               density = 1000.0\nconstraints = [ { kind = \"tet-strain\", stiffness = 1.0e6 } ]\n";
        let scene = Scene::parse(&text, Syntax::Toml, Path::new("cube.toml")).unwrap();
        let mut sim = scene.build().unwrap();
        let steps: Vec<(usize, f64)> = (0..scene.steps)
            .map(|_| sim.step().unwrap())
            .map(|stats| (stats.iterations, stats.estimated_error))
            .collect();
        assert!(
            steps.iter().all(|(iterations, _)| *iterations < 100),
            "{method}: free-fall steps (iterations, estimated error): {steps:?}"
        );
    }
}
