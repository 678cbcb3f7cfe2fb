//! Scenes select the new mesh readers by the file's extension and the new
//! frame formats by name; a bad mesh file's error reaches the user with its
//! file and line.

mod common;

use std::path::{Path, PathBuf};

use pd_io::Error;
use pd_io::scene::{FrameFormat, MeshSource, Scene, Syntax};

fn scene_with(mesh: &str, constraint: &str, formats: &str) -> String {
    format!(
        r#"
[simulation]
dt = 0.01
steps = 2

[[body]]
mesh = {mesh}
density = 100.0
constraints = [ {constraint} ]
fixed = {{ vertices = [0] }}

[output]
formats = {formats}
"#
    )
}

#[test]
fn the_file_extension_chooses_the_reader() {
    let cases = [
        ("m.msh", MeshSource::Gmsh as fn(PathBuf) -> MeshSource),
        ("m.MSH", MeshSource::Gmsh),
        ("m.mesh", MeshSource::Medit),
        ("m.obj", MeshSource::Obj),
        ("m.1.face", MeshSource::TetGenSurface),
        ("m.1.node", MeshSource::TetGen),
    ];
    for (file, source) in cases {
        let text = scene_with(
            &format!("{{ file = \"{file}\" }}"),
            "{ kind = \"spring\", stiffness = 1.0 }",
            "[]",
        );
        let scene = Scene::parse(&text, Syntax::Toml, Path::new("dir/s.toml")).unwrap();
        assert_eq!(
            scene.bodies[0].mesh,
            source(Path::new("dir").join(file)),
            "{file}"
        );
    }
    let text = scene_with(
        "{ file = \"m.stl\" }",
        "{ kind = \"spring\", stiffness = 1.0 }",
        "[]",
    );
    let err = Scene::parse(&text, Syntax::Toml, Path::new("s.toml")).unwrap_err();
    let shown = err.to_string();
    assert!(
        shown.contains("body[0].mesh.file: unsupported mesh format \".stl\"")
            && shown.contains("Gmsh .msh"),
        "{shown}"
    );
}

#[test]
fn frame_formats_vtu_and_ply_are_accepted_and_others_named() {
    let text = scene_with(
        "{ generator = \"chain\", points = 3, length = 1.0 }",
        "{ kind = \"spring\", stiffness = 1.0 }",
        "[\"vtk\", \"vtu\", \"obj\", \"ply\"]",
    );
    let scene = Scene::parse(&text, Syntax::Toml, Path::new("s.toml")).unwrap();
    assert_eq!(
        scene.output.formats,
        [
            FrameFormat::Vtk,
            FrameFormat::Vtu,
            FrameFormat::Obj,
            FrameFormat::Ply
        ]
    );
    let text = scene_with(
        "{ generator = \"chain\", points = 3, length = 1.0 }",
        "{ kind = \"spring\", stiffness = 1.0 }",
        "[\"vtu\", \"stl\"]",
    );
    let shown = Scene::parse(&text, Syntax::Toml, Path::new("s.toml"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        shown,
        "s.toml: output.formats[1]: unknown format \"stl\"; expected \"vtk\", \"vtu\", \"obj\" or \"ply\""
    );
}

#[test]
fn scenes_build_and_run_from_every_new_format() {
    let formats = common::data_dir().join("formats");
    let cases = [
        ("two_tets.msh", "tet-strain", 5, 2),
        ("two_tets.mesh", "tet-strain", 5, 2),
        ("quad_cloth.obj", "spring", 6, 4),
        ("two_tets.1.face", "spring", 5, 6),
    ];
    for (file, kind, vertices, elements) in cases {
        let text = scene_with(
            &format!("{{ file = \"{file}\" }}"),
            &format!("{{ kind = \"{kind}\", stiffness = 1000.0 }}"),
            "[\"vtu\"]",
        );
        let scene = Scene::parse(&text, Syntax::Toml, &formats.join("scene.toml")).unwrap();
        let mut sim = scene.build().unwrap_or_else(|e| panic!("{file}: {e}"));
        let mesh = sim.model().bodies()[0].mesh.clone();
        assert_eq!(
            (mesh.num_vertices(), mesh.num_elements()),
            (vertices, elements),
            "{file}"
        );
        sim.run(scene.steps).unwrap();
        // Gravity pulls the free vertices down.
        let state = sim.state();
        assert!(
            state.positions[1..]
                .iter()
                .zip(&mesh.vertices()[1..])
                .all(|(x, r)| x.y < r.y),
            "{file}"
        );
    }
}

#[test]
fn a_bad_mesh_file_is_reported_with_its_line_when_building() {
    let dir = common::scratch_dir("scene_bad_mesh");
    std::fs::write(dir.join("bad.obj"), "v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap();
    let text = scene_with(
        "{ file = \"bad.obj\" }",
        "{ kind = \"spring\", stiffness = 1.0 }",
        "[]",
    );
    let scene = Scene::parse(&text, Syntax::Toml, &dir.join("s.toml")).unwrap();
    let err = scene.build().unwrap_err();
    assert!(matches!(&err, Error::Parse { line: 3, .. }), "{err}");
    assert!(
        err.to_string().starts_with(&format!(
            "{}:3: vertex index 3 is out of range",
            dir.join("bad.obj").display()
        )),
        "{err}"
    );
}
