//! Properties of the generated meshes: counts, volumes and masses, positive
//! orientation, conformity and a closed, outward-facing boundary surface.

use std::collections::HashMap;

use pd_mesh::{Mesh, MeshError, Point, VertexSelection, generators};

/// Deliberately different sizes and cell counts on each axis, so that a
/// mix-up of axes in the indexing or the positions shows.
const SIZE: [f64; 3] = [1.3, 0.7, 0.45];
const CELLS: [usize; 3] = [4, 3, 5];

fn beam() -> Mesh {
    generators::box_tets(SIZE, CELLS).unwrap()
}

/// Relative round-off bound for a sum of `terms` floating-point values, each
/// itself computed to a few ulps: `terms * 8 eps` is generous for recursive
/// summation (whose error grows at most linearly in the number of terms).
fn summation_tolerance(terms: usize) -> f64 {
    terms as f64 * 8.0 * f64::EPSILON
}

fn assert_invalid(result: Result<Mesh, MeshError>, expected_name: &str) {
    match result {
        Err(MeshError::InvalidParameter { name, reason }) => {
            assert_eq!(name, expected_name, "{reason}");
            assert!(!reason.is_empty());
        }
        other => panic!("expected an invalid {expected_name}, got {other:?}"),
    }
}

#[test]
fn box_has_expected_counts_and_layout() {
    let [nx, ny, nz] = CELLS;
    let mesh = beam();
    assert_eq!(mesh.num_vertices(), (nx + 1) * (ny + 1) * (nz + 1));
    assert_eq!(mesh.tets().len(), 6 * nx * ny * nz);
    assert!(mesh.triangles().is_empty());
    // Spot-check the documented index formula and positions. The corners
    // must be exact, so that selections by box bounds find them.
    let index = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    assert_eq!(mesh.vertices()[index(0, 0, 0)], Point::zeros());
    assert_eq!(mesh.vertices()[index(nx, ny, nz)], Point::from(SIZE));
    let p = mesh.vertices()[index(1, 2, 3)];
    let expected = Point::new(
        1.0 * SIZE[0] / 4.0,
        2.0 * SIZE[1] / 3.0,
        3.0 * SIZE[2] / 5.0,
    );
    // Two roundings either way of computing i s / n: a few ulps of 1 m.
    assert!((p - expected).amax() < 4.0 * f64::EPSILON, "{p:?}");
    let (lo, hi) = mesh.bounding_box().unwrap();
    assert_eq!((lo, hi), (Point::zeros(), Point::from(SIZE)));
}

#[test]
fn box_tets_are_positive_and_fill_the_box() {
    let mesh = beam();
    let volumes = mesh.tet_volumes();
    assert!(volumes.iter().all(|&v| v > 0.0));
    let total: f64 = volumes.iter().sum();
    let expected = SIZE.iter().product::<f64>();
    // One sum of 360 volumes, each a few-ulp determinant: the round-off
    // bound summation_tolerance(360) ~ 6e-13 is below 1e-12.
    assert!(summation_tolerance(volumes.len()) < 1e-12);
    assert!(
        ((total - expected) / expected).abs() < 1e-12,
        "total {total}, expected {expected}"
    );
    // All tets of a Kuhn split of a cuboid have the same volume.
    let cell_volume = expected / volumes.len() as f64;
    // Each volume is a 3x3 determinant of coordinates that are themselves
    // rounded: a relative error of a few hundred ulps at most.
    assert!(
        volumes
            .iter()
            .all(|v| ((v - cell_volume) / cell_volume).abs() < 1e-13)
    );
}

#[test]
fn box_masses_add_up_to_density_times_volume() {
    let density = 1200.0; // kg/m^3
    let masses = beam().lumped_masses(density).unwrap();
    let total: f64 = masses.iter().sum();
    let expected = density * SIZE.iter().product::<f64>();
    // Two nested sums: 4 shares per tet accumulated into vertices, then the
    // vertices summed; bounded by the round-off of 4 * 360 terms.
    let terms = 4 * beam().tets().len();
    assert!(((total - expected) / expected).abs() < summation_tolerance(terms));
    assert!(
        masses.iter().all(|&m| m > 0.0),
        "every vertex belongs to some tet"
    );
}

/// Number of tetrahedra sharing each face, keyed by its sorted vertices.
fn tets_per_face(mesh: &Mesh) -> HashMap<[usize; 3], usize> {
    let mut counts = HashMap::new();
    for tet in mesh.tets() {
        for skip in 0..4 {
            let mut face = [0; 3];
            let others = (0..4).filter(|&v| v != skip).map(|v| tet[v]);
            face.iter_mut().zip(others).for_each(|(slot, v)| *slot = v);
            face.sort_unstable();
            *counts.entry(face).or_insert(0) += 1;
        }
    }
    counts
}

