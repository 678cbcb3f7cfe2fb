//! VTU, PVD and PLY frames parse back, with small independent parsers
//! written here, to exactly the numbers written; the strain field matches
//! closed-form strains; a recorded run writes a `.pvd` series listing every
//! `.vtu` frame with its time, and the last frame equals the final state.

mod common;

use pd_io::Error;
use pd_io::frames::Cells;
use pd_io::ply::write_ply;
use pd_io::recorder::{Outcome, Recorder};
use pd_io::scene::{Scene, Syntax};
use pd_io::strain::StrainMeasure;
use pd_io::vtu::{PvdEntry, write_pvd, write_vtu};
use pd_mesh::Point;

/// Values whose text forms are awkward: thirds, tiny, huge, subnormal, -0.
fn awkward(i: usize) -> Point {
    let t = i as f64 + 1.0;
    match i % 3 {
        0 => Point::new(t / 3.0, -t / 7.0, 5e-324 * t),
        1 => Point::new(t * 1.7e300, -0.0, 1e-300 / t),
        _ => Point::new(t.sin(), t.cos() * 1e-7, 1e15 + t / 9.0),
    }
}

fn same_bits(a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert_eq!(x.to_bits(), y.to_bits(), "value {i}: read {x}, wrote {y}");
    }
}

fn flatten(points: &[Point]) -> Vec<f64> {
    points.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

/// The attribute `name="..."` of an XML start tag.
fn attribute<'a>(tag: &'a str, name: &str) -> &'a str {
    let key = format!(" {name}=\"");
    let start = tag
        .find(&key)
        .unwrap_or_else(|| panic!("no {name} in {tag}"))
        + key.len();
    let end = tag[start..].find('"').unwrap() + start;
    &tag[start..end]
}

/// The text inside `<DataArray ... Name="name" ...> ... </DataArray>`, with
/// its start tag.
fn data_array<'a>(xml: &'a str, name: &str) -> Option<(&'a str, &'a str)> {
    let mut rest = xml;
    while let Some(start) = rest.find("<DataArray") {
        let tag_end = rest[start..].find('>').unwrap() + start;
        let tag = &rest[start..=tag_end];
        let close = rest[tag_end..].find("</DataArray>").unwrap() + tag_end;
        if attribute(tag, "Name") == name {
            return Some((tag, &rest[tag_end + 1..close]));
        }
        rest = &rest[close..];
    }
    None
}

fn numbers<T: std::str::FromStr>(text: &str) -> Vec<T>
where
    T::Err: std::fmt::Debug,
{
    text.split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect()
}

#[test]
fn vtu_frame_reads_back_exactly() {
    let dir = common::scratch_dir("vtu_round_trip");
    let path = dir.join("frame.vtu");
    let positions: Vec<Point> = (0..7).map(awkward).collect();
    let velocities: Vec<Point> = (0..7).map(|i| -awkward(i + 3)).collect();
    let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
    let triangles = [[4, 5, 6]];
    let lines = [[5, 6], [0, 6]];
    let cells = Cells {
        tets: &tets,
        triangles: &triangles,
        lines: &lines,
    };
    let strain = [1.0 / 3.0, 2e-310, 0.0, -0.25, 7e12];
    write_vtu(&path, &positions, &cells, Some(&velocities), Some(&strain)).unwrap();
    let xml = std::fs::read_to_string(&path).unwrap();

    assert!(xml.starts_with("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\""));
    let piece_start = xml.find("<Piece").unwrap();
    let piece = &xml[piece_start..=piece_start + xml[piece_start..].find('>').unwrap()];
    assert_eq!(attribute(piece, "NumberOfPoints"), "7");
    assert_eq!(attribute(piece, "NumberOfCells"), "5");

    let (tag, text) = data_array(&xml, "Points").unwrap();
    assert_eq!(attribute(tag, "NumberOfComponents"), "3");
    assert_eq!(attribute(tag, "type"), "Float64");
    same_bits(&numbers(text), &flatten(&positions));
    let (tag, text) = data_array(&xml, "velocity").unwrap();
    assert_eq!(attribute(tag, "NumberOfComponents"), "3");
    same_bits(&numbers(text), &flatten(&velocities));
    same_bits(&numbers(data_array(&xml, "strain").unwrap().1), &strain);
    // The velocity is point data, the strain cell data.
    let point_data = &xml[xml.find("<PointData").unwrap()..xml.find("</PointData>").unwrap()];
    assert!(point_data.contains("Name=\"velocity\""));
    let cell_data = &xml[xml.find("<CellData").unwrap()..xml.find("</CellData>").unwrap()];
    assert!(cell_data.contains("Name=\"strain\""));

    let connectivity: Vec<usize> = numbers(data_array(&xml, "connectivity").unwrap().1);
    assert_eq!(connectivity, [0, 1, 2, 3, 1, 2, 3, 4, 4, 5, 6, 5, 6, 0, 6]);
    let offsets: Vec<usize> = numbers(data_array(&xml, "offsets").unwrap().1);
    assert_eq!(offsets, [4, 8, 11, 13, 15]);
    let types: Vec<u8> = numbers(data_array(&xml, "types").unwrap().1);
    assert_eq!(types, [10, 10, 5, 3, 3]);
}

