//! Checkpoint files: a run's full state after some step together with the
//! scene it belongs to, so that `pd resume` can continue the run and produce
//! results identical bit for bit to an uninterrupted run.
//!
//! A checkpoint is one JSON object (written atomically, so an interrupted
//! write leaves the previous checkpoint intact):
//!
//! ```json
//! {
//!   "format": "pd-checkpoint",
//!   "version": 1,
//!   "scene": { "source": "/abs/path/scene.toml", "syntax": "toml",
//!              "text": "...the scene file's text...", "hash": "fnv1a64:0123456789abcdef" },
//!   "steps_requested": 200,
//!   "threads": 0,
//!   "checkpoint_every": 20,
//!   "steps": 40, "time": 0.4,
//!   "integrator": "bdf2",
//!   "positions": [[x, y, z], ...], "velocities": [[x, y, z], ...],
//!   "history": [ { "positions": [...], "velocities": [...] } ],
//!   "energy_reference": -1.5, "energy_scale": 12.0
//! }
//! ```
//!
//! Optional keys, written only when there is something to keep: `contact`
//! (the active contacts), `predictor` (the predictor's corrections),
//! `rotation` (the rotation-preserving damping's reference lever arms,
//! `{ "arms": [[x, y, z], ...], "key": [...] }`, `pd_solver::RotationState`)
//! and `solver` (what the iteration method carries between steps: `[rho]`,
//! the estimate of Chebyshev with `rho = "auto"`), e.g.
//!
//! ```json
//! { "...": "...", "solver": [0.7712] }
//! ```
//!
//! `model`, the fingerprint of the model the state belongs to
//! (`pd_solver::Model::fingerprint`, as `fnv1a64:` and 16 hex digits):
//! restoring refuses the checkpoint into a simulation of another model,
//! e.g. when a mesh file the scene names was changed since. A file without
//! it (written before it was kept) is restored without that check.
//! `contraction` (the local-global contraction the error estimate carries
//! from step to step, docs/design/solver.md "How far from converged"),
//! and `method`, the iteration method a run chose by measurement (a scene
//! with `accuracy` and no `[solver] method`), which `pd resume` keeps
//! rather than choosing again: `"method": "lbfgs"`.
//!
//! The scene's text is embedded (with the absolute path it was read from, so
//! that relative mesh paths still resolve) and a 64-bit FNV-1a hash of it,
//! which reading checks: an edited or damaged scene text is refused. Files
//! the scene refers to (meshes, initial states) are not embedded; the
//! simulation rebuilt from them must have the checkpoint's vertex count.
//! `steps_requested` and `threads` are the run's values after command-line
//! overrides. Numbers are written with serde_json's shortest round-trip
//! formatting and read back with its `float_roundtrip` parser, so every
//! `f64` comes back with the same bits.

use std::io::Write;
use std::path::{Path, PathBuf};

use pd_integrators::History;
use pd_mesh::Point;
use pd_solver::{Checkpoint, State};
use serde::{Deserialize, Serialize};

use crate::atomic::write_atomically;
use crate::scene::Syntax;
use crate::{Error, Result};

/// The file name of a run's checkpoint inside its output folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";

/// The scene a checkpoint belongs to.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneText {
    /// Where the text was read from (absolute when it could be resolved);
    /// relative paths inside the scene are anchored at its folder.
    pub source: PathBuf,
    /// TOML or JSON.
    pub syntax: Syntax,
    /// The scene file's text.
    pub text: String,
}

impl SceneText {
    /// The 64-bit FNV-1a hash of the text, as `fnv1a64:` and 16 hex digits.
    /// It detects accidental edits and damage, not deliberate tampering.
    pub fn hash(&self) -> String {
        let mut hash = crate::hash::Fnv1a::new();
        hash.write_bytes(self.text.as_bytes());
        format!("fnv1a64:{:016x}", hash.finish())
    }
}

