//! Parameters named by scene field paths (as `pd fit --fit` takes them)
//! reach the scene's fields: the gradient with respect to each path agrees
//! with central differences of the loss over scenes whose field is changed
//! in the text.

use std::path::Path;

use pd_adjoint::{AdjointOptions, Parameter, ParameterGradient, ProbeLoss, loss_and_gradient};
use pd_io::scene::{Scene, Syntax};
use pd_mesh::Point;
use pd_solver::Simulation;

const STEPS: usize = 10;

/// The scene's fields, in the order of [`PATHS`].
const VALUES: [f64; 6] = [0.5, 0.01, 2e4, 50.0, 1000.0, 2e-7];
const PATHS: [&str; 6] = [
    "damping.mass",
    "damping.stiffness",
    "body[0].constraints[0].stiffness",
    "body[0].constraints[1].stiffness",
    "body[0].density",
    "damping.series[0]",
];

/// A clamped beam of 20 vertices with tet strain and two attachments
/// (constraint groups 0 and 1), a three-term Caughey series damping,
/// swinging down.
fn scene(values: [f64; 6]) -> Simulation {
    let [mass, stiffness, strain, attachment, density, a3] = values;
    let text = format!(
        "[simulation]\ndt = 0.01\nsteps = {STEPS}\ngravity = [0.0, -9.81, 0.0]\n\
         integrator = \"backward-euler\"\n\n\
         [damping]\nmodel = \"laplacian\"\nstiffness = {stiffness:?}\nmass = {mass:?}\n\
         series = [{a3:?}]\n\n\
         [[body]]\nmesh = {{ generator = \"box\", size = [1.0, 0.2, 0.2], cells = [4, 1, 1] }}\n\
         density = {density:?}\n\
         constraints = [\n  {{ kind = \"tet-strain\", stiffness = {strain:?} }},\n  \
         {{ kind = \"attachment\", stiffness = {attachment:?}, vertices = [4, 19] }},\n]\n\
         fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] }} }}\n"
    );
    Scene::parse(&text, Syntax::Toml, Path::new("scene_paths.toml"))
        .and_then(|s| s.build())
        .unwrap()
}

fn loss() -> ProbeLoss {
    let rest = scene(VALUES).model().rest_positions().to_vec();
    let vertices = vec![4, 14];
    let targets = (1..=STEPS)
        .map(|s| {
            vertices
                .iter()
                .map(|&v| rest[v] + Point::new(0.0, -0.001 * s as f64, 0.002))
                .collect()
        })
        .collect();
    ProbeLoss { vertices, targets }
}

#[test]
fn scene_paths_reach_their_fields() {
    let loss = loss();
    let options = AdjointOptions {
        forward_tolerance: 1e-12,
        ..AdjointOptions::default()
    };
    let parameters: Vec<Parameter> = PATHS.iter().map(|p| p.parse().unwrap()).collect();
    let result = loss_and_gradient(scene(VALUES), STEPS, &loss, &parameters, &options).unwrap();
    let at = |values| {
        loss_and_gradient(scene(values), STEPS, &loss, &[], &options)
            .unwrap()
            .loss
    };
    for (i, path) in PATHS.iter().enumerate() {
        let ParameterGradient::Scalar(adjoint) = result.gradients[i] else {
            panic!("{path}: a scalar gradient was expected");
        };
        // A central difference at 1e-3 of the value: its truncation error
        // is about 1e-6 relative, its round-off (the forward run stops at
        // 1e-12 of each step) about 1e-9 of the loss over the step.
        let eps = 1e-3 * VALUES[i];
        let mut plus = VALUES;
        plus[i] += eps;
        let mut minus = VALUES;
        minus[i] -= eps;
        let difference = (at(plus) - at(minus)) / (2.0 * eps);
        println!("{path}: adjoint {adjoint:e}, difference {difference:e}");
        // 1%, the tolerance asked of the gradient; the agreement measured
        // is far closer (1e-6).
        assert!(
            (adjoint - difference).abs() <= 0.01 * difference.abs(),
            "{path}: adjoint {adjoint:e} against {difference:e}"
        );
        assert!(difference != 0.0, "{path} does not change the loss");
    }
}
