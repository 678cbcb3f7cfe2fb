//! A damping model of your own, outside `pd-damping`: it damps only the
//! velocity along one direction (here vertical), like a dashpot acting on
//! the height of every vertex, and leaves horizontal motion alone.
//!
//! It uses the velocity-filter channel of `pd_damping::Damping`: after each
//! step, `v . d` decays by `exp(-rate h)`, the exact decay of
//! `d(v . d)/dt = -rate (v . d)` over the step, so the effect does not
//! depend on the time step. Nothing in the workspace is edited; the
//! simulation takes the model as a `Box<dyn Damping>`.
//!
//! `cargo run -p pd --example custom_damping`

use pd::damping::DampingContext;
use pd::prelude::*;

/// Damps the velocity component along `direction` (a unit vector) at
/// `rate` (1/s); fixed vertices are left at rest.
#[derive(Debug, Clone, Copy)]
struct DirectionalDrag {
    direction: Point,
    rate: f64,
}

impl Damping for DirectionalDrag {
    fn name(&self) -> &'static str {
        "directional-drag"
    }

    fn filter_velocities(
        &self,
        context: &DampingContext<'_>,
        _positions: &[Point],
        velocities: &mut [Point],
    ) {
        let keep = (-self.rate * context.h).exp();
        for (v, &fixed) in velocities.iter_mut().zip(context.fixed) {
            if !fixed {
                let along = v.dot(&self.direction);
                *v -= self.direction * (along * (1.0 - keep));
            }
        }
    }
}

/// A free block thrown sideways and upwards, without gravity.
fn thrown(damping: Box<dyn Damping>) -> Result<Simulation, Box<dyn std::error::Error>> {
    let block = generators::box_tets([0.2, 0.2, 0.2], [2, 2, 2])?;
    let masses = block.lumped_masses(500.0)?;
    let mut model = Model::new();
    let body = model.add_body(block, masses)?;
    model.add_tet_strain(body, 1e5, None)?;
    let mut sim = Simulation::builder(model)
        .integrator(ImplicitMidpoint)
        .damping_boxed(damping)
        .dt(0.01)
        .gravity(Point::zeros())
        .build()?;
    sim.add_rigid_velocity(0, Point::new(1.0, 1.0, 0.0), Point::zeros())
        .unwrap();
    Ok(sim)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let drag = DirectionalDrag {
        direction: Point::new(0.0, 1.0, 0.0),
        rate: 2.0,
    };
    for (label, damping) in [
        ("undamped", Box::new(NoDamping) as Box<dyn Damping>),
        ("vertical drag, 2/s", Box::new(drag)),
    ] {
        let mut sim = thrown(damping)?;
        let mass: f64 = sim.model().masses().iter().sum();
        sim.run(100)?;
        let velocity = sim.linear_momentum() / mass;
        println!(
            "{label:>20}: after 1 s the block moves at ({:.4}, {:.4}) m/s",
            velocity.x, velocity.y
        );
    }
    // The vertical speed decays as exp(-2 t): 1 m/s -> 0.1353 m/s after 1 s;
    // the horizontal speed is untouched.
    Ok(())
}
