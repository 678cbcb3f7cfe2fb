//! The typed output of `pd-probe`: one struct per probe, which `pd-probe`
//! prints as one JSON line and `cargo xtask bench-report` and
//! `cargo xtask cpp-compare` read back.
//!
//! Times are in ms unless a field's name says otherwise, memory in bytes.
//! A number that is not finite (a diverged run's error, a median of no
//! samples) is written as JSON `null` and read back as NaN; a number that
//! is missing is read as NaN too.
//!
//! ```
//! use pd_benches::schema::AccuracyRow;
//!
//! let row: AccuracyRow = serde_json::from_str(
//!     r#"{"iters": 3, "position_error_rel": null, "energy_error_rel": 0.5,
//!         "step_ms_median": 1.5, "diverged": true}"#,
//! )
//! .unwrap();
//! assert!(row.position_error_rel.is_nan());
//! assert_eq!(serde_json::to_value(&row).unwrap()["position_error_rel"], serde_json::Value::Null);
//! ```

use serde::{Deserialize, Deserializer, Serialize};

/// A number read from JSON, NaN for `null`: the `deserialize_with` of
/// every `f64` field here (with `default = "nan"`), for reports that embed
/// these outputs too.
///
/// # Errors
/// A value that is neither a number nor `null`.
pub fn number<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
}

/// The value of a number that is missing: NaN.
pub fn nan() -> f64 {
    f64::NAN
}

/// `pd-probe step`: set-up and steps of one beam, cloth sheet or mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Step {
    /// Vertices.
    pub n_verts: usize,
    /// Tetrahedra.
    pub n_tets: usize,
    /// Triangles, for a cloth sheet only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub n_triangles: Option<usize>,
    /// What one local pass reads and writes (bytes).
    pub local_bytes: usize,
    /// Free vertices.
    pub n_free: usize,
    /// Stored entries of the Cholesky factor.
    #[serde(rename = "nnz_L_factor")]
    pub nnz_l_factor: usize,
    /// Structural non-zeros of the Cholesky factor.
    #[serde(rename = "nnz_L_exact")]
    pub nnz_l_exact: usize,
    /// Assembly, ordering and symbolic factorisation.
    #[serde(default = "nan", deserialize_with = "number")]
    pub symbolic_ms: f64,
    /// Analysis and the first numeric factorisation.
    #[serde(default = "nan", deserialize_with = "number")]
    pub factor_ms: f64,
    /// The first numeric factorisation.
    #[serde(default = "nan", deserialize_with = "number")]
    pub numeric_factor_ms: f64,
    /// Median step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub step_ms_median: f64,
    /// Median local phase of a step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub local_ms_median: f64,
    /// Median global phase of a step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub global_ms_median: f64,
    /// Median solve alone (no right-hand side), per iteration.
    #[serde(default = "nan", deserialize_with = "number")]
    pub solve_ms_median: f64,
    /// Fastest solve alone.
    #[serde(default = "nan", deserialize_with = "number")]
    pub solve_ms_min: f64,
    /// Median right-hand side and solve, per iteration.
    #[serde(default = "nan", deserialize_with = "number")]
    pub rhs_and_solve_ms_median: f64,
    /// Steps taken.
    pub steps: usize,
    /// Iterations per step.
    pub iters: usize,
    /// Threads.
    pub threads: usize,
    /// Damping preset.
    pub model: String,
    /// Integrator, by its short name.
    pub integrator: String,
    /// Centroid of the final positions (m).
    pub centroid: [f64; 3],
    /// Lowest final y (m).
    #[serde(default = "nan", deserialize_with = "number")]
    pub min_y: f64,
    /// Final kinetic energy (J).
    #[serde(default = "nan", deserialize_with = "number")]
    pub kinetic_energy: f64,
    /// Peak resident memory of the process (`VmHWM`), if known.
    pub peak_bytes: Option<u64>,
    /// Peak resident memory after the set-up, if known.
    pub setup_peak_bytes: Option<u64>,
    /// FNV-1a of the final state's bits, 16 hex digits.
    pub state_hash: String,
}

