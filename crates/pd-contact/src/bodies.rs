//! Contact between bodies (`contact.bodies = true`, docs/design/contact.md):
//! vertices of each body against the surface triangles (tet boundary faces,
//! cloth triangles) of every other body, in the same projected Uzawa
//! framework as the colliders.
//!
//! A pair is a vertex `v` and a triangle `(a, b, c)` with barycentric
//! weights `w` and unit normal `n`, both fixed for the step (a linearised
//! constraint, as for colliders). Its relative position is
//! `r = x_v - sum_i w_i x_i`; the constraint keeps `n . r >= thickness`
//! and, while sticking, `r` tangentially where the vertex met the
//! triangle's material point, so friction acts relative to the triangle's
//! motion. The force `f` enters the right-hand side at `v` and, times
//! `-w_i`, at the triangle's vertices: the forces sum to zero and momentum
//! is exchanged, never created.
//!
//! Step size. With `J` the pairs' rows (`1` at `v`, `-w_i` at `a, b, c`),
//! the response of the pairs to their forces is `J A^-1 J^T <= h^2 J M^-1
//! J^T`, and by Cauchy-Schwarz `J M^-1 J^T <= D`, `D_k = sum_{i in k}
//! count_i w_ki^2 / m_i`, where `count_i` is the number of contacts (pairs
//! and collider contacts) vertex `i` takes part in. So `rho_k = omega /
//! (h^2 D_k)` converges for `omega` in `(0, 2)`, however many pairs share
//! a vertex; a collider contact's step `omega m_v / h^2` is divided by
//! `count_v` for the same reason.
//!
//! Self-contact (`contact.self = true`) is the same constraint with the
//! vertex and the triangle on one body: only the admission of candidates
//! differs ([`BodyContact::admits`]), which leaves out the vertex's rest
//! neighbours (`neighbourhood.rs`).
//!
//! This file holds the state, the hooks the contact state calls (start of
//! step, detection, force update, projection, velocity filter) and the
//! per-iteration grid's swept test; the rest of `impl BodyContact` is by
//! topic in `bodies/`: `counts.rs` (the contact counts and the paired
//! vertices), `listed.rs` (detection against the candidate lists and its
//! fast path), `live.rs` (the step's live candidate entries for that fast
//! path) and `pair_force.rs` (a pair's Uzawa step and compliance).

use pd_mesh::Point;

use crate::SurfacePairs;
use crate::candidates::Candidates;
use crate::grid::Grid;
use crate::neighbourhood::RestNeighbourhood;

/// Barycentric slack of the inside test (a vertex on a shared edge or
/// corner belongs to either triangle; the first in triangle order wins).
const INSIDE_SLACK: f64 = 1e-9;

/// One surface triangle of a body.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Face {
    vertices: [usize; 3],
    body: usize,
    /// Cloth: either side is outside (the side the vertex comes from).
    two_sided: bool,
}

/// A vertex's contact with a triangle of another body, for one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pair {
    pub(super) face: usize,
    weights: [f64; 3],
    pub(super) normal: Point,
    /// The force on the vertex (`A dx` units); the triangle gets `-w_i f`.
    pub(super) force: Point,
    /// Moved apart by the end-of-step projection.
    projected: bool,
    /// Carried over from the previous step.
    warm: bool,
}

impl Pair {
    pub(super) fn active(&self) -> bool {
        self.force.dot(&self.normal) > 0.0
    }
}

