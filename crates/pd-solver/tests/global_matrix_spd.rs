//! The global matrix is symmetric positive definite for every integrator and
//! damping model with `h > 0`, `a1, a2 >= 0`, in any state, inverted
//! elements included.
//!
//! Sharp check: `A = (1/h^2 + c1 c2 gamma a1) M + (positive semi-definite
//! terms)`, so by Weyl's inequality its smallest eigenvalue is at least
//! `min_i m_i (1/h^2 + c1 c2 gamma a1)`. An indefinite term (an unprojected
//! Hessian, a sign error) would push it below that bound.

mod common;

use common::jittered_box;
use nalgebra::{DMatrix, SymmetricEigen};
use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged};
use pd_integrators::{BackwardEuler, Bdf2, ImplicitMidpoint, Integrator};
use pd_mesh::{Point, VertexSelection};
use pd_solver::{Model, Settings, Simulation, SolverError, State};

/// A scene name and a constructor.
type MakeIntegrator = (&'static str, fn() -> Box<dyn Integrator>);

fn integrators() -> Vec<MakeIntegrator> {
    vec![
        ("backward-euler", || Box::new(BackwardEuler)),
        ("implicit-midpoint", || Box::new(ImplicitMidpoint)),
        ("bdf2", || Box::new(Bdf2::new())),
    ]
}

/// Each model with its `a1` (the mass-proportional coefficient).
fn models() -> Vec<(Box<dyn Damping>, f64)> {
    vec![
        (Box::new(NoDamping), 0.0),
        (Box::new(EtherDrag::implicit(3.0).unwrap()), 3.0),
        (Box::new(EtherDrag::factor(0.1).unwrap()), 0.0),
        (Box::new(PbdDamping::new(0.5).unwrap()), 0.0),
        (
            Box::new(LaplacianDamping::new(0.05, 0.0, false).unwrap()),
            0.0,
        ),
        (
            Box::new(LaplacianDamping::new(0.05, 2.0, true).unwrap()),
            2.0,
        ),
        (Box::new(RayleighLagged::new(0.05, 0.0).unwrap()), 0.0),
        (Box::new(RayleighLagged::new(0.2, 1.5).unwrap()), 1.5),
    ]
}

fn model() -> Model {
    let mesh = jittered_box([3, 2, 2], [0.6, 0.3, 0.3], 0.15, 11);
    let clamp = VertexSelection::Box {
        min: [-1.0; 3],
        max: [0.05, 1.0, 1.0],
    }
    .resolve(&mesh)
    .unwrap();
    let masses = mesh.lumped_masses(900.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 3e5, None).unwrap();
    model.add_springs(body, 2e3).unwrap();
    model.add_attachments(body, &[30], 50.0).unwrap();
    model.fix_vertices(body, &clamp).unwrap();
    model
}

#[test]
fn global_matrix_is_spd_for_every_integrator_and_model() {
    for dt in [1e-4, 0.01, 0.2] {
        for (name, make) in integrators() {
            for (damping, a1) in models() {
                let model = model();
                let min_mass = model.masses().iter().copied().fold(f64::INFINITY, f64::min);
                let damping_name = damping.name();
                let settings = Settings {
                    dt,
                    iterations: 3,
                    ..Settings::default()
                };
                let mut sim = Simulation::new(model, make(), damping, settings).unwrap();
                // A strongly deformed state with inverted elements: mirror
                // the body through the plane y = 0.15 (every tet inverts).
                let positions: Vec<Point> = sim
                    .state()
                    .positions
                    .iter()
                    .map(|p| Point::new(p.x, 0.3 - p.y, p.z))
                    .collect();
                let velocities = vec![Point::new(0.1, -0.2, 0.3); positions.len()];
                sim.set_state(State {
                    positions,
                    velocities,
                })
                .unwrap();
                // Two steps, so that BDF-2 has left its backward Euler start.
                sim.run(2).unwrap();
                let c = make().coefficients(dt);
                let (c1, c2, gamma) = if name == "bdf2" {
                    (4.0 / 9.0, 1.0, 1.5 / dt)
                } else {
                    (c.c1, c.c2, c.gamma)
                };
                let bound = min_mass * (1.0 / (dt * dt) + c1 * c2 * gamma * a1);

                let a = sim.global_matrix().unwrap();
                let n = a.nrows();
                let mut dense = DMatrix::<f64>::zeros(n, n);
                for t in a.triplets() {
                    dense[(t.row, t.column)] = t.value;
                }
                assert_eq!(
                    dense,
                    dense.transpose(),
                    "{name} + {damping_name}: not symmetric"
                );
                let norm = (0..n)
                    .map(|r| a.row(r).map(|(_, v)| v.abs()).sum::<f64>())
                    .fold(0.0, f64::max);
                let smallest = SymmetricEigen::new(dense).eigenvalues.min();
                // The eigensolver is backward stable: eigenvalues are exact to
                // about n u |A|.
                let slack = 4.0 * n as f64 * f64::EPSILON * norm;
                assert!(
                    smallest >= bound - slack,
                    "{name} + {damping_name}, dt {dt}: smallest eigenvalue {smallest:e} < bound {bound:e}"
                );
            }
        }
    }
}

/// Coefficients beyond floating-point range (1/h^2 and a2/h overflow) break
/// the factorisation; the reason says what to check, in words.
#[test]
fn a_factorisation_of_overflowing_coefficients_says_what_to_check() {
    let settings = Settings {
        dt: 1e-308,
        ..Settings::default()
    };
    let damping = Box::new(LaplacianDamping::new(1e308, 0.0, false).unwrap());
    match Simulation::new(model(), Box::new(BackwardEuler), damping, settings) {
        Err(SolverError::Factorisation { reason }) => {
            assert!(reason.contains("not positive definite"), "{reason}");
            assert!(reason.contains("check dt, masses, stiffness"), "{reason}");
            assert!(!reason.contains("NonPositivePivot"), "{reason}");
        }
        Err(other) => panic!("expected a factorisation error, got {other}"),
        Ok(_) => panic!("expected a factorisation error"),
    }
}