#[test]
fn vtu_without_fields_has_no_data_sections_and_bad_input_is_refused() {
    let dir = common::scratch_dir("vtu_plain");
    let path = dir.join("plain.vtu");
    let positions = [Point::zeros(), Point::x()];
    let cells = Cells {
        lines: &[[0, 1]],
        ..Cells::default()
    };
    write_vtu(&path, &positions, &cells, None, None).unwrap();
    let xml = std::fs::read_to_string(&path).unwrap();
    assert!(!xml.contains("<PointData") && !xml.contains("<CellData"));

    let refused = dir.join("refused.vtu");
    let errors = [
        write_vtu(&refused, &positions, &cells, None, Some(&[])),
        write_vtu(&refused, &positions, &cells, None, Some(&[f64::NAN])),
        write_vtu(&refused, &positions, &cells, Some(&[Point::zeros()]), None),
        write_vtu(
            &refused,
            &positions,
            &Cells {
                lines: &[[0, 2]],
                ..Cells::default()
            },
            None,
            None,
        ),
        write_vtu(
            &refused,
            &[Point::new(f64::INFINITY, 0.0, 0.0)],
            &Cells::default(),
            None,
            None,
        ),
    ];
    for err in errors {
        let err = err.unwrap_err();
        assert!(
            matches!(&err, Error::Content { path, .. } if *path == refused),
            "{err}"
        );
    }
    assert!(!refused.exists());
}

#[test]
fn pvd_lists_frames_with_their_times() {
    let dir = common::scratch_dir("pvd");
    let path = dir.join("run.pvd");
    let entries: Vec<PvdEntry> = (0..4)
        .map(|k| PvdEntry {
            time: k as f64 * 0.1,
            file: format!("frames/frame_{k:05}.vtu"),
        })
        .collect();
    write_pvd(&path, &entries).unwrap();
    let xml = std::fs::read_to_string(&path).unwrap();
    assert!(xml.contains("<VTKFile type=\"Collection\""));
    let datasets: Vec<(f64, String)> = xml
        .lines()
        .filter(|l| l.trim_start().starts_with("<DataSet"))
        .map(|l| {
            (
                attribute(l, "timestep").parse().unwrap(),
                attribute(l, "file").to_string(),
            )
        })
        .collect();
    assert_eq!(datasets.len(), 4);
    for (entry, (time, file)) in entries.iter().zip(&datasets) {
        assert_eq!(entry.time.to_bits(), time.to_bits());
        assert_eq!(&entry.file, file);
    }
    let err = write_pvd(
        &path,
        &[PvdEntry {
            time: f64::NAN,
            file: "x".into(),
        }],
    )
    .unwrap_err();
    assert!(matches!(err, Error::Content { .. }), "{err}");
}

/// A small PLY parser: header with element counts and properties, then the
/// bodies in declaration order.
struct Ply {
    vertices: Vec<Point>,
    faces: Vec<Vec<usize>>,
    edges: Vec<[usize; 2]>,
}

fn parse_ply(text: &str) -> Ply {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("ply"));
    assert_eq!(lines.next(), Some("format ascii 1.0"));
    let mut elements: Vec<(String, usize, Vec<String>)> = Vec::new();
    for line in lines.by_ref() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        match fields[0] {
            "comment" => {}
            "element" => elements.push((fields[1].into(), fields[2].parse().unwrap(), Vec::new())),
            "property" => elements.last_mut().unwrap().2.push(fields[1..].join(" ")),
            "end_header" => break,
            other => panic!("unexpected header line {other}"),
        }
    }
    let mut ply = Ply {
        vertices: Vec::new(),
        faces: Vec::new(),
        edges: Vec::new(),
    };
    for (name, count, properties) in elements {
        for _ in 0..count {
            let fields: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
            match name.as_str() {
                "vertex" => {
                    assert_eq!(properties, ["double x", "double y", "double z"]);
                    let v: Vec<f64> = fields.iter().map(|f| f.parse().unwrap()).collect();
                    ply.vertices.push(Point::new(v[0], v[1], v[2]));
                }
                "face" => {
                    assert_eq!(properties, ["list uchar int vertex_indices"]);
                    let n: usize = fields[0].parse().unwrap();
                    assert_eq!(fields.len(), n + 1);
                    ply.faces
                        .push(fields[1..].iter().map(|f| f.parse().unwrap()).collect());
                }
                "edge" => {
                    assert_eq!(properties, ["int vertex1", "int vertex2"]);
                    ply.edges
                        .push([fields[0].parse().unwrap(), fields[1].parse().unwrap()]);
                }
                other => panic!("unexpected element {other}"),
            }
        }
    }
    assert_eq!(lines.next(), None, "data after the declared elements");
    ply
}