/// Body-contact state: the surface, the per-vertex pairs and the broad
/// phase's buffers.
#[derive(Debug, Clone)]
pub(crate) struct BodyContact {
    faces: Vec<Face>,
    /// Body of each vertex, `usize::MAX` for vertices on no surface.
    body_of: Vec<usize>,
    masses: Vec<f64>,
    fixed: Vec<bool>,
    /// Coulomb coefficient between bodies.
    friction: f64,
    /// Largest depth behind a triangle at the step's start at which a
    /// vertex still counts as in front of it, m (a quarter of the mean
    /// surface edge): what lies deeper is the far side of the other body.
    reach: f64,
    /// Pairs between different bodies are admitted.
    between: bool,
    /// With self-contact: the rest neighbours each vertex never pairs with.
    neighbourhood: Option<RestNeighbourhood>,
    pub(super) pairs: Vec<Option<Pair>>,
    /// Contacts each vertex takes part in, this iteration.
    pub(super) count: Vec<u32>,
    grid: Grid,
    boxes: Vec<(Point, Point)>,
    /// Per vertex, the box of its segment `x_n -> x_n + dx` this iteration
    /// (surface vertices only).
    segments: Vec<(Point, Point)>,
    /// The vertices on a surface, in increasing order.
    on_surface: Vec<usize>,
    /// The vertices of the candidates of the step's searching vertices
    /// (`fill_start_planes`): the fast path's segments are taken for them;
    /// `in_needed` marks them while the list is made (false otherwise).
    needed: Vec<usize>,
    in_needed: Vec<bool>,
    /// The per-step broad phase (`candidates.rs`).
    candidates: Candidates,
    /// The vertices with a pair after this iteration's detection, in order.
    paired: Vec<usize>,
    /// Per vertex, its pair's shared compliance and the counts it was taken
    /// with (`bodies/pair_force.rs`); cleared with the pairs' weights.
    compliances: Vec<Option<([u32; 4], f64)>>,
    /// Each triangle's vertices (for the candidate lists).
    triangles: Vec<[usize; 3]>,
    /// Per candidate-list entry, what its start plane
    /// ([`BodyContact::start_plane`], from `x_n`) tells of every crossing
    /// in the step ([`listed::StartHit`]), filled with the live entries
    /// (`bodies/live.rs`); valid while `start_planes_fresh` (cleared at a
    /// step's start and by a build).
    start_hits: Vec<listed::StartHit>,
    start_planes_fresh: bool,
    /// The counts and `paired` are those of the current pairs and
    /// collider contacts (`bodies/counts.rs`): false at a step's start and
    /// after a restore.
    counted: bool,
    /// Per vertex, whether its collider contact is in `count`.
    has_collider: Vec<bool>,
    /// The vertices that got a pair in this iteration's detection, in
    /// increasing order.
    found: Vec<usize>,
    /// The step's live entries ([`live::LiveEntry`]): `v`'s in the range
    /// `live_of[v]`; the vertices with any, in order, `live_vertices`.
    live: Vec<live::LiveEntry>,
    live_of: Vec<(u32, u32)>,
    live_vertices: Vec<usize>,
}

/// A body's surface for [`crate::ContactState::set_surfaces`]: its
/// triangles in global vertex numbers and whether it is a cloth
/// (two-sided).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BodySurface {
    /// The triangles, in global vertex numbers (a solid's outward side is
    /// the one its triangles' normals point to).
    pub triangles: Vec<[usize; 3]>,
    /// A cloth: either side of a triangle is outside.
    pub two_sided: bool,
}

