//! The part of [`BodyContact`] that detects pairs against the per-step
//! candidate lists (`candidates.rs`): building them, the listed
//! counterpart of [`BodyContact::first_hit`], its fast path without the
//! grid's arithmetic (docs/design/contact.md, "Contact's own cost"), the
//! detection over an iteration's triangle boxes it is part of
//! ([`BodyContact::detect_with_boxes`]: against the lists, or the grid
//! when they cannot be built), and the end-plane test of a crossing.

use pd_mesh::Point;

use super::{BodyContact, Pair, inside, project_onto};
use crate::candidates::{Surface, apart};
use crate::end_plane::surely_beyond;
use crate::grid::{cell_index, cell_size, query_end};

/// What a candidate entry's start plane tells of its crossings in every
/// iteration of a step (docs/design/contact.md, "Detection and the broad phase"). When the vertex
/// starts within the thickness of the triangle's plane (`d0 <= thickness`),
/// a crossing's fraction `s` is `+0` or `-0` whatever the iterate (the
/// numerator `d0 - thickness` is not positive, the other branch is `0`),
/// so the crossing point is `a + (b - a) s` and the triangle's corners
/// `start + (end - start) s`: with finite differences (the fast path's
/// coverage bounds every coordinate) the products are zeros, and adding a
/// zero of either sign to a float returns it exactly unless it is `-0`
/// (`-0 + +0 = +0`), so when no coordinate of `a` and of the start
/// triangle is `-0` these are `a` and `start` bit for bit. The projection
/// is then the one of the step's start, taken once.
#[derive(Debug, Clone, Copy)]
pub(super) enum StartHit {
    /// Not known: the full crossing runs.
    Unknown,
    /// Every crossing of the step is `None`: the start projection is not
    /// inside the triangle.
    Never,
    /// A crossing that passes the end-plane test is a pair with these
    /// weights and normal (turned to the start normal's side).
    Inside([f64; 3], Point),
}

impl BodyContact {
    /// The detection of [`BodyContact::detect`] over this iteration's
    /// triangle boxes: against the candidate lists (rebuilt if they do not
    /// cover the iterate), or the grid if they cannot be built. Lists just
    /// rebuilt to cover the iterate go to the fast path
    /// ([`BodyContact::detect_listed_fast`], the same pairs bit for bit,
    /// without the sweep of every triangle's box and the cell arithmetic;
    /// docs/design/contact.md, "Detection and the broad phase"), unless it declines (having
    /// changed no pair); `motion` is the largest `|dx|_inf` (m).
    pub(super) fn detect_with_boxes(
        &mut self,
        x_n: &[Point],
        dx: &[Point],
        (thickness, motion): (f64, f64),
    ) {
        // Neither the coverage test nor the build reads this iteration's
        // boxes: they are swept after them, when needed.
        let mut listed = self.candidates.covers(x_n, dx, &self.on_surface);
        if !listed {
            listed = self.build_candidates(x_n, dx, thickness);
            if listed && self.detect_listed_fast(x_n, dx, (thickness, motion)) {
                return;
            }
        }
        self.sweep_boxes(x_n, dx, thickness);
        if listed {
            let cell = cell_size(&self.boxes);
            for v in 0..x_n.len() {
                if self.searching(v) {
                    self.pairs[v] = self.first_listed_hit(v, x_n, dx, (thickness, cell));
                    if self.pairs[v].is_some() {
                        self.found.push(v);
                    }
                }
            }
        } else {
            self.grid.build(&self.boxes);
            for v in 0..x_n.len() {
                if self.searching(v) {
                    self.pairs[v] = self.first_hit(v, x_n, dx, thickness);
                    if self.pairs[v].is_some() {
                        self.found.push(v);
                    }
                }
            }
        }
    }