/// `pd-probe overhead`: every damping model stepped from one state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Overhead {
    /// Integrator, by its short name.
    pub integrator: String,
    /// Vertices.
    pub n_verts: usize,
    /// Iterations per step.
    pub iters: usize,
    /// Threads.
    pub threads: usize,
    /// Interleaved rounds.
    pub rounds: usize,
    /// One entry per damping model.
    pub models: Vec<OverheadModel>,
}

/// One damping model of [`Overhead`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OverheadModel {
    /// The preset.
    pub model: String,
    /// Median step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub median_ms: f64,
    /// Median step over that of `none`.
    #[serde(default = "nan", deserialize_with = "number")]
    pub ratio_to_none: f64,
    /// Fastest step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub min_ms: f64,
    /// Every step.
    pub samples_ms: Vec<f64>,
}

/// `pd-probe phases`: the local step, global solve and factorisation alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Phases {
    /// Vertices.
    pub n_verts: usize,
    /// Tetrahedra.
    pub n_tets: usize,
    /// Triangles, for a cloth sheet only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub n_triangles: Option<usize>,
    /// Threads.
    pub threads: usize,
    /// Damping preset.
    pub model: String,
    /// MiB streamed before each repetition (0: none).
    pub evict_mib: usize,
    /// Sleep before each repetition, microseconds (0: none).
    pub idle_us: u64,
    /// Median local step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub local_ms_median: f64,
    /// Fastest pass per part of the first constraint block, ns per
    /// constraint (empty without `--parts`).
    pub local_part_ns_per_tet_min: Vec<f64>,
    /// Median right-hand side and solve.
    #[serde(default = "nan", deserialize_with = "number")]
    pub global_solve_ms_median: f64,
    /// Median numeric factorisation.
    #[serde(default = "nan", deserialize_with = "number")]
    pub numeric_factor_ms_median: f64,
    /// Stored entries of the Cholesky factor.
    #[serde(rename = "nnz_L_factor")]
    pub nnz_l_factor: usize,
    /// Peak resident memory of the process (`VmHWM`), if known.
    pub peak_bytes: Option<u64>,
}

/// `pd-probe accuracy`: error against time per step over iteration counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Accuracy {
    /// Integrator, by its short name.
    pub integrator: String,
    /// Damping preset.
    pub model: String,
    /// Vertices.
    pub n_verts: usize,
    /// Simulated time (s).
    #[serde(default = "nan", deserialize_with = "number")]
    pub time: f64,
    /// Time step (s).
    #[serde(default = "nan", deserialize_with = "number")]
    pub dt: f64,
    /// Steps.
    pub steps: usize,
    /// Relative tolerance of the reference run.
    #[serde(default = "nan", deserialize_with = "number")]
    pub reference_tolerance: f64,
    /// Reference steps that did not converge.
    pub reference_unconverged_steps: usize,
    /// Mean iterations per reference step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub reference_mean_iterations: f64,
    /// Wall time of the reference run (s).
    #[serde(default = "nan", deserialize_with = "number")]
    pub reference_seconds: f64,
    /// `m g L`, the energy errors' scale (J).
    #[serde(default = "nan", deserialize_with = "number")]
    pub energy_scale_joule: f64,
    /// One row per iteration count.
    pub rows: Vec<AccuracyRow>,
}

/// One iteration count of [`Accuracy`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AccuracyRow {
    /// Iterations per step.
    pub iters: usize,
    /// Largest vertex distance to the reference over the body's diagonal.
    #[serde(default = "nan", deserialize_with = "number")]
    pub position_error_rel: f64,
    /// Energy error over `m g L`.
    #[serde(default = "nan", deserialize_with = "number")]
    pub energy_error_rel: f64,
    /// Median step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub step_ms_median: f64,
    /// Whether the run stopped with an error.
    pub diverged: bool,
}