#[test]
fn ply_frame_reads_back_exactly() {
    let dir = common::scratch_dir("ply_round_trip");
    let path = dir.join("frame.ply");
    let positions: Vec<Point> = (0..6).map(awkward).collect();
    let triangles = [[0, 1, 2], [2, 1, 3], [3, 4, 5]];
    write_ply(&path, &positions, &triangles, &[]).unwrap();
    let ply = parse_ply(&std::fs::read_to_string(&path).unwrap());
    same_bits(&flatten(&ply.vertices), &flatten(&positions));
    let expected: Vec<Vec<usize>> = triangles.iter().map(|t| t.to_vec()).collect();
    assert_eq!(ply.faces, expected);
    assert!(ply.edges.is_empty());

    let chain = dir.join("chain.ply");
    write_ply(&chain, &positions[..3], &[], &[[0, 1], [1, 2]]).unwrap();
    let ply = parse_ply(&std::fs::read_to_string(&chain).unwrap());
    assert_eq!(ply.edges, [[0, 1], [1, 2]]);
    assert!(ply.faces.is_empty());

    let err = write_ply(&dir.join("bad.ply"), &positions, &[[0, 1, 6]], &[]).unwrap_err();
    assert!(matches!(err, Error::Content { .. }), "{err}");
}

#[test]
fn strain_is_zero_for_rigid_motions_and_matches_closed_forms_for_stretches() {
    let rest = vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
        Point::new(0.0, 1.0, 0.0),
        Point::new(0.0, 0.0, 1.0),
    ];
    let (tets, triangles, lines) = ([[0, 1, 2, 3]], [[0, 1, 2]], [[0, 1], [2, 3]]);
    let cells = Cells {
        tets: &tets,
        triangles: &triangles,
        lines: &lines,
    };
    let measure = StrainMeasure::new(&rest, &cells);
    assert_eq!(measure.len(), 4);
    let mut out = Vec::new();

    // A rotation (about a skew axis) plus a translation.
    let rotation = nalgebra::Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(Point::new(1.0, 2.0, 3.0)),
        0.7,
    );
    let moved: Vec<Point> = rest
        .iter()
        .map(|p| rotation * p + Point::new(5.0, -2.0, 1.0))
        .collect();
    measure.measure_into(&moved, &mut out);
    // Round-off only: entries of F are O(1) and computed with a few
    // operations each, so F^T F - I is within a few ulps (2.2e-16) of 0.
    for (cell, s) in out.iter().enumerate() {
        assert!(
            s.abs() < 1e-14,
            "cell {cell}: strain {s} under a rigid motion"
        );
    }

    // Uniaxial stretch by l along x: Green strain E = diag((l^2 - 1) / 2, 0, 0).
    let l = 1.3_f64;
    let stretched: Vec<Point> = rest.iter().map(|p| Point::new(l * p.x, p.y, p.z)).collect();
    measure.measure_into(&stretched, &mut out);
    let green = (l * l - 1.0) / 2.0;
    // Tolerance: a few ulps of the O(1) result.
    assert!((out[0] - green).abs() < 1e-14, "tet {} vs {green}", out[0]);
    assert!(
        (out[1] - green).abs() < 1e-14,
        "triangle {} vs {green}",
        out[1]
    );
    // Springs: edge 0-1 along x stretches by l; edge 2-3 is unchanged.
    assert!((out[2] - (l - 1.0)).abs() < 1e-14, "spring {}", out[2]);
    assert!(out[3].abs() < 1e-15, "spring {}", out[3]);
    // Compression gives a negative spring elongation.
    let squeezed: Vec<Point> = rest.iter().map(|p| 0.5 * p).collect();
    measure.measure_into(&squeezed, &mut out);
    assert!((out[2] + 0.5).abs() < 1e-15);
    // Uniform scaling by s: E = (s^2 - 1)/2 I, norm sqrt(3) |s^2 - 1| / 2 in 3D,
    // sqrt(2) |s^2 - 1| / 2 for the triangle.
    let e = (0.25_f64 - 1.0).abs() / 2.0;
    assert!((out[0] - 3f64.sqrt() * e).abs() < 1e-14);
    assert!((out[1] - 2f64.sqrt() * e).abs() < 1e-14);
}

const SCENE: &str = r#"
[simulation]
dt = 0.01
steps = 4

