//! The initial-state file: exact round trips, and every kind of bad file
//! reported with its path and its line or field.

mod common;

use std::path::{Path, PathBuf};

use pd_io::Error;
use pd_io::state::{StateFile, read_state, write_state};
use pd_mesh::Point;

fn write_text(test: &str, text: &str) -> PathBuf {
    let path = common::scratch_dir(test).join("state.json");
    std::fs::write(&path, text).unwrap();
    path
}

fn field_error(err: Error) -> (PathBuf, String, String) {
    match err {
        Error::Field {
            path,
            field,
            message,
        } => (path, field, message),
        other => panic!("expected a field error, got {other:?}"),
    }
}

fn parse_error(err: Error) -> (PathBuf, usize, String) {
    match err {
        Error::Parse {
            path,
            line,
            message,
        } => (path, line, message),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn round_trip_is_bit_exact() {
    let dir = common::scratch_dir("state_round_trip");
    let path = dir.join("state.json");
    let positions: Vec<Point> = (0..50)
        .map(|i| {
            let t = i as f64;
            Point::new(t / 3.0, -(t.sqrt()) * 1e-300, (t * 0.7).sin() * 1e300)
        })
        .chain([
            Point::new(-0.0, 5e-324, f64::MAX),
            Point::new(f64::MIN_POSITIVE, 0.1, -1e16),
        ])
        .collect();
    let velocities: Vec<Point> = positions.iter().map(|p| p.map(|c| c / 7.0)).collect();
    write_state(&path, &positions, &velocities).unwrap();

    let state = read_state(&path).unwrap();
    for (read, written) in [
        (state.positions_as_points(), &positions),
        (state.velocities_as_points(), &velocities),
    ] {
        assert_eq!(read.len(), written.len());
        for (a, b) in read.iter().zip(written) {
            for k in 0..3 {
                // Exact parsing needs serde_json's `float_roundtrip` feature;
                // without it about a third of all f64 come back 1 ulp off.
                assert_eq!(
                    a[k].to_bits(),
                    b[k].to_bits(),
                    "read {:e}, wrote {:e} (is serde_json's float_roundtrip feature on?)",
                    a[k],
                    b[k]
                );
            }
        }
    }
    assert_eq!(common::file_names(&dir), ["state.json"]);
}

#[test]
fn written_file_has_one_vertex_per_line() {
    let dir = common::scratch_dir("state_layout");
    let path = dir.join("state.json");
    let positions = [Point::new(0.0, 1.5, -2.0), Point::new(1e-7, 0.0, 0.0)];
    write_state(&path, &positions, &[Point::zeros(); 2]).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.contains("\n    [0.0,1.5,-2.0],\n    [1e-7,0.0,0.0]\n"),
        "{text}"
    );
    write_state(&path, &[], &[]).unwrap();
    assert_eq!(read_state(&path).unwrap().positions, Vec::<[f64; 3]>::new());
}

#[test]
fn missing_velocities_mean_zeros() {
    let path = write_text(
        "state_no_velocities",
        r#"{"positions": [[1, 2, 3], [4.5, 5, 6]]}"#,
    );
    let state = read_state(&path).unwrap();
    assert_eq!(
        state,
        StateFile {
            positions: vec![[1.0, 2.0, 3.0], [4.5, 5.0, 6.0]],
            velocities: None,
        }
    );
    assert_eq!(state.velocities_as_points(), vec![Point::zeros(); 2]);
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let path = common::scratch_dir("state_missing").join("state.json");
    match read_state(&path).unwrap_err() {
        Error::Io { path: p, source } => {
            assert_eq!(p, path);
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("expected an I/O error, got {other:?}"),
    }
}

#[test]
fn malformed_json_is_reported_at_its_line() {
    let path = write_text(
        "state_malformed",
        "{\n  \"positions\": [\n    [0, 0, 0],\n    [1, 0 0]\n  ]\n}\n",
    );
    let (p, line, message) = parse_error(read_state(&path).unwrap_err());
    assert_eq!((p, line), (path.clone(), 4), "{message}");
    assert!(message.contains("expected"), "{message}");

    let path = write_text("state_truncated", "{\"positions\": [[0, 0, 0]");
    let (_, line, message) = parse_error(read_state(&path).unwrap_err());
    assert_eq!(line, 1, "{message}");

    let path = write_text("state_empty", "");
    parse_error(read_state(&path).unwrap_err());

    let path = write_text("state_trailing", "{\"positions\": []}\n\nx\n");
    let (_, line, message) = parse_error(read_state(&path).unwrap_err());
    assert_eq!(line, 3, "{message}");
}

#[test]
fn wrong_values_name_their_path() {
    let path = write_text(
        "state_wrong_type",
        r#"{"positions": [[0,0,0],[0,0,0],[0,0,0],[0,"one",0]]}"#,
    );
    let (p, field, message) = field_error(read_state(&path).unwrap_err());
    assert_eq!(p, path);
    assert_eq!(field, "positions[3][1]", "{message}");

    let path = write_text(
        "state_two_components",
        r#"{"positions": [[0,0,0]], "velocities": [[1,2]]}"#,
    );
    let (_, field, message) = field_error(read_state(&path).unwrap_err());
    assert_eq!(field, "velocities[0]", "{message}");
    assert!(message.contains("length"), "{message}");
}

#[test]
fn velocities_of_another_length_are_rejected() {
    let path = write_text(
        "state_wrong_length",
        r#"{"positions": [[0,0,0],[1,0,0],[0,1,0]], "velocities": [[0,0,0],[0,0,0]]}"#,
    );
    let (p, field, message) = field_error(read_state(&path).unwrap_err());
    assert_eq!((p, field.as_str()), (path, "velocities"));
    assert!(
        message.contains("2 entries") && message.contains("positions has 3"),
        "{message}"
    );
}

#[test]
fn unknown_keys_are_rejected() {
    let path = write_text(
        "state_unknown_key",
        "{\n\"positions\": [],\n\"velocity\": []\n}",
    );
    let (_, field, message) = field_error(read_state(&path).unwrap_err());
    assert_eq!(field, "velocity");
    assert!(
        message.contains("unknown field `velocity`") && message.contains("line 3"),
        "{message}"
    );
}

#[test]
fn a_top_level_array_is_not_a_state() {
    let path = write_text("state_array", "\n [[0, 0, 0]]");
    let (_, line, message) = parse_error(read_state(&path).unwrap_err());
    assert_eq!(line, 2);
    assert!(message.contains("JSON object"), "{message}");
}

#[test]
fn missing_positions_are_rejected() {
    let path = write_text("state_no_positions", r#"{"velocities": []}"#);
    let err = read_state(&path).unwrap_err();
    assert!(
        err.to_string().contains("missing field `positions`"),
        "{err}"
    );
}

#[test]
fn overflowing_numbers_are_reported_not_read_as_infinity() {
    let path = write_text(
        "state_overflow",
        "{\"positions\": [\n[0, 0, 0],\n[0, 1e400, 0]\n]}",
    );
    let err = read_state(&path).unwrap_err();
    let text = err.to_string();
    match err {
        Error::Parse { line, .. } => assert_eq!(line, 3, "{text}"),
        Error::Field { field, .. } => assert_eq!(field, "positions[1][1]", "{text}"),
        other => panic!("expected the overflow to be reported, got {other:?}"),
    }
}

#[test]
fn non_finite_values_cannot_be_written() {
    let path = common::scratch_dir("state_write_nan").join("state.json");
    let err = write_state(
        &path,
        &[Point::new(0.0, f64::INFINITY, 0.0)],
        &[Point::zeros()],
    )
    .unwrap_err();
    assert!(matches!(err, Error::Content { .. }), "{err}");
    assert!(err.to_string().contains("position of vertex 0"), "{err}");
    let err = write_state(&path, &[Point::zeros()], &[]).unwrap_err();
    assert!(
        err.to_string()
            .contains("0 velocities given for 1 positions"),
        "{err}"
    );
    assert!(!Path::new(&path).exists());
}