/// `pd-probe bandwidth`: streaming read bandwidth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bandwidth {
    /// Bytes read per repetition.
    pub bytes: usize,
    /// Repetitions.
    pub reps: usize,
    /// Threads reading at once.
    pub threads: usize,
    /// Fastest repetition (s).
    #[serde(default = "nan", deserialize_with = "number")]
    pub best_seconds: f64,
    /// Bytes per second of the fastest repetition.
    #[serde(default = "nan", deserialize_with = "number")]
    pub bytes_per_second: f64,
    /// Sum of what was read (keeps the reads from being optimised away).
    #[serde(default = "nan", deserialize_with = "number")]
    pub checksum: f64,
}

/// `pd-probe cache-scaling`: a repeated read from 1 to 2 threads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CacheScaling {
    /// Working set (MiB).
    pub mib: usize,
    /// Reads of the working set per trial.
    pub reps: usize,
    /// Bytes per second on one thread.
    #[serde(default = "nan", deserialize_with = "number")]
    pub bytes_per_second_1_thread: f64,
    /// Bytes per second on two threads.
    #[serde(default = "nan", deserialize_with = "number")]
    pub bytes_per_second_2_threads: f64,
    /// Two threads' speed over one's.
    #[serde(default = "nan", deserialize_with = "number")]
    pub speedup: f64,
    /// Sum of what was read.
    #[serde(default = "nan", deserialize_with = "number")]
    pub checksum: f64,
}

/// `pd-probe contact`: step time with contact against the same scene
/// without any (`crate::contact`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    /// One row per scene.
    pub rows: Vec<ContactRow>,
    /// Steps measured per scene.
    pub steps: usize,
    /// Steps before the measurement.
    pub warmup: usize,
}

/// One scene of [`Contact`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactRow {
    /// What the scene is.
    pub scene: String,
    /// Cells along a cube's side.
    pub cells: usize,
    /// Upper median step without contact.
    #[serde(default = "nan", deserialize_with = "number")]
    pub without_ms: f64,
    /// Upper median step with contact.
    #[serde(default = "nan", deserialize_with = "number")]
    pub with_ms: f64,
    /// `with_ms / without_ms`.
    #[serde(default = "nan", deserialize_with = "number")]
    pub ratio: f64,
    /// Fastest round's mean step without contact.
    #[serde(default = "nan", deserialize_with = "number")]
    pub min_round_without_ms: f64,
    /// Fastest round's mean step with contact.
    #[serde(default = "nan", deserialize_with = "number")]
    pub min_round_with_ms: f64,
    /// `min_round_with_ms / min_round_without_ms`.
    #[serde(default = "nan", deserialize_with = "number")]
    pub min_round_ratio: f64,
    /// Active contacts at the end.
    pub contacts: usize,
    /// Mean iterations per step without contact.
    pub iterations_without: usize,
    /// Mean iterations per step with contact.
    pub iterations_with: usize,
}

/// A number that may be missing (`None`, and then not written), read as
/// NaN when it is `null`: the `deserialize_with` of the optional numbers
/// here (with `default`).
///
/// # Errors
/// A value that is neither a number nor `null`.
pub fn optional_number<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<Option<f64>, D::Error> {
    number(deserializer).map(Some)
}

/// `pd-probe methods`: error against cost per step for each iteration
/// method (`crate::methods`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Methods {
    /// Integrator, by its short name.
    pub integrator: String,
    /// Damping preset.
    pub damping: String,
    /// Vertices.
    pub n_verts: usize,
    /// Steps of every run.
    pub steps: usize,
    /// Time step (s).
    #[serde(default = "nan", deserialize_with = "number")]
    pub dt: f64,
    /// Relative residual of Newton's reference solution.
    #[serde(default = "nan", deserialize_with = "number")]
    pub reference_tolerance: f64,
    /// Reference steps that did not converge.
    pub reference_unconverged_steps: usize,
    /// Mean Newton iterations per reference step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub reference_iterations_per_step: f64,
    /// The local step's share of a plain iteration's time (NaN if plain PD
    /// with 20 iterations was not run).
    #[serde(default = "nan", deserialize_with = "number")]
    pub local_fraction: f64,
    /// One row per method and budget.
    pub rows: Vec<MethodsRow>,
}

