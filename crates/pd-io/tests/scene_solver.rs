//! The `[solver]` table: defaults, every key read as written, and each
//! mistake reported at its field path.

use std::path::Path;

use pd_io::scene::{Scene, Syntax};
use pd_solver::{SolverMethod, SolverSpec, SpectralRadius};

fn scene(solver: &str) -> String {
    format!(
        "[simulation]\ndt = 0.01\nsteps = 1\n\n{solver}\n\n[[body]]\n\
         mesh = {{ generator = \"chain\", points = 3, length = 1.0 }}\nvertex_mass = 0.1\n\
         constraints = [{{ kind = \"spring\", stiffness = 10.0 }}]\n"
    )
}

fn parse(solver: &str) -> pd_io::Result<Scene> {
    Scene::parse(&scene(solver), Syntax::Toml, Path::new("s.toml"))
}

/// Each `(table, expected)`: the table is refused with exactly that error.
fn assert_errors(cases: &[(&str, &str)]) {
    for (table, expected) in cases {
        let error = parse(table).expect_err(table).to_string();
        assert_eq!(&error, expected, "{table}");
    }
}

#[test]
fn without_a_table_and_with_a_budget_the_method_is_local_global() {
    let s = parse("").unwrap();
    assert_eq!(s.solver, SolverSpec::default());
    // No budget: the default accuracy target, the method chosen by probe.
    assert!(s.choose_method);
    let text = scene("").replace("steps = 1\n", "steps = 1\niterations = 10\n");
    let s = Scene::parse(&text, Syntax::Toml, Path::new("s.toml")).unwrap();
    assert!(!s.choose_method);
    assert_eq!(s.settings.accuracy, 0.0);
    assert_eq!(s.build().unwrap().position_solver_name(), "local-global");
}

/// A scene that sets no budget (`iterations`, `tolerance`, `accuracy`)
/// gets the default accuracy target with the cap, and its method is
/// chosen by measurement when it is built; a named method is kept.
#[test]
fn without_a_budget_the_default_accuracy_chooses_the_method() {
    let s = parse("").unwrap();
    assert_eq!(s.settings.accuracy, pd_io::scene::DEFAULT_ACCURACY);
    assert_eq!(s.settings.iterations, pd_io::scene::ACCURACY_ITERATIONS);
    let sim = s.build().unwrap();
    let choice = sim.method_choice().expect("chosen by measurement");
    assert_eq!(sim.position_solver_name(), choice.chosen.name());
    assert_eq!(sim.steps(), 0);
    let named = parse("[solver]\nmethod = \"chebyshev\"").unwrap();
    assert!(!named.choose_method);
    let sim = named.build().unwrap();
    assert!(sim.method_choice().is_none());
    assert_eq!(sim.position_solver_name(), "chebyshev");
    // A tolerance is a budget: no accuracy, the old default cap.
    let text = scene("").replace("steps = 1\n", "steps = 1\ntolerance = 1e-6\n");
    let s = Scene::parse(&text, Syntax::Toml, Path::new("s.toml")).unwrap();
    assert_eq!((s.settings.accuracy, s.settings.iterations), (0.0, 10));
}

#[test]
fn keys_are_read_as_written() {
    let s = parse("[solver]\nmethod = \"anderson\"\nwindow = 7").unwrap();
    assert_eq!(s.solver.method, SolverMethod::Anderson);
    assert_eq!(s.solver.window, 7);
    assert_eq!(s.build().unwrap().position_solver_name(), "anderson");
    let s = parse("[solver]\nmethod = \"chebyshev\"\nrho = 0.99\nstart = 4").unwrap();
    assert_eq!(s.solver.rho, SpectralRadius::Fixed(0.99));
    assert_eq!(s.solver.start, 4);
    let s = parse("[solver]\nmethod = \"chebyshev\"\nrho = \"auto\"").unwrap();
    assert_eq!(s.solver.rho, SpectralRadius::Auto);
    for method in ["newton", "lbfgs"] {
        let mut sim = parse(&format!("[solver]\nmethod = \"{method}\""))
            .unwrap()
            .build()
            .unwrap();
        assert_eq!(sim.position_solver_name(), method);
        sim.step().unwrap();
    }
}

#[test]
fn mistakes_name_the_field() {
    let cases: &[(&str, &str)] = &[
        (
            "[solver]\nmethod = \"gauss-seidel\"",
            "s.toml: solver.method: unknown method \"gauss-seidel\"; expected one of: local-global, anderson, chebyshev, lbfgs, newton",
        ),
        (
            "[solver]\nwindow = 0",
            "s.toml: solver.window: must be between 1 and 50, got 0",
        ),
        (
            "[solver]\nrho = 1.5",
            "s.toml: solver.rho: must be in (0, 1) or \"auto\", got 1.5",
        ),
        (
            "[solver]\nrho = \"fast\"",
            "s.toml: solver.rho: must be a number in (0, 1) or \"auto\", got \"fast\"",
        ),
        (
            "[solver]\nstart = 1",
            "s.toml: solver.start: must be at least 2, got 1",
        ),
    ];
    assert_errors(cases);
    let error = parse("[solver]\nmethods = \"anderson\"")
        .unwrap_err()
        .to_string();
    assert!(error.contains("unknown field `methods`"), "{error}");
}

#[test]
fn a_method_s_own_keys_are_refused_with_another_method() {
    let cases: &[(&str, &str)] = &[
        (
            "[solver]\nrho = 0.5",
            "s.toml: solver.rho: applies only with method = \"chebyshev\" (method is \"local-global\")",
        ),
        (
            "[solver]\nmethod = \"anderson\"\nstart = 4",
            "s.toml: solver.start: applies only with method = \"chebyshev\" (method is \"anderson\")",
        ),
        (
            "[solver]\nmethod = \"chebyshev\"\nwindow = 4",
            "s.toml: solver.window: applies only with method = \"anderson\" or \"lbfgs\" (method is \"chebyshev\")",
        ),
        (
            "[solver]\nmethod = \"newton\"\nwindow = 5",
            "s.toml: solver.window: applies only with method = \"anderson\" or \"lbfgs\" (method is \"newton\")",
        ),
    ];
    assert_errors(cases);
    // Each key with a method that reads it.
    for table in [
        "[solver]\nmethod = \"lbfgs\"\nwindow = 3",
        "[solver]\nmethod = \"anderson\"\nwindow = 3",
        "[solver]\nmethod = \"chebyshev\"\nrho = 0.7\nstart = 3",
    ] {
        parse(table).expect(table);
    }
}

#[test]
fn a_method_that_cannot_run_the_damping_is_refused_when_the_scene_builds() {
    for method in ["newton", "lbfgs"] {
        let table = format!(
            "[solver]\nmethod = \"{method}\"\n\n[damping]\nmodel = \"rayleigh-lagged\"\nstiffness = 0.01"
        );
        let error = parse(&table).unwrap().build().unwrap_err().to_string();
        assert!(
            error.starts_with("s.toml: solver.method: ") && error.contains("rayleigh-lagged"),
            "{method}: {error}"
        );
    }
    // Anderson runs the lagged model.
    let table = "[solver]\nmethod = \"anderson\"\n\n[damping]\nmodel = \"rayleigh-lagged\"\nstiffness = 0.01";
    parse(table).unwrap().build().unwrap().step().unwrap();
}
