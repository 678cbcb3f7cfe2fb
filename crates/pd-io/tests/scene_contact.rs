//! The contact keys of a scene (`[[collider]]`, `[contact]`, `[[body]]
//! translate`; docs/reference/scene-format.md, "Contact"): valid ones build a
//! simulation with contact, bad ones are errors naming the field.

use std::path::Path;

use pd_io::scene::{Scene, Syntax};
use pd_mesh::Point;
use pd_solver::contact::ColliderShape;

const BODY: &str = r#"[simulation]
dt = 0.01
steps = 10

[[body]]
mesh = { generator = "box", size = [0.2, 0.2, 0.2], cells = [2, 2, 2] }
density = 1000.0
constraints = [ { kind = "tet-strain", stiffness = 1.0e5 } ]
"#;

fn parse(extra: &str) -> pd_io::Result<Scene> {
    let text = format!("{BODY}{extra}");
    Scene::parse(&text, Syntax::Toml, Path::new("scenes/contact.toml"))
}

fn error(extra: &str) -> String {
    parse(extra).unwrap_err().to_string()
}

#[test]
fn every_shape_is_read_with_defaults() {
    let scene = parse(
        r#"
[[collider]]
shape = "plane"
point = [0.0, -1.0, 0.0]
normal = [0.0, 2.0, 0.0]
friction = 0.3

[[collider]]
shape = "sphere"
center = [1.0, 0.0, 0.0]
radius = 0.5
restitution = 0.5

[[collider]]
shape = "box"
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]

[contact]
thickness = 0.001
"#,
    )
    .unwrap();
    let contact = scene.contact.as_ref().unwrap();
    assert_eq!(contact.thickness, 0.001);
    assert_eq!(contact.colliders.len(), 3);
    // The normal is normalised; friction and restitution default to 0.
    assert_eq!(
        contact.colliders[0].shape,
        ColliderShape::Plane {
            point: Point::new(0.0, -1.0, 0.0),
            normal: Point::y()
        }
    );
    assert_eq!(contact.colliders[0].friction, 0.3);
    assert_eq!(contact.colliders[0].restitution, 0.0);
    assert_eq!(contact.colliders[1].restitution, 0.5);
    assert_eq!(contact.colliders[2].friction, 0.0);
    let sim = scene.build().unwrap();
    assert_eq!(sim.contact().unwrap().colliders.len(), 3);
}

#[test]
fn a_scene_without_colliders_builds_no_contact() {
    let scene = parse("\n[contact]\nthickness = 0.01\n").unwrap();
    assert!(scene.contact.is_none());
    assert!(scene.build().unwrap().contact().is_none());
}

#[test]
fn the_ball_generator_builds_a_ball_and_names_its_bad_keys() {
    let text = BODY.replace(
        r#"{ generator = "box", size = [0.2, 0.2, 0.2], cells = [2, 2, 2] }"#,
        r#"{ generator = "ball", radius = 0.1, cells = [4] }"#,
    );
    let scene = Scene::parse(&text, Syntax::Toml, Path::new("t.toml")).unwrap();
    let sim = scene.build().unwrap();
    assert_eq!(sim.state().positions.len(), 125);
    let far = (sim.state().positions.iter())
        .map(|p| p.norm())
        .fold(0.0, f64::max);
    // The cube grid's corners land on the sphere, up to round-off.
    assert!((far - 0.1).abs() < 1e-15, "{far}");
    for (from, to, expected) in [
        ("radius = 0.1", "radius = -0.1", "body[0].mesh.radius"),
        (
            "cells = [4]",
            "cells = [4, 4]",
            "body[0].mesh.cells: needs 1 values",
        ),
        ("radius = 0.1, ", "", "body[0].mesh.radius: missing"),
        (
            "cells = [4]",
            "cells = [4], size = [1.0]",
            "body[0].mesh.size: is not a parameter",
        ),
    ] {
        let bad = text.replace(from, to);
        let message = Scene::parse(&bad, Syntax::Toml, Path::new("t.toml"))
            .and_then(|s| s.build().map(drop))
            .unwrap_err()
            .to_string();
        assert!(message.contains(expected), "{to}: {message}");
    }
    let one = text.replace("cells = [4]", "cells = [1]");
    let message = Scene::parse(&one, Syntax::Toml, Path::new("t.toml"))
        .and_then(|s| s.build().map(drop))
        .unwrap_err()
        .to_string();
    assert!(message.contains("at least 2 cells"), "{message}");
}

