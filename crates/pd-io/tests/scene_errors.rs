//! Every bad scene is rejected with an error that says where: the file and
//! the 1-based line for syntax errors and unknown keys ([`Error::Parse`]),
//! the file and the field path for invalid values ([`Error::Field`]), the
//! mesh file for unreadable or invalid meshes. One test per bad input.

use std::path::{Path, PathBuf};

use pd_io::Error;
use pd_io::scene::{MassSpec, Scene, Syntax};
use pd_mesh::MeshError;

/// The name bad scenes are parsed under; every message must contain it.
const SOURCE: &str = "scenes/bad.toml";

/// A valid scene that each test breaks in one place. The constraints are
/// written one per line, so that a key inside a constraint has its own line.
const VALID: &str = r#"[simulation]
dt = 0.01
steps = 10
gravity = [0.0, -9.81, 0.0]
integrator = "backward-euler"
iterations = 10
tolerance = 0.0

[damping]
model = "none"

[[body]]
mesh = { generator = "box", size = [1.0, 0.2, 0.2], cells = [4, 1, 1] }
density = 1000.0
constraints = [
    { kind = "tet-strain", stiffness = 1.0e5 },
    { kind = "spring", stiffness = 100.0 },
]
fixed = { box = { min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] } }

[output]
every = 1
formats = ["vtk"]
probes = [0, 5]
"#;

/// [`VALID`] with the first occurrence of `from` replaced by `to`.
fn edit(from: &str, to: &str) -> String {
    assert!(VALID.contains(from), "the valid scene has no `{from}`");
    VALID.replacen(from, to, 1)
}

fn parse(text: &str) -> Result<Scene, Error> {
    Scene::parse(text, Syntax::Toml, Path::new(SOURCE))
}

/// The 1-based number of the only line of `text` that contains `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    let lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, line)| line.contains(needle))
        .map(|(index, _)| index + 1)
        .collect();
    assert_eq!(lines.len(), 1, "`{needle}` must be on exactly one line");
    lines[0]
}

/// Asserts a parse error of [`SOURCE`] at `line` whose message mentions
/// every one of `mentions`; returns the message.
fn expect_parse_error(result: Result<Scene, Error>, line: usize, mentions: &[&str]) -> String {
    let err = result.expect_err("the scene must be rejected");
    let shown = err.to_string();
    match err {
        Error::Parse {
            path,
            line: found,
            message,
        } => {
            assert_eq!(path, Path::new(SOURCE), "{shown}");
            assert_eq!(found, line, "{shown}");
            assert!(shown.starts_with(&format!("{SOURCE}:{line}: ")), "{shown}");
            for mention in mentions {
                assert!(message.contains(mention), "no `{mention}` in: {shown}");
            }
            message
        }
        other => panic!("expected a parse error at line {line}, got {other:?}"),
    }
}

/// Asserts a field error of [`SOURCE`] naming `field` whose message
/// mentions every one of `mentions`; returns the message.
fn expect_field_error(result: Result<Scene, Error>, field: &str, mentions: &[&str]) -> String {
    let err = result.expect_err("the scene must be rejected");
    field_error_of(err, Path::new(SOURCE), field, mentions)
}

fn field_error_of(err: Error, source: &Path, field: &str, mentions: &[&str]) -> String {
    let shown = err.to_string();
    match err {
        Error::Field {
            path,
            field: found,
            message,
        } => {
            assert_eq!(path, source, "{shown}");
            assert_eq!(found, field, "{shown}");
            assert!(
                shown.starts_with(&format!("{}: {field}: ", source.display())),
                "{shown}"
            );
            for mention in mentions {
                assert!(message.contains(mention), "no `{mention}` in: {shown}");
            }
            message
        }
        other => panic!("expected a field error naming {field}, got {other:?}"),
    }
}

/// A fresh, empty folder under the system's temporary folder, unique to
/// this process and `test`.
fn scratch_dir(test: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("pd-io-scene-errors-{}-{test}", std::process::id()));
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn the_valid_scene_parses_and_builds() {
    let scene = parse(VALID).unwrap();
    scene.build().unwrap();
}

// --- Unknown keys: Error::Parse at the line of the offending key. ---

