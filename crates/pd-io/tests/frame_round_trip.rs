//! Frames written as VTK and OBJ parse back, with an independent parser, to
//! exactly the numbers, cells and cell types that were written.

mod common;

use pd_io::Error;
use pd_io::frames::{Cells, write_obj, write_vtk};
use pd_mesh::Point;

/// Positions whose text forms are awkward: thirds, tiny and huge values,
/// negative zero, subnormals.
fn awkward_points(count: usize) -> Vec<Point> {
    (0..count)
        .map(|i| {
            let t = i as f64;
            match i % 4 {
                0 => Point::new(t / 3.0, -t / 7.0, (t + 0.1).sqrt()),
                1 => Point::new(t * 1e-300, -0.0, 5e-324 * t),
                2 => Point::new(t * 1.7e300, -t * 1e16, 1e15 + t),
                _ => Point::new((t).sin(), (t).cos() * 1e-7, std::f64::consts::PI * t),
            }
        })
        .collect()
}

fn assert_same_bits(read: &[Point], written: &[Point]) {
    assert_eq!(read.len(), written.len());
    for (i, (a, b)) in read.iter().zip(written).enumerate() {
        for k in 0..3 {
            assert_eq!(
                a[k].to_bits(),
                b[k].to_bits(),
                "vertex {i}: read {a}, wrote {b}"
            );
        }
    }
}

/// What a legacy VTK unstructured grid holds.
#[derive(Debug, Default)]
struct Vtk {
    points: Vec<Point>,
    cells: Vec<Vec<usize>>,
    cell_types: Vec<u32>,
    velocities: Option<Vec<Point>>,
}

/// A small legacy-VTK parser: checks the header, then reads the sections by
/// their keywords and declared counts.
fn parse_vtk(text: &str) -> Vtk {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("# vtk DataFile Version 3.0"));
    lines.next().expect("title line");
    assert_eq!(lines.next(), Some("ASCII"));
    assert_eq!(lines.next(), Some("DATASET UNSTRUCTURED_GRID"));
    let mut vtk = Vtk::default();
    let mut num_points = None;
    while let Some(line) = lines.next() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["POINTS", n, "double"] => {
                let n: usize = n.parse().unwrap();
                vtk.points = (0..n)
                    .map(|_| parse_vector(lines.next().unwrap()))
                    .collect();
                num_points = Some(n);
            }
            ["CELLS", n, size] => {
                let n: usize = n.parse().unwrap();
                vtk.cells = (0..n)
                    .map(|_| {
                        let numbers: Vec<usize> = lines
                            .next()
                            .unwrap()
                            .split_whitespace()
                            .map(|w| w.parse().unwrap())
                            .collect();
                        assert_eq!(numbers[0], numbers.len() - 1, "vertex count of a cell");
                        numbers[1..].to_vec()
                    })
                    .collect();
                let list_size: usize = vtk.cells.iter().map(|c| c.len() + 1).sum();
                assert_eq!(size.parse::<usize>().unwrap(), list_size);
            }
            ["CELL_TYPES", n] => {
                let n: usize = n.parse().unwrap();
                vtk.cell_types = (0..n)
                    .map(|_| lines.next().unwrap().trim().parse().unwrap())
                    .collect();
            }
            ["POINT_DATA", n] => {
                assert_eq!(Some(n.parse().unwrap()), num_points);
            }
            ["VECTORS", "velocity", "double"] => {
                let n = num_points.unwrap();
                vtk.velocities = Some(
                    (0..n)
                        .map(|_| parse_vector(lines.next().unwrap()))
                        .collect(),
                );
            }
            [] => {}
            other => panic!("unexpected VTK line {other:?}"),
        }
    }
    vtk
}

fn parse_vector(line: &str) -> Point {
    let v: Vec<f64> = line
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    assert_eq!(v.len(), 3, "{line}");
    Point::new(v[0], v[1], v[2])
}