impl BodyContact {
    /// `thickness` (m) only sets the self-contact neighbourhood's radius.
    pub fn new(
        surfaces: Vec<BodySurface>,
        rest: &[Point],
        (masses, fixed): (&[f64], &[bool]),
        (friction, thickness): (f64, f64),
        which: SurfacePairs,
    ) -> Self {
        let mut faces = Vec::new();
        let mut body_of = vec![usize::MAX; rest.len()];
        let (mut edges, mut edge_sum) = (0usize, 0.0);
        for (body, surface) in surfaces.into_iter().enumerate() {
            for t in surface.triangles {
                for (k, &v) in t.iter().enumerate() {
                    body_of[v] = body;
                    edge_sum += (rest[v] - rest[t[(k + 1) % 3]]).norm();
                    edges += 1;
                }
                faces.push(Face {
                    vertices: t,
                    body,
                    two_sided: surface.two_sided,
                });
            }
        }
        let reach = if edges > 0 {
            0.25 * edge_sum / edges as f64
        } else {
            0.0
        };
        let neighbourhood = which.self_contact.then(|| {
            let triangles: Vec<_> = faces.iter().map(|f| (f.vertices, f.body)).collect();
            RestNeighbourhood::new(&triangles, &body_of, rest, 4.0 * reach + thickness)
        });
        let on_surface = (0..rest.len())
            .filter(|&v| body_of[v] != usize::MAX)
            .collect();
        let triangles = faces.iter().map(|f| f.vertices).collect();
        Self {
            faces,
            body_of,
            on_surface,
            needed: Vec::new(),
            in_needed: vec![false; rest.len()],
            candidates: Candidates::default(),
            triangles,
            masses: masses.to_vec(),
            fixed: fixed.to_vec(),
            friction,
            reach,
            between: which.between_bodies,
            neighbourhood,
            pairs: vec![None; rest.len()],
            compliances: vec![None; rest.len()],
            paired: Vec::new(),
            count: vec![0; rest.len()],
            grid: Grid::default(),
            boxes: Vec::new(),
            segments: vec![(Point::zeros(), Point::zeros()); rest.len()],
            start_hits: Vec::new(),
            start_planes_fresh: false,
            counted: false,
            has_collider: vec![false; rest.len()],
            found: Vec::new(),
            live: Vec::new(),
            live_of: Vec::new(),
            live_vertices: Vec::new(),
        }
    }

    /// The number of surface triangles.
    pub fn faces(&self) -> usize {
        self.faces.len()
    }

    /// Replaces the pairs by saved ones (checked by the caller): what
    /// [`BodyContact::begin_step`] needs of them, the triangle, the normal's
    /// side and the force.
    pub fn load(&mut self, saved: &[crate::SavedContact]) {
        self.pairs.iter_mut().for_each(|p| *p = None);
        self.compliances.iter_mut().for_each(|c| *c = None);
        self.candidates.valid = false;
        self.start_planes_fresh = false;
        self.counted = false;
        for c in saved {
            self.pairs[c.vertex] = Some(Pair {
                face: c.other,
                weights: [0.0; 3],
                normal: Point::from(c.normal),
                force: Point::from(c.force),
                projected: false,
                warm: true,
            });
        }
    }

    /// Start of a step: keeps the pairs that ended the last one active,
    /// re-anchored at `x_n` (the vertex's projection onto its triangle
    /// becomes the contact point; a vertex that left its triangle loses the
    /// pair and is detected anew), forces warm-started. The candidate lists
    /// are kept: they hold every free surface vertex, with or without a
    /// pair, and stay exact while they cover the iterates
    /// (`candidates.rs`).
    pub fn begin_step(&mut self, x_n: &[Point]) {
        self.candidates.begin_step(x_n, &self.on_surface);
        self.start_planes_fresh = false;
        let (listed, count) = self.pair_slots();
        self.counted = false;
        self.compliances.iter_mut().for_each(|c| *c = None);
        for k in 0..count {
            let v = self.pair_slot(k, listed);
            let pair = &mut self.pairs[v];
            let Some(p) = pair.filter(Pair::active) else {
                *pair = None;
                continue;
            };
            let face = self.faces[p.face];
            let tri = face.vertices.map(|i| x_n[i]);
            *pair = project_onto(&tri, &x_n[v]).and_then(|(weights, normal, _)| {
                let normal = if normal.dot(&p.normal) >= 0.0 {
                    normal
                } else {
                    -normal
                };
                inside(&weights).then_some(Pair {
                    weights,
                    normal,
                    projected: false,
                    warm: true,
                    ..p
                })
            });
        }
    }

