//! Hyperelastic materials in scenes (`kind = "neo-hookean" | "stvk" |
//! "corotated"`, `young`, `poisson`; docs/reference/scene-format.md): read as written,
//! built into the model, each mistake reported at its field path, and a
//! PD-only method refused at `solver.method`.

use std::path::Path;

use pd_constraints::MaterialKind;
use pd_io::scene::{ConstraintSpec, Scene, Syntax};

fn scene(constraint: &str, solver: &str) -> String {
    format!(
        "[simulation]\ndt = 0.01\nsteps = 1\n\n{solver}\n\n[[body]]\n\
         mesh = {{ generator = \"box\", size = [0.4, 0.1, 0.1], cells = [4, 1, 1] }}\n\
         density = 1000.0\nconstraints = [{constraint}]\n\
         fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] }} }}\n"
    )
}

fn parse(constraint: &str, solver: &str) -> pd_io::Result<Scene> {
    Scene::parse(
        &scene(constraint, solver),
        Syntax::Toml,
        Path::new("s.toml"),
    )
}

#[test]
fn every_material_is_read_built_and_stepped() {
    for kind in MaterialKind::ALL {
        for method in ["lbfgs", "newton"] {
            let s = parse(
                &format!(
                    "{{ kind = \"{}\", young = 1.0e6, poisson = 0.45 }}",
                    kind.name()
                ),
                &format!("[solver]\nmethod = \"{method}\""),
            )
            .unwrap();
            assert_eq!(
                s.bodies[0].constraints[0],
                ConstraintSpec::Material {
                    kind,
                    young: 1.0e6,
                    poisson: 0.45
                }
            );
            let mut sim = s.build().unwrap();
            assert!(sim.model().has_materials());
            let stats = sim.step().unwrap();
            assert!(stats.iterations > 0, "{} {method}", kind.name());
            assert!(sim.energies().elastic > 0.0, "{} {method}", kind.name());
        }
    }
}

#[test]
fn mistakes_name_the_field() {
    let lbfgs = "[solver]\nmethod = \"lbfgs\"";
    let at = "s.toml: body[0].constraints[0]";
    let cases: Vec<(String, &str, String)> = vec![
        (
            "{ kind = \"neo-hookean\", young = 0.0, poisson = 0.3 }".into(),
            lbfgs,
            format!("{at}.young: must be finite and > 0 Pa, got 0"),
        ),
        (
            "{ kind = \"stvk\", young = -5.0, poisson = 0.3 }".into(),
            lbfgs,
            format!("{at}.young: must be finite and > 0 Pa, got -5"),
        ),
        (
            "{ kind = \"corotated\", young = nan, poisson = 0.3 }".into(),
            lbfgs,
            format!("{at}.young: must be finite and > 0 Pa, got NaN"),
        ),
        (
            "{ kind = \"corotated\", young = 1e6, poisson = 0.5 }".into(),
            lbfgs,
            format!("{at}.poisson: must be in [0, 0.5), got 0.5"),
        ),
        (
            "{ kind = \"corotated\", young = 1e6, poisson = -0.1 }".into(),
            lbfgs,
            format!("{at}.poisson: must be in [0, 0.5), got -0.1"),
        ),
        (
            "{ kind = \"neo-hookean\", young = 1e6, poisson = nan }".into(),
            lbfgs,
            format!("{at}.poisson: must be in [0, 0.5), got NaN"),
        ),
        (
            "{ kind = \"neo-hookean\", poisson = 0.3 }".into(),
            lbfgs,
            format!("{at}.young: missing"),
        ),
        (
            "{ kind = \"neo-hookean\", young = 1e6 }".into(),
            lbfgs,
            format!("{at}.poisson: missing"),
        ),
        (
            "{ kind = \"neo-hookean\", young = 1e6, poisson = 0.3, stiffness = 5.0 }".into(),
            lbfgs,
            format!(
                "{at}.stiffness: is not a parameter of neo-hookean; a material takes young \
                 (Pa) and poisson"
            ),
        ),
        (
            "{ kind = \"tet-strain\", stiffness = 1e6, poisson = 0.3 }".into(),
            "",
            format!("{at}.poisson: is not a parameter of tet-strain"),
        ),
        (
            "{ kind = \"tet-strain\" }".into(),
            "",
            format!("{at}.stiffness: missing"),
        ),
    ];
    for (constraint, solver, expected) in cases {
        let error = parse(&constraint, solver).unwrap_err().to_string();
        assert_eq!(error, expected, "{constraint}");
    }
}

/// Without a `[solver]` table or a budget, the default accuracy target
/// chooses among the methods that run materials.
#[test]
fn a_material_scene_without_a_method_gets_one_that_runs_it() {
    let material = "{ kind = \"stvk\", young = 1e6, poisson = 0.3 }";
    let sim = parse(material, "").unwrap().build().unwrap();
    let name = sim.position_solver_name();
    assert!(name == "lbfgs" || name == "newton", "{name}");
}

#[test]
fn pd_only_methods_are_refused_at_solver_method() {
    let material = "{ kind = \"stvk\", young = 1e6, poisson = 0.3 }";
    for (solver, name) in [
        ("[solver]\nmethod = \"local-global\"", "local-global"),
        ("[solver]\nmethod = \"anderson\"", "anderson"),
        ("[solver]\nmethod = \"chebyshev\"", "chebyshev"),
    ] {
        let error = parse(material, solver).unwrap_err().to_string();
        assert_eq!(
            error,
            format!(
                "s.toml: solver.method: method \"{name}\" cannot run the non-quadratic material \
                 \"stvk\" of body[0].constraints[0]: it only minimises Projective Dynamics' \
                 quadratic energies; use \"lbfgs\" or \"newton\""
            )
        );
    }
}
