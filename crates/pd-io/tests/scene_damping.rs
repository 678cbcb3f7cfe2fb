//! The `[damping]` table: every shape of mistake is reported with today's
//! message, at the key it concerns (`damping.KEY`), or at `damping` for a
//! value outside its domain. The keys and the checks come from
//! `pd_damping::registry`; these messages are the scene format's contract
//! (`docs/reference/scene-format.md`), pinned here so a registry change cannot alter
//! them unnoticed.

use std::path::Path;

use pd_io::scene::{DampingSpec, Scene, Syntax};

fn toml_scene(damping: &str) -> String {
    format!(
        "[simulation]\ndt = 0.01\nsteps = 1\n\n[damping]\n{damping}\n\n[[body]]\n\
         mesh = {{ generator = \"chain\", points = 3, length = 1.0 }}\nvertex_mass = 0.1\n"
    )
}

fn json_scene(damping: &str) -> String {
    format!(
        "{{\"simulation\":{{\"dt\":0.01,\"steps\":1}},\n\"damping\":{damping},\n\
         \"body\":[{{\"mesh\":{{\"generator\":\"chain\",\"points\":3,\"length\":1.0}},\
         \"vertex_mass\":0.1}}]}}"
    )
}

fn toml_error(damping: &str) -> String {
    Scene::parse(&toml_scene(damping), Syntax::Toml, Path::new("d.toml"))
        .expect_err(damping)
        .to_string()
}

fn json_error(damping: &str) -> String {
    Scene::parse(&json_scene(damping), Syntax::Json, Path::new("d.json"))
        .expect_err(damping)
        .to_string()
}

#[test]
fn toml_mistakes_keep_their_messages() {
    let cases: &[(&str, &str)] = &[
        (
            "model = \"none\"\nfactor = 0.1",
            "d.toml: damping.factor: is not a parameter of model \"none\"",
        ),
        (
            "model = \"viscous\"",
            "d.toml: damping.model: unknown damping model \"viscous\"; expected one of: none, ether-drag, pbd, rayleigh-lagged, laplacian",
        ),
        (
            "model = \"viscous\"\nfactor = 0.1",
            "d.toml: damping.model: unknown damping model \"viscous\"; expected one of: none, ether-drag, pbd, rayleigh-lagged, laplacian",
        ),
        ("factor = 0.1", "d.toml:5: damping: missing field `model`"),
        (
            "model = \"ether-drag\"",
            "d.toml: damping.factor: ether-drag needs exactly one of factor (per step) or rate (1/s)",
        ),
        (
            "model = \"ether-drag\"\nfactor = 0.1\nrate = 1.0",
            "d.toml: damping.factor: ether-drag needs exactly one of factor (per step) or rate (1/s)",
        ),
        (
            "model = \"ether-drag\"\nfactor = 0.1\nimplicit = true",
            "d.toml: damping.implicit: implicit ether drag takes a rate (1/s), not a per-step factor",
        ),
        (
            "model = \"ether-drag\"\nrate = -1.0",
            "d.toml: damping: invalid damping parameter `rate` = -1: must be a finite number >= 0",
        ),
        (
            "model = \"ether-drag\"\nfactor = 1.5",
            "d.toml: damping: invalid damping parameter `factor` = 1.5: must be a finite number in [0, 1]",
        ),
        (
            "model = \"ether-drag\"\nfactor = 0.5\nmass = 1.0",
            "d.toml: damping.mass: is not a parameter of model \"ether-drag\"",
        ),
        (
            "model = \"ether-drag\"\nimplicit = true",
            "d.toml: damping.factor: ether-drag needs exactly one of factor (per step) or rate (1/s)",
        ),
        (
            "model = \"pbd\"",
            "d.toml: damping.factor: model \"pbd\" needs it",
        ),
        (
            "model = \"pbd\"\nfactor = 2.0",
            "d.toml: damping: invalid damping parameter `factor` = 2: must be a finite number in [0, 1]",
        ),
        (
            "model = \"pbd\"\nrate = 2.0\nstiffness = 1.0",
            "d.toml: damping.rate: is not a parameter of model \"pbd\"",
        ),
        (
            "model = \"pbd\"\nstiffness = 1.0\nrate = 2.0",
            "d.toml: damping.rate: is not a parameter of model \"pbd\"",
        ),
        (
            "model = \"rayleigh-lagged\"",
            "d.toml: damping.stiffness: model \"rayleigh-lagged\" needs it",
        ),
        (
            "model = \"rayleigh-lagged\"\nmass = 1.0",
            "d.toml: damping.stiffness: model \"rayleigh-lagged\" needs it",
        ),
        (
            "model = \"rayleigh-lagged\"\nstiffness = 0.01\npreserve_rotation = true",
            "d.toml: damping.preserve_rotation: is not a parameter of model \"rayleigh-lagged\"",
        ),
        (
            "model = \"rayleigh-lagged\"\nstiffness = -0.01",
            "d.toml: damping: invalid damping parameter `stiffness` = -0.01: must be a finite number >= 0",
        ),
        (
            "model = \"rayleigh-lagged\"\nstiffness = 0.01\nmass = nan",
            "d.toml: damping: invalid damping parameter `mass` = NaN: must be a finite number >= 0",
        ),
        (
            "model = \"laplacian\"",
            "d.toml: damping.stiffness: model \"laplacian\" needs it",
        ),
        (
            "model = \"laplacian\"\nstiffness = 0.01\nfactor = 0.5",
            "d.toml: damping.factor: is not a parameter of model \"laplacian\"",
        ),
        (
            "model = \"laplacian\"\nstiffness = inf",
            "d.toml: damping: invalid damping parameter `stiffness` = inf: must be a finite number >= 0",
        ),
        (
            "model = \"laplacian\"\nstiffness = \"x\"",
            "d.toml:7: damping.stiffness: invalid type: string \"x\", expected f64",
        ),
        (
            "model = \"laplacian\"\nstiffness = 0.01\npreserve_rotation = 1",
            "d.toml:8: damping.preserve_rotation: invalid type: integer `1`, expected a boolean",
        ),
        (
            "model = \"laplacian\"\nstiffness = 0.01\nfoo = 1",
            "d.toml:8: damping.foo: unknown field `foo`, expected one of `model`, `factor`, `rate`, `implicit`, `mass`, `stiffness`, `preserve_rotation`, `ratio`, `mode`, `ratios`, `modes`, `band`, `series`",
        ),
        (
            "model = \"laplacian\"\nstiffness = 0.01\nmodel = \"pbd\"",
            "d.toml:8: duplicate key",
        ),
        (
            "model = 3",
            "d.toml:6: damping.model: invalid type: integer `3`, expected a string",
        ),
    ];
    for (damping, expected) in cases {
        assert_eq!(toml_error(damping), *expected, "{damping}");
    }
}