    /// Every triangle's box for this iterate: the hull of its vertices'
    /// segments `x_n -> x_n + dx`, widened by the thickness and the reach.
    /// Each surface vertex's segment box is taken once and a triangle's box
    /// is the hull of its three: min and max are exact, so the bounds are
    /// those of the hull of the six points taken one by one, up to the
    /// sign of a zero bound, which adding the margin removes (and which
    /// compares equal anyway). A non-finite iterate takes the points one by
    /// one, in the order that decides where a NaN lands.
    pub(super) fn sweep_boxes(&mut self, x_n: &[Point], dx: &[Point], thickness: f64) {
        let m = Point::repeat(thickness + self.reach);
        self.boxes.clear();
        let mut finite = true;
        for &i in &self.on_surface {
            let (a, b) = (x_n[i], x_n[i] + dx[i]);
            finite &= a.iter().chain(b.iter()).all(|c| c.is_finite());
            self.segments[i] = (a.inf(&b), a.sup(&b));
        }
        if !finite {
            self.sweep_boxes_one_by_one(x_n, dx, &m);
            return;
        }
        for face in &self.faces {
            let [p, q, r] = face.vertices.map(|i| self.segments[i]);
            let (lo, hi) = (p.0.inf(&q.0).inf(&r.0), p.1.sup(&q.1).sup(&r.1));
            self.boxes.push((lo - m, hi + m));
        }
    }

    /// [`BodyContact::sweep_boxes`] point by point (for non-finite
    /// iterates).
    fn sweep_boxes_one_by_one(&mut self, x_n: &[Point], dx: &[Point], m: &Point) {
        for face in &self.faces {
            let (mut lo, mut hi) = (x_n[face.vertices[0]], x_n[face.vertices[0]]);
            for &i in &face.vertices {
                for p in [x_n[i], x_n[i] + dx[i]] {
                    lo = lo.inf(&p);
                    hi = hi.sup(&p);
                }
            }
            self.boxes.push((lo - m, hi + m));
        }
    }

    /// Builds the candidate lists around `x_n` with an inflation of twice
    /// the largest displacement of a surface vertex (this iterate's or the
    /// last build's), m; whether they cover `x_n + dx`. They serve the
    /// following iterations and steps until an iterate leaves them.
    pub(super) fn build_candidates(&mut self, x_n: &[Point], dx: &[Point], thickness: f64) -> bool {
        let motion = (self.on_surface.iter())
            .map(|&i| dx[i].amax())
            .fold(0.0_f64, f64::max);
        let delta = 2.0 * motion.max(self.candidates.last_motion);
        self.candidates.last_motion = motion;
        self.start_planes_fresh = false;
        let mut candidates = std::mem::take(&mut self.candidates);
        let surface = Surface {
            faces: &self.triangles,
            // Every vertex that may search while the lists last, pair or
            // not: a pair is dropped at a step's start, and the lists
            // outlive the step.
            listed: |v: usize| self.body_of[v] != usize::MAX && !self.fixed[v],
            admits: |v: usize, f: usize| self.admits(v, f),
            group: &|f| self.faces[f].body,
            // `admits` with `f` of body `g`: another body's with `between`,
            // its own with self-contact (then per triangle).
            queried: |v: usize, g: usize| {
                if g == self.body_of[v] {
                    self.neighbourhood.is_some()
                } else {
                    self.between
                }
            },
        };
        let margin = thickness + self.reach;
        let covered = candidates.build(
            &surface,
            (x_n, dx, &self.on_surface),
            (delta, margin, thickness),
        );
        self.candidates = candidates;
        covered
    }