/// One method and budget of [`Methods`]. A run that failed has only the
/// method, the budget, `diverged` and the error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodsRow {
    /// The method, with `+PREDICTOR` when it starts at a predictor.
    pub method: String,
    /// Iterations per step.
    pub budget: usize,
    /// Largest vertex distance to the reference over the body's diagonal.
    #[serde(
        default,
        deserialize_with = "optional_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub position_error_rel: Option<f64>,
    /// Mean iterations per step.
    #[serde(
        default,
        deserialize_with = "optional_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub iterations_per_step: Option<f64>,
    /// Mean objective evaluations per step.
    #[serde(
        default,
        deserialize_with = "optional_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub evaluations_per_step: Option<f64>,
    /// Median step.
    #[serde(
        default,
        deserialize_with = "optional_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub step_ms_median: Option<f64>,
    /// Whether the run stopped with an error.
    pub diverged: bool,
    /// The error, for a run that stopped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// A list of numbers read from JSON, NaN for each `null`: the
/// `deserialize_with` of the per-step lists here.
///
/// # Errors
/// A value that is not a list of numbers and `null`s.
pub fn numbers<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<f64>, D::Error> {
    Ok(Vec::<Option<f64>>::deserialize(deserializer)?
        .into_iter()
        .map(|x| x.unwrap_or(f64::NAN))
        .collect())
}

/// `pd-probe accuracy-target`: per iteration method, what an accuracy
/// target costs and delivers on one scene, and the method the automatic
/// choice picks (`crate::accuracy_target`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AccuracyTarget {
    /// The scene's label (`beam 2304`, `cloth strip`, `armadillo`, ...).
    pub scene: String,
    /// What the scene is, in a sentence.
    pub description: String,
    /// Vertices.
    pub n_verts: usize,
    /// Time step (s).
    #[serde(default = "nan", deserialize_with = "number")]
    pub dt: f64,
    /// Steps of each method before the measured ones.
    pub warmup: usize,
    /// Measured steps of each method.
    pub steps: usize,
    /// The iteration cap of a step (`[simulation] iterations`).
    pub iteration_cap: usize,
    /// The method of the reference solution of each measured step.
    pub reference_method: String,
    /// Its relative residual.
    #[serde(default = "nan", deserialize_with = "number")]
    pub reference_tolerance: f64,
    /// Reference steps that stopped at their cap above that residual.
    pub reference_unconverged_steps: usize,
    /// Median iterations of a reference step.
    #[serde(default = "nan", deserialize_with = "number")]
    pub reference_iterations_median: f64,
    /// One entry per accuracy target.
    pub targets: Vec<TargetRun>,
    /// Wall time of the whole measurement (s).
    #[serde(default = "nan", deserialize_with = "number")]
    pub wall_seconds: f64,
}

/// One accuracy target of [`AccuracyTarget`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetRun {
    /// The target (`[simulation] accuracy`).
    #[serde(default = "nan", deserialize_with = "number")]
    pub target: f64,
    /// The automatic choice at the scene's initial state.
    pub choice: TargetChoice,
    /// Every method, in the order of `pd_solver::SolverMethod::ALL`.
    pub methods: Vec<TargetMethod>,
}

/// What `Simulation::choose_method` chose and what its probe cost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetChoice {
    /// The chosen method.
    pub chosen: String,
    /// Whether some candidate met the target on every probe step (else
    /// the choice is the default).
    pub measured: bool,
    /// Wall time of the whole probe (ms).
    #[serde(default = "nan", deserialize_with = "number")]
    pub probe_ms: f64,
    /// Every candidate, in the order probed.
    pub candidates: Vec<TargetCandidate>,
}

