//! A constraint kind of your own, outside `pd-constraints`: a *rail* that
//! keeps one vertex on the horizontal line `y = height, z = 0`. It is a
//! Projective Dynamics constraint like the built-in ones: a weight, a linear
//! operator `G` (here: select the vertex), and a projection onto the
//! constraint set (here: the closest point of the line). The solver puts
//! `w G^T G` into its prefactored matrix and projects it in the parallel
//! local step with the rest.
//!
//! A chain of springs hangs from a vertex that slides freely along the rail:
//! gravity swings the chain and the slider rides along.
//!
//! `cargo run -p pd --example custom_constraint`

use pd::prelude::*;

/// Keeps vertex `vertex[0]` on the line `y = height, z = 0` with weight
/// `stiffness` (N/m).
#[derive(Debug, Clone)]
struct Rail {
    vertex: [usize; 1],
    height: f64,
    stiffness: f64,
}

impl Constraint for Rail {
    const STENCIL: usize = 1;
    const ROWS: usize = 1;
    // It sees the absolute position, so it is an anchor, like an attachment.
    const TRANSLATION_INVARIANT: bool = false;
    const KIND: &'static str = "rail";

    type Vertices<'a> = &'a [usize];

    fn vertices(&self) -> &[usize] {
        &self.vertex
    }

    fn weight(&self) -> f64 {
        self.stiffness
    }

    fn operator(&self, _row: usize, _column: usize) -> f64 {
        1.0
    }

    fn project(&self, gx: &[Point], out: &mut [Point]) {
        out[0] = Point::new(gx[0].x, self.height, 0.0);
    }

    fn gx_hessian(&self, _gx: &[Point], _project_psd: bool, out: &mut [f64]) {
        // Energy w/2 ((y - height)^2 + z^2): constant Hessian diag(0, w, w).
        out.iter_mut().for_each(|h| *h = 0.0);
        out[4] = self.stiffness;
        out[8] = self.stiffness;
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A horizontal chain of 6 vertices over 1 m, 0.1 kg each.
    let chain = generators::chain(6, 1.0)?;
    let mut model = Model::new();
    let body = model.add_body(chain, vec![0.1; 6])?;
    model.add_springs(body, 200.0)?;
    let first = model.bodies()[body.0].offset;
    let height = model.rest_positions()[first].y;
    model.add_constraints(vec![Rail {
        vertex: [first],
        height,
        stiffness: 1e4,
    }])?;
    // Backward Euler and no damping are the builder's defaults.
    let mut sim = Simulation::builder(model).dt(0.01).iterations(20).build()?;
    for _ in 0..5 {
        sim.run(20)?;
        let s = sim.state().positions[first];
        let end = sim.state().positions[first + 5];
        println!(
            "t = {:.1} s: slider at x = {:+.3} m (y {:+.4}), chain end at ({:+.3}, {:+.3}) m",
            sim.time(),
            s.x,
            s.y - height,
            end.x,
            end.y
        );
    }
    Ok(())
}