    /// [`BodyContact::first_hit`] over vertex `v`'s candidates, with the
    /// same result bit for bit: a candidate counts if the grid of this
    /// iteration's boxes (cells of size `cell`, m) would visit it, and
    /// among the earliest hits the first the grid would visit wins (cells
    /// in order, then triangles in order).
    pub(super) fn first_listed_hit(
        &self,
        v: usize,
        x_n: &[Point],
        dx: &[Point],
        (thickness, cell): (f64, f64),
    ) -> Option<Pair> {
        let (a, b) = (x_n[v], x_n[v] + dx[v]);
        let m = Point::repeat(thickness);
        let (lo, hi) = (a.inf(&b) - m, a.sup(&b) + m);
        let q_lo = cell_index(&lo, cell);
        let q_hi = query_end(&q_lo, &cell_index(&hi, cell));
        let query = (lo, hi);
        // The earliest hit; among equally early ones, the first the grid
        // would visit (cells in order, then triangles in order). Kept as a
        // running best: no allocation inside the iterations.
        let mut best: Option<(f64, ([i64; 3], usize), Pair)> = None;
        for &f in self.candidates.of(v) {
            let f = f as usize;
            let (f_lo, f_hi) = &self.boxes[f];
            if apart(&query, &self.boxes[f]) {
                continue;
            }
            let (c_lo, c_hi) = (cell_index(f_lo, cell), cell_index(f_hi, cell));
            // Written out, not `[0, 1, 2].map`: this loop is the hot spot
            // of detection, and the closures of `map` are not all inlined.
            let first = [
                q_lo[0].max(c_lo[0]),
                q_lo[1].max(c_lo[1]),
                q_lo[2].max(c_lo[2]),
            ];
            // `|`, not `||`: one branch instead of up to three.
            let outside = (first[0] > q_hi[0].min(c_hi[0]))
                | (first[1] > q_hi[1].min(c_hi[1]))
                | (first[2] > q_hi[2].min(c_hi[2]));
            if outside {
                continue;
            }
            let face = self.faces[f];
            let [i, j, k] = face.vertices;
            let start = [x_n[i], x_n[j], x_n[k]];
            let end = [x_n[i] + dx[i], x_n[j] + dx[j], x_n[k] + dx[k]];
            if let Some((s, pair)) = self.crossing(&face, (&start, &end), (&a, &b), thickness) {
                let key = (first, f);
                if best.is_none_or(|(t, k, _)| s < t || (s == t && key < k)) {
                    best = Some((s, key, Pair { face: f, ..pair }));
                }
            }
        }
        best.map(|(_, _, p)| p)
    }
}

/// Two candidates of one vertex hit at the same fraction (or at fractions
/// that do not compare): the winner is the grid's visiting order, which
/// only [`BodyContact::first_listed_hit`] knows.
pub(super) struct Tie;

/// The largest ratio of a coordinate's magnitude to the detection margin
/// at which [`BodyContact::detect_listed_fast`] runs: below it, a
/// coordinate divided by the grid's cell (twice the margin plus the
/// triangle's extent, at least about 1.5 margins after rounding) is below
/// `2^50`, where floats are spaced by at most 1/8, so a query box no wider
/// than a cell never spans more than 3 cells (the grid's query looks up at
/// most 4 per side).
const FAST_MAGNITUDE: f64 = (1u64 << 50) as f64;