#[test]
fn unknown_key_at_top_level() {
    let text = format!("speed = 2\n{VALID}");
    expect_parse_error(parse(&text), 1, &["unknown field `speed`"]);
}

#[test]
fn unknown_key_in_simulation() {
    let text = edit("steps = 10\n", "steps = 10\nspeed = 2\n");
    let line = line_of(&text, "speed");
    expect_parse_error(parse(&text), line, &["simulation", "unknown field `speed`"]);
}

#[test]
fn unknown_key_in_body() {
    let text = edit("density = 1000.0\n", "density = 1000.0\ncolour = \"red\"\n");
    let line = line_of(&text, "colour");
    expect_parse_error(parse(&text), line, &["body[0]", "unknown field `colour`"]);
}

#[test]
fn unknown_key_in_mesh_table() {
    // The mesh as a standard table, so that the unknown key has a line of
    // its own, apart from the table's header.
    let text = edit(
        "mesh = { generator = \"box\", size = [1.0, 0.2, 0.2], cells = [4, 1, 1] }\n",
        "",
    )
    .replacen(
        "[output]",
        "[body.mesh]\ngenerator = \"box\"\nsize = [1.0, 0.2, 0.2]\ncells = [4, 1, 1]\n\
         smooth = true\n\n[output]",
        1,
    );
    assert!(parse(&text.replacen("smooth = true\n", "", 1)).is_ok());
    let line = line_of(&text, "smooth");
    expect_parse_error(
        parse(&text),
        line,
        &["body[0].mesh", "unknown field `smooth`"],
    );
}

#[test]
fn unknown_key_in_inline_mesh_table() {
    let text = edit("cells = [4, 1, 1] }", "cells = [4, 1, 1], smooth = true }");
    let line = line_of(&text, "smooth");
    expect_parse_error(
        parse(&text),
        line,
        &["body[0].mesh", "unknown field `smooth`"],
    );
}

#[test]
fn unknown_key_in_constraint() {
    let text = edit(
        "{ kind = \"spring\", stiffness = 100.0 }",
        "{ kind = \"spring\", stiffness = 100.0, damping = 0.5 }",
    );
    let line = line_of(&text, "damping = 0.5");
    expect_parse_error(
        parse(&text),
        line,
        &["body[0].constraints[1]", "unknown field `damping`"],
    );
}

// --- Syntax and types: Error::Parse at the line of the value. ---

#[test]
fn value_of_the_wrong_type() {
    let text = edit("dt = 0.01", "dt = \"fast\"");
    let line = line_of(&text, "fast");
    expect_parse_error(parse(&text), line, &["simulation.dt"]);
}

#[test]
fn malformed_toml_unclosed_bracket() {
    let text = edit("[damping]", "[damping");
    let line = line_of(&text, "[damping");
    expect_parse_error(parse(&text), line, &[]);
}

#[test]
fn malformed_json_names_its_line() {
    // The comma after the simulation object is missing.
    let json = "{\n  \"simulation\": { \"dt\": 0.01, \"steps\": 10 }\n  \"body\": []\n}\n";
    let source = Path::new("scenes/bad.json");
    let err = Scene::parse(json, Syntax::Json, source).unwrap_err();
    let shown = err.to_string();
    assert!(matches!(err, Error::Parse { line: 3, .. }), "{shown}");
    assert!(shown.starts_with("scenes/bad.json:3: "), "{shown}");
    assert!(shown.contains("expected `,` or `}`"), "{shown}");
}

