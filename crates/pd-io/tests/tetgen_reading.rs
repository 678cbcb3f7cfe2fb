//! Reading TetGen meshes: real TetGen output in both index bases, comments,
//! optional columns, base-name handling, and write/read round trips.
//!
//! `tests/data/cube.1.*` is TetGen 1.5.0's output for a unit cube given as a
//! 1-based `.poly` (`tetgen -pa0.2`); `tests/data/cube_regions.1.*` is its
//! output for the same cube with a node attribute, boundary markers and a
//! region attribute, numbered from 0 (`tetgen -pAz`).

mod common;

use std::path::Path;

use pd_io::tetgen::{read_tetgen, read_tetgen_base, write_tetgen};
use pd_mesh::{Mesh, Point, generators};

fn total_volume(mesh: &Mesh) -> f64 {
    mesh.tet_volumes().iter().sum()
}

#[test]
fn one_based_tetgen_output_reads_as_the_unit_cube() {
    let mesh = read_tetgen_base(&common::data_dir().join("cube.1")).unwrap();
    assert_eq!(mesh.num_vertices(), 20);
    assert_eq!(mesh.tets().len(), 22);
    // Node 1 of the file is vertex 0; tetrahedron 1 is `8 15 16 20`.
    assert_eq!(mesh.vertices()[0], Point::new(0.0, 0.0, 0.0));
    assert_eq!(mesh.vertices()[19], Point::new(0.0, 1.0, 0.5));
    assert_eq!(mesh.tets()[0], [7, 14, 15, 19]);
    assert!((total_volume(&mesh) - 1.0).abs() < 1e-12);
}

#[test]
fn zero_based_output_with_attributes_markers_and_regions_reads() {
    let mesh = read_tetgen_base(&common::data_dir().join("cube_regions.1")).unwrap();
    assert_eq!(mesh.num_vertices(), 8);
    assert_eq!(mesh.tets()[0], [0, 3, 7, 2]);
    assert_eq!(mesh.tets().len(), 6);
    assert!((total_volume(&mesh) - 1.0).abs() < 1e-12);
}

#[test]
fn base_may_name_either_file() {
    let data = common::data_dir();
    let expected = read_tetgen(&data.join("cube.1.node"), &data.join("cube.1.ele")).unwrap();
    for base in ["cube.1", "cube.1.node", "cube.1.ele"] {
        assert_eq!(
            read_tetgen_base(&data.join(base)).unwrap(),
            expected,
            "{base}"
        );
    }
}

#[test]
fn comments_blank_lines_and_tabs_are_accepted() {
    let dir = common::scratch_dir("tetgen_comments");
    let node = "# a unit tetrahedron\n\n4 3 0 1  # header\n\
                1\t0 0 0  5\n\
                2 1 0 0 -1   # negative marker\n\
                \n   # indented comment\n\
                3 0 1 0 0\n\
                4 0 0 1e0 0\n# end\n";
    let ele = "1 4 1\n1 1 2 3 4 -2.5\n\n";
    std::fs::write(dir.join("tet.node"), node).unwrap();
    std::fs::write(dir.join("tet.ele"), ele).unwrap();
    let mesh = read_tetgen_base(&dir.join("tet")).unwrap();
    assert_eq!(mesh.tets(), &[[0, 1, 2, 3]]);
    assert_eq!(mesh.vertices()[3], Point::new(0.0, 0.0, 1.0));
}

#[test]
fn written_mesh_reads_back_bit_for_bit() {
    let dir = common::scratch_dir("tetgen_round_trip");
    let beam = generators::box_tets([1.0, 0.2, 0.2], [4, 2, 1]).unwrap();
    // Coordinates with all 17 significant digits, at ordinary, tiny and huge
    // scales; the jitter is small against the 0.1 m cells, so every
    // tetrahedron keeps a positive volume.
    for (scale, offset) in [(1.0 / 3.0, 0.1), (1e-100, -1e-101), (1e100, 7e99)] {
        let vertices: Vec<Point> = beam
            .vertices()
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let jitter = (i as f64).sin() * 1e-3;
                (p.add_scalar(jitter) * scale).add_scalar(offset)
            })
            .collect();
        let mesh = Mesh::from_tets(vertices, beam.tets().to_vec()).unwrap();
        let base = dir.join("beam");
        write_tetgen(&base, &mesh).unwrap();
        let read_back = read_tetgen_base(&base).unwrap();
        assert_eq!(read_back.tets(), mesh.tets());
        for (a, b) in read_back.vertices().iter().zip(mesh.vertices()) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "scale {scale}: {a} != {b}");
            }
        }
        assert_eq!(common::file_names(&dir), ["beam.ele", "beam.node"]);
    }
}

#[test]
fn writing_a_mesh_without_tetrahedra_is_refused() {
    let dir = common::scratch_dir("tetgen_no_tets");
    let cloth = generators::cloth([1.0, 1.0], [2, 2]).unwrap();
    let err = write_tetgen(&dir.join("cloth"), &cloth).unwrap_err();
    assert!(matches!(err, pd_io::Error::Content { .. }), "{err}");
    assert!(common::file_names(&dir).is_empty());
}

#[test]
fn writing_into_a_missing_directory_names_the_file() {
    let dir = common::scratch_dir("tetgen_missing_dir");
    let mesh = generators::box_tets([1.0, 1.0, 1.0], [1, 1, 1]).unwrap();
    let base = dir.join("no_such_dir").join("box");
    let err = write_tetgen(&base, &mesh).unwrap_err();
    match err {
        pd_io::Error::Io { path, .. } => assert_eq!(path, Path::new(&base).with_extension("node")),
        other => panic!("expected an I/O error, got {other}"),
    }
}
