//! What the adjoint refuses, and how it says so; the fallbacks of the adjoint
//! solve and of the forward run.

use pd_adjoint::{
    AdjointError, AdjointOptions, Parameter, ParameterGradient, ProbeLoss, loss_and_gradient,
};
use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged};
use pd_integrators::BackwardEuler;
use pd_mesh::{Point, VertexSelection, generators};
use pd_solver::contact::{Collider, ColliderShape, ContactSettings};
use pd_solver::{Model, Settings, Simulation, SolverMethod};

const STEPS: usize = 5;

/// A clamped beam of 20 vertices, `damping`, optionally `masses` instead of
/// the lumped ones at 1000 kg/m^3.
fn beam(damping: Box<dyn Damping>, masses: Option<Vec<f64>>) -> Simulation {
    let mesh = generators::box_tets([1.0, 0.2, 0.2], [4, 1, 1]).unwrap();
    let clamp = VertexSelection::Box {
        min: [-1.0; 3],
        max: [1e-9, 1.0, 1.0],
    }
    .resolve(&mesh)
    .unwrap();
    let masses = masses.unwrap_or_else(|| mesh.lumped_masses(1000.0).unwrap());
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e5, None).unwrap();
    model.fix_vertices(body, &clamp).unwrap();
    let settings = Settings {
        dt: 0.01,
        ..Settings::default()
    };
    Simulation::new(model, Box::new(BackwardEuler), damping, settings).unwrap()
}

fn laplacian() -> Box<dyn Damping> {
    Box::new(LaplacianDamping::new(0.01, 0.0, false).unwrap())
}

fn loss(sim: &Simulation) -> ProbeLoss {
    let tip = sim.state().positions[4] + Point::new(0.0, 0.01, 0.0);
    ProbeLoss {
        vertices: vec![4],
        targets: vec![vec![tip]; STEPS],
    }
}

/// The error of a gradient of `sim` with respect to `parameters`.
fn error(sim: Simulation, parameters: &[Parameter]) -> String {
    let loss = loss(&sim);
    let result = loss_and_gradient(sim, STEPS, &loss, parameters, &AdjointOptions::default());
    result.expect_err("must be refused").to_string()
}

#[test]
fn contact_is_refused_naming_it() {
    let mut sim = beam(laplacian(), None);
    sim.set_contact(ContactSettings {
        colliders: vec![Collider {
            shape: ColliderShape::Plane {
                point: Point::new(0.0, -1.0, 0.0),
                normal: Point::new(0.0, 1.0, 0.0),
            },
            friction: 0.0,
            restitution: 0.0,
        }],
        thickness: 0.0,
    })
    .unwrap();
    let message = error(sim, &[Parameter::DampingStiffness]);
    assert!(message.contains("[contact]"), "{message}");
    assert!(message.contains("colliders"), "{message}");
    assert!(message.starts_with("not differentiated"), "{message}");
}

#[test]
fn unsupported_damping_is_refused_naming_the_model() {
    let cases: [(Box<dyn Damping>, &str); 4] = [
        (
            Box::new(LaplacianDamping::new(0.01, 0.0, true).unwrap()),
            "preserve_rotation",
        ),
        (Box::new(PbdDamping::new(0.1).unwrap()), "pbd"),
        (
            Box::new(RayleighLagged::new(0.01, 0.0).unwrap()),
            "rayleigh-lagged",
        ),
        (
            Box::new(EtherDrag::rate(1.0).unwrap()),
            "explicit ether drag",
        ),
    ];
    for (damping, expected) in cases {
        let message = error(beam(damping, None), &[Parameter::DampingMass]);
        assert!(message.contains(expected), "{expected}: {message}");
        assert!(message.starts_with("not differentiated"), "{message}");
    }
    // The implicit forms are differentiated.
    for damping in [
        Box::new(EtherDrag::implicit(1.0).unwrap()) as Box<dyn Damping>,
        Box::new(NoDamping),
    ] {
        let sim = beam(damping, None);
        let loss = loss(&sim);
        let options = AdjointOptions::default();
        assert!(loss_and_gradient(sim, STEPS, &loss, &[Parameter::DampingMass], &options).is_ok());
    }
}

#[test]
fn invalid_arguments_are_named() {
    let cases = [
        (
            Parameter::ConstraintStiffness {
                body: 0,
                constraint: 1,
            },
            "body[0].constraints[1].stiffness: body 0 has 1 constraint groups",
        ),
        (
            Parameter::ConstraintStiffness {
                body: 2,
                constraint: 0,
            },
            "body[2].constraints[0].stiffness: the model has 1 bodies",
        ),
        (
            Parameter::Density { body: 1 },
            "body[1].density: the model has 1 bodies",
        ),
        (
            Parameter::DampingSeries(6),
            "damping.series[6]: a Caughey series has at most 6 higher terms (damping.series[0] \
             to damping.series[5])",
        ),
    ];
    for (parameter, expected) in cases {
        let message = error(beam(laplacian(), None), &[parameter]);
        assert_eq!(message, format!("invalid {expected}"));
    }
    // A series term of a model that has no series.
    let drag = Box::new(EtherDrag::implicit(0.5).unwrap());
    let message = error(beam(drag, None), &[Parameter::DampingSeries(0)]);
    assert_eq!(
        message,
        "invalid damping.series[0]: the ether-drag damping model has no Caughey series: use \
         laplacian"
    );
    // Masses that are not one density times the lumped volumes.
    let masses = (0..20).map(|v| 1.0 + v as f64).collect();
    let message = error(
        beam(laplacian(), Some(masses)),
        &[Parameter::Density { body: 0 }],
    );
    assert!(
        message.contains("not its mesh's lumped masses"),
        "{message}"
    );

    let sim = beam(laplacian(), None);
    let loss = loss(&sim);
    let options = AdjointOptions::default();
    let message = loss_and_gradient(sim, STEPS + 1, &loss, &[], &options)
        .unwrap_err()
        .to_string();
    assert_eq!(
        message,
        "invalid loss: it has targets for 5 steps, the run has 6"
    );
    let sim = beam(laplacian(), None);
    let far = ProbeLoss {
        vertices: vec![20],
        targets: vec![vec![Point::zeros()]; STEPS],
    };
    let message = loss_and_gradient(sim, STEPS, &far, &[], &options)
        .unwrap_err()
        .to_string();
    assert_eq!(
        message,
        "invalid loss: probe vertex 20 is out of range: the model has 20 vertices"
    );
}