#[test]
fn json_mistakes_keep_their_messages() {
    let cases: &[(&str, &str)] = &[
        (
            "{\"model\":\"pbd\",\"factor\":0.1,\"factor\":0.2}",
            "d.json:2: damping: duplicate field `factor`",
        ),
        (
            "{\"model\":\"pbd\"}",
            "d.json: damping.factor: model \"pbd\" needs it",
        ),
        (
            "{\"factor\":0.1}",
            "d.json:2: damping: missing field `model`",
        ),
        (
            "5",
            "d.json:2: damping: invalid type: integer `5`, expected struct Damping",
        ),
        (
            "[\"pbd\"]",
            "d.json:2: damping: invalid length 1, expected struct Damping with 7 elements",
        ),
        (
            "{\"model\":\"pbd\",\"factor\":null}",
            "d.json: damping.factor: model \"pbd\" needs it",
        ),
        (
            "{\"model\":\"pbd\",\"factor\":0.1,\"zz\":1}",
            "d.json:2: damping.zz: unknown field `zz`, expected one of `model`, `factor`, `rate`, `implicit`, `mass`, `stiffness`, `preserve_rotation`, `ratio`, `mode`, `ratios`, `modes`, `band`, `series`",
        ),
    ];
    for (damping, expected) in cases {
        assert_eq!(json_error(damping), *expected, "{damping}");
    }
}

#[test]
fn valid_tables_mean_the_same_models() {
    let parse = |damping: &str| {
        Scene::parse(&toml_scene(damping), Syntax::Toml, Path::new("d.toml"))
            .expect(damping)
            .damping
    };
    assert_eq!(parse("model = \"none\""), DampingSpec::None);
    let drag = parse("model = \"ether-drag\"\nfactor = 0.1\nimplicit = false");
    assert_eq!(drag.number("factor"), Some(0.1));
    assert_eq!(drag.number("rate"), None);
    let implicit = parse("model = \"ether-drag\"\nrate = 1.0\nimplicit = true");
    assert_eq!(implicit.create().unwrap().implicit_matrix().mass, 1.0);
    let laplacian =
        parse("model = \"laplacian\"\nstiffness = 0.01\nmass = 0.5\npreserve_rotation = true");
    let model = laplacian.create().unwrap();
    assert_eq!(model.implicit_matrix().damping_laplacian, 0.01);
    assert_eq!(model.implicit_matrix().mass, 0.5);
    assert!(model.preserves_rotation());
    // A JSON `null` is a key left out, and serde's array form of a struct
    // (values in key order) is accepted as it always was.
    for damping in [
        r#"{"model":"pbd","factor":0.1,"rate":null}"#,
        r#"["pbd", 0.1, null, null, null, null, null]"#,
    ] {
        let spec = Scene::parse(&json_scene(damping), Syntax::Json, Path::new("d.json"))
            .expect(damping)
            .damping;
        assert_eq!(spec.number("factor"), Some(0.1), "{damping}");
        assert_eq!(spec.number("rate"), None, "{damping}");
    }
}