/// One candidate of [`TargetChoice`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetCandidate {
    /// The method.
    pub method: String,
    /// `measured`, `excluded`, `slower`, `missed-target` or `failed`.
    pub outcome: String,
    /// Mean time of its timed probe steps (ms), when measured.
    #[serde(
        default,
        deserialize_with = "optional_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub step_ms: Option<f64>,
    /// Mean iterations of its timed probe steps, when measured.
    #[serde(
        default,
        deserialize_with = "optional_number",
        skip_serializing_if = "Option::is_none"
    )]
    pub iterations: Option<f64>,
    /// The probe's own line for it (`ProbeResult::describe`).
    pub text: String,
}

/// One method at one target of [`AccuracyTarget`]: its measured steps, one
/// entry per step in each list. A method that cannot run the scene has only
/// `excluded`; one that failed has `error` and the steps before.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetMethod {
    /// The method.
    pub method: String,
    /// Why it cannot run the scene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub excluded: Option<String>,
    /// The error that stopped it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Wall time of each step (ms).
    #[serde(default, deserialize_with = "numbers")]
    pub step_ms: Vec<f64>,
    /// Iterations of each step.
    #[serde(default)]
    pub iterations: Vec<usize>,
    /// Whether each step met the target (its estimate at most the target
    /// within the cap).
    #[serde(default)]
    pub met_target: Vec<bool>,
    /// The step's own estimate of its relative error.
    #[serde(default, deserialize_with = "numbers")]
    pub estimated_error: Vec<f64>,
    /// The step's true relative error, against the reference.
    #[serde(default, deserialize_with = "numbers")]
    pub true_error: Vec<f64>,
}

/// True errors at or below this are not compared with the estimate: there
/// the reference's own error counts (Newton's steps end far below any
/// target).
pub const TRUE_ERROR_FLOOR: f64 = 1e-6;

/// What a [`TargetMethod`]'s steps add up to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetSummary {
    /// Measured steps.
    pub steps: usize,
    /// Median step (ms).
    pub step_ms_median: f64,
    /// Median iterations.
    pub iterations_median: f64,
    /// Median true error.
    pub true_error_median: f64,
    /// Largest true error.
    pub true_error_max: f64,
    /// Steps whose estimate met the target.
    pub met_target: usize,
    /// Steps whose true error is at most the target.
    pub true_within_target: usize,
    /// Steps whose true error is above [`TRUE_ERROR_FLOOR`]: those whose
    /// ratio estimate / truth is counted.
    pub compared: usize,
    /// Median of estimate / truth over the compared steps.
    pub ratio_median: f64,
    /// Smallest of them (the worst under-report).
    pub ratio_min: f64,
    /// Largest of them.
    pub ratio_max: f64,
    /// Compared steps whose estimate is below the truth.
    pub below_one: usize,
    /// Compared steps whose estimate is below half the truth.
    pub below_half: usize,
}

impl TargetMethod {
    /// A method that cannot run the scene, and why.
    pub fn excluded(method: &str, reason: String) -> Self {
        Self {
            method: method.into(),
            excluded: Some(reason),
            error: None,
            step_ms: Vec::new(),
            iterations: Vec::new(),
            met_target: Vec::new(),
            estimated_error: Vec::new(),
            true_error: Vec::new(),
        }
    }