impl BodyContact {
    /// The listed detection of an iteration, without the per-iteration
    /// grid arithmetic (docs/design/contact.md, "Contact's own cost"): returns
    /// `false`, having changed no pair, when it cannot give the result of
    /// [`BodyContact::first_listed_hit`] bit for bit (lists not valid or
    /// not covering the iterate, non-finite or enormous coordinates); the
    /// caller then runs that path.
    ///
    /// Why it is the same. (1) The segment boxes and the coverage test are
    /// the expressions of [`BodyContact::sweep_boxes`] and
    /// [`crate::candidates::Candidates::covers`], fused in one pass
    /// (the coverage of the step's start `x_n` is checked once per step and
    /// at each build: `start_covered`); a candidate's box is built from the
    /// segment boxes on demand with the expressions of `sweep_boxes`, so it
    /// has the same bounds. A candidate's start plane depends on `x_n` only
    /// and is taken once per step (`fill_start_planes`), and a vertex with
    /// no candidate finds nothing, so only the listed ones are visited. (2) The grid's cell
    /// is at least the extent of every triangle box, which holds the
    /// segment of each of its vertices widened by `thickness + reach`, so
    /// a searching vertex's query box (its segment widened by `thickness`)
    /// is no wider than a cell: the query is never clamped, and since
    /// `floor(p / cell)` is monotone in `p`, a triangle whose box is not
    /// apart from the query shares a cell with it: the cell test of
    /// `first_listed_hit` never rejects. (3) Its cells only order ties:
    /// when two candidates hit at the same fraction, the vertex is handed
    /// to `first_listed_hit` ([`Tie`]).
    pub(super) fn detect_listed_fast(
        &mut self,
        x_n: &[Point],
        dx: &[Point],
        (thickness, motion): (f64, f64),
    ) -> bool {
        let margin = thickness + self.reach;
        let fast = self.candidates.valid
            && self.candidates.start_covered
            && margin > 0.0
            && self.candidates.magnitude <= margin * FAST_MAGNITUDE;
        if !fast {
            return false;
        }
        // The full test only when the motion bound cannot tell.
        let on_surface = &self.on_surface;
        let quick = (self.candidates).covers_motion(x_n, on_surface, motion);
        let mut covered = true;
        for &i in if quick { &[][..] } else { &on_surface[..] } {
            let b = x_n[i] + dx[i];
            let (lo, hi) = self.candidates.bounds(i);
            // `Candidates::covers`' comparisons for the iterate (the start
            // was checked at the step's start or at the build), combined
            // without short-circuit (false for a NaN).
            for k in 0..3 {
                covered &= (lo[k] <= b[k]) & (b[k] <= hi[k]);
            }
        }
        if !covered {
            return false;
        }
        if !self.start_planes_fresh {
            self.fill_start_planes(x_n, thickness);
        }
        // Only the candidates' vertices of the vertices still searching
        // read a segment box (the same expressions as `sweep_boxes`).
        for &i in &self.needed {
            let (a, b) = (x_n[i], x_n[i] + dx[i]);
            self.segments[i] = (a.inf(&b), a.sup(&b));
        }
        let mut cell = None;
        // A vertex with an empty list finds nothing; a listed one is on a
        // surface and free, so it searches if it has no pair. Only the
        // vertices with a live entry (`fill_start_planes`) can find one.
        for k in 0..self.live_vertices.len() {
            let v = self.live_vertices[k];
            if self.pairs[v].is_some() {
                continue;
            }
            let found = match self.first_listed_hit_fast(v, x_n, dx, thickness) {
                Ok(pair) => pair,
                Err(Tie) => {
                    let cell = *cell.get_or_insert_with(|| {
                        self.sweep_boxes(x_n, dx, thickness);
                        cell_size(&self.boxes)
                    });
                    self.first_listed_hit(v, x_n, dx, (thickness, cell))
                }
            };
            // The slot is empty: written only when a pair is found (the
            // store of a 100-byte `None` over `None` was a hot spot).
            if found.is_some() {
                self.pairs[v] = found;
                self.found.push(v);
            }
        }
        true
    }

    /// [`BodyContact::first_listed_hit`] where no cell test rejects (see
    /// [`BodyContact::detect_listed_fast`]): the earliest hit, or [`Tie`]
    /// if two candidates hit at the same fraction.
    pub(super) fn first_listed_hit_fast(
        &self,
        v: usize,
        x_n: &[Point],
        dx: &[Point],
        thickness: f64,
    ) -> Result<Option<Pair>, Tie> {
        let (a, b) = (x_n[v], x_n[v] + dx[v]);
        let m = Point::repeat(thickness);
        let query = (a.inf(&b) - m, a.sup(&b) + m);
        let widen = Point::repeat(thickness + self.reach);
        let mut best: Option<(f64, Pair)> = None;
        // Only the live entries: the others (no start plane, or never hit)
        // were skipped here entry by entry before (`fill_start_planes`).
        let (from, to) = self.live_of[v];
        for live in &self.live[from as usize..to as usize] {
            let (f, start_plane, known) = (live.face, live.plane, live.known);
            let face = self.faces[f];
            let [i, j, k] = face.vertices;
            let [p, q, r] = [self.segments[i], self.segments[j], self.segments[k]];
            let (lo, hi) = (p.0.inf(&q.0).inf(&r.0), p.1.sup(&q.1).sup(&r.1));
            if apart(&query, &(lo - widen, hi + widen)) {
                continue;
            }
            // `crossing_from` in two halves: most entries end beyond the
            // thickness, and only the others read the start triangle.
            let end = [x_n[i] + dx[i], x_n[j] + dx[j], x_n[k] + dx[k]];
            let Some(s) = self.end_fraction(start_plane, &end, &b, thickness) else {
                continue;
            };
            let pair = match known {
                StartHit::Inside(weights, normal) => Pair {
                    face: f,
                    weights,
                    normal,
                    force: Point::zeros(),
                    projected: false,
                    warm: false,
                },
                _ => {
                    let start = [x_n[i], x_n[j], x_n[k]];
                    match crossing_at(s, &start_plane.0, (&start, &end), (&a, &b)) {
                        Some(pair) => pair,
                        None => continue,
                    }
                }
            };
            match best {
                Some((t, _)) if s > t => {}
                Some((t, _)) if !(s < t) => return Err(Tie),
                _ => best = Some((s, Pair { face: f, ..pair })),
            }
        }
        Ok(best.map(|(_, p)| p))
    }
}

