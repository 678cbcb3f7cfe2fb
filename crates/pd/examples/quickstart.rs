//! A cantilever beam in a few lines: build a model, pick an integrator and
//! a damping model, step, read the result.
//!
//! `cargo run -p pd --example quickstart`

use pd::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A 1 x 0.2 x 0.2 m beam of 10 x 2 x 2 cubes (6 tets each), 1000 kg/m^3.
    let beam = generators::box_tets([1.0, 0.2, 0.2], [10, 2, 2])?;
    let clamp = VertexSelection::Box {
        min: [-1.0; 3],
        max: [1e-9, 1.0, 1.0],
    }
    .resolve(&beam)?;
    let masses = beam.lumped_masses(1000.0)?;
    let mut model = Model::new();
    let body = model.add_body(beam, masses)?;
    model.add_tet_strain(body, 1e6, None)?; // corotational strain, 1e6 Pa
    model.fix_vertices(body, &clamp)?;

    // Implicit midpoint adds no numerical damping: all damping is the
    // Laplacian damping's, a2 = 0.003 s.
    let damping = LaplacianDamping::new(0.003, 0.0, false)?;
    let mut sim = Simulation::builder(model)
        .integrator(ImplicitMidpoint)
        .damping(damping)
        .dt(0.01)
        .iterations(10)
        .build()?;
    for second in 1..=3 {
        sim.run(100)?;
        let tip = sim
            .state()
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        let e = sim.energies();
        println!(
            "t = {second} s: lowest point {tip:+.4} m, kinetic {:.3e} J, elastic {:.3e} J",
            e.kinetic, e.elastic
        );
    }
    Ok(())
}
