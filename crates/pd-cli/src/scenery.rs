//! The colliders of a run's scene as `pd render` scenery: the scene is the
//! one `summary.json` names; a horizontal plane becomes the ground, other
//! shapes grey solids.

use std::path::Path;

use pd_io::scene::Scene;
use pd_solver::contact::ColliderShape;
use pd_viz::obj::Surface;
use pd_viz::render::Scenery;

/// Half the side of the square drawn for a tilted plane, in multiples of
/// the distance from its point to the origin plus 1 m.
const PLANE_HALF_SIDE: f64 = 1.0;

/// The scenery of the run in `dir`: nothing when its summary or scene
/// cannot be read (a run without colliders, or a moved scene file), so that
/// the picture is the one without colliders.
pub(crate) fn of_run(dir: &Path) -> Scenery {
    of_scene(run_scene(dir).as_ref())
}

/// The scene `dir/summary.json` names, if it can still be read.
pub(crate) fn run_scene(dir: &Path) -> Option<Scene> {
    std::fs::read_to_string(dir.join("summary.json"))
        .ok()
        .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).ok())
        .and_then(|summary| summary.get("scene")?.as_str().map(str::to_owned))
        .and_then(|path| Scene::load(Path::new(&path)).ok())
}

/// The colliders of `scene` as scenery (nothing without a scene or
/// colliders).
pub(crate) fn of_scene(scene: Option<&Scene>) -> Scenery {
    let Some(contact) = scene.and_then(|s| s.contact.as_ref()) else {
        return Scenery::default();
    };
    let mut scenery = Scenery::default();
    for collider in &contact.colliders {
        match &collider.shape {
            ColliderShape::Plane { point, normal } if normal.y > 1.0 - 1e-12 => {
                scenery.ground = Some(scenery.ground.map_or(point.y, |g: f64| g.max(point.y)));
            }
            ColliderShape::Plane { point, normal } => scenery.solids.push(tilted(point, normal)),
            ColliderShape::Sphere { center, radius } => {
                scenery
                    .solids
                    .push(Scenery::sphere((*center).into(), *radius, 16));
            }
            ColliderShape::Box { min, max } => {
                scenery
                    .solids
                    .push(Scenery::cuboid((*min).into(), (*max).into()));
            }
            ColliderShape::Mesh(mesh) => scenery.solids.push(Surface {
                positions: mesh.vertices().iter().map(|p| (*p).into()).collect(),
                triangles: mesh.triangles().to_vec(),
                lines: Vec::new(),
            }),
        }
    }
    scenery
}

/// A square piece of a tilted plane around its point.
fn tilted(point: &pd_mesh::Point, normal: &pd_mesh::Point) -> Surface {
    let helper = if normal.x.abs() < 0.9 {
        pd_mesh::Point::x()
    } else {
        pd_mesh::Point::y()
    };
    let u = normal.cross(&helper).normalize() * PLANE_HALF_SIDE;
    let v = normal.cross(&u);
    let corners = [point - u - v, point + u - v, point + u + v, point - u + v];
    Surface {
        positions: corners.iter().map(|p| (*p).into()).collect(),
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        lines: Vec::new(),
    }
}