#[test]
fn vtk_frame_reads_back_exactly() {
    let dir = common::scratch_dir("vtk_round_trip");
    let path = dir.join("frame_0007.vtk");
    let positions = awkward_points(9);
    let velocities: Vec<Point> = awkward_points(9).iter().map(|p| -p * 0.5).collect();
    let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
    let triangles = [[4, 5, 6]];
    let lines = [[6, 7], [7, 8], [8, 0]];
    let cells = Cells {
        tets: &tets,
        triangles: &triangles,
        lines: &lines,
    };
    write_vtk(&path, &positions, &cells, Some(&velocities)).unwrap();

    let vtk = parse_vtk(&std::fs::read_to_string(&path).unwrap());
    assert_same_bits(&vtk.points, &positions);
    assert_same_bits(vtk.velocities.as_ref().unwrap(), &velocities);
    let expected_cells: Vec<Vec<usize>> = tets
        .iter()
        .map(|c| c.to_vec())
        .chain(triangles.iter().map(|c| c.to_vec()))
        .chain(lines.iter().map(|c| c.to_vec()))
        .collect();
    assert_eq!(vtk.cells, expected_cells);
    assert_eq!(vtk.cell_types, [10, 10, 5, 3, 3, 3]);
}

#[test]
fn vtk_frame_without_velocities_or_cells_has_no_point_data() {
    let dir = common::scratch_dir("vtk_points_only");
    let path = dir.join("points.vtk");
    let positions = awkward_points(3);
    write_vtk(&path, &positions, &Cells::default(), None).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(!text.contains("POINT_DATA"));
    let vtk = parse_vtk(&text);
    assert_same_bits(&vtk.points, &positions);
    assert!(vtk.cells.is_empty() && vtk.cell_types.is_empty());
    assert!(vtk.velocities.is_none());
}

/// What an OBJ file holds: vertices, faces and lines, indices made 0-based.
#[derive(Debug, Default)]
struct Obj {
    vertices: Vec<Point>,
    faces: Vec<[usize; 3]>,
    lines: Vec<[usize; 2]>,
    comments: usize,
}

fn parse_obj(text: &str) -> Obj {
    let mut obj = Obj::default();
    let index = |w: &str| {
        w.parse::<usize>()
            .unwrap()
            .checked_sub(1)
            .expect("OBJ indices are 1-based")
    };
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["v", ..] => obj.vertices.push(parse_vector(&line[1..])),
            ["f", a, b, c] => obj.faces.push([index(a), index(b), index(c)]),
            ["l", a, b] => obj.lines.push([index(a), index(b)]),
            [first, ..] if first.starts_with('#') => obj.comments += 1,
            other => panic!("unexpected OBJ line {other:?}"),
        }
    }
    obj
}

#[test]
fn obj_frame_reads_back_exactly_with_one_based_indices() {
    let dir = common::scratch_dir("obj_round_trip");
    let path = dir.join("cloth.obj");
    let positions = awkward_points(6);
    let triangles = [[0, 1, 2], [2, 3, 0], [3, 4, 5]];
    let lines = [[0, 5], [1, 4]];
    write_obj(&path, &positions, &triangles, &lines).unwrap();

    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with('#'), "a comment header comes first");
    assert!(text.contains("\nf 1 2 3\n"));
    let obj = parse_obj(&text);
    assert_same_bits(&obj.vertices, &positions);
    assert_eq!(obj.faces, triangles);
    assert_eq!(obj.lines, lines);
    assert_eq!(obj.comments, 1);
}

#[test]
fn inconsistent_frames_are_refused_before_writing() {
    let dir = common::scratch_dir("inconsistent_frames");
    let path = dir.join("bad.vtk");
    let positions = awkward_points(4);
    let out_of_range = Cells {
        tets: &[[0, 1, 2, 4]],
        ..Cells::default()
    };
    let err = write_vtk(&path, &positions, &out_of_range, None).unwrap_err();
    assert!(
        matches!(&err, Error::Content { path: p, .. } if *p == path),
        "{err}"
    );
    assert!(
        err.to_string().contains("tetrahedron 0 refers to vertex 4"),
        "{err}"
    );

    let err = write_vtk(&path, &positions, &Cells::default(), Some(&positions[..3])).unwrap_err();
    assert!(
        err.to_string()
            .contains("3 velocities given for 4 positions"),
        "{err}"
    );

    let mut not_finite = positions.clone();
    not_finite[2].y = f64::NAN;
    let err = write_obj(&dir.join("bad.obj"), &not_finite, &[], &[]).unwrap_err();
    assert!(err.to_string().contains("vertex 2 is not finite"), "{err}");
    let err = write_obj(&dir.join("bad.obj"), &positions, &[], &[[3, 9]]).unwrap_err();
    assert!(
        err.to_string().contains("line 0 refers to vertex 9"),
        "{err}"
    );

    assert!(common::file_names(&dir).is_empty(), "nothing was written");
}
