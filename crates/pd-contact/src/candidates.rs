//! Candidate triangles of body contact (docs/design/contact.md, "Detection and
//! the broad phase"): the broad phase built once and kept over iterations and
//! steps instead of rebuilt in every iteration, with results bit for
//! bit those of the per-iteration grid.
//!
//! Built at a step's start positions `x_n` with an inflation `delta`
//! (m): vertex `i` is given the box `[x_n[i] - delta, x_n[i] + delta]`
//! (float operations, as stored in `bounds`), a triangle the hull of its
//! vertices' boxes widened by the detection margin, a vertex's query box
//! its own box widened by the thickness; a listed vertex's candidates
//! (every free surface vertex is listed, with or without a pair, so that
//! the lists outlive the step in which they were built) are the admitted
//! triangles whose box is not apart from its query box.
//!
//! Why it is exact. An iteration's boxes are the same expressions with
//! `x_n[i] + dx[i]` in place of the inflation. While every surface vertex's
//! iterate `x_n[i] + dx[i]` lies inside its stored box ([`Candidates::covers`],
//! compared exactly), each of an iteration's box bounds is a min (max) of
//! values no lower (higher) than the stored ones, shifted by the same
//! float subtraction (addition), which is monotone: every iteration box
//! lies inside its stored box, so an iteration's pair of boxes that is not
//! apart was not apart at the build, and every triangle the per-iteration
//! grid would test is a candidate. When an iterate leaves its box, the
//! lists are built again around it (`delta` twice its displacement).

use pd_mesh::Point;

use crate::grid::{Grid, cell_index, cell_size};

/// The candidate lists, kept from step to step while they cover the
/// iterates.
#[derive(Debug, Clone, Default)]
pub(super) struct Candidates {
    /// Built (false before the first build, after a restore and after a
    /// build that failed).
    pub valid: bool,
    /// Per vertex, `(x_n - delta, x_n + delta)` at the build (`x_n` of
    /// the step that built them).
    bounds: Vec<(Point, Point)>,
    /// `faces[start[v]..start[v + 1]]`: vertex `v`'s candidates, in
    /// increasing order.
    start: Vec<u32>,
    faces: Vec<u32>,
    /// Largest displacement `|dx|_inf` of a surface vertex seen at the
    /// previous build, m: with the current one, sets the next build's
    /// inflation.
    pub last_motion: f64,
    /// The largest magnitude of a surface vertex's stored bound, m (what
    /// [`crate::bodies::BodyContact`]'s fast detection checks its cell
    /// arithmetic against).
    pub magnitude: f64,
    /// Whether every surface vertex's step start `x_n` lies in its stored
    /// box (set by [`Candidates::build`] and [`Candidates::begin_step`]):
    /// then an iteration only needs its iterates checked.
    pub start_covered: bool,
    /// The least room between a surface vertex's step start `x_n` and its
    /// stored box, over the vertices and axes, m ([`Candidates::room`]);
    /// `None` until taken after a step's start or a build.
    room: Option<f64>,
    /// The vertices with at least one candidate, in increasing order.
    nonempty: Vec<usize>,
    /// Each triangle's box at the build, m.
    boxes: Vec<(Point, Point)>,
    /// The triangles by group (body), each with its own grid: a vertex's
    /// query skips the groups it admits no triangle of (its own body
    /// without self-contact), most of the triangles near it.
    groups: Vec<Group>,
}

/// One group's triangles in a grid of their own (cells of the size shared
/// by every group: the size one grid of all the triangles would take).
#[derive(Debug, Clone, Default)]
struct Group {
    grid: Grid,
    /// The group's triangles, in increasing order (the grid's items).
    faces: Vec<u32>,
    boxes: Vec<(Point, Point)>,
    /// The hull of `boxes`, m.
    hull: (Point, Point),
}

/// Whether two boxes `(min, max)` are apart (a strict gap on some axis):
/// all six comparisons, combined without short-circuit, so that the test
/// is one branch, not up to six that depend on the data (the most
/// mispredicted of the candidate loops).
pub(super) fn apart(a: &(Point, Point), b: &(Point, Point)) -> bool {
    let ((a_lo, a_hi), (b_lo, b_hi)) = (a, b);
    (a_hi[0] < b_lo[0])
        | (a_lo[0] > b_hi[0])
        | (a_hi[1] < b_lo[1])
        | (a_lo[1] > b_hi[1])
        | (a_hi[2] < b_lo[2])
        | (a_lo[2] > b_hi[2])
}

