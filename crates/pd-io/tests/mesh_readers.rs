//! The Gmsh, Medit, OBJ and TetGen `.face` readers: the fixtures read to the
//! meshes written by hand below, and every malformed, truncated or empty
//! input and every out-of-range index is an error naming the file and line
//! (and the element, for a flat or inverted one), never a panic.

mod common;

use std::path::{Path, PathBuf};

use pd_io::Error;
use pd_io::gmsh::read_gmsh;
use pd_io::medit::read_medit;
use pd_io::obj::read_obj;
use pd_io::tetgen::{read_tetgen_surface, read_tetgen_surface_base};
use pd_mesh::{Mesh, Point};

/// A mesh reader of this crate.
type Reader = fn(&Path) -> Result<Mesh, Error>;

fn fixture(name: &str) -> PathBuf {
    common::data_dir().join("formats").join(name)
}

/// The vertices of the two-tetrahedra fixtures, in the Medit/TetGen order:
/// the unit tetrahedron's corners, then (1, 1, 1).
fn two_tet_vertices() -> Vec<Point> {
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
        Point::new(0.0, 1.0, 0.0),
        Point::new(0.0, 0.0, 1.0),
        Point::new(1.0, 1.0, 1.0),
    ]
}

/// Writes `text` as `name` in a fresh directory for `test`, reads it with
/// `read`, and expects a parse error at `line` whose message contains
/// `needle`.
fn expect_parse_error(
    test: &str,
    name: &str,
    text: &str,
    read: fn(&Path) -> Result<Mesh, Error>,
    line: usize,
    needle: &str,
) {
    let dir = common::scratch_dir(test);
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    match read(&path) {
        Err(Error::Parse {
            path: p,
            line: l,
            message,
        }) => {
            assert_eq!(p, path, "{message}");
            assert_eq!(l, line, "{test}: {message}");
            assert!(
                message.contains(needle),
                "{test}: `{message}` lacks `{needle}`"
            );
            // The displayed error starts with file:line.
            let shown = Error::Parse {
                path: p,
                line: l,
                message,
            }
            .to_string();
            assert!(shown.starts_with(&format!("{}:{line}: ", path.display())));
        }
        Err(other) => panic!("{test}: expected a parse error, got {other}"),
        Ok(mesh) => panic!("{test}: expected a parse error, got {mesh:?}"),
    }
}

// ---------------------------------------------------------------- Gmsh