/// A checkpoint file's contents.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckpointFile {
    /// The scene.
    pub scene: SceneText,
    /// Steps the run is to take in all (the scene's, or the override).
    pub steps_requested: usize,
    /// Threads of the local step (0: all cores).
    pub threads: usize,
    /// The run's checkpoint interval in steps, which a resumed run keeps.
    pub checkpoint_every: usize,
    /// The simulation's state.
    pub checkpoint: Checkpoint,
    /// The iteration method the run chose by measurement (a scene with
    /// `accuracy` and no `[solver] method`), which a resumed run keeps;
    /// `None` when the scene names the method.
    pub method: Option<String>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    source: PathBuf,
    syntax: String,
    text: String,
    hash: String,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawState {
    positions: Vec<[f64; 3]>,
    velocities: Vec<[f64; 3]>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    format: String,
    version: u32,
    scene: RawScene,
    steps_requested: usize,
    threads: usize,
    checkpoint_every: usize,
    steps: usize,
    time: f64,
    integrator: String,
    positions: Vec<[f64; 3]>,
    velocities: Vec<[f64; 3]>,
    history: Vec<RawState>,
    energy_reference: f64,
    energy_scale: f64,
    /// Written only when a contact is active, so that files without
    /// contact are as before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    contact: Option<crate::checkpoint_contact::RawContact>,
    /// The extrapolated predictor's stored correction, written only when
    /// there is one (pd_solver::PredictorState).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    predictor: Option<RawPredictor>,
    /// The rotation-preserving damping's reference lever arms, written
    /// only when there are some (pd_solver::RotationState).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rotation: Option<RawRotation>,
    /// What the iteration method carries between steps (Chebyshev's
    /// estimated `rho`), written only when there is something.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    solver: Vec<f64>,
    /// The method chosen by measurement, written only when the run chose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    method: Option<String>,
    /// The model's fingerprint (`fnv1a64:` and 16 hex digits), written
    /// whenever the checkpoint has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    model: Option<String>,
    /// The contraction the error estimate carries between steps, written
    /// only when there is one.
    #[serde(default, skip_serializing_if = "is_zero")]
    contraction: f64,
}

/// Whether an optional number is absent (0).
fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// `pd_solver::PredictorState`: the last step's correction (m per vertex)
/// and the step's `[h, c1, c2, gamma]`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPredictor {
    correction: Vec<[f64; 3]>,
    key: [f64; 4],
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    previous: Vec<[f64; 3]>,
    /// The fitted predictor's older corrections, newest first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    history: Vec<Vec<[f64; 3]>>,
}

/// `pd_solver::RotationState`: the reference lever arms (m per projected
/// vertex) and the step matrix's coefficients they were solved with.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRotation {
    arms: Vec<[f64; 3]>,
    key: Vec<f64>,
}

const FORMAT: &str = "pd-checkpoint";
const VERSION: u32 = 1;
/// How the `model` key spells a fingerprint: this, then 16 hex digits.
const MODEL_PREFIX: &str = "fnv1a64:";

/// The `model` key's fingerprint, 0 when the file has none.
fn model_fingerprint(raw: &Raw, field: impl Fn(&str, String) -> Error) -> Result<u64> {
    let Some(text) = &raw.model else {
        return Ok(0);
    };
    text.strip_prefix(MODEL_PREFIX)
        .filter(|hex| hex.len() == 16)
        .and_then(|hex| u64::from_str_radix(hex, 16).ok())
        .filter(|&fingerprint| fingerprint != 0)
        .ok_or_else(|| {
            field(
                "model",
                format!(
                    "is {}; expected {MODEL_PREFIX} and 16 hex digits, not all zero",
                    crate::lines::quoted(text)
                ),
            )
        })
}

fn arrays(points: &[Point]) -> Vec<[f64; 3]> {
    points.iter().map(|p| [p.x, p.y, p.z]).collect()
}