    /// Detects new pairs for the free surface vertices without one (the
    /// linearised swept test of [`BodyContact::first_hit`]), then counts
    /// every vertex's contacts and lists the paired vertices (`paired`);
    /// `collider` lists the vertices holding a collider contact (each
    /// once); `motion` is the largest `|dx|_inf` (m).
    pub fn detect(
        &mut self,
        x_n: &[Point],
        dx: &[Point],
        (thickness, motion): (f64, f64),
        collider: &[usize],
    ) {
        self.found.clear();
        if !self.detect_listed_fast(x_n, dx, (thickness, motion)) {
            self.detect_with_boxes(x_n, dx, (thickness, motion));
        }
        self.count_contacts(collider);
    }

    /// The earliest admitted triangle ([`BodyContact::admits`]) that the segment `x_n[v] ->
    /// x_n[v] + dx[v]` meets, relative to the triangle's own motion from
    /// `x_n` to `x_n + dx` (both linearised: the signed distance to the
    /// triangle's plane is interpolated between the segment's ends, and the
    /// crossing point is tested against the interpolated triangle).
    fn first_hit(&self, v: usize, x_n: &[Point], dx: &[Point], thickness: f64) -> Option<Pair> {
        let (a, b) = (x_n[v], x_n[v] + dx[v]);
        let m = Point::repeat(thickness);
        let (lo, hi) = (a.inf(&b) - m, a.sup(&b) + m);
        let mut best: Option<(f64, Pair)> = None;
        let mut seen = usize::MAX;
        self.grid.query(&lo, &hi, |f| {
            let face = self.faces[f];
            let (f_lo, f_hi) = &self.boxes[f];
            let apart = (0..3).any(|k| hi[k] < f_lo[k] || lo[k] > f_hi[k]);
            if apart || f == seen || !self.admits(v, f) {
                return;
            }
            seen = f;
            let start = face.vertices.map(|i| x_n[i]);
            let end = face.vertices.map(|i| x_n[i] + dx[i]);
            let Some(hit) = self.crossing(&face, (&start, &end), (&a, &b), thickness) else {
                return;
            };
            if best.is_none_or(|(s, _)| hit.0 < s) {
                best = Some((hit.0, Pair { face: f, ..hit.1 }));
            }
        });
        best.map(|(_, p)| p)
    }

    /// Whether vertex `v` looks for a new pair: on a surface, free, without
    /// one.
    fn searching(&self, v: usize) -> bool {
        self.pairs[v].is_none() && self.body_of[v] != usize::MAX && !self.fixed[v]
    }

    /// Whether vertex `v` may pair with triangle `f`: another body's with
    /// `between`, its own body's with self-contact unless they are rest
    /// neighbours.
    fn admits(&self, v: usize, f: usize) -> bool {
        if self.faces[f].body != self.body_of[v] {
            return self.between;
        }
        self.neighbourhood
            .as_ref()
            .is_some_and(|near| !near.excludes(v, f))
    }

    /// Where the vertex segment `a -> b` comes within `thickness` of the
    /// triangle moving from `start` to `end`: the fraction and the pair.
    fn crossing(
        &self,
        face: &Face,
        (start, end): (&[Point; 3], &[Point; 3]),
        (a, b): (&Point, &Point),
        thickness: f64,
    ) -> Option<(f64, Pair)> {
        let start_plane = self.start_plane(face, start, a, thickness)?;
        self.crossing_from(start_plane, (start, end), (a, b), thickness)
    }

    /// The part of [`BodyContact::crossing`] that depends only on the
    /// step's start: the triangle's unit normal at `start` turned towards
    /// the side the vertex `a` is on (for a two-sided triangle) and the
    /// signed distance along it; `None` if the triangle is degenerate or
    /// the vertex is more than `thickness + reach` behind it.
    pub(super) fn start_plane(
        &self,
        face: &Face,
        start: &[Point; 3],
        a: &Point,
        thickness: f64,
    ) -> Option<(Point, f64)> {
        // Each rejection as soon as its values are known (the same
        // values, so the same result as testing them all at the end).
        let (n0, d0) = plane_of(start, a)?;
        let side = if face.two_sided && d0 < 0.0 {
            -1.0
        } else {
            1.0
        };
        let (d0, n0) = (side * d0, side * n0);
        if d0 < -(thickness + self.reach) {
            return None;
        }
        Some((n0, d0))
    }