/// What a build needs of the body-contact state (generic over the two
/// tests, so that they are inlined into the build's loop: as `dyn`
/// calls they cost a call per visited triangle).
pub(super) struct Surface<'a, L, A, Q> {
    /// Each triangle's vertices.
    pub faces: &'a [[usize; 3]],
    /// Each triangle's group (its body).
    pub group: &'a dyn Fn(usize) -> usize,
    /// Whether a vertex gets a list: every vertex that may look for new
    /// pairs while the lists last (on a surface, free).
    pub listed: L,
    /// Whether vertex `v` may pair with triangle `f`.
    pub admits: A,
    /// Whether vertex `v` may pair with some triangle of group `g`: when
    /// `false`, `admits(v, f)` is `false` for every triangle `f` of `g`.
    pub queried: Q,
}

impl Candidates {
    /// Vertex `v`'s candidate triangles.
    pub fn of(&self, v: usize) -> &[u32] {
        &self.faces[self.entries(v)]
    }

    /// The entries of vertex `v`'s candidates (indices into the list of
    /// all entries, `0..self.len()`).
    pub fn entries(&self, v: usize) -> std::ops::Range<usize> {
        self.start[v] as usize..self.start[v + 1] as usize
    }

    /// The candidate triangle of entry `e`.
    pub fn face(&self, e: usize) -> usize {
        self.faces[e] as usize
    }

    /// The number of entries of all lists.
    pub fn entry_count(&self) -> usize {
        self.faces.len()
    }

    /// The vertices with at least one candidate, in increasing order.
    pub fn listed(&self) -> &[usize] {
        &self.nonempty
    }

    /// Vertex `v`'s stored box `(x_n - delta, x_n + delta)`, m.
    pub fn bounds(&self, v: usize) -> &(Point, Point) {
        &self.bounds[v]
    }

    /// At a step's start `x_n`: records whether every surface vertex's
    /// start lies in its stored box ([`Candidates::start_covered`]).
    pub fn begin_step(&mut self, x_n: &[Point], on_surface: &[usize]) {
        self.start_covered = self.valid && self.contains(x_n, on_surface);
        self.room = None;
    }

    /// Whether every surface vertex's iterate `x_n + dx` surely lies in its
    /// stored box, from `motion`, the largest `|dx|_inf` (m), alone: the
    /// verdict of [`Candidates::covers`] where it answers yes. Only with
    /// [`Candidates::start_covered`]. Why: with `r` the least computed
    /// room `x_n - lo` (or `hi - x_n`), the exact room is at least `r (1 -
    /// u)`; if `|dx_k| <= motion <= r (1 - 1e-12)`, the exact `x_n + dx`
    /// lies in `[lo, hi]`, and since `lo` and `hi` are floats and rounding
    /// is monotone, so does the computed one. A NaN or infinite motion
    /// never passes.
    pub fn covers_motion(&mut self, x_n: &[Point], on_surface: &[usize], motion: f64) -> bool {
        let room = *self.room.get_or_insert_with(|| {
            let mut least = f64::INFINITY;
            for &i in on_surface {
                let (lo, hi) = &self.bounds[i];
                let room = (x_n[i] - lo).inf(&(hi - x_n[i]));
                least = least.min(room.min());
            }
            least
        });
        motion <= room * (1.0 - 1e-12)
    }

    /// Whether every vertex of `on_surface` has its point of `points` in
    /// its stored box (false for NaN).
    fn contains(&self, points: &[Point], on_surface: &[usize]) -> bool {
        on_surface.iter().all(|&i| {
            let (lo, hi) = &self.bounds[i];
            let a = points[i];
            (0..3).all(|k| lo[k] <= a[k] && a[k] <= hi[k])
        })
    }

    /// Whether every vertex of `surface` (`on_surface`) has its start
    /// point and iterate inside its stored box (false for non-finite
    /// values).
    pub fn covers(&self, x_n: &[Point], dx: &[Point], on_surface: &[usize]) -> bool {
        self.valid
            && on_surface.iter().all(|&i| {
                let (lo, hi) = &self.bounds[i];
                let (a, b) = (x_n[i], x_n[i] + dx[i]);
                (0..3).all(|k| lo[k] <= a[k] && a[k] <= hi[k] && lo[k] <= b[k] && b[k] <= hi[k])
            })
    }