impl BodyContact {
    /// The second half of [`BodyContact::crossing_from`]'s start: the end
    /// plane of the triangle at `end` (its normal turned to `n0`'s side),
    /// the vertex's signed distance `d1` to it at `b`, and the fraction `s`
    /// at which the vertex comes within `thickness`; `None` if the end
    /// triangle is degenerate or `d1 >= thickness`.
    pub(super) fn end_fraction(
        &self,
        (n0, d0): (Point, f64),
        end: &[Point; 3],
        b: &Point,
        thickness: f64,
    ) -> Option<f64> {
        // `plane_of(end, b)`'s operations written out, so that the
        // pre-test (`end_plane.rs`) reads the same cross product and
        // `b - end[0]` and, where it can tell, spares the square root and
        // the divisions of a vertex that ends beyond the thickness.
        let cross = (end[1] - end[0]).cross(&(end[2] - end[0]));
        let area2 = cross.norm_squared();
        if !(area2 > 0.0) {
            return None;
        }
        let q = b - end[0];
        if surely_beyond(&cross, area2, &q, &n0, thickness) {
            return None;
        }
        let n1 = cross / area2.sqrt();
        let n1 = if n1.dot(&n0) >= 0.0 { n1 } else { -n1 };
        let d1 = n1.dot(&q);
        if d1 >= thickness {
            return None;
        }
        Some(if d0 > d1 {
            ((d0 - thickness) / (d0 - d1)).clamp(0.0, 1.0)
        } else {
            0.0
        })
    }
}

/// The second half of [`BodyContact::crossing_from`], once the fraction
/// `s` of [`BodyContact::end_fraction`] is known: the pair where the
/// vertex segment `a -> b` at `s` projects inside the triangle moving from
/// `start` to `end` (its normal turned to `n0`'s side; `face` left 0).
pub(super) fn crossing_at(
    s: f64,
    n0: &Point,
    (start, end): (&[Point; 3], &[Point; 3]),
    (a, b): (&Point, &Point),
) -> Option<Pair> {
    let lerp = |p: &Point, q: &Point| p + (q - p) * s;
    let tri = [0, 1, 2].map(|k| lerp(&start[k], &end[k]));
    let (weights, normal, _) = project_onto(&tri, &lerp(a, b))?;
    let normal = if normal.dot(n0) >= 0.0 {
        normal
    } else {
        -normal
    };
    inside(&weights).then_some(Pair {
        face: 0,
        weights,
        normal,
        force: Point::zeros(),
        projected: false,
        warm: false,
    })
}

/// What the start plane `(n0, d0)` of the triangle `start` and the vertex
/// at `a` tells of the step's crossings ([`StartHit`]).
pub(super) fn start_hit(
    (n0, d0): (Point, f64),
    start: &[Point; 3],
    a: &Point,
    thickness: f64,
) -> StartHit {
    let kept = |p: &Point| p.iter().all(|&c| c.to_bits() != (-0.0_f64).to_bits());
    if !(d0 <= thickness && kept(a) && start.iter().all(kept)) {
        return StartHit::Unknown;
    }
    let Some((weights, normal, _)) = project_onto(start, a) else {
        return StartHit::Never;
    };
    let normal = if normal.dot(&n0) >= 0.0 {
        normal
    } else {
        -normal
    };
    if inside(&weights) {
        StartHit::Inside(weights, normal)
    } else {
        StartHit::Never
    }
}