#[test]
fn contact_between_bodies_builds_without_colliders() {
    let scene = parse("\n[contact]\nbodies = true\nthickness = 0.002\nfriction = 0.4\n").unwrap();
    assert_eq!(scene.body_contact.as_ref().unwrap().friction, 0.4);
    let contact = scene.contact.as_ref().unwrap();
    assert!(contact.colliders.is_empty());
    assert_eq!(contact.thickness, 0.002);
    assert!(scene.build().unwrap().contact().is_some());
}

#[test]
fn bad_colliders_name_their_field() {
    let cases = [
        (
            "[[collider]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 0.0]\n",
            "collider[0].normal: zero vector",
        ),
        (
            "[[collider]]\nshape = \"plane\"\nnormal = [0.0, 1.0, 0.0]\n",
            "collider[0].point: missing",
        ),
        (
            "[[collider]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = -1.0\n",
            "collider[0].radius: must be finite and > 0, got -1",
        ),
        (
            "[[collider]]\nshape = \"box\"\nmin = [0.0, 2.0, 0.0]\nmax = [1.0, 1.0, 1.0]\n",
            "collider[0].max: min > max along axis 1 (2 > 1)",
        ),
        (
            "[[collider]]\nshape = \"cone\"\n",
            "collider[0].shape: unknown shape \"cone\"",
        ),
        ("[[collider]]\nradius = 1.0\n", "collider[0].shape: missing"),
        (
            "[[collider]]\nshape = \"mesh\"\nfile = \"no-such-bowl.obj\"\n",
            "collider[0].file: no such file: scenes/no-such-bowl.obj",
        ),
        (
            "[[collider]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nradius = 1.0\n",
            "collider[0].radius: not a key of shape \"plane\"",
        ),
        (
            "[[collider]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nfriction = -0.1\n",
            "collider[0].friction: must be finite and >= 0",
        ),
        (
            "[[collider]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nrestitution = 1.5\n",
            "collider[0].restitution: must be in [0, 1]",
        ),
        (
            "[contact]\nthickness = -0.1\n",
            "contact.thickness: must be finite and >= 0",
        ),
        (
            "[contact]\nbodies = true\nfriction = -1.0\n",
            "contact.friction: must be finite and >= 0, got -1",
        ),
        (
            "[contact]\nfriction = 0.5\n",
            "contact.friction: only with bodies = true",
        ),
    ];
    for (extra, expected) in cases {
        let message = error(extra);
        assert!(message.contains("scenes/contact.toml"), "{message}");
        assert!(message.contains(expected), "{extra}: {message}");
    }
    // The second collider is named by its index.
    let second = "[[collider]]\nshape = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\n\
                  [[collider]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.0\n";
    assert!(
        error(second).contains("collider[1].radius"),
        "{}",
        error(second)
    );
}

#[test]
fn translate_places_the_mesh_and_selections_are_in_world_coordinates() {
    let text = BODY.replace(
        "density = 1000.0\n",
        "density = 1000.0\ntranslate = [0.0, 0.5, 0.0]\n\
         fixed = { box = { min = [-1.0, 0.45, -1.0], max = [1.0, 0.55, 1.0] } }\n",
    );
    let scene = Scene::parse(&text, Syntax::Toml, Path::new("t.toml")).unwrap();
    let sim = scene.build().unwrap();
    let lowest = sim
        .state()
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(lowest, 0.5);
    // The box around y = 0.5 holds the bottom layer (9 of 27 vertices): it
    // is read after the translation; before it, it would hold none.
    let fixed: Vec<bool> = sim.model().fixed().to_vec();
    assert_eq!(fixed.iter().filter(|&&f| f).count(), 9);
    for (p, f) in sim.state().positions.iter().zip(&fixed) {
        assert_eq!(*f, p.y == 0.5);
    }
}