#[test]
fn json_scene_with_an_unknown_key_names_its_line() {
    let json = r#"{
  "simulation": { "dt": 0.01, "steps": 10 },
  "body": [
    {
      "mesh": { "generator": "chain", "points": 4, "length": 1.0 },
      "vertex_mass": 0.1,
      "colour": "red",
      "constraints": [ { "kind": "spring", "stiffness": 100.0 } ]
    }
  ]
}
"#;
    let source = Path::new("scenes/bad.json");
    assert!(
        Scene::parse(
            &json.replacen("\"colour\": \"red\",", "", 1),
            Syntax::Json,
            source
        )
        .is_ok()
    );
    let err = Scene::parse(json, Syntax::Json, source).unwrap_err();
    let shown = err.to_string();
    let line = line_of(json, "colour");
    match err {
        Error::Parse {
            path,
            line: found,
            message,
        } => {
            assert_eq!(path, source, "{shown}");
            assert_eq!(found, line, "{shown}");
            assert!(
                shown.starts_with(&format!("scenes/bad.json:{line}: ")),
                "{shown}"
            );
            assert!(
                message.contains("body[0]") && message.contains("unknown field `colour`"),
                "{shown}"
            );
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

// --- Invalid values: Error::Field naming the field path. ---

#[test]
fn zero_time_step() {
    expect_field_error(
        parse(&edit("dt = 0.01", "dt = 0.0")),
        "simulation.dt",
        &["> 0"],
    );
}

#[test]
fn negative_time_step() {
    expect_field_error(
        parse(&edit("dt = 0.01", "dt = -0.1")),
        "simulation.dt",
        &["-0.1"],
    );
}

#[test]
fn zero_iterations() {
    expect_field_error(
        parse(&edit("iterations = 10", "iterations = 0")),
        "simulation.iterations",
        &["at least 1"],
    );
}

#[test]
fn negative_tolerance() {
    expect_field_error(
        parse(&edit("tolerance = 0.0", "tolerance = -1e-3")),
        "simulation.tolerance",
        &[">= 0"],
    );
}

#[test]
fn absurd_thread_count() {
    expect_field_error(
        parse(&edit(
            "tolerance = 0.0",
            "tolerance = 0.0\nthreads = 100000",
        )),
        "simulation.threads",
        &["at most 1024", "100000"],
    );
    // The largest accepted count builds.
    let scene = parse(&edit("tolerance = 0.0", "tolerance = 0.0\nthreads = 1024")).unwrap();
    assert_eq!(scene.settings.threads, 1024);
}

#[test]
fn negative_density() {
    expect_field_error(
        parse(&edit("density = 1000.0", "density = -1000.0")),
        "body[0].density",
        &["-1000"],
    );
}

#[test]
fn negative_stiffness() {
    expect_field_error(
        parse(&edit("stiffness = 1.0e5", "stiffness = -1.0e5")),
        "body[0].constraints[0].stiffness",
        &[">= 0"],
    );
}

#[test]
fn neither_density_nor_vertex_mass() {
    expect_field_error(
        parse(&edit("density = 1000.0\n", "")),
        "body[0].density",
        &["density", "vertex_mass"],
    );
}

#[test]
fn both_density_and_vertex_mass() {
    expect_field_error(
        parse(&edit(
            "density = 1000.0\n",
            "density = 1000.0\nvertex_mass = 0.1\n",
        )),
        "body[0].vertex_mass",
        &["not both"],
    );
}

#[test]
fn unknown_integrator() {
    expect_field_error(
        parse(&edit("\"backward-euler\"", "\"forward-euler\"")),
        "simulation.integrator",
        &["forward-euler", "backward-euler"],
    );
}

#[test]
fn unknown_damping_model() {
    expect_field_error(
        parse(&edit("model = \"none\"", "model = \"viscous\"")),
        "damping.model",
        &["viscous", "none"],
    );
}

#[test]
fn unknown_generator() {
    expect_field_error(
        parse(&edit("generator = \"box\"", "generator = \"sphere\"")),
        "body[0].mesh.generator",
        &["sphere", "box"],
    );
}

#[test]
fn unknown_constraint_kind() {
    expect_field_error(
        // A kind the format does not have; the message lists the real ones.
        parse(&edit("kind = \"spring\"", "kind = \"plasticity\"")),
        "body[0].constraints[1].kind",
        &["plasticity", "spring"],
    );
}

#[test]
fn box_cells_with_two_values() {
    expect_field_error(
        parse(&edit("cells = [4, 1, 1]", "cells = [4, 1]")),
        "body[0].mesh.cells",
        &["needs 3 values, got 2"],
    );
}

#[test]
fn box_cells_containing_zero_fail_at_build() {
    // Parsing only checks the shape; the generator checks the counts.
    let scene = parse(&edit("cells = [4, 1, 1]", "cells = [4, 0, 1]")).unwrap();
    let err = scene.build().unwrap_err();
    field_error_of(err, Path::new(SOURCE), "body[0].mesh", &["cells"]);
}

#[test]
fn fixed_vertex_out_of_range_fails_at_build() {
    // The 4 x 1 x 1 box has 5 * 2 * 2 = 20 vertices, numbered 0 to 19.
    let scene = parse(&edit(
        "fixed = { box = { min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] } }",
        "fixed = { vertices = [0, 20] }",
    ))
    .unwrap();
    let err = scene.build().unwrap_err();
    field_error_of(
        err,
        Path::new(SOURCE),
        "body[0].fixed",
        &["20", "out of range"],
    );
}

#[test]
fn probe_out_of_range_fails_at_build() {
    let scene = parse(&edit("probes = [0, 5]", "probes = [20, 5]")).unwrap();
    let err = scene.build().unwrap_err();
    field_error_of(
        err,
        Path::new(SOURCE),
        "output.probes[0]",
        &["vertex 20", "20 vertices"],
    );
}

#[test]
fn no_body() {
    let text = VALID.replace(
        &VALID[VALID.find("[[body]]").unwrap()..VALID.find("[output]").unwrap()],
        "",
    );
    assert!(!text.contains("body"));
    expect_field_error(parse(&text), "body", &["[[body]]"]);
}

// --- TOML's `nan` and `inf` literals cannot sneak in. ---

#[test]
fn nan_time_step() {
    expect_field_error(
        parse(&edit("dt = 0.01", "dt = nan")),
        "simulation.dt",
        &["finite"],
    );
}

#[test]
fn infinite_density() {
    expect_field_error(
        parse(&edit("density = 1000.0", "density = inf")),
        "body[0].density",
        &["finite"],
    );
}

#[test]
fn nan_gravity_component() {
    expect_field_error(
        parse(&edit(
            "gravity = [0.0, -9.81, 0.0]",
            "gravity = [0.0, nan, 0.0]",
        )),
        "simulation.gravity[1]",
        &["finite"],
    );
}

/// A finite but absurd gravity is refused at load, naming the key and the
/// limit, instead of running until the divergence check's bound overflows.
#[test]
fn absurd_gravity() {
    expect_field_error(
        parse(&edit(
            "gravity = [0.0, -9.81, 0.0]",
            "gravity = [0.0, -1e300, 0.0]",
        )),
        "simulation.gravity",
        &["-1e300", "at most 1e154 m/s^2"],
    );
    // The limit itself is accepted.
    parse(&edit(
        "gravity = [0.0, -9.81, 0.0]",
        "gravity = [0.0, -1e6, 0.0]",
    ))
    .unwrap();
}

/// A `Scene` built in code (not read from a file, whose reader checks the
/// key) with a vertex mass out of its domain: building it names the key
/// that carries the mass, not the mesh.
#[test]
fn vertex_mass_out_of_domain_in_a_scene_built_in_code() {
    for bad in [-1.0, 0.0, f64::NAN, f64::INFINITY] {
        let mut scene = parse(&edit("density = 1000.0", "vertex_mass = 0.1")).unwrap();
        scene.bodies[0].mass = MassSpec::VertexMass(bad);
        let Err(err) = scene.build() else {
            panic!("a vertex mass of {bad} must be refused")
        };
        field_error_of(err, Path::new(SOURCE), "body[0].vertex_mass", &["> 0"]);
    }
}

// --- Mesh files: errors name the mesh file, and the line or element. ---

/// Two positively oriented tetrahedra, 0-1-2-3 and 0-1-4-3, where node 4 at
/// (1, 1, 0) lies in the plane of nodes 0, 1 and 2: tests make the second
/// tetrahedron 0-1-2-4, which is flat.
const NODE: &str = "# two tets\n5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 0\n";
const ELE: &str = "2 4 0\n0 0 1 2 3\n1 0 1 4 3\n";

/// Writes `mesh.node`, `mesh.ele` and a scene naming `file = "mesh.node"`
/// (relative) into a fresh folder; returns the scene's path.
fn tetgen_scene(test: &str, node: &str, ele: &str) -> PathBuf {
    let dir = scratch_dir(test);
    std::fs::write(dir.join("mesh.node"), node).unwrap();
    std::fs::write(dir.join("mesh.ele"), ele).unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "[simulation]\ndt = 0.01\nsteps = 1\n\n[[body]]\nmesh = { file = \"mesh.node\" }\n\
         density = 1000.0\nconstraints = [ { kind = \"tet-strain\", stiffness = 1.0e5 } ]\n",
    )
    .unwrap();
    scene
}

#[test]
fn the_valid_tetgen_mesh_builds() {
    let scene = tetgen_scene("valid_tetgen", NODE, ELE);
    let sim = Scene::load(&scene).unwrap().build().unwrap();
    assert_eq!(sim.model().num_vertices(), 5);
    std::fs::remove_dir_all(scene.parent().unwrap()).unwrap();
}

#[test]
fn missing_mesh_file_is_an_io_error_at_build() {
    let dir = scratch_dir("missing_mesh");
    let source = dir.join("scene.toml");
    let text = edit(
        "mesh = { generator = \"box\", size = [1.0, 0.2, 0.2], cells = [4, 1, 1] }",
        "mesh = { file = \"meshes/missing.node\" }",
    );
    // Parsing does not touch the mesh file.
    let scene = Scene::parse(&text, Syntax::Toml, &source).unwrap();
    let err = scene.build().unwrap_err();
    let shown = err.to_string();
    let expected = dir.join("meshes").join("missing.node");
    match err {
        Error::Io { path, .. } => assert_eq!(path, expected, "{shown}"),
        other => panic!("expected an I/O error, got {other:?}"),
    }
    assert!(shown.contains(&expected.display().to_string()), "{shown}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn empty_mesh_file_names_the_field() {
    // Joined to the scene's folder, an empty path would be read as the
    // TetGen base `folder/` and reported as a missing `folder/.node`.
    let text = edit(
        "mesh = { generator = \"box\", size = [1.0, 0.2, 0.2], cells = [4, 1, 1] }",
        "mesh = { file = \"\" }",
    );
    let message = expect_field_error(parse(&text), "body[0].mesh.file", &["is empty"]);
    assert!(!message.contains(".node"), "{message}");
}

#[test]
fn mesh_file_that_is_a_directory_names_the_field() {
    let dir = scratch_dir("mesh_directory");
    std::fs::create_dir(dir.join("meshes")).unwrap();
    let source = dir.join("scene.toml");
    let text = edit(
        "mesh = { generator = \"box\", size = [1.0, 0.2, 0.2], cells = [4, 1, 1] }",
        "mesh = { file = \"meshes\" }",
    );
    let err = Scene::parse(&text, Syntax::Toml, &source).unwrap_err();
    let folder = dir.join("meshes").display().to_string();
    let message = field_error_of(
        err,
        &source,
        "body[0].mesh.file",
        &[&folder, "is a directory"],
    );
    assert!(!message.contains(".node"), "{message}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn tetgen_mesh_with_a_flat_tet_names_the_tet() {
    let ele = ELE.replace("1 0 1 4 3", "1 0 1 2 4");
    let scene = tetgen_scene("flat_tet", NODE, &ele);
    let err = Scene::load(&scene).unwrap().build().unwrap_err();
    let shown = err.to_string();
    let ele_path = scene.with_file_name("mesh.ele");
    match &err {
        Error::Mesh { path, source } => {
            assert_eq!(*path, ele_path, "{shown}");
            assert!(
                matches!(source, MeshError::NonPositiveVolume { element: 1, .. }),
                "{shown}"
            );
        }
        other => panic!("expected a mesh error, got {other:?}"),
    }
    assert!(
        shown.starts_with(&ele_path.display().to_string()),
        "{shown}"
    );
    assert!(shown.contains("tetrahedron 1 "), "{shown}");
    std::fs::remove_dir_all(scene.parent().unwrap()).unwrap();
}

/// Builds the scene and expects a parse error in `file` of the scene's
/// folder at `line` mentioning `mentions`.
fn expect_mesh_parse_error(scene: &Path, file: &str, line: usize, mentions: &[&str]) {
    let err = Scene::load(scene).unwrap().build().unwrap_err();
    let shown = err.to_string();
    let expected = scene.with_file_name(file);
    match err {
        Error::Parse {
            path,
            line: found,
            message,
        } => {
            assert_eq!(path, expected, "{shown}");
            assert_eq!(found, line, "{shown}");
            for mention in mentions {
                assert!(message.contains(mention), "no `{mention}` in: {shown}");
            }
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
    assert!(
        shown.starts_with(&format!("{}:{line}: ", expected.display())),
        "{shown}"
    );
}

#[test]
fn tetgen_mesh_with_a_nan_coordinate() {
    let node = NODE.replace("2 0 1 0", "2 0 nan 0");
    let scene = tetgen_scene("nan_coordinate", &node, ELE);
    let line = line_of(&node, "nan");
    expect_mesh_parse_error(
        &scene,
        "mesh.node",
        line,
        &["y coordinate", "node 2", "finite"],
    );
    std::fs::remove_dir_all(scene.parent().unwrap()).unwrap();
}

#[test]
fn tetgen_mesh_with_an_out_of_range_index() {
    let ele = ELE.replace("1 0 1 4 3", "1 0 1 4 7");
    let scene = tetgen_scene("index_out_of_range", NODE, &ele);
    let line = line_of(&ele, "1 0 1 4 7");
    expect_mesh_parse_error(&scene, "mesh.ele", line, &["tetrahedron 1", "node 7"]);
    std::fs::remove_dir_all(scene.parent().unwrap()).unwrap();
}

// --- Known bugs, ignored until fixed. ---

#[test]
fn json_scene_with_trailing_characters_is_rejected() {
    let json = "{\n  \"simulation\": { \"dt\": 0.01, \"steps\": 10 },\n  \"body\": [ { \"mesh\": \
                { \"generator\": \"chain\", \"points\": 4, \"length\": 1.0 }, \"vertex_mass\": \
                0.1 } ]\n}\n";
    let source = Path::new("scenes/bad.json");
    assert!(Scene::parse(json, Syntax::Json, source).is_ok());
    // A second object pasted after the first, e.g. by a bad merge.
    let text = format!("{json}{{ \"simulation\": {{ \"dt\": -1.0 }} }}\n");
    let err = Scene::parse(&text, Syntax::Json, source).expect_err("trailing text is accepted");
    let shown = err.to_string();
    assert!(
        matches!(err, Error::Parse { line: 5, .. }),
        "expected a parse error at line 5, got {shown}"
    );
}

#[test]
fn malformed_json_shows_no_placeholder_field() {
    let json = "{\n  \"simulation\": { \"dt\": 0.01, \"steps\": 10 }\n  \"body\": []\n}\n";
    let shown = Scene::parse(json, Syntax::Json, Path::new("scenes/bad.json"))
        .unwrap_err()
        .to_string();
    assert!(!shown.contains(" ?: "), "{shown}");
}

#[test]
fn accuracy_outside_zero_to_one() {
    for bad in ["0.0", "-0.01", "1.0", "2.5", "nan", "inf"] {
        expect_field_error(
            parse(&edit("tolerance = 0.0", &format!("accuracy = {bad}"))),
            "simulation.accuracy",
            &["(0, 1)"],
        );
    }
}

#[test]
fn accuracy_with_a_tolerance() {
    expect_field_error(
        parse(&edit(
            "tolerance = 0.0",
            "tolerance = 0.001\naccuracy = 0.01",
        )),
        "simulation.accuracy",
        &["simulation.tolerance", "0.001"],
    );
}

#[test]
fn accuracy_makes_iterations_a_cap() {
    // Without `iterations`, the cap is 10000; with it, the scene's.
    let without = edit("iterations = 10\ntolerance = 0.0", "accuracy = 0.01");
    let scene = parse(&without).unwrap();
    assert_eq!(scene.settings.accuracy, 0.01);
    assert_eq!(scene.settings.iterations, 10_000);
    let with = parse(&edit("tolerance = 0.0", "accuracy = 0.01")).unwrap();
    assert_eq!(with.settings.iterations, 10);
    // `tolerance = 0` is no tolerance, and no conflict; without accuracy
    // the settings are today's.
    let zero = parse(&edit("tolerance = 0.0", "tolerance = 0.0\naccuracy = 0.01")).unwrap();
    assert_eq!(zero.settings.accuracy, 0.01);
    let plain = parse(&edit("tolerance = 0.0", "tolerance = 0.0")).unwrap();
    assert_eq!(plain.settings.accuracy, 0.0);
    assert_eq!(plain.settings.iterations, 10);
}
