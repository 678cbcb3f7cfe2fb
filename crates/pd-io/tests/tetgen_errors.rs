//! Every malformed TetGen input is reported with its file and 1-based line
//! (or as an I/O or mesh error naming the file), and no input panics.

mod common;

use std::path::{Path, PathBuf};

use pd_io::Error;
use pd_io::tetgen::read_tetgen;
use pd_mesh::MeshError;

/// A unit tetrahedron, 1-based, with a comment line first.
const NODE: &str = "# unit tet\n4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
const ELE: &str = "1 4 0\n1 1 2 3 4\n";

/// Writes the two files into a fresh directory and reads them.
fn read(test: &str, node: &str, ele: &str) -> (PathBuf, PathBuf, Result<pd_mesh::Mesh, Error>) {
    let dir = common::scratch_dir(test);
    let (node_path, ele_path) = (dir.join("m.node"), dir.join("m.ele"));
    std::fs::write(&node_path, node).unwrap();
    std::fs::write(&ele_path, ele).unwrap();
    let result = read_tetgen(&node_path, &ele_path);
    (node_path, ele_path, result)
}

/// Reads and expects a parse error in `file` ("node" or "ele") at `line`;
/// returns its message.
fn parse_error(test: &str, node: &str, ele: &str, file: &str, line: usize) -> String {
    let (node_path, ele_path, result) = read(test, node, ele);
    let expected_path = if file == "node" { node_path } else { ele_path };
    match result {
        Err(Error::Parse {
            path,
            line: found_line,
            message,
        }) => {
            assert_eq!(path, expected_path, "{message}");
            assert_eq!(found_line, line, "{message}");
            message
        }
        Err(other) => panic!("expected a parse error, got {other:?}"),
        Ok(_) => panic!("expected a parse error, got a mesh"),
    }
}

#[test]
fn the_valid_reference_input_reads() {
    let (_, _, result) = read("valid", NODE, ELE);
    assert_eq!(result.unwrap().tets(), &[[0, 1, 2, 3]]);
}

#[test]
fn missing_files_are_io_errors_naming_the_file() {
    let dir = common::scratch_dir("missing_files");
    let (node, ele) = (dir.join("m.node"), dir.join("m.ele"));
    let err = read_tetgen(&node, &ele).unwrap_err();
    assert!(
        matches!(&err, Error::Io { path, .. } if *path == node),
        "{err:?}"
    );
    std::fs::write(&node, NODE).unwrap();
    let err = read_tetgen(&node, &ele).unwrap_err();
    assert!(
        matches!(&err, Error::Io { path, .. } if *path == ele),
        "{err:?}"
    );
}

#[test]
fn empty_file_lacks_its_header_at_line_1() {
    let message = parse_error("empty_node", "", ELE, "node", 1);
    assert!(message.contains("header is missing"), "{message}");
    let message = parse_error("empty_ele", NODE, "", "ele", 1);
    assert!(message.contains("header is missing"), "{message}");
}

#[test]
fn comment_only_file_lacks_its_header_at_its_last_line() {
    let message = parse_error("comment_only", "# nothing\n\n# here\n", ELE, "node", 3);
    assert!(message.contains("header is missing"), "{message}");
}

#[test]
fn short_headers_are_rejected() {
    let message = parse_error("short_node_header", "4 3 0\n", ELE, "node", 1);
    assert!(
        message.contains("4 fields") && message.contains("found 3"),
        "{message}"
    );
    let message = parse_error("short_ele_header", NODE, "1 4\n1 1 2 3 4\n", "ele", 1);
    assert!(
        message.contains("3 fields") && message.contains("found 2"),
        "{message}"
    );
}

#[test]
fn non_numeric_fields_are_named() {
    let node = NODE.replace("4 3 0 0", "4 three 0 0");
    let message = parse_error("word_in_header", &node, ELE, "node", 2);
    assert!(
        message.contains("dimension") && message.contains("`three`"),
        "{message}"
    );
    let node = NODE.replace("3 0 1 0", "3 0 1.5x 0");
    let message = parse_error("word_coordinate", &node, ELE, "node", 5);
    assert!(
        message.contains("y coordinate") && message.contains("`1.5x`"),
        "{message}"
    );
    let message = parse_error("negative_count", "-4 3 0 0\n", ELE, "node", 1);
    assert!(message.contains("non-negative integer"), "{message}");
    let message = parse_error("float_index", NODE, "1 4 0\n1 1 2.0 3 4\n", "ele", 2);
    assert!(message.contains("`2.0`"), "{message}");
}

