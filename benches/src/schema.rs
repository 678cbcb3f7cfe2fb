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