    /// Sorts the triangles' boxes into their groups (`group` of each
    /// triangle) and builds each group's grid with cells of size `cell`
    /// (m). Why the lists are those of one grid of all the triangles: the
    /// query of a vertex is not clamped in any grid (the caller checks the
    /// span of its cells, of the shared size), so each grid visits every
    /// triangle of its group whose box is not apart from the query, and
    /// only groups without an admitted triangle or apart from the query
    /// are skipped; the lists are sorted and deduplicated. (A hull ignores
    /// a NaN bound, but lists built at a NaN start are never used: they
    /// do not cover it.)
    fn build_groups(&mut self, group: &dyn Fn(usize) -> usize, cell: f64) {
        for g in &mut self.groups {
            g.faces.clear();
            g.boxes.clear();
        }
        for (f, b) in self.boxes.iter().enumerate() {
            let g = group(f);
            if g >= self.groups.len() {
                self.groups.resize_with(g + 1, Group::default);
            }
            let group = &mut self.groups[g];
            if group.faces.is_empty() {
                group.hull = *b;
            }
            group.hull = (group.hull.0.inf(&b.0), group.hull.1.sup(&b.1));
            group.faces.push(f as u32);
            group.boxes.push(*b);
        }
        for g in &mut self.groups {
            if g.faces.is_empty() {
                // Never queried: apart from everything (NaN compares false,
                // so an inverted infinite hull).
                g.hull = (
                    Point::repeat(f64::INFINITY),
                    Point::repeat(f64::NEG_INFINITY),
                );
            }
            g.grid.build_with_cell(&g.boxes, cell);
        }
    }

    /// Builds the lists at `x_n` with inflation `delta` (m), widening the
    /// triangles by `margin` and the query boxes by `thickness` (m).
    /// Returns whether the lists cover `x_n + dx` ([`Candidates::covers`]);
    /// `false` leaves them invalid (the caller falls back to the grid).
    pub fn build<L, A, Q>(
        &mut self,
        surface: &Surface<'_, L, A, Q>,
        (x_n, dx, on_surface): (&[Point], &[Point], &[usize]),
        (delta, margin, thickness): (f64, f64, f64),
    ) -> bool
    where
        L: Fn(usize) -> bool,
        A: Fn(usize, usize) -> bool,
        Q: Fn(usize, usize) -> bool,
    {
        self.valid = false;
        self.room = None;
        if !delta.is_finite() {
            return false;
        }
        let d = Point::repeat(delta);
        self.bounds.clear();
        self.bounds.extend(x_n.iter().map(|x| (x - d, x + d)));
        self.magnitude = (on_surface.iter())
            .map(|&i| self.bounds[i].0.amax().max(self.bounds[i].1.amax()))
            .fold(0.0, f64::max);
        let m = Point::repeat(margin);
        self.boxes.clear();
        for t in surface.faces {
            let (mut lo, mut hi) = self.bounds[t[0]];
            for &i in t {
                lo = lo.inf(&self.bounds[i].0);
                hi = hi.sup(&self.bounds[i].1);
            }
            self.boxes.push((lo - m, hi + m));
        }
        let cell = cell_size(&self.boxes);
        self.build_groups(surface.group, cell);
        let t = Point::repeat(thickness);
        self.start.clear();
        self.faces.clear();
        self.nonempty.clear();
        for v in 0..x_n.len() {
            self.start.push(self.faces.len() as u32);
            if !(surface.listed)(v) {
                continue;
            }
            let (lo, hi) = (self.bounds[v].0 - t, self.bounds[v].1 + t);
            let (a, b) = (cell_index(&lo, cell), cell_index(&hi, cell));
            // The grid's query visits at most 4 cells per side.
            if (0..3).any(|k| b[k] > a[k].saturating_add(3)) {
                return false;
            }
            let from = self.faces.len();
            let query = (lo, hi);
            for (g, group) in self.groups.iter().enumerate() {
                // A group whose hull is apart from the query holds no
                // triangle that is not.
                if !(surface.queried)(v, g) || apart(&query, &group.hull) {
                    continue;
                }
                let (boxes, faces) = (&group.boxes, &mut self.faces);
                group.grid.query(&lo, &hi, |item| {
                    // The six comparisons of the `any` they replace,
                    // without its short circuit (one branch, not up to
                    // six): the same verdict.
                    let f = group.faces[item];
                    if !apart(&query, &boxes[item]) && (surface.admits)(v, f as usize) {
                        faces.push(f);
                    }
                });
            }
            self.faces[from..].sort_unstable();
            let mut kept = from;
            for k in from..self.faces.len() {
                if k == from || self.faces[k] != self.faces[kept - 1] {
                    self.faces[kept] = self.faces[k];
                    kept += 1;
                }
            }
            self.faces.truncate(kept);
            if kept > from {
                self.nonempty.push(v);
            }
            if self.faces.len() > u32::MAX as usize {
                return false;
            }
        }
        self.start.push(self.faces.len() as u32);
        self.valid = true;
        self.start_covered = self.contains(x_n, on_surface);
        self.covers(x_n, dx, on_surface)
    }
}