fn points(arrays: &[[f64; 3]]) -> Vec<Point> {
    arrays.iter().map(|&a| Point::from(a)).collect()
}

/// Writes a checkpoint file, replacing any previous one atomically.
///
/// # Errors
/// [`Error::Content`] for a non-finite number (JSON cannot hold it);
/// [`Error::Io`] naming `path`.
pub fn write_checkpoint(path: &Path, file: &CheckpointFile) -> Result<()> {
    let text = checkpoint_to_json(path, file)?;
    write_atomically(path, |w| writeln!(w, "{text}"))
}

/// The text of a checkpoint file (one line of JSON, without the final
/// newline): what [`write_checkpoint`] writes and [`checkpoint_from_json`]
/// reads back bit for bit. `path` names the checkpoint in messages.
///
/// # Errors
/// [`Error::Content`] for a non-finite number (JSON cannot hold it).
pub fn checkpoint_to_json(path: &Path, file: &CheckpointFile) -> Result<String> {
    let c = &file.checkpoint;
    let finite = |points: &[Point]| points.iter().all(|p| p.iter().all(|x| x.is_finite()));
    let history_finite = c.history.states.iter().all(|(x, v)| finite(x) && finite(v));
    if !(finite(&c.state.positions)
        && finite(&c.state.velocities)
        && history_finite
        && c.time.is_finite()
        && c.energy_reference.is_finite()
        && c.energy_scale.is_finite()
        && (c.contact.colliders.iter().chain(&c.contact.pairs))
            .all(|s| s.force.iter().chain(&s.normal).all(|x| x.is_finite()))
        && finite(&c.predictor.correction)
        && finite(&c.predictor.previous)
        && c.predictor.history.iter().all(|h| finite(h))
        && c.predictor.key.iter().all(|x| x.is_finite())
        && finite(&c.rotation.arms)
        && c.rotation.key.iter().all(|x| x.is_finite())
        && c.solver.iter().all(|x| x.is_finite()))
    {
        return Err(Error::Content {
            path: path.to_path_buf(),
            message: "the state has a non-finite value; JSON cannot hold it".into(),
        });
    }
    let raw = Raw {
        format: FORMAT.into(),
        version: VERSION,
        scene: RawScene {
            source: file.scene.source.clone(),
            syntax: match file.scene.syntax {
                Syntax::Toml => "toml".into(),
                Syntax::Json => "json".into(),
            },
            text: file.scene.text.clone(),
            hash: file.scene.hash(),
        },
        steps_requested: file.steps_requested,
        threads: file.threads,
        checkpoint_every: file.checkpoint_every,
        steps: c.steps,
        time: c.time,
        integrator: c.integrator.clone(),
        model: (c.model != 0).then(|| format!("{MODEL_PREFIX}{:016x}", c.model)),
        positions: arrays(&c.state.positions),
        velocities: arrays(&c.state.velocities),
        history: c
            .history
            .states
            .iter()
            .map(|(x, v)| RawState {
                positions: arrays(x),
                velocities: arrays(v),
            })
            .collect(),
        energy_reference: c.energy_reference,
        energy_scale: c.energy_scale,
        contact: crate::checkpoint_contact::RawContact::of(&c.contact),
        predictor: (!c.predictor.is_empty()).then(|| RawPredictor {
            correction: arrays(&c.predictor.correction),
            key: c.predictor.key,
            previous: arrays(&c.predictor.previous),
            history: c.predictor.history.iter().map(|h| arrays(h)).collect(),
        }),
        rotation: (!c.rotation.is_empty()).then(|| RawRotation {
            arms: arrays(&c.rotation.arms),
            key: c.rotation.key.clone(),
        }),
        solver: c.solver.clone(),
        method: file.method.clone(),
        contraction: c.contraction,
    };
    serde_json::to_string(&raw).map_err(|e| Error::Content {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Reads and checks a checkpoint file.
///
/// # Errors
/// [`Error::Io`] if it cannot be read; [`Error::Parse`] (with the line) for
/// malformed JSON, a missing or unknown key; [`Error::Field`] naming the
/// field for a wrong format name or version, a scene text whose hash does
/// not match, an unknown syntax, or states of mismatched lengths.
pub fn read_checkpoint(path: &Path) -> Result<CheckpointFile> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    checkpoint_from_json(path, &text)
}

/// Reads and checks the text of a checkpoint file; `path` names it in
/// messages.
///
/// # Errors
/// As [`read_checkpoint`], except that nothing is read from disk.
pub fn checkpoint_from_json(path: &Path, text: &str) -> Result<CheckpointFile> {
    let raw = parse_raw(path, text)?;
    let field = |field: &str, message: String| Error::Field {
        path: path.to_path_buf(),
        field: field.into(),
        message,
    };
    let scene = checked_scene(&raw, field)?;
    check_state(&raw, field)?;
    let model = model_fingerprint(&raw, field)?;
    Ok(into_file(raw, scene, model))
}

/// The checkpoint's JSON image; a type or value error names its field, a
/// syntax error its line.
fn parse_raw(path: &Path, text: &str) -> Result<Raw> {
    let mut deserializer = serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(&mut deserializer).map_err(|err| {
        let field = err.path().to_string();
        let inner = err.into_inner();
        if inner.classify() == serde_json::error::Category::Data && field != "." {
            Error::Field {
                path: path.to_path_buf(),
                field,
                message: inner.to_string(),
            }
        } else {
            Error::Parse {
                path: path.to_path_buf(),
                line: inner.line().max(1),
                message: inner.to_string(),
            }
        }
    })
}

/// The format and version, and the embedded scene text, whose syntax must
/// be known and whose hash must match.
fn checked_scene(raw: &Raw, field: impl Fn(&str, String) -> Error) -> Result<SceneText> {
    if raw.format != FORMAT {
        return Err(field(
            "format",
            format!("is {:?}, expected {FORMAT:?}", raw.format),
        ));
    }
    if raw.version != VERSION {
        return Err(field(
            "version",
            format!("is {}, this pd reads version {VERSION}", raw.version),
        ));
    }
    let syntax = match raw.scene.syntax.as_str() {
        "toml" => Syntax::Toml,
        "json" => Syntax::Json,
        other => {
            return Err(field(
                "scene.syntax",
                format!("is {other:?}, expected \"toml\" or \"json\""),
            ));
        }
    };
    let scene = SceneText {
        source: raw.scene.source.clone(),
        syntax,
        text: raw.scene.text.clone(),
    };
    if scene.hash() != raw.scene.hash {
        return Err(field(
            "scene.hash",
            format!(
                "is {}, but the embedded scene text hashes to {}: the checkpoint was edited or damaged",
                raw.scene.hash,
                scene.hash()
            ),
        ));
    }
    Ok(scene)
}

/// The run's counters and the state's lengths.
fn check_state(raw: &Raw, field: impl Fn(&str, String) -> Error) -> Result<()> {
    if raw.steps_requested < raw.steps {
        return Err(field(
            "steps_requested",
            format!(
                "is {}, below the {} steps already run",
                raw.steps_requested, raw.steps
            ),
        ));
    }
    if !(raw.time.is_finite() && raw.time >= 0.0) {
        return Err(field(
            "time",
            format!("must be finite and >= 0 s, got {}", raw.time),
        ));
    }
    if !(raw.energy_scale.is_finite() && raw.energy_scale > 0.0) {
        return Err(field(
            "energy_scale",
            format!("must be finite and > 0 J, got {}", raw.energy_scale),
        ));
    }
    if raw.threads > pd_solver::Settings::MAX_THREADS {
        return Err(field(
            "threads",
            format!(
                "must be at most {}, got {}",
                pd_solver::Settings::MAX_THREADS,
                raw.threads
            ),
        ));
    }
    let n = raw.positions.len();
    if raw.velocities.len() != n {
        return Err(field(
            "velocities",
            format!("has {} entries for {n} positions", raw.velocities.len()),
        ));
    }
    for (i, state) in raw.history.iter().enumerate() {
        if state.positions.len() != n || state.velocities.len() != n {
            return Err(field(
                &format!("history[{i}]"),
                format!(
                    "has {} positions and {} velocities for {n} vertices",
                    state.positions.len(),
                    state.velocities.len()
                ),
            ));
        }
    }
    Ok(())
}

/// The checked image as the solver's checkpoint and the run's settings.
fn into_file(raw: Raw, scene: SceneText, model: u64) -> CheckpointFile {
    CheckpointFile {
        scene,
        steps_requested: raw.steps_requested,
        threads: raw.threads,
        checkpoint_every: raw.checkpoint_every,
        method: raw.method,
        checkpoint: Checkpoint {
            steps: raw.steps,
            time: raw.time,
            state: State {
                positions: points(&raw.positions),
                velocities: points(&raw.velocities),
            },
            integrator: raw.integrator,
            model,
            history: History {
                states: raw
                    .history
                    .iter()
                    .map(|s| (points(&s.positions), points(&s.velocities)))
                    .collect(),
            },
            energy_reference: raw.energy_reference,
            energy_scale: raw.energy_scale,
            contact: raw.contact.map(Into::into).unwrap_or_default(),
            predictor: raw
                .predictor
                .map(|p| pd_solver::PredictorState {
                    correction: points(&p.correction),
                    key: p.key,
                    previous: points(&p.previous),
                    history: p.history.iter().map(|h| points(h)).collect(),
                })
                .unwrap_or_default(),
            solver: raw.solver,
            contraction: raw.contraction,
            rotation: raw
                .rotation
                .map(|r| pd_solver::RotationState {
                    arms: points(&r.arms),
                    key: r.key,
                })
                .unwrap_or_default(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> CheckpointFile {
        let awkward = [
            Point::new(0.1, 1.0 / 3.0, -1e-300),
            Point::new(f64::MAX, f64::MIN_POSITIVE, -0.0),
        ];
        CheckpointFile {
            scene: SceneText {
                source: PathBuf::from("/tmp/scene.toml"),
                syntax: Syntax::Toml,
                text: "[simulation]\ndt = 0.01\nsteps = 3\n\"quoted\" = 1\n".into(),
            },
            steps_requested: 7,
            threads: 1,
            checkpoint_every: 3,
            method: Some("lbfgs".into()),
            checkpoint: Checkpoint {
                steps: 3,
                time: 0.03,
                state: State {
                    positions: awkward.to_vec(),
                    velocities: vec![awkward[1], awkward[0]],
                },
                integrator: "bdf2".into(),
                model: 0x0123_4567_89ab_cdef,
                history: History {
                    states: vec![(awkward.to_vec(), awkward.to_vec())],
                },
                energy_reference: -2.0 / 7.0,
                energy_scale: 1e-17 / 3.0,
                contact: Default::default(),
                predictor: Default::default(),
                solver: vec![0.7234567890123457],
                contraction: 0.9987654321,
                rotation: pd_solver::RotationState {
                    arms: awkward.to_vec(),
                    key: vec![1e4, 0.25, 1.0 / 3.0, 0.0, 0.0, 0.0],
                },
            },
        }
    }

    fn temp(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("pd-io-checkpoint-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(CHECKPOINT_FILE)
    }

    #[test]
    fn round_trips_every_bit() {
        let path = temp("round-trip");
        let file = sample();
        write_checkpoint(&path, &file).unwrap();
        let back = read_checkpoint(&path).unwrap();
        // PartialEq on f64 would accept -0.0 == 0.0: compare bits too.
        assert_eq!(back, file);
        let bits = |p: &[Point]| {
            p.iter()
                .flat_map(|v| v.iter().map(|x| x.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            bits(&back.checkpoint.state.positions),
            bits(&file.checkpoint.state.positions)
        );
        assert_eq!(
            back.checkpoint.energy_scale.to_bits(),
            file.checkpoint.energy_scale.to_bits()
        );
    }

    #[test]
    fn the_text_form_is_the_file_and_reads_back_the_same() {
        let path = temp("text");
        let file = sample();
        write_checkpoint(&path, &file).unwrap();
        let text = checkpoint_to_json(&path, &file).unwrap();
        // The file is the text and a final newline.
        assert_eq!(std::fs::read_to_string(&path).unwrap(), format!("{text}\n"));
        let back = checkpoint_from_json(Path::new("in-memory"), &text).unwrap();
        assert_eq!(back, file);
        let err = checkpoint_from_json(Path::new("in-memory"), "{}")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("in-memory:"), "{err}");
    }

    #[test]
    fn refuses_edited_scene_text_and_bad_fields() {
        let path = temp("edited");
        write_checkpoint(&path, &sample()).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let edited = text.replace("steps = 3", "steps = 4");
        std::fs::write(&path, edited).unwrap();
        let err = read_checkpoint(&path).unwrap_err().to_string();
        assert!(err.contains("scene.hash"), "{err}");

        std::fs::write(&path, text.replace("\"pd-checkpoint\"", "\"other\"")).unwrap();
        let err = read_checkpoint(&path).unwrap_err().to_string();
        assert!(err.contains("format"), "{err}");

        std::fs::write(&path, &text[..text.len() / 2]).unwrap();
        let err = read_checkpoint(&path).unwrap_err().to_string();
        assert!(err.contains(&format!("{}:1", path.display())), "{err}");

        std::fs::write(&path, "").unwrap();
        assert!(read_checkpoint(&path).is_err());
    }

    #[test]
    fn refuses_edited_counters_naming_the_field() {
        let path = temp("counters");
        type Edit = fn(&mut CheckpointFile);
        let cases: [(&str, Edit); 4] = [
            ("steps_requested", |f| f.steps_requested = 2),
            ("time", |f| f.checkpoint.time = -1.0),
            ("energy_scale", |f| f.checkpoint.energy_scale = -1.0),
            ("threads", |f| f.threads = 1_000_000),
        ];
        for (name, edit) in cases {
            let mut file = sample();
            edit(&mut file);
            write_checkpoint(&path, &file).unwrap();
            let err = read_checkpoint(&path).unwrap_err().to_string();
            assert!(
                err.starts_with(&format!("{}: {name}: ", path.display())),
                "{name}: {err}"
            );
        }
    }

    #[test]
    fn reads_the_model_fingerprint_or_its_absence_and_refuses_a_malformed_one() {
        let path = temp("model");
        write_checkpoint(&path, &sample()).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let key = "\"model\":\"fnv1a64:0123456789abcdef\",";
        assert!(text.contains(key), "{text}");
        // A file written before the key was kept reads, without a fingerprint.
        std::fs::write(&path, text.replace(key, "")).unwrap();
        assert_eq!(read_checkpoint(&path).unwrap().checkpoint.model, 0);
        for bad in [
            "fnv1a64:0123",
            "0123456789abcdef",
            "fnv1a64:0000000000000000",
            "fnv1a64:xyz3456789abcdef",
        ] {
            let edited = text.replace("fnv1a64:0123456789abcdef", bad);
            std::fs::write(&path, edited).unwrap();
            let err = read_checkpoint(&path).unwrap_err().to_string();
            assert!(
                err.starts_with(&format!("{}: model: ", path.display())),
                "{bad}: {err}"
            );
        }
    }

    #[test]
    fn refuses_non_finite_state() {
        let path = temp("nan");
        let mut file = sample();
        file.checkpoint.state.velocities[1].y = f64::NAN;
        let err = write_checkpoint(&path, &file).unwrap_err().to_string();
        assert!(err.contains("non-finite"), "{err}");
    }
}