    /// The rest of [`BodyContact::crossing`], from the start plane
    /// `(n0, d0)` of [`BodyContact::start_plane`].
    pub(super) fn crossing_from(
        &self,
        (n0, d0): (Point, f64),
        (start, end): (&[Point; 3], &[Point; 3]),
        (a, b): (&Point, &Point),
        thickness: f64,
    ) -> Option<(f64, Pair)> {
        let s = self.end_fraction((n0, d0), end, b, thickness)?;
        Some((s, listed::crossing_at(s, &n0, (start, end), (a, b))?))
    }

    /// Updates every pair's force (one projected Uzawa step at the iterate
    /// `x_n + dx`) and adds it to `rhs` at the free vertices (`free_index`,
    /// `usize::MAX` for fixed ones). In the first iteration a warm force is
    /// applied as it is. Visits `paired` of this iteration's `detect`, in
    /// order (the forces reach `rhs` as in a pass over all vertices).
    #[allow(clippy::too_many_arguments)]
    pub fn apply(
        &mut self,
        x_n: &[Point],
        dx: &[Point],
        (h, omega, thickness): (f64, f64, f64),
        first: bool,
        free_index: &[usize],
        rhs: &mut [Point],
    ) {
        // The pair is read in place and only its force written back (a
        // copy of the 100-byte pair in and out was a third of the loop),
        // and the triangle's point is summed inline (`weighted`, the
        // iterator sum's operations).
        for k in 0..self.paired.len() {
            let v = self.paired[k];
            let Some(pair) = &self.pairs[v] else {
                continue;
            };
            let (weights, warm) = (pair.weights, pair.warm);
            let mut force = pair.force;
            let tri = self.faces[pair.face].vertices;
            if !(first && warm) {
                let compliance = h * h * self.shared_compliance(v, &tri, &weights);
                if compliance > 0.0 {
                    let x = |i: usize| x_n[i] + dx[i];
                    let r =
                        x(v) - pair_force::weighted([x(tri[0]), x(tri[1]), x(tri[2])], &weights);
                    if let Some(pair) = &self.pairs[v] {
                        force = self.update_force(pair, &r, omega / compliance, thickness);
                    }
                }
            }
            pair_force::add_pair_force(free_index, rhs, v, &tri, (&weights, force));
            if let Some(p) = &mut self.pairs[v] {
                p.force = force;
            }
        }
    }

    /// `sum_i share_i w_i^2 / m_i` over the free vertices of a pair, with
    /// `share_i` the contact count (`shared`) or 1.
    pub(super) fn compliance(
        &self,
        v: usize,
        tri: &[usize; 3],
        weights: &[f64; 3],
        shared: bool,
    ) -> f64 {
        let term = |i: usize, w: f64| {
            if self.fixed[i] {
                0.0
            } else {
                let share = if shared {
                    f64::from(self.count[i].max(1))
                } else {
                    1.0
                };
                share * w * w / self.masses[i]
            }
        };
        term(v, 1.0) + (0..3).map(|k| term(tri[k], weights[k])).sum::<f64>()
    }