#[test]
fn box_is_conforming() {
    let [nx, ny, nz] = CELLS;
    let mesh = beam();
    let counts = tets_per_face(&mesh);
    assert!(
        counts.values().all(|&c| c <= 2),
        "a face is shared by more than 2 tets"
    );
    // A non-conforming split would leave unmatched faces inside the box, so
    // the number of single-tet faces is exactly the box's own surface: each
    // of the 2 (nx ny + ny nz + nz nx) cube faces on it, split in 2.
    let expected_boundary = 2 * 2 * (nx * ny + ny * nz + nz * nx);
    assert_eq!(
        counts.values().filter(|&&c| c == 1).count(),
        expected_boundary
    );
    assert_eq!(mesh.surface_triangles().len(), expected_boundary);
}

#[test]
fn box_surface_is_closed_and_faces_outward() {
    let mesh = beam();
    let vertices = mesh.vertices();
    let centre = Point::from(SIZE) / 2.0;
    let surface = mesh.surface_triangles();
    let mut area_vector_sum = Point::zeros();
    let mut total_area = 0.0;
    for face in &surface {
        let [a, b, c] = face.map(|v| vertices[v]);
        // Twice the area times the unit normal.
        let area_vector = (b - a).cross(&(c - a));
        let face_centroid = (a + b + c) / 3.0;
        assert!(
            area_vector.dot(&(face_centroid - centre)) > 0.0,
            "{face:?} faces inward"
        );
        // Every boundary face lies on one of the box's six sides.
        let on_a_side = (0..3).any(|axis| {
            [a, b, c].iter().all(|p| p[axis] == 0.0)
                || [a, b, c].iter().all(|p| p[axis] == SIZE[axis])
        });
        assert!(on_a_side, "{face:?} is not on the box surface");
        area_vector_sum += area_vector;
        total_area += area_vector.norm() / 2.0;
    }
    let box_area = 2.0 * (SIZE[0] * SIZE[1] + SIZE[1] * SIZE[2] + SIZE[2] * SIZE[0]);
    // A sum of 188 face areas, each a cross product norm of a few ulps.
    assert!(((total_area - box_area) / box_area).abs() < summation_tolerance(surface.len()));
    // A closed surface has zero total area vector. The terms cancel in
    // opposite pairs of sides, so the residual is pure round-off, relative to
    // the total area (twice it, as the vectors are twice the areas).
    let closure_tolerance = 2.0 * box_area * summation_tolerance(surface.len());
    assert!(
        area_vector_sum.norm() < closure_tolerance,
        "{area_vector_sum:?}"
    );
}

#[test]
fn single_cube_has_six_tets_and_twelve_surface_triangles() {
    let cube = generators::box_tets([2.0; 3], [1, 1, 1]).unwrap();
    assert_eq!(cube.num_vertices(), 8);
    assert_eq!(cube.tets().len(), 6);
    // 12 cube edges, 6 face diagonals and the main diagonal.
    assert_eq!(cube.edges().len(), 19);
    assert!(cube.tets().iter().all(|t| t.contains(&0) && t.contains(&7)));
    assert_eq!(cube.surface_triangles().len(), 12);
}

#[test]
fn box_parameter_errors() {
    assert_invalid(generators::box_tets([1.0; 3], [0, 1, 1]), "cells");
    assert_invalid(generators::box_tets([1.0; 3], [1, 1, 0]), "cells");
    assert_invalid(generators::box_tets([1.0; 3], [usize::MAX; 3]), "cells");
    assert_invalid(generators::box_tets([1.0, 0.0, 1.0], [1; 3]), "size");
    assert_invalid(generators::box_tets([1.0, 1.0, -1.0], [1; 3]), "size");
    assert_invalid(generators::box_tets([f64::NAN, 1.0, 1.0], [1; 3]), "size");
    assert_invalid(
        generators::box_tets([1.0, f64::INFINITY, 1.0], [1; 3]),
        "size",
    );
}

#[test]
fn chain_counts_positions_and_masses() {
    let length = 2.5;
    let rope = generators::chain(6, length).unwrap();
    assert_eq!(rope.num_vertices(), 6);
    assert_eq!(rope.edges(), &[[0, 1], [1, 2], [2, 3], [3, 4], [4, 5]]);
    assert!(rope.tets().is_empty() && rope.triangles().is_empty());
    assert_eq!(rope.vertices()[0], Point::zeros());
    assert_eq!(rope.vertices()[5], Point::new(length, 0.0, 0.0));
    assert_eq!(rope.vertices()[2], Point::new(1.0, 0.0, 0.0));
    let density = 0.3; // kg/m
    let masses = rope.lumped_masses(density).unwrap();
    let total: f64 = masses.iter().sum();
    // A sum of 2 * 5 shares.
    assert!((total / (density * length) - 1.0).abs() < summation_tolerance(10));
    // End vertices carry half a segment, inner ones a whole segment. Exact:
    // the positions k * 2.5 / 5 are exact binary fractions, so every segment
    // has the same length and the inner sum is an exact doubling.
    assert_eq!(masses[0] * 2.0, masses[1]);
}

