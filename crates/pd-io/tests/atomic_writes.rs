//! Every writer replaces its file atomically: after a successful write only
//! the final file exists (no temporary is left behind), a rewrite replaces
//! the old contents, and a write into a missing directory is an I/O error
//! naming the file that was asked for.

mod common;

use std::path::Path;

use pd_io::Error;
use pd_io::frames::{Cells, write_obj, write_vtk};
use pd_io::state::write_state;
use pd_mesh::Point;

fn positions() -> Vec<Point> {
    vec![
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
        Point::new(0.0, 1.0, 0.0),
        Point::new(0.0, 0.0, 1.0),
    ]
}

/// Runs every writer on `dir/NAME` with the given positions.
fn write_all(dir: &Path, positions: &[Point]) -> Vec<Result<(), Error>> {
    let cells = Cells {
        tets: &[[0, 1, 2, 3]],
        ..Cells::default()
    };
    let velocities = vec![Point::zeros(); positions.len()];
    vec![
        write_vtk(&dir.join("frame.vtk"), positions, &cells, Some(&velocities)),
        write_obj(&dir.join("frame.obj"), positions, &[[0, 1, 2]], &[[2, 3]]),
        write_state(&dir.join("state.json"), positions, &velocities),
    ]
}

#[test]
fn successful_writes_leave_only_the_final_files() {
    let dir = common::scratch_dir("atomic_final_files");
    for result in write_all(&dir, &positions()) {
        result.unwrap();
    }
    assert_eq!(
        common::file_names(&dir),
        ["frame.obj", "frame.vtk", "state.json"]
    );
}

#[test]
fn rewriting_replaces_the_old_contents() {
    let dir = common::scratch_dir("atomic_rewrite");
    for result in write_all(&dir, &positions()) {
        result.unwrap();
    }
    let first = std::fs::read_to_string(dir.join("frame.vtk")).unwrap();
    let moved: Vec<Point> = positions().iter().map(|p| p * 2.0).collect();
    for result in write_all(&dir, &moved) {
        result.unwrap();
    }
    let second = std::fs::read_to_string(dir.join("frame.vtk")).unwrap();
    assert_ne!(first, second);
    assert!(second.contains("\n2 0 0\n"), "{second}");
    assert_eq!(
        common::file_names(&dir),
        ["frame.obj", "frame.vtk", "state.json"]
    );
}

#[test]
fn writing_into_a_missing_directory_is_an_io_error_naming_the_file() {
    let dir = common::scratch_dir("atomic_missing_dir");
    let missing = dir.join("not_created");
    let expected = ["frame.vtk", "frame.obj", "state.json"];
    for (result, name) in write_all(&missing, &positions()).into_iter().zip(expected) {
        match result {
            Err(Error::Io { path, source }) => {
                assert_eq!(path, missing.join(name));
                assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
            }
            other => panic!("expected an I/O error for {name}, got {other:?}"),
        }
    }
    assert!(common::file_names(&dir).is_empty());
}