#[test]
fn gmsh_fixture_reads_with_scattered_tags_blocks_and_skipped_sections() {
    let mesh = read_gmsh(&fixture("two_tets.msh")).unwrap();
    // Vertices in $Nodes order: tags 40, 10, 30, 20, 55.
    let expected = [
        Point::new(0.0, 0.0, 1.0),
        Point::new(0.0, 0.0, 0.0),
        Point::new(0.0, 1.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
        Point::new(1.0, 1.0, 1.0),
    ];
    assert_eq!(mesh.vertices(), expected);
    // Element 8: tags 10 20 30 40; element 9: 20 30 40 55.
    assert_eq!(mesh.tets(), &[[1, 3, 2, 0], [3, 2, 0, 4]]);
    // The triangle (boundary) is dropped from a tetrahedral mesh.
    assert!(mesh.triangles().is_empty());
    let volumes = mesh.tet_volumes();
    assert!((volumes[0] - 1.0 / 6.0).abs() < 1e-15 && (volumes[1] - 2.0 / 6.0).abs() < 1e-15);
}

const GMSH_HEAD: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
const GMSH_NODES: &str =
    "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n";

fn gmsh(elements: &str) -> String {
    format!("{GMSH_HEAD}{GMSH_NODES}$Elements\n{elements}$EndElements\n")
}

#[test]
fn gmsh_triangles_only_give_a_surface() {
    let dir = common::scratch_dir("gmsh_surface");
    let path = dir.join("s.msh");
    std::fs::write(&path, gmsh("1 2 1 2\n2 1 2 2\n1 1 2 3\n2 1 3 4\n")).unwrap();
    let mesh = read_gmsh(&path).unwrap();
    assert_eq!(mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
    assert!(mesh.tets().is_empty());
    assert_eq!(mesh.edges().len(), 5);
}

#[test]
fn gmsh_malformed_inputs_name_file_and_line() {
    let r = read_gmsh;
    let e =
        |t: &str, text: &str, line, needle| expect_parse_error(t, "m.msh", text, r, line, needle);
    e("gmsh_empty", "", 1, "empty");
    e("gmsh_blank", "\n\n\n", 3, "empty");
    e("gmsh_not_gmsh", "solid cube\n", 1, "not a Gmsh");
    e(
        "gmsh_v22",
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n",
        2,
        "version `2.2` is not supported",
    );
    e(
        "gmsh_binary",
        "$MeshFormat\n4.1 1 8\n$EndMeshFormat\n",
        2,
        "binary .msh files are not supported",
    );
    e(
        "gmsh_format_end",
        "$MeshFormat\n4.1 0 8\n$Nodes\n",
        3,
        "expected `$EndMeshFormat`",
    );
    e("gmsh_no_nodes", GMSH_HEAD, 3, "no `$Nodes`");
    e(
        "gmsh_elements_first",
        &format!("{GMSH_HEAD}$Elements\n"),
        4,
        "before `$Nodes`",
    );
    let truncated_nodes =
        format!("{GMSH_HEAD}$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n");
    e("gmsh_truncated_nodes", &truncated_nodes, 12, "truncated");
    let bad_number = GMSH_NODES.replace("0 1 0\n", "0 one 0\n");
    e(
        "gmsh_bad_number",
        &format!("{GMSH_HEAD}{bad_number}"),
        13,
        "y coordinate must be a number",
    );
    let nan = GMSH_NODES.replace("0 1 0\n", "0 nan 0\n");
    e("gmsh_nan", &format!("{GMSH_HEAD}{nan}"), 13, "not finite");
    let twice = GMSH_NODES.replace("1\n2\n3\n4\n", "1\n2\n2\n4\n");
    e(
        "gmsh_tag_twice",
        &format!("{GMSH_HEAD}{twice}"),
        9,
        "node tag 2 is defined twice",
    );
    let count = GMSH_NODES.replace("1 4 1 4\n", "1 5 1 4\n");
    e(
        "gmsh_node_count",
        &format!("{GMSH_HEAD}{count}"),
        5,
        "declares 5 nodes",
    );
    e(
        "gmsh_missing_end_nodes",
        &format!("{GMSH_HEAD}{}", GMSH_NODES.replace("$EndNodes\n", "")),
        14,
        "truncated",
    );
    e(
        "gmsh_unknown_tag",
        &gmsh("1 1 1 1\n3 1 4 1\n1 1 2 3 7\n"),
        19,
        "node tag 7",
    );
    e(
        "gmsh_repeated_node",
        &gmsh("1 1 1 1\n3 1 4 1\n1 1 2 3 3\n"),
        19,
        "uses vertex 3 more than once",
    );
    e(
        "gmsh_hexahedra",
        &gmsh("1 1 1 1\n3 1 5 1\n1 1 2 3 4 1 2 3 4\n"),
        18,
        "8-node hexahedron",
    );
    e(
        "gmsh_short_element",
        &gmsh("1 1 1 1\n3 1 4 1\n1 1 2 3\n"),
        19,
        "expected 5 fields",
    );
    e(
        "gmsh_element_count",
        &gmsh("1 2 1 1\n3 1 4 1\n1 1 2 3 4\n"),
        17,
        "declares 2 elements",
    );
    e(
        "gmsh_truncated_elements",
        &format!("{GMSH_HEAD}{GMSH_NODES}$Elements\n1 1 1 1\n3 1 4 1\n"),
        18,
        "truncated",
    );
    e(
        "gmsh_no_elements",
        &gmsh("1 1 1 1\n0 1 15 1\n1 1\n"),
        20,
        "no tetrahedra",
    );
    e(
        "gmsh_unclosed_section",
        &format!("{GMSH_HEAD}$Comments\nhello\n"),
        5,
        "has no `$EndComments`",
    );
    e(
        "gmsh_stray_text",
        &format!("{GMSH_HEAD}hello\n"),
        4,
        "expected a section",
    );
    e(
        "gmsh_negative_tag",
        &gmsh("1 1 1 1\n3 1 4 1\n1 1 2 3 -4\n"),
        19,
        "node tag must be a non-negative integer",
    );
}

#[test]
fn gmsh_inverted_and_flat_tetrahedra_are_named_by_index_and_line() {
    // The second tetrahedron swaps two vertices: inverted.
    let text = gmsh("1 2 1 2\n3 1 4 2\n1 1 2 3 4\n2 1 3 2 4\n");
    expect_parse_error(
        "gmsh_inverted",
        "m.msh",
        &text,
        read_gmsh,
        20,
        "tetrahedron 1 has non-positive rest volume",
    );
    let flat = format!(
        "{GMSH_HEAD}{}$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n",
        GMSH_NODES.replace("0 0 1\n", "1 1 0\n")
    );
    expect_parse_error(
        "gmsh_flat",
        "m.msh",
        &flat,
        read_gmsh,
        19,
        "tetrahedron 0 has non-positive rest volume",
    );
}

// ---------------------------------------------------------------- Medit

#[test]
fn medit_fixture_reads() {
    let mesh = read_medit(&fixture("two_tets.mesh")).unwrap();
    assert_eq!(mesh.vertices(), two_tet_vertices());
    assert_eq!(mesh.tets(), &[[0, 1, 2, 3], [1, 2, 3, 4]]);
    assert!(mesh.triangles().is_empty());
}

const MEDIT_HEAD: &str =
    "MeshVersionFormatted 1\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n";

#[test]
fn medit_triangles_only_give_a_surface() {
    let dir = common::scratch_dir("medit_surface");
    let path = dir.join("s.mesh");
    std::fs::write(
        &path,
        format!("{MEDIT_HEAD}Triangles 2\n1 2 3 0\n1 3 4 0\nEnd\n"),
    )
    .unwrap();
    let mesh = read_medit(&path).unwrap();
    assert_eq!(mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn medit_malformed_inputs_name_file_and_line() {
    let r = read_medit;
    let e =
        |t: &str, text: &str, line, needle| expect_parse_error(t, "m.mesh", text, r, line, needle);
    e("medit_empty", "", 1, "empty");
    e("medit_comment_only", "# nothing\n", 1, "empty");
    e("medit_not_medit", "ply\n", 1, "not a Medit");
    e(
        "medit_version",
        "MeshVersionFormatted 9\n",
        1,
        "must be 1 to 4",
    );
    e(
        "medit_dimension",
        "MeshVersionFormatted 1\nDimension\n2\n",
        3,
        "dimension 2 is not supported",
    );
    e(
        "medit_vertices_first",
        "MeshVersionFormatted 1\nVertices\n1\n",
        2,
        "before `Dimension 3`",
    );
    e(
        "medit_truncated",
        &MEDIT_HEAD.replace("0 0 1 0\n", ""),
        7,
        "truncated",
    );
    e(
        "medit_no_value",
        "MeshVersionFormatted 1\nDimension\n",
        2,
        "has no value",
    );
    e(
        "medit_bad_number",
        &MEDIT_HEAD.replace("0 1 0 0", "0 x 0 0"),
        7,
        "y coordinate must be a number",
    );
    e(
        "medit_inf",
        &MEDIT_HEAD.replace("0 1 0 0", "0 inf 0 0"),
        7,
        "not finite",
    );
    e(
        "medit_short_vertex",
        &MEDIT_HEAD.replace("0 1 0 0", "0 1 0"),
        7,
        "expected 4 fields",
    );
    e(
        "medit_out_of_range",
        &format!("{MEDIT_HEAD}Tetrahedra\n1\n1 2 3 5 0\n"),
        11,
        "refers to vertex 5, but there are 4 vertices numbered 1 to 4",
    );
    e(
        "medit_zero_index",
        &format!("{MEDIT_HEAD}Tetrahedra\n1\n0 2 3 4 0\n"),
        11,
        "refers to vertex 0",
    );
    e(
        "medit_repeated",
        &format!("{MEDIT_HEAD}Tetrahedra\n1\n1 2 3 3 0\n"),
        11,
        "uses vertex 3 more than once",
    );
    e(
        "medit_elements_first",
        "MeshVersionFormatted 1\nDimension 3\nTetrahedra\n1\n1 2 3 4 0\n",
        3,
        "before `Vertices`",
    );
    e(
        "medit_hexahedra",
        &format!("{MEDIT_HEAD}Hexahedra\n0\n"),
        9,
        "are not supported",
    );
    e(
        "medit_unknown",
        &format!("{MEDIT_HEAD}Colours\n0\n"),
        9,
        "unknown or unsupported keyword `Colours`",
    );
    e(
        "medit_no_elements",
        &format!("{MEDIT_HEAD}End\n"),
        9,
        "no `Tetrahedra`",
    );
    e(
        "medit_no_vertices",
        "MeshVersionFormatted 1\nDimension 3\nEnd\n",
        3,
        "no `Vertices`",
    );
    e(
        "medit_truncated_elements",
        &format!("{MEDIT_HEAD}Tetrahedra\n2\n1 2 3 4 0\n"),
        11,
        "announces 2 tetrahedron records, found 1",
    );
    e(
        "medit_inverted",
        &format!("{MEDIT_HEAD}Tetrahedra\n2\n1 2 3 4 0\n1 3 2 4 0\n"),
        12,
        "tetrahedron 1 has non-positive rest volume",
    );
    e(
        "medit_flat",
        &format!(
            "{}Tetrahedra\n1\n1 2 3 4 0\n",
            MEDIT_HEAD.replace("0 0 1 0\n", "1 1 0 0\n")
        ),
        11,
        "tetrahedron 0 has non-positive rest volume",
    );
}

// ---------------------------------------------------------------- OBJ

#[test]
fn obj_fixture_reads_quads_as_fans_with_all_corner_forms() {
    let mesh = read_obj(&fixture("quad_cloth.obj")).unwrap();
    let expected: Vec<Point> = [0.0, 1.0, 2.0]
        .iter()
        .map(|&x| Point::new(x, 0.0, 0.0))
        .chain([0.0, 1.0, 2.0].iter().map(|&x| Point::new(x, 0.0, 1.0)))
        .collect();
    assert_eq!(mesh.vertices(), expected);
    // f 1 4 5 2 and f -4 -1 -2 -5 (= 3 6 5 2), each split from its first corner.
    assert_eq!(
        mesh.triangles(),
        &[[0, 3, 4], [0, 4, 1], [2, 5, 4], [2, 4, 1]]
    );
    assert_eq!(mesh.edges().len(), 9);
}

#[test]
fn obj_lines_give_a_spring_network() {
    let dir = common::scratch_dir("obj_lines");
    let path = dir.join("net.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 2 0 0\nl 1 2 3\nl 3 -3\n").unwrap();
    let mesh = read_obj(&path).unwrap();
    assert!(mesh.triangles().is_empty());
    assert_eq!(mesh.edges().len(), 3);
}

#[test]
fn obj_malformed_inputs_name_file_and_line() {
    let r = read_obj;
    let e =
        |t: &str, text: &str, line, needle| expect_parse_error(t, "m.obj", text, r, line, needle);
    const V: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    e("obj_empty", "", 1, "no faces");
    e("obj_vertices_only", V, 3, "no faces");
    e("obj_short_vertex", "v 0 0\n", 1, "a vertex needs");
    e(
        "obj_bad_number",
        "v 0 zero 0\n",
        1,
        "y coordinate must be a number",
    );
    e("obj_nan", "v 0 0 NaN\n", 1, "not finite");
    e(
        "obj_zero_index",
        &format!("{V}f 0 1 2\n"),
        4,
        "vertex index 0 is invalid",
    );
    e(
        "obj_out_of_range",
        &format!("{V}f 1 2 4\n"),
        4,
        "vertex index 4 is out of range: 3 vertices",
    );
    e(
        "obj_negative_out_of_range",
        &format!("{V}f -1 -2 -4\n"),
        4,
        "vertex index -4 is out of range",
    );
    e(
        "obj_forward_reference",
        &format!("f 1 2 3\n{V}"),
        1,
        "0 vertices are defined",
    );
    // Integers too large for any index are out of range, not "not integers".
    e(
        "obj_huge_index",
        &format!("{V}f 1 2 99999999999999999999\n"),
        4,
        "vertex index `99999999999999999999` of corner `99999999999999999999` is out of \
         range: 3 vertices",
    );
    e(
        "obj_huge_negative_index",
        &format!("{V}f 1 2 -99999999999999999999/1\n"),
        4,
        "vertex index `-99999999999999999999` of corner `-99999999999999999999/1` is out of range",
    );
    e(
        "obj_not_an_integer",
        &format!("{V}f 1 2 3.0\n"),
        4,
        "must be an integer, found `3.0`",
    );
    e(
        "obj_bad_corner",
        &format!("{V}f 1/a 2 3\n"),
        4,
        "integer indices",
    );
    e(
        "obj_too_many_slashes",
        &format!("{V}f 1/1/1/1 2 3\n"),
        4,
        "v/vt/vn",
    );
    e("obj_two_corners", &format!("{V}f 1 2\n"), 4, "at least 3");
    e(
        "obj_repeated",
        &format!("{V}f 1 2 1\n"),
        4,
        "uses vertex 1 more than once",
    );
    e(
        "obj_self_line",
        &format!("{V}l 2 2\n"),
        4,
        "joins vertex 2 to itself",
    );
    e(
        "obj_zero_length_line",
        "v 0 0 0\nv 1 0 0\nv 1 0 0\nl 1 2 3\n",
        4,
        "joins vertices 2 and 3, which are at the same position",
    );
    e(
        "obj_mixed",
        &format!("{V}f 1 2 3\nl 1 2\n"),
        5,
        "both faces",
    );
    e(
        "obj_freeform",
        "cstype bspline\n",
        1,
        "unsupported OBJ statement `cstype`",
    );
    e(
        "obj_continuation",
        &format!("{V}f 1 2 \\\n3\n"),
        4,
        "continuation",
    );
    e(
        "obj_collinear",
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 4\nf 1 2 3\n",
        6,
        "triangle 1 has zero rest area",
    );
}

// ---------------------------------------------------------------- TetGen .face

#[test]
fn tetgen_face_fixture_reads_as_a_surface() {
    let by_pair =
        read_tetgen_surface(&fixture("two_tets.1.node"), &fixture("two_tets.1.face")).unwrap();
    assert_eq!(by_pair.vertices(), two_tet_vertices());
    assert_eq!(
        by_pair.triangles(),
        &[
            [0, 2, 1],
            [0, 1, 3],
            [0, 3, 2],
            [1, 4, 3],
            [1, 2, 4],
            [2, 3, 4]
        ]
    );
    for base in ["two_tets.1", "two_tets.1.face", "two_tets.1.node"] {
        assert_eq!(
            read_tetgen_surface_base(&fixture(base)).unwrap(),
            by_pair,
            "{base}"
        );
    }
}

fn read_face_in(test: &str, face: &str) -> (PathBuf, Result<Mesh, Error>) {
    let dir = common::scratch_dir(test);
    std::fs::write(
        dir.join("m.node"),
        "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n",
    )
    .unwrap();
    let path = dir.join("m.face");
    std::fs::write(&path, face).unwrap();
    let result = read_tetgen_surface(&dir.join("m.node"), &path);
    (path, result)
}

#[test]
fn tetgen_face_malformed_inputs_name_file_and_line() {
    let cases: [(&str, &str, usize, &str); 10] = [
        ("face_empty", "", 1, "header is missing"),
        ("face_header", "2\n", 1, "must have 2 fields"),
        ("face_no_faces", "0 0\n", 1, "declares no faces"),
        ("face_markers", "1 2\n", 1, "must be 0 or 1"),
        ("face_truncated", "2 0\n0 0 1 2\n", 2, "truncated"),
        ("face_out_of_range", "1 0\n0 0 1 4\n", 2, "refers to node 4"),
        (
            "face_extra",
            "1 0\n0 0 1 2\n1 0 1 3\n",
            3,
            "unexpected data",
        ),
        (
            "face_repeated",
            "1 0\n0 0 1 1\n",
            2,
            "face 0 uses vertex 1 more than once",
        ),
        (
            "face_bad_marker",
            "1 1\n0 0 1 2 x\n",
            2,
            "boundary marker must be an integer",
        ),
        (
            "face_huge_marker",
            "1 1\n0 0 1 2 -99999999999999999999\n",
            2,
            "boundary marker `-99999999999999999999` is out of range",
        ),
    ];
    for (test, text, line, needle) in cases {
        let (path, result) = read_face_in(test, text);
        match result {
            Err(Error::Parse {
                path: p,
                line: l,
                message,
            }) => {
                assert_eq!((p, l), (path, line), "{test}: {message}");
                assert!(
                    message.contains(needle),
                    "{test}: `{message}` lacks `{needle}`"
                );
            }
            other => panic!("{test}: expected a parse error, got {other:?}"),
        }
    }
}

#[test]
fn tetgen_face_zero_area_is_named_by_index_and_line() {
    let dir = common::scratch_dir("face_zero_area");
    std::fs::write(
        dir.join("m.node"),
        "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 2 0 0\n3 0 0 1\n",
    )
    .unwrap();
    let path = dir.join("m.face");
    std::fs::write(&path, "2 0\n0 0 1 3\n1 0 1 2\n").unwrap();
    let err = read_tetgen_surface(&dir.join("m.node"), &path).unwrap_err();
    assert!(
        matches!(&err, Error::Parse { line: 3, message, .. } if message.contains("triangle 1 has zero rest area")),
        "{err}"
    );
}

#[test]
fn missing_files_are_io_errors_naming_them() {
    let dir = common::scratch_dir("readers_missing");
    for read in [read_gmsh, read_medit, read_obj] {
        let path = dir.join("absent");
        let err = read(&path).unwrap_err();
        assert!(
            matches!(&err, Error::Io { path: p, .. } if *p == path),
            "{err}"
        );
    }
}

#[test]
fn a_byte_order_mark_is_skipped_by_every_reader() {
    let dir = common::scratch_dir("byte_order_mark");
    let with_mark = |name: &str| {
        let mut bytes = vec![0xef, 0xbb, 0xbf];
        bytes.extend(std::fs::read(fixture(name)).unwrap());
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    };
    let read: [(&str, Reader); 3] = [
        ("quad_cloth.obj", read_obj),
        ("two_tets.msh", read_gmsh),
        ("two_tets.mesh", read_medit),
    ];
    for (name, read) in read {
        let marked = read(&with_mark(name)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(marked, read(&fixture(name)).unwrap(), "{name}");
    }
    let marked = read_tetgen_surface(&with_mark("two_tets.1.node"), &with_mark("two_tets.1.face"))
        .unwrap_or_else(|e| panic!("{e}"));
    let plain =
        read_tetgen_surface(&fixture("two_tets.1.node"), &fixture("two_tets.1.face")).unwrap();
    assert_eq!(marked, plain);
}

#[test]
fn long_tokens_are_quoted_cut_with_their_length() {
    let digits = "1".repeat(100_000);
    let word = "x".repeat(100_000);
    let cases: [(&str, String, Reader, &str); 6] = [
        // Parses as infinity.
        (
            "m.obj",
            format!("v 0 0 {digits}\n"),
            read_obj,
            "not finite: `111",
        ),
        (
            "m.obj",
            format!("v 0 {digits}x 0\n"),
            read_obj,
            "must be a number, found `111",
        ),
        (
            "m.obj",
            format!("{word}\n"),
            read_obj,
            "unsupported OBJ statement `xxx",
        ),
        (
            "m.msh",
            format!("{word}\n"),
            read_gmsh,
            "expected `$MeshFormat`, found `xxx",
        ),
        ("m.mesh", format!("{word}\n"), read_medit, "found `xxx"),
        (
            "m.mesh",
            format!("MeshVersionFormatted 1\nDimension 3\n{word}\n"),
            read_medit,
            "unknown or unsupported keyword `xxx",
        ),
    ];
    for (case, (name, text, read, needle)) in cases.into_iter().enumerate() {
        let dir = common::scratch_dir(&format!("long_token_{case}"));
        let path = dir.join(name);
        std::fs::write(&path, &text).unwrap();
        let message = read(&path).unwrap_err().to_string();
        assert!(message.contains(needle), "case {case}: {message:.300}");
        assert!(message.contains("…` (100"), "case {case}: {message:.300}");
        assert!(message.len() < 400, "case {case}: {message:.300}");
    }
}

#[test]
fn invalid_utf8_is_a_parse_error_at_its_line() {
    for (name, read) in [
        ("m.msh", read_gmsh as fn(&Path) -> Result<Mesh, Error>),
        ("m.mesh", read_medit),
        ("m.obj", read_obj),
    ] {
        let dir = common::scratch_dir(&format!("utf8_{name}"));
        let path = dir.join(name);
        std::fs::write(&path, b"v 0 0 0\n\xff\n").unwrap();
        let err = read(&path).unwrap_err();
        assert!(matches!(&err, Error::Parse { line: 2, .. }), "{err}");
    }
}