#[test]
fn a_mesh_collider_reads_its_obj_relative_to_the_scene() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let text = format!("{BODY}\n[[collider]]\nshape = \"mesh\"\nfile = \"meshes/bowl.obj\"\n");
    let parsed = Scene::parse(&text, Syntax::Toml, &dir.join("bowl_test.toml"));
    if cfg!(feature = "mesh-collider") {
        let scene = parsed.unwrap();
        let shape = &scene.contact.as_ref().unwrap().colliders[0].shape;
        let ColliderShape::Mesh(surface) = shape else {
            panic!("{shape:?}");
        };
        // 1 + 12 rings of 32 vertices; 32 + 2 * 11 * 32 triangles.
        assert_eq!(surface.vertices().len(), 385);
        assert_eq!(surface.triangles().len(), 736);
    } else {
        let message = parsed.unwrap_err().to_string();
        assert!(
            message.contains("collider[0].shape: mesh colliders need"),
            "{message}"
        );
    }
}

/// Colliders work with the local-global method only: the accelerated and
/// converged methods judge iterates by the step objective, which does not
/// contain the contact forces. Asking for both is an error at the method's
/// field, at build time, not a silent fallback.
#[test]
fn colliders_with_an_objective_judging_method_are_refused_at_solver_method() {
    for method in ["anderson", "lbfgs", "newton", "chebyshev"] {
        let scene = parse(&format!(
            "[solver]\nmethod = \"{method}\"\n\n[[collider]]\nshape = \"plane\"\npoint = [0.0, -1.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\n"
        ))
        .unwrap();
        let e = scene.build().unwrap_err().to_string();
        assert!(e.contains("solver.method"), "{method}: {e}");
        assert!(
            e.contains(method) && e.contains("local-global"),
            "{method}: {e}"
        );
    }
    let scene = parse(
        "[solver]\nmethod = \"local-global\"\n\n[[collider]]\nshape = \"plane\"\npoint = [0.0, -1.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\n",
    )
    .unwrap();
    assert!(scene.build().unwrap().contact().is_some());
}

#[test]
fn a_malformed_mesh_collider_is_named_by_its_field_and_line() {
    let dir = std::env::temp_dir().join(format!("pd-io-collider-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("bad.obj"), "v 0 0 0\nv 1 0 0\nf 1 2 9\n").unwrap();
    let text = format!("{BODY}\n[[collider]]\nshape = \"mesh\"\nfile = \"bad.obj\"\n");
    let message = Scene::parse(&text, Syntax::Toml, &dir.join("s.toml"))
        .unwrap_err()
        .to_string();
    std::fs::remove_dir_all(&dir).unwrap();
    if cfg!(feature = "mesh-collider") {
        // The scene's field, then the OBJ file's own line.
        assert!(
            message.contains("s.toml: collider[0].file: ") && message.contains("bad.obj:3"),
            "{message}"
        );
    }
}

#[test]
fn a_plane_normal_of_extreme_entries_is_normalised() {
    for (normal, expected) in [
        ("[0.0, 1e308, 1e308]", [0.0, 1.0, 1.0]),
        ("[0.0, 1e-320, 0.0]", [0.0, 1.0, 0.0]),
    ] {
        let scene = parse(&format!(
            "[[collider]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = {normal}\n"
        ))
        .unwrap();
        let ColliderShape::Plane { normal: n, .. } = scene.contact.unwrap().colliders[0].shape
        else {
            panic!("not a plane");
        };
        let expected = Point::from(expected).normalize();
        // One rounding per division and in the square root: a few ulps.
        assert!((n - expected).norm() < 4.0 * f64::EPSILON, "{normal}: {n}");
    }
}
