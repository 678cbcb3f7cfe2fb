//! A scene file loaded and built in one call, then stepped from Rust: the
//! bundled cantilever (`scenes/cantilever.toml`, or a scene named on the
//! command line), with its energies printed every 50 steps.
//!
//! `cargo run -p pd --example load_scene [-- SCENE.toml]`

use pd::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).unwrap_or_else(|| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/cantilever.toml").into()
    });
    let mut sim = load_scene(&path)?;
    println!(
        "{path}: {} vertices, dt {} s",
        sim.state().positions.len(),
        sim.settings().dt
    );
    for _ in 0..4 {
        sim.run(50)?;
        let e = sim.energies();
        println!(
            "t = {:.2} s: kinetic {:.4e} J, elastic {:.4e} J, total {:.4e} J",
            sim.time(),
            e.kinetic,
            e.elastic,
            e.total()
        );
    }
    Ok(())
}
