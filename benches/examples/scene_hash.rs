//! `cargo run -p pd-benches --example scene_hash -- SCENE.toml STEPS`:
//! runs a scene for `STEPS` steps (after the scene's own setup) and prints
//! an FNV-1a hash of every position and velocity bit, so that a change
//! which must not move results can be checked bit for bit on any scene,
//! contact scenes included.

use std::path::Path;

use pd_io::scene::{Scene, Syntax};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [path, steps] = args.as_slice() else {
        return Err("usage: scene_hash SCENE.toml STEPS".into());
    };
    let steps: usize = steps.parse().map_err(|_| format!("STEPS: {steps:?}"))?;
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let scene = Scene::parse(&text, Syntax::Toml, Path::new(path)).map_err(|e| e.to_string())?;
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    sim.run(steps).map_err(|e| e.to_string())?;
    let hash = pd_benches::state_hash(sim.state());
    println!("{path} {steps} steps: {hash:016x}");
    Ok(())
}