    /// The summary of the steps against `target`; `None` without steps.
    pub fn summary(&self, target: f64) -> Option<TargetSummary> {
        if self.step_ms.is_empty() {
            return None;
        }
        let median = pd_io::stats::median;
        let ratios: Vec<f64> = (self.estimated_error.iter().zip(&self.true_error))
            .filter(|(_, t)| **t > TRUE_ERROR_FLOOR)
            .map(|(e, t)| e / t)
            .collect();
        let iterations: Vec<f64> = self.iterations.iter().map(|&i| i as f64).collect();
        Some(TargetSummary {
            steps: self.step_ms.len(),
            step_ms_median: median(&self.step_ms),
            iterations_median: median(&iterations),
            true_error_median: median(&self.true_error),
            true_error_max: self.true_error.iter().copied().fold(f64::NAN, f64::max),
            met_target: self.met_target.iter().filter(|m| **m).count(),
            true_within_target: self.true_error.iter().filter(|t| **t <= target).count(),
            compared: ratios.len(),
            ratio_median: median(&ratios),
            ratio_min: ratios.iter().copied().fold(f64::NAN, f64::min),
            ratio_max: ratios.iter().copied().fold(f64::NAN, f64::max),
            below_one: ratios.iter().filter(|r| **r < 1.0).count(),
            below_half: ratios.iter().filter(|r| **r < 0.5).count(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A method at a target, with a step whose true error is below the
    /// floor and one whose true error is not a number.
    fn method() -> TargetMethod {
        TargetMethod {
            method: "anderson".into(),
            excluded: None,
            error: None,
            step_ms: vec![2.0, 1.0, 4.0],
            iterations: vec![5, 6, 9],
            met_target: vec![true, true, false],
            estimated_error: vec![0.004, 0.008, 0.02],
            true_error: vec![0.01, 1e-9, f64::NAN],
        }
    }

    /// `pd-probe accuracy-target`'s output writes and reads back as it
    /// was, a NaN as `null` and back.
    #[test]
    fn an_accuracy_target_run_round_trips() {
        let run = AccuracyTarget {
            scene: "beam 20".into(),
            reference_tolerance: f64::NAN,
            targets: vec![TargetRun {
                target: 0.01,
                choice: TargetChoice {
                    chosen: "anderson".into(),
                    measured: true,
                    probe_ms: 12.5,
                    candidates: vec![
                        TargetCandidate {
                            method: "anderson".into(),
                            outcome: "measured".into(),
                            step_ms: Some(1.5),
                            iterations: Some(5.0),
                            text: "anderson: 1.500 ms a step".into(),
                        },
                        TargetCandidate {
                            method: "newton".into(),
                            outcome: "slower".into(),
                            step_ms: None,
                            iterations: None,
                            text: "newton: stopped".into(),
                        },
                    ],
                },
                methods: vec![method(), TargetMethod::excluded("lbfgs", "no".into())],
            }],
            ..AccuracyTarget::default()
        };
        let text = serde_json::to_string(&run).unwrap();
        assert!(text.contains("null"), "{text}");
        let back: AccuracyTarget = serde_json::from_str(&text).unwrap();
        assert!(back.reference_tolerance.is_nan());
        assert!(back.targets[0].methods[0].true_error[2].is_nan());
        // NaN is not equal to itself: compare the text written again.
        assert_eq!(serde_json::to_string(&back).unwrap(), text);
        let excluded = &back.targets[0].methods[1];
        assert_eq!(excluded.excluded.as_deref(), Some("no"));
        assert!(excluded.summary(0.01).is_none());
    }

    /// The summary counts ratios only above the floor, and the target
    /// met by the estimate and by the truth separately.
    #[test]
    fn the_summary_of_a_method_counts_what_it_says() {
        let s = method().summary(0.01).unwrap();
        assert_eq!((s.steps, s.met_target, s.true_within_target), (3, 2, 2));
        assert_eq!((s.step_ms_median, s.iterations_median), (2.0, 6.0));
        // Only the first step is compared: 0.004 / 0.01.
        assert_eq!((s.compared, s.below_one, s.below_half), (1, 1, 1));
        assert!((s.ratio_median - 0.4).abs() < 1e-12);
        assert_eq!(s.ratio_min, s.ratio_max);
        assert_eq!(s.true_error_max, 0.01);
    }
}