#[test]
fn only_three_dimensions_are_supported() {
    let node = "3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n";
    let message = parse_error("two_d", node, ELE, "node", 1);
    assert!(
        message.contains("dimension 2") && message.contains("3D"),
        "{message}"
    );
}

#[test]
fn quadratic_tetrahedra_are_not_supported() {
    let ele = "1 10 0\n1 1 2 3 4 5 6 7 8 9 10\n";
    let message = parse_error("quadratic", NODE, ele, "ele", 1);
    assert!(
        message.contains("10-node") && message.contains("not supported"),
        "{message}"
    );
    let message = parse_error("three_nodes", NODE, "1 3 0\n1 1 2 3\n", "ele", 1);
    assert!(message.contains("4 nodes"), "{message}");
}

#[test]
fn truncated_files_say_how_many_lines_were_expected_and_found() {
    let node = "# unit tet\n6 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n# end\n";
    let message = parse_error("truncated_node", node, ELE, "node", 7);
    assert!(message.contains("truncated"), "{message}");
    assert!(
        message.contains("declares 6") && message.contains("found 4"),
        "{message}"
    );
    let message = parse_error("truncated_ele", NODE, "3 4 0\n1 1 2 3 4", "ele", 2);
    assert!(
        message.contains("declares 3") && message.contains("found 1"),
        "{message}"
    );
}

#[test]
fn extra_data_lines_are_reported_where_they_start() {
    let node = format!("{NODE}\n5 1 1 1\n");
    let message = parse_error("extra_node", &node, ELE, "node", 8);
    assert!(message.contains("after the 4 nodes"), "{message}");
    let message = parse_error("extra_ele", NODE, "1 4 0\n1 1 2 3 4\n2 1 2 3 4\n", "ele", 3);
    assert!(message.contains("after the 1 tetrahedra"), "{message}");
}

#[test]
fn non_finite_coordinates_are_rejected() {
    for (test, value) in [
        ("nan", "NaN"),
        ("inf", "inf"),
        ("neg_inf", "-infinity"),
        ("overflow", "1e400"),
    ] {
        let node = NODE.replace("4 0 0 1", &format!("4 0 0 {value}"));
        let message = parse_error(test, &node, ELE, "node", 6);
        assert!(
            message.contains("z coordinate") && message.contains("not finite"),
            "{message}"
        );
        assert!(message.contains(value), "{message}");
    }
}

#[test]
fn node_indices_must_start_at_0_or_1_and_be_consecutive() {
    let node = NODE.replace("3 0 1 0", "5 0 1 0");
    let message = parse_error("gap", &node, ELE, "node", 5);
    assert!(message.contains("expected 3"), "{message}");
    let node = "2 3 0 0\n2 0 0 0\n3 1 0 0\n";
    let message = parse_error("starts_at_2", node, ELE, "node", 2);
    assert!(message.contains("start at 0 or 1"), "{message}");
}

#[test]
fn wrong_field_counts_are_reported_per_line() {
    let node = NODE
        .replace("4 3 0 0", "4 3 1 1")
        .replace("2 1 0 0", "2 1 0 0 0.5 1");
    let message = parse_error("missing_columns", &node, ELE, "node", 3);
    assert!(
        message.contains("expected 6 fields") && message.contains("found 4"),
        "{message}"
    );
    let message = parse_error("extra_column", NODE, "1 4 0\n1 1 2 3 4 9\n", "ele", 2);
    assert!(message.contains("expected 5 fields"), "{message}");
    let message = parse_error("missing_region", NODE, "1 4 1\n1 1 2 3 4\n", "ele", 2);
    assert!(message.contains("region attribute"), "{message}");
}

#[test]
fn node_references_are_checked_against_the_detected_base() {
    // 1-based: node 0 does not exist.
    let message = parse_error("one_based_zero", NODE, "1 4 0\n1 0 1 2 3\n", "ele", 2);
    assert!(
        message.contains("node 0") && message.contains("numbered 1 to 4"),
        "{message}"
    );
    // 0-based: node 4 does not exist.
    let zero_based = "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
    let message = parse_error("zero_based_four", zero_based, ELE, "ele", 2);
    assert!(
        message.contains("node 4") && message.contains("numbered 0 to 3"),
        "{message}"
    );
    let (_, _, result) = read("zero_based_ok", zero_based, "1 4 0\n0 0 1 2 3\n");
    assert_eq!(result.unwrap().tets(), &[[0, 1, 2, 3]]);
}

