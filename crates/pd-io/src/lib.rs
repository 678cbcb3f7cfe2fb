//! Files in and out of the pd simulator: scene files (TOML or JSON, the same
//! structure), meshes (TetGen `.node`/`.ele`/`.face`, Gmsh `.msh` 4.1,
//! Wavefront OBJ, Medit `.mesh`), frame files (legacy VTK, VTK XML `.vtu`
//! with a `.pvd` series, OBJ, PLY), initial-state files, and the run
//! recorder that writes `metrics.csv`, `probes.csv`, `summary.json` and
//! frames.
//!
//! Every reader and writer is hand-written, with no dependency beyond the
//! workspace's (so none needs a cargo feature).
//!
//! Readers never panic on malformed input: every error names the file and
//! the line or field. Writers write atomically (a temporary file, then a
//! rename), so an interrupted run never leaves a half-written file.
//!
//! ```
//! use pd_io::scene::{Scene, Syntax};
//! use std::path::Path;
//!
//! let text = r#"
//! [simulation]
//! dt = 0.01
//! steps = 5
//!
//! [[body]]
//! mesh = { generator = "chain", points = 4, length = 1.0 }
//! vertex_mass = 0.1
//! constraints = [ { kind = "spring", stiffness = 100.0 } ]
//! fixed = { vertices = [0] }
//! "#;
//! let scene = Scene::parse(text, Syntax::Toml, Path::new("chain.toml")).unwrap();
//! let mut sim = scene.build().unwrap();
//! sim.run(scene.steps).unwrap();
//! assert!(sim.state().positions[3].y < 0.0); // the chain falls under gravity
//!
//! // Unknown keys are rejected with their place.
//! let err = Scene::parse("[simulation]\ndt = 0.01\nsteps = 1\nspeed = 2\n", Syntax::Toml, Path::new("bad.toml")).unwrap_err();
//! assert!(err.to_string().contains("bad.toml:4"), "{err}");
//! ```

mod atomic;
pub mod checkpoint;
mod checkpoint_contact;
mod error;
pub mod frames;
pub mod gmsh;
pub mod hash;
mod lines;
pub mod medit;
pub mod modes_report;
pub mod obj;
pub mod ply;
pub mod probes;
mod readers;
pub mod recorder;
pub mod scene;
pub mod state;
pub mod stats;
pub mod strain;
pub mod tetgen;
pub mod vtu;

pub use atomic::write_atomically;
pub use error::{Error, Result};
