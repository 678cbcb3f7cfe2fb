//! Every constructor that reads rest positions by index refuses an index
//! beyond them with `VertexOutOfRange`, instead of panicking.

use pd_constraints::{
    Area, Bending, ConstraintError, MaterialTet, PlateBending, Spring, TetStrain, TriangleStrain,
    Volume,
};
use pd_mesh::Point;

/// A unit tetrahedron's corners.
fn rest() -> Vec<Point> {
    vec![Point::zeros(), Point::x(), Point::y(), Point::z()]
}

fn assert_out_of_range<T: std::fmt::Debug>(name: &str, result: Result<T, ConstraintError>) {
    match result {
        Err(ConstraintError::VertexOutOfRange {
            vertex: 9,
            count: 4,
            ..
        }) => {}
        other => panic!("{name}: expected vertex 9 of 4 out of range, got {other:?}"),
    }
}

#[test]
fn an_index_beyond_the_rest_positions_is_an_error() {
    let r = rest();
    assert_out_of_range("spring", Spring::new(&r, [0, 9], 1.0));
    assert_out_of_range("tet strain", TetStrain::new(&r, [0, 1, 2, 9], 1.0, None));
    assert_out_of_range("volume", Volume::new(&r, [9, 1, 2, 3], 1.0));
    assert_out_of_range(
        "triangle strain",
        TriangleStrain::new(&r, [0, 9, 2], 1.0, None),
    );
    assert_out_of_range("area", Area::new(&r, [0, 1, 9], 1.0));
    assert_out_of_range("bending", Bending::new(&r, [0, 1, 2, 9], 1.0));
    assert_out_of_range(
        "plate bending",
        PlateBending::new(&r, [0, 1, 2], [Some(9), None, None], 1.0),
    );
    assert_out_of_range("material tet", MaterialTet::new(&r, [0, 1, 9, 3]));
    // In range, they build.
    assert!(TetStrain::new(&r, [0, 1, 2, 3], 1.0, None).is_ok());
    assert!(Spring::new(&r, [0, 3], 1.0).is_ok());
}
