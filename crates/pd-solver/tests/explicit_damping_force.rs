//! The explicit-force channel of the `Damping` trait: a force `f` returned by
//! `add_explicit_force` enters the inertial target as `c1 c2 h^2 M^-1 f`
//! (docs/design/integrators.md), so that each integrator applies it by its own
//! force law. With no other net force (free body, no gravity, springs only)
//! the momentum then follows exactly
//! - backward Euler and implicit midpoint: `p_{n+1} = p_n + h F`,
//! - BDF-2 (after its backward Euler start): `p_{n+1} = (4 p_n - p_{n-1})/3 + 2h/3 F`,
//!
//! with `F` the total force. A wrong factor (`h^2` instead of `c1 c2 h^2`)
//! would double the impulse for implicit midpoint and miss BDF-2's 4/9.

mod common;

use common::{SCHEMES, Scheme, U, laplacian_norm};
use pd_damping::{Damping, DampingContext, Point as DampingPoint};
use pd_mesh::{Point, generators};
use pd_solver::{Model, Settings, Simulation};

/// A test model that pushes every vertex with the force `m_i a`.
#[derive(Debug)]
struct UniformPush {
    acceleration: Point,
}

impl Damping for UniformPush {
    fn name(&self) -> &'static str {
        "uniform-push"
    }
    fn has_explicit_force(&self) -> bool {
        true
    }
    fn add_explicit_force(
        &self,
        context: &DampingContext<'_>,
        _positions: &[DampingPoint],
        _velocities: &[DampingPoint],
        forces: &mut [DampingPoint],
    ) {
        for (f, m) in forces.iter_mut().zip(context.masses) {
            *f += self.acceleration * *m;
        }
    }
}

#[test]
fn explicit_force_follows_each_integrators_force_law() {
    let acceleration = Point::new(0.3, -1.2, 0.5);
    let dt = 0.01;
    for scheme in SCHEMES {
        let chain = generators::chain(5, 1.0).unwrap();
        let mut model = Model::new();
        let body = model
            .add_body(chain, vec![0.2, 0.1, 0.3, 0.1, 0.2])
            .unwrap();
        model.add_springs(body, 500.0).unwrap();
        let n = model.num_vertices() as f64;
        let max_mass = 0.3;
        let stiffness = laplacian_norm(&model);
        let total_force = acceleration * model.masses().iter().sum::<f64>();
        let settings = Settings {
            dt,
            iterations: 3,
            gravity: Point::zeros(),
            ..Settings::default()
        };
        let mut sim = Simulation::new(
            model,
            scheme.integrator(),
            Box::new(UniformPush { acceleration }),
            settings,
        )
        .unwrap();
        sim.add_rigid_velocity(0, Point::new(0.0, 0.5, 0.0), Point::new(0.0, 0.0, 1.0))
            .unwrap();
        let mut previous: Option<Point> = None;
        let mut current = sim.linear_momentum();
        for step in 1..=10 {
            sim.step().unwrap();
            let expected = match (scheme, previous) {
                (Scheme::Bdf2, Some(old)) => {
                    (current * 4.0 - old) / 3.0 + total_force * (2.0 * dt / 3.0)
                }
                _ => current + total_force * dt,
            };
            let measured = sim.linear_momentum();
            // Round-off as in linear_momentum.rs: velocities are position
            // differences over h, and the solve's backward error.
            let extent = sim
                .state()
                .positions
                .iter()
                .map(|x| x.amax())
                .fold(0.0, f64::max);
            let tolerance = 16.0 * U * n * step as f64 * (max_mass / dt + dt * stiffness) * extent;
            let error = (measured - expected).amax();
            assert!(
                error <= tolerance,
                "{scheme:?} step {step}: error {error:e} > {tolerance:e}"
            );
            previous = Some(current);
            current = measured;
        }
    }
}
