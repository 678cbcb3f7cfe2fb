//! The cloth and shell constraint kinds in scene files: their keys as
//! written (docs/reference/scene-format.md, "Cloth and shell constraints"),
//! and the input errors, which name the field path and the offending
//! triangle.

use std::path::Path;

use pd_io::scene::{ConstraintSpec, Scene, Syntax};

fn parse(text: &str) -> Result<Scene, String> {
    Scene::parse(text, Syntax::Toml, Path::new("cloth.toml")).map_err(|e| e.to_string())
}

fn built(text: &str) -> Result<usize, String> {
    let scene = parse(text)?;
    let sim = scene.build().map_err(|e| e.to_string())?;
    Ok(sim.model().num_constraints())
}

const SHEET: &str = r#"
[simulation]
dt = 0.01
steps = 1

[[body]]
mesh = { generator = "cloth", size = [1.0, 0.5], cells = [4, 2] }
density = 0.2
fixed = { vertices = [0, 4] }
constraints = [
  { kind = "triangle-strain", stiffness = 5.0e3, limits = [0.95, 1.05] },
  { kind = "bending", stiffness = 1.0e-3 },
  { kind = "area", stiffness = 1.0e3 },
]
"#;

#[test]
fn the_contract_keys_are_accepted_as_written() {
    let scene = parse(SHEET).unwrap();
    assert_eq!(
        scene.bodies[0].constraints,
        vec![
            ConstraintSpec::TriangleStrain {
                stiffness: 5.0e3,
                limits: Some((0.95, 1.05))
            },
            ConstraintSpec::Bending { stiffness: 1.0e-3 },
            ConstraintSpec::Area { stiffness: 1.0e3 },
        ]
    );
    // 16 triangles, each with strain, area and (flat sheet) plate bending.
    assert_eq!(built(SHEET).unwrap(), 3 * 16);

    let solid = r#"
[simulation]
dt = 0.01
steps = 1

[[body]]
mesh = { generator = "box", size = [1.0, 1.0, 1.0], cells = [1, 1, 1] }
density = 1000.0
constraints = [ { kind = "tet-strain", stiffness = 1.0e5 }, { kind = "volume", stiffness = 1.0e5 } ]
"#;
    let scene = parse(solid).unwrap();
    assert_eq!(
        scene.bodies[0].constraints[1],
        ConstraintSpec::Volume { stiffness: 1.0e5 }
    );
    let tets = built(solid).unwrap() / 2;
    assert!(tets > 0);
}

#[test]
fn wrong_meshes_and_parameters_are_named() {
    let on_tets = r#"
[simulation]
dt = 0.01
steps = 1

[[body]]
mesh = { generator = "box", size = [1.0, 1.0, 1.0], cells = [1, 1, 1] }
density = 1000.0
constraints = [ { kind = "bending", stiffness = 1.0 } ]
"#;
    let e = built(on_tets).unwrap_err();
    assert!(
        e.contains("body[0].constraints[0]") && e.contains("triangle mesh"),
        "{e}"
    );

    let volume_on_cloth = SHEET.replace(r#"kind = "area""#, r#"kind = "volume""#);
    let e = built(&volume_on_cloth).unwrap_err();
    assert!(
        e.contains("body[0].constraints[2]") && e.contains("tetrahedral"),
        "{e}"
    );

    let limits_on_bending = SHEET.replace(
        r#"{ kind = "bending", stiffness = 1.0e-3 }"#,
        r#"{ kind = "bending", stiffness = 1.0e-3, limits = [0.9, 1.1] }"#,
    );
    let e = parse(&limits_on_bending).unwrap_err();
    assert!(e.contains("constraints[1].limits"), "{e}");

    let bad_limits = SHEET.replace("[0.95, 1.05]", "[1.05, 0.95]");
    let e = parse(&bad_limits).unwrap_err();
    assert!(e.contains("constraints[0].limits"), "{e}");
}

/// Writes `obj` next to a scene using it and returns the build error.
fn obj_error(name: &str, obj: &str) -> String {
    let dir = std::env::temp_dir().join(format!("pd-io-cloth-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let text = r#"
[simulation]
dt = 0.01
steps = 1

[[body]]
mesh = { file = "m.obj" }
density = 0.2
constraints = [ { kind = "triangle-strain", stiffness = 1.0e3 }, { kind = "bending", stiffness = 1.0e-3 } ]
"#;
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let result = Scene::load(&path).and_then(|s| s.build().map(drop));
    std::fs::remove_dir_all(&dir).unwrap();
    result.map_err(|e| e.to_string()).unwrap_err()
}

#[test]
fn degenerate_and_non_manifold_triangles_are_rejected_by_index() {
    // Triangle 1 is collinear: zero area. The OBJ reader already names it
    // (file, line and triangle index); the model's own check, for meshes
    // from elsewhere, is tested in pd-solver's `cloth_physics`.
    let degenerate = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n";
    let e = obj_error("degenerate", degenerate);
    assert!(e.contains("m.obj") && e.contains("triangle 1"), "{e}");
    // Three triangles on the edge 1-2 (0-based 0-1).
    let fan = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n";
    let e = obj_error("fan", fan);
    assert!(
        e.contains("body[0].constraints[0]") && e.contains("[0, 1]") && e.contains("non-manifold"),
        "{e}"
    );
}

#[test]
fn open_edges_and_pinned_corners_are_fine() {
    // A single triangle: all edges open, no hinge; two corners pinned.
    let dir = std::env::temp_dir().join(format!("pd-io-cloth-{}-open", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let text = r#"
[simulation]
dt = 0.01
steps = 1

[[body]]
mesh = { file = "m.obj" }
density = 0.2
fixed = { vertices = [0, 1] }
constraints = [ { kind = "triangle-strain", stiffness = 1.0e3 }, { kind = "bending", stiffness = 1.0e-3 } ]
"#;
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let sim = Scene::load(&path).unwrap().build().unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(sim.model().num_constraints(), 1);
}
