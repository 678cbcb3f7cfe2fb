//! Triangle-mesh colliders (docs/design/contact.md), with the `mesh-collider`
//! feature: a mesh floor acts as the plane it lies in, and a soft body comes
//! to rest in a bowl.
#![cfg(feature = "mesh-collider")]

use pd_damping::NoDamping;
use pd_integrators::BackwardEuler;
use pd_mesh::{Point, generators};
use pd_solver::contact::{Collider, ColliderShape, ContactSettings, TriangleSurface};
use pd_solver::{Model, Settings, Simulation};

/// A 0.1 m cube, 2 cells per side, 1000 kg/m^3, 1e5 Pa, its lowest corner at
/// `corner`.
fn cube(corner: Point) -> Model {
    let mesh = generators::box_tets([0.1; 3], [2; 3]).unwrap();
    let mesh = mesh.translated(corner);
    let masses = mesh.lumped_masses(1000.0).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, 1e5, None).unwrap();
    model
}

fn run(shape: ColliderShape, corner: Point, steps: usize) -> Simulation {
    let settings = Settings {
        dt: 0.005,
        iterations: 20,
        gravity: Point::new(0.0, -9.81, 0.0),
        ..Settings::default()
    };
    let mut sim = Simulation::new(
        cube(corner),
        Box::new(BackwardEuler),
        Box::new(NoDamping),
        settings,
    )
    .unwrap();
    sim.set_contact(ContactSettings {
        colliders: vec![Collider {
            shape,
            friction: 0.5,
            restitution: 0.0,
        }],
        thickness: 0.001,
    })
    .unwrap();
    sim.run(steps).unwrap();
    sim
}

/// The lower half of a sphere of radius `r` about `c`, open at the top, its
/// triangles facing the centre (the inside of the bowl is its outside).
fn bowl(c: Point, r: f64, rings: usize, segments: usize) -> TriangleSurface {
    let mut vertices = vec![c - Point::new(0.0, r, 0.0)];
    for i in 1..=rings {
        let polar = std::f64::consts::FRAC_PI_2 * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            let (s, k) = (polar.sin(), polar.cos());
            vertices.push(c + Point::new(r * s * phi.cos(), -r * k, r * s * phi.sin()));
        }
    }
    let ring = |i: usize, j: usize| 1 + (i - 1) * segments + j % segments;
    let mut triangles = Vec::new();
    for j in 0..segments {
        triangles.push([0, ring(1, j), ring(1, j + 1)]);
    }
    for i in 1..rings {
        for j in 0..segments {
            let (a, b) = (ring(i, j), ring(i, j + 1));
            let (e, d) = (ring(i + 1, j), ring(i + 1, j + 1));
            triangles.push([a, e, d]);
            triangles.push([a, d, b]);
        }
    }
    // Orient every triangle towards the centre.
    for t in &mut triangles {
        let [a, b, p] = t.map(|i| vertices[i]);
        let n = (b - a).cross(&(p - a));
        if n.dot(&(c - (a + b + p) / 3.0)) < 0.0 {
            t.swap(1, 2);
        }
    }
    TriangleSurface::new(vertices, triangles)
}

#[test]
fn a_mesh_floor_acts_as_its_plane() {
    let corner = Point::new(0.0, 0.05, 0.0);
    let plane = run(
        ColliderShape::Plane {
            point: Point::zeros(),
            normal: Point::y(),
        },
        corner,
        200,
    );
    let floor = TriangleSurface::new(
        vec![
            Point::new(-2.0, 0.0, -2.0),
            Point::new(2.0, 0.0, -2.0),
            Point::new(2.0, 0.0, 2.0),
            Point::new(-2.0, 0.0, 2.0),
        ],
        vec![[0, 2, 1], [0, 3, 2]],
    );
    let mesh = run(ColliderShape::Mesh(floor), corner, 200);
    // Same plane, same normals: only the closest-point arithmetic differs
    // (parry's projection against the plane's dot product), at round-off;
    // measured 2.3e-16 m after 200 steps; 1e-9 m leaves room for its growth.
    let difference = plane
        .state()
        .positions
        .iter()
        .zip(&mesh.state().positions)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max);
    assert!(difference < 1e-9, "{difference}");
}

#[test]
fn a_body_dropped_into_a_bowl_rests_inside_it() {
    let (c, r) = (Point::new(0.0, 0.5, 0.0), 0.5);
    let thickness = 0.001;
    // Dropped off-centre from below the rim: it slides down and settles.
    let sim = run(
        ColliderShape::Mesh(bowl(c, r, 12, 24)),
        Point::new(0.05, 0.4, -0.05),
        600,
    );
    // The facets are chords of the sphere: a vertex on a facet is up to
    // r (1 - cos(pi / 24)) = 4.3 mm inside the sphere's radius, never
    // outside it (minus the thickness).
    for p in &sim.state().positions {
        let d = (p - c).norm();
        assert!(
            d <= r - thickness + 1e-12,
            "vertex at {d} m from the centre"
        );
    }
    let low = sim
        .state()
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    assert!(
        low < 0.05,
        "it reached the bottom: lowest vertex at {low} m"
    );
    assert!(sim.energies().kinetic < 1e-6, "{:?}", sim.energies());
}