[[body]]
mesh = { generator = "box", size = [1.0, 0.2, 0.2], cells = [3, 1, 1] }
density = 1000
constraints = [ { kind = "tet-strain", stiffness = 1e5 } ]
fixed = { box = { min = [-0.01, -1, -1], max = [0.01, 1, 1] } }

[[body]]
mesh = { generator = "chain", points = 3, length = 1.0 }
vertex_mass = 0.1
constraints = [ { kind = "spring", stiffness = 100.0 } ]
fixed = { vertices = [0] }
translate = [0.0, 1.0, 0.0]

[output]
every = 2
formats = ["vtu", "ply"]
"#;

#[test]
fn a_recorded_run_writes_a_pvd_series_and_frames_matching_the_state() {
    let dir = common::scratch_dir("recorded_vtu_ply");
    let scene = Scene::parse(SCENE, Syntax::Toml, &dir.join("scene.toml")).unwrap();
    let mut sim = scene.build().unwrap();
    let mut recorder = Recorder::create(&dir, &scene, &sim).unwrap();
    for _ in 0..scene.steps {
        let stats = sim.step().unwrap();
        recorder.record(&sim, &stats).unwrap();
    }
    recorder.finish(&scene, &sim, &Outcome::Completed).unwrap();

    // Frames 0, 1, 2 at steps 0, 2, 4, in both formats.
    let names = common::file_names(&dir.join("frames"));
    let expected: Vec<String> = (0..3)
        .flat_map(|k| [format!("frame_{k:05}.ply"), format!("frame_{k:05}.vtu")])
        .collect();
    assert_eq!(names, expected);
    let pvd = std::fs::read_to_string(dir.join("frames.pvd")).unwrap();
    let datasets: Vec<(f64, String)> = pvd
        .lines()
        .filter(|l| l.trim_start().starts_with("<DataSet"))
        .map(|l| {
            (
                attribute(l, "timestep").parse().unwrap(),
                attribute(l, "file").to_string(),
            )
        })
        .collect();
    assert_eq!(datasets.len(), 3);
    for (k, (time, file)) in datasets.iter().enumerate() {
        assert_eq!(file, &format!("frames/frame_{k:05}.vtu"));
        assert!(dir.join(file).exists());
        // The recorder writes sim.time(), which is steps * dt.
        assert!((time - 0.02 * k as f64).abs() < 1e-15, "{time}");
    }

    // The last frame holds the final state, bit for bit.
    let state = sim.state();
    let xml = std::fs::read_to_string(dir.join("frames/frame_00002.vtu")).unwrap();
    same_bits(
        &numbers(data_array(&xml, "Points").unwrap().1),
        &flatten(&state.positions),
    );
    same_bits(
        &numbers(data_array(&xml, "velocity").unwrap().1),
        &flatten(&state.velocities),
    );
    // One strain value per cell: 18 tets and 2 chain edges; the box bends
    // under gravity, so its strain is positive, and finite everywhere.
    let strain: Vec<f64> = numbers(data_array(&xml, "strain").unwrap().1);
    assert_eq!(strain.len(), 18 + 2);
    assert!(
        strain[..18].iter().all(|s| s.is_finite() && *s > 0.0),
        "{strain:?}"
    );
    // Frame 0 is the rest state: zero strain up to round-off (D_m^{-1}
    // rounds, so D_m D_m^{-1} is I within a few ulps of O(1) entries).
    let xml0 = std::fs::read_to_string(dir.join("frames/frame_00000.vtu")).unwrap();
    let strain0: Vec<f64> = numbers(data_array(&xml0, "strain").unwrap().1);
    assert!(strain0.iter().all(|s| s.abs() < 1e-14), "{strain0:?}");

    let ply = parse_ply(&std::fs::read_to_string(dir.join("frames/frame_00002.ply")).unwrap());
    same_bits(&flatten(&ply.vertices), &flatten(&state.positions));
    assert_eq!(
        ply.faces.len(),
        sim.model().bodies()[0].mesh.surface_triangles().len()
    );
    // The box has 4 x 2 x 2 = 16 vertices; the chain follows.
    assert_eq!(ply.edges, [[16, 17], [17, 18]]);
}

/// A scene whose probes were changed after it built (its fields are
/// public) is refused by the recorder, naming the probe, before it writes
/// anything; it used to index past the positions and panic.
#[test]
fn the_recorder_refuses_a_probe_beyond_the_simulation() {
    let dir = common::scratch_dir("recorder_probe_range");
    let mut scene = Scene::parse(SCENE, Syntax::Toml, &dir.join("scene.toml")).unwrap();
    let sim = scene.build().unwrap();
    // A box of 16 vertices and a chain of 3.
    scene.output.probes = vec![1, 19];
    let out = dir.join("out");
    let error = Recorder::create(&out, &scene, &sim)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("output.probes[1]") && error.contains("19 vertices"),
        "{error}"
    );
    assert!(!out.exists());
}
