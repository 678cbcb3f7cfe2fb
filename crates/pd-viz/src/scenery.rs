//! Static scenery drawn with the bodies: the ground at a given height and
//! solids (colliders: spheres, boxes, triangle meshes) as grey surfaces.

use crate::obj::Surface;

/// What `pd render` draws besides the bodies. The default (nothing) gives
/// the pictures of a run without colliders: the ground grid at the lowest
/// vertex reached.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scenery {
    /// Height of a horizontal ground plane (m, along `+y`), where the grid
    /// is drawn instead of at the lowest vertex.
    pub ground: Option<f64>,
    /// Static solids, in world coordinates (m).
    pub solids: Vec<Surface>,
}

impl Scenery {
    /// Widens the box `lo..hi` by the ground height and every solid's
    /// vertices.
    pub(crate) fn widen(&self, lo: &mut [f64; 3], hi: &mut [f64; 3]) {
        if let Some(y) = self.ground {
            lo[1] = lo[1].min(y);
        }
        for p in self.solids.iter().flat_map(|s| &s.positions) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }

    /// A sphere of `radius` (m) around `centre`, as a latitude-longitude
    /// surface of `rings` x `2 rings` quads.
    pub fn sphere(centre: [f64; 3], radius: f64, rings: usize) -> Surface {
        let rings = rings.max(2);
        let segments = 2 * rings;
        let mut positions = Vec::new();
        for i in 0..=rings {
            let theta = std::f64::consts::PI * i as f64 / rings as f64;
            for j in 0..segments {
                let phi = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
                positions.push([
                    centre[0] + radius * theta.sin() * phi.cos(),
                    centre[1] + radius * theta.cos(),
                    centre[2] + radius * theta.sin() * phi.sin(),
                ]);
            }
        }
        let index = |i: usize, j: usize| i * segments + j % segments;
        let mut triangles = Vec::new();
        for i in 0..rings {
            for j in 0..segments {
                let (a, b) = (index(i, j), index(i, j + 1));
                let (c, d) = (index(i + 1, j), index(i + 1, j + 1));
                triangles.push([a, d, c]);
                triangles.push([a, b, d]);
            }
        }
        Surface {
            positions,
            triangles,
            lines: Vec::new(),
        }
    }

    /// The axis-aligned box `min..max` (m) as 12 triangles.
    pub fn cuboid(min: [f64; 3], max: [f64; 3]) -> Surface {
        let positions = (0..8)
            .map(|c: usize| [0, 1, 2].map(|k| if c >> k & 1 == 0 { min[k] } else { max[k] }))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        Surface {
            positions,
            triangles,
            lines: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every non-degenerate triangle's normal `(b - a) x (c - a)` points
    /// away from `centre` (the renderer culls the others).
    fn outward(surface: &Surface, centre: [f64; 3]) -> bool {
        surface.triangles.iter().all(|t| {
            let [a, b, c] = t.map(|i| surface.positions[i]);
            let e1 = [0, 1, 2].map(|k| b[k] - a[k]);
            let e2 = [0, 1, 2].map(|k| c[k] - a[k]);
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let out = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0 - centre[k]);
            let area = n.iter().map(|x| x * x).sum::<f64>();
            area < 1e-24 || n.iter().zip(&out).map(|(x, y)| x * y).sum::<f64>() > 0.0
        })
    }

    #[test]
    fn sphere_and_cuboid_face_outwards() {
        assert!(outward(
            &Scenery::sphere([1.0, 2.0, 3.0], 0.5, 8),
            [1.0, 2.0, 3.0]
        ));
        let cuboid = Scenery::cuboid([0.0, 0.0, 0.0], [1.0, 2.0, 3.0]);
        assert_eq!(cuboid.triangles.len(), 12);
        assert!(outward(&cuboid, [0.5, 1.0, 1.5]));
    }
}