/// `a` and `b` agree to `tolerance` relative (the scalar's magnitude, or
/// the largest point's).
fn assert_same(a: &[ParameterGradient], b: &[ParameterGradient], tolerance: f64) {
    let (ParameterGradient::Scalar(x), ParameterGradient::Scalar(y)) = (&a[0], &b[0]) else {
        panic!("scalar gradients expected");
    };
    assert!((x - y).abs() <= tolerance * x.abs(), "{x} against {y}");
    let (ParameterGradient::Points(p), ParameterGradient::Points(q)) = (&a[1], &b[1]) else {
        panic!("vector gradients expected");
    };
    let scale = p.iter().map(|p| p.norm()).fold(0.0, f64::max);
    assert!(scale > 0.0);
    for (p, q) in p.iter().zip(q) {
        assert!((p - q).norm() <= tolerance * scale, "{p:?} against {q:?}");
    }
}

/// With one conjugate-gradient iteration allowed, every step's adjoint
/// system goes to a fallback: the dense LU factorisation, or MINRES when
/// the dense limit is 0. Both must give the gradient the conjugate
/// gradients give.
#[test]
fn fallbacks_give_the_same_gradient() {
    let parameters = [Parameter::DampingStiffness, Parameter::InitialVelocities];
    let run = |options: AdjointOptions| {
        let sim = beam(laplacian(), None);
        let loss = loss(&sim);
        loss_and_gradient(sim, STEPS, &loss, &parameters, &options)
    };
    let iterative = run(AdjointOptions::default()).unwrap();
    let dense = run(AdjointOptions {
        max_iterations: 1,
        ..AdjointOptions::default()
    })
    .unwrap();
    let minres = run(AdjointOptions {
        max_iterations: 1,
        dense_limit: 0,
        ..AdjointOptions::default()
    })
    .unwrap();
    assert_eq!(iterative.fallback_steps, 0);
    assert_eq!(dense.fallback_steps, STEPS);
    assert_eq!(minres.fallback_steps, STEPS);
    // Each iteration stops at a relative residual of 1e-10 per step (in its
    // own norm); with H's condition number on this beam (the mass term
    // dominates at dt = 0.01 s; A-preconditioned, close to 1) the
    // solutions agree to about 1e-8 relative: 1e-7 leaves a margin.
    assert_same(&iterative.gradients, &dense.gradients, 1e-7);
    assert_same(&iterative.gradients, &minres.gradients, 1e-7);

    // Without a fallback that converges, the failure is reported with its
    // step.
    let result = run(AdjointOptions {
        max_iterations: 1,
        dense_limit: 0,
        minres_iterations: 1,
        ..AdjointOptions::default()
    });
    let Err(AdjointError::NotConverged { step, unknowns, .. }) = result else {
        panic!("the adjoint solve must fail: {result:?}");
    };
    assert_eq!((step, unknowns), (STEPS, 3 * 16));
}

/// A forward method that cannot reach the tolerance in its budget
/// (local-global, 2 iterations, which cannot shrink a step's residual by
/// 1e-10) has every step solved again by Newton's method, and the gradient
/// is the one of a run converged throughout.
#[test]
fn newton_solves_the_steps_the_forward_method_leaves() {
    let parameters = [Parameter::DampingStiffness, Parameter::InitialVelocities];
    let run = |options: AdjointOptions| {
        let sim = beam(laplacian(), None);
        let loss = loss(&sim);
        loss_and_gradient(sim, STEPS, &loss, &parameters, &options).unwrap()
    };
    let reference = run(AdjointOptions {
        forward_method: SolverMethod::Newton,
        ..AdjointOptions::default()
    });
    let retried = run(AdjointOptions {
        forward_method: SolverMethod::LocalGlobal,
        forward_iterations: 2,
        ..AdjointOptions::default()
    });
    assert_eq!(
        (reference.forward_retries, reference.unconverged_steps),
        (0, 0)
    );
    assert_eq!(
        (retried.forward_retries, retried.unconverged_steps),
        (STEPS, 0)
    );
    // Both runs are converged to 1e-10 of each step; the gradients agree
    // to about that relative accuracy: 1e-7 leaves a margin.
    assert_same(&reference.gradients, &retried.gradients, 1e-7);
}