#[test]
fn invalid_tetrahedra_are_mesh_errors_naming_the_ele_file() {
    let (_, ele, result) = read("inverted", NODE, "1 4 0\n1 1 3 2 4\n");
    match result {
        Err(Error::Mesh {
            path,
            source: MeshError::NonPositiveVolume { element: 0, .. },
        }) => assert_eq!(path, ele),
        other => panic!("expected an inverted tetrahedron, got {other:?}"),
    }
    let (_, ele, result) = read("repeated", NODE, "1 4 0\n1 1 2 3 3\n");
    match result {
        Err(Error::Mesh {
            path,
            source: MeshError::RepeatedVertex { vertex: 2, .. },
        }) => assert_eq!(path, ele),
        other => panic!("expected a repeated vertex, got {other:?}"),
    }
}

#[test]
fn errors_display_as_file_colon_line() {
    let (node, _, result) = read("display", "4 3 0\n", ELE);
    let text = result.unwrap_err().to_string();
    assert!(
        text.starts_with(&format!("{}:1: ", node.display())),
        "{text}"
    );
}

#[test]
fn invalid_utf8_is_reported_at_its_line() {
    let dir = common::scratch_dir("utf8");
    let (node, ele) = (dir.join("m.node"), dir.join("m.ele"));
    std::fs::write(&node, b"4 3 0 0\n1 0 0 0\n2 \xff 0 0\n").unwrap();
    std::fs::write(&ele, ELE).unwrap();
    let err = read_tetgen(&node, &ele).unwrap_err();
    assert!(matches!(err, Error::Parse { line: 3, .. }), "{err:?}");
}

#[test]
fn absurd_header_counts_fail_without_allocating_them() {
    let message = parse_error(
        "huge_count",
        "18446744073709551615 3 0 0\n1 0 0 0\n",
        ELE,
        "node",
        2,
    );
    assert!(message.contains("truncated"), "{message}");
    let message = parse_error(
        "huge_attributes",
        "1 3 18446744073709551615 1\n1 0 0 0\n",
        ELE,
        "node",
        2,
    );
    assert!(message.contains("fields"), "{message}");
    let message = parse_error(
        "too_big_for_usize",
        "99999999999999999999999 3 0 0\n",
        ELE,
        "node",
        1,
    );
    assert!(
        message.contains("number of points") && message.contains("too large"),
        "{message}"
    );
}

/// Every prefix of the real fixtures, and every line of them replaced by
/// troublesome tokens, reads as a mesh or as an error, never a panic.
#[test]
fn mangled_real_files_never_panic() {
    let data = common::data_dir();
    let node = std::fs::read_to_string(data.join("cube_regions.1.node")).unwrap();
    let ele = std::fs::read_to_string(data.join("cube_regions.1.ele")).unwrap();
    let dir = common::scratch_dir("mangled");
    let (node_path, ele_path) = (dir.join("m.node"), dir.join("m.ele"));
    let read = |node_text: &str, ele_text: &str| {
        std::fs::write(&node_path, node_text).unwrap();
        std::fs::write(&ele_path, ele_text).unwrap();
        let _ = read_tetgen(&node_path, &ele_path);
    };

    for cut in 0..=node.len() {
        read(&node[..cut], &ele);
    }
    for cut in 0..=ele.len() {
        read(&node, &ele[..cut]);
    }
    let replacements = [
        "",
        "#",
        "0",
        "-1",
        "1",
        "x",
        "nan",
        "1e999",
        "18446744073709551615",
        "18446744073709551616",
        "0 0 0 0 0 0 0 0 0 0",
        "4 10 1",
        "3 2 0 0",
    ];
    for (text, is_node) in [(&node, true), (&ele, false)] {
        let lines: Vec<&str> = text.lines().collect();
        for i in 0..lines.len() {
            for replacement in replacements {
                let mut mangled = lines.clone();
                mangled[i] = replacement;
                let mangled = mangled.join("\n");
                if is_node {
                    read(&mangled, &ele);
                } else {
                    read(&node, &mangled);
                }
            }
        }
    }
}

#[test]
fn paths_in_errors_are_the_ones_given() {
    let err = read_tetgen(Path::new("no/such.node"), Path::new("no/such.ele")).unwrap_err();
    assert!(err.to_string().starts_with("no/such.node: "), "{err}");
}