#[test]
fn chain_parameter_errors() {
    assert_invalid(generators::chain(0, 1.0), "points");
    assert_invalid(generators::chain(1, 1.0), "points");
    assert_invalid(generators::chain(usize::MAX, 1.0), "points");
    assert_invalid(generators::chain(2, 0.0), "length");
    assert_invalid(generators::chain(2, -1.0), "length");
    assert_invalid(generators::chain(2, f64::NAN), "length");
    assert_invalid(generators::chain(2, f64::INFINITY), "length");
}

#[test]
fn cloth_counts_layout_and_masses() {
    let size = [1.5, 0.8];
    let [nx, nz] = [5, 4];
    let sheet = generators::cloth(size, [nx, nz]).unwrap();
    assert_eq!(sheet.num_vertices(), (nx + 1) * (nz + 1));
    assert_eq!(sheet.triangles().len(), 2 * nx * nz);
    assert!(sheet.tets().is_empty());
    // Grid lines along x and z, plus one diagonal per cell.
    assert_eq!(sheet.edges().len(), nx * (nz + 1) + nz * (nx + 1) + nx * nz);
    assert!(sheet.vertices().iter().all(|p| p.y == 0.0));
    let p = sheet.vertices()[2 + (nx + 1) * 3];
    // Two roundings either way of computing i s / n: a few ulps of 1 m.
    assert!((p - Point::new(2.0 * 1.5 / 5.0, 0.0, 3.0 * 0.8 / 4.0)).amax() < 4.0 * f64::EPSILON);
    assert_eq!(
        sheet.vertices()[(nx + 1) * (nz + 1) - 1],
        Point::new(size[0], 0.0, size[1])
    );
    let vertices = sheet.vertices();
    for t in sheet.triangles() {
        let [a, b, c] = t.map(|v| vertices[v]);
        assert!((b - a).cross(&(c - a)).y > 0.0, "{t:?} does not face +y");
    }
    let density = 0.2; // kg/m^2
    let total: f64 = sheet.lumped_masses(density).unwrap().iter().sum();
    let expected = density * size[0] * size[1];
    // A sum of 3 shares per triangle.
    let terms = 3 * sheet.triangles().len();
    assert!(((total - expected) / expected).abs() < summation_tolerance(terms));
}

#[test]
fn cloth_parameter_errors() {
    assert_invalid(generators::cloth([1.0; 2], [0, 1]), "cells");
    assert_invalid(generators::cloth([1.0; 2], [1, 0]), "cells");
    assert_invalid(generators::cloth([1.0; 2], [usize::MAX, 2]), "cells");
    assert_invalid(generators::cloth([0.0, 1.0], [1; 2]), "size");
    assert_invalid(generators::cloth([1.0, f64::NEG_INFINITY], [1; 2]), "size");
}

#[test]
fn selections_on_a_generated_box() {
    let [nx, ny, nz] = CELLS;
    let mesh = beam();
    // The face x = 0 (bounds inclusive), with a margin far below the cell size.
    let clamp = VertexSelection::Box {
        min: [-1e-9, -1e-9, -1e-9],
        max: [1e-9, SIZE[1] + 1e-9, SIZE[2] + 1e-9],
    };
    let clamped = clamp.resolve(&mesh).unwrap();
    assert_eq!(clamped.len(), (ny + 1) * (nz + 1));
    assert!(clamped.windows(2).all(|w| w[0] < w[1]));
    assert!(clamped.iter().all(|&v| mesh.vertices()[v].x == 0.0));
    // The far edge x = sx, y = sy, exactly on the bounds.
    let edge = VertexSelection::Box {
        min: [SIZE[0], SIZE[1], 0.0],
        max: [SIZE[0], SIZE[1], SIZE[2]],
    };
    assert_eq!(edge.resolve(&mesh).unwrap().len(), nz + 1);

    let last = mesh.num_vertices() - 1;
    let by_index = VertexSelection::Indices(vec![last, 0, last]);
    assert_eq!(by_index.resolve(&mesh).unwrap(), vec![0, last]);
    let err = VertexSelection::Indices(vec![0, last + 1])
        .resolve(&mesh)
        .unwrap_err();
    let expected_reason = format!(
        "vertex {} is out of range: the mesh has {} vertices",
        last + 1,
        (nx + 1) * (ny + 1) * (nz + 1)
    );
    assert_eq!(
        err,
        MeshError::InvalidParameter {
            name: "vertices",
            reason: expected_reason
        }
    );
    let inverted = VertexSelection::Box {
        min: [1.0, 0.0, 0.0],
        max: [0.0, 1.0, 1.0],
    };
    assert!(matches!(
        inverted.resolve(&mesh),
        Err(MeshError::InvalidParameter { name: "box", .. })
    ));
}