    /// After the iterations: separates every pair left closer than the
    /// thickness along its normal, splitting the correction by inverse
    /// mass so that the centre of mass does not move. Returns the deepest
    /// correction, m.
    pub fn project(&mut self, positions: &mut [Point], thickness: f64) -> f64 {
        let (mut deepest, (listed, count)) = (0.0_f64, self.pair_slots());
        for k in 0..count {
            let v = self.pair_slot(k, listed);
            let Some(mut pair) = self.pairs[v] else {
                continue;
            };
            let tri = self.faces[pair.face].vertices;
            let r = positions[v]
                - (0..3)
                    .map(|k| positions[tri[k]] * pair.weights[k])
                    .sum::<Point>();
            let depth = thickness - pair.normal.dot(&r);
            let compliance = self.compliance(v, &tri, &pair.weights, false);
            pair.projected = depth > 0.0 && compliance > 0.0;
            if pair.projected {
                let impulse = pair.normal * (depth / compliance);
                self.push(positions, v, &tri, &pair.weights, impulse);
                deepest = deepest.max(depth);
            }
            self.pairs[v] = Some(pair);
        }
        deepest
    }

    /// Moves (or accelerates) the pair's free vertices by `impulse / m`:
    /// `+` at the vertex, `-w_i` at the triangle.
    fn push(&self, values: &mut [Point], v: usize, tri: &[usize; 3], w: &[f64; 3], impulse: Point) {
        if !self.fixed[v] {
            values[v] += impulse / self.masses[v];
        }
        for k in 0..3 {
            if !self.fixed[tri[k]] {
                values[tri[k]] -= impulse * (w[k] / self.masses[tri[k]]);
            }
        }
    }

    /// Inside the velocity filter: the relative normal velocity of every
    /// active or projected pair is set to zero by an equal and opposite
    /// impulse (momentum is kept; kinetic energy only falls, as in a
    /// perfectly inelastic contact).
    pub fn filter_velocities(&self, velocities: &mut [Point]) {
        let (listed, count) = self.pair_slots();
        for v in (0..count).map(|k| self.pair_slot(k, listed)) {
            let Some(pair) = self.pairs[v].filter(|p| p.active() || p.projected) else {
                continue;
            };
            let tri = self.faces[pair.face].vertices;
            let relative = velocities[v]
                - (0..3)
                    .map(|k| velocities[tri[k]] * pair.weights[k])
                    .sum::<Point>();
            let speed = pair.normal.dot(&relative);
            let compliance = self.compliance(v, &tri, &pair.weights, false);
            if speed != 0.0 && compliance > 0.0 {
                let impulse = pair.normal * (-speed / compliance);
                self.push(velocities, v, &tri, &pair.weights, impulse);
            }
        }
    }
}

/// The plane of triangle `t`: `(b - a) x (c - a)`, its squared length and
/// the unit normal; `None` for a degenerate triangle.
fn plane(t: &[Point; 3]) -> Option<(Point, f64, Point)> {
    let cross = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let area2 = cross.norm_squared();
    if !(area2 > 0.0) {
        return None;
    }
    Some((cross, area2, cross / area2.sqrt()))
}

/// The unit normal of triangle `t` and the signed distance of `p` from
/// its plane: [`project_onto`] without the barycentric weights (the same
/// operations, so the same values bit for bit).
fn plane_of(t: &[Point; 3], p: &Point) -> Option<(Point, f64)> {
    let (_, _, normal) = plane(t)?;
    Some((normal, normal.dot(&(p - t[0]))))
}

/// Projection of `p` onto the plane of triangle `t`: barycentric weights,
/// unit normal `(b - a) x (c - a)` and signed distance along it; `None`
/// for a degenerate triangle.
fn project_onto(t: &[Point; 3], p: &Point) -> Option<([f64; 3], Point, f64)> {
    let (cross, area2, normal) = plane(t)?;
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let q = p - t[0];
    let distance = normal.dot(&q);
    let w1 = e2.cross(&q).dot(&(-cross)) / area2;
    let w2 = e1.cross(&q).dot(&cross) / area2;
    Some(([1.0 - w1 - w2, w1, w2], normal, distance))
}

mod counts;
mod listed;
mod live;
mod pair_force;
#[cfg(test)]
mod tests;

fn inside(w: &[f64; 3]) -> bool {
    w.iter().all(|&x| x >= -INSIDE_SLACK)
}
