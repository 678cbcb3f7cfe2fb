//! A per-step bound that lets the per-iteration collider test skip the
//! vertices far from every plane collider (docs/design/contact.md, "Detection
//! and the broad phase"), with the verdict of
//! [`crate::ColliderShape::misses`] bit for bit, and the collider
//! pass of an iteration with body contact
//! ([`ContactState::detect_bodies`]).
//!
//! Why it is the same. At the step's start each free vertex without a
//! contact gets its clearance: the least, over the colliders, of the plane
//! gap `n . (x_n - p) - thickness` at `x_n`, computed with the expression
//! of `misses` (so the same value); `-inf` if a collider is not a plane
//! (its test is not bounded here) or the gap is not finite. In an
//! iteration, with `D` the largest `|dx|_inf` of any vertex, the exact gap
//! of the iterate `x_n + dx` is at least the exact gap of `x_n` minus
//! `|n|_1 D`. Rounding: `x_n + dx`, the subtraction of `p`, the dot product
//! and the subtraction of the thickness are each off by at most a few
//! units in the last place of values no larger than `|n|_1 (|x_n| + D +
//! |p|) + thickness` (infinity norms), and so is the start gap: about
//! `11 u` of it in all (`u = 2^-53`, 1.1e-16). [`Clearance::threshold`]
//! adds `1e-12` of it (a factor of about 800 to spare) and takes `|n|_1 D`
//! up by `1e-12` relative for the rounding of its own products. A vertex
//! whose clearance exceeds the threshold therefore has both computed gaps
//! positive: `misses` says yes, and the full test would have skipped it.
//! Non-finite motion (NaN, overflow) gives an infinite threshold: nothing
//! is skipped.

use pd_mesh::Point;

use crate::{ColliderShape, ContactSettings, ContactState, Slot};

/// Relative slack for rounding (see the module's header).
const ROUNDING: f64 = 1e-12;

/// The clearance of each vertex for the current step and what the
/// threshold needs.
#[derive(Debug, Clone, Default)]
pub(super) struct Clearance {
    /// Per vertex: its least plane gap at `x_n` (m); `+inf` for a fixed
    /// vertex, `-inf` for one with a contact or not bounded here (it takes
    /// the full test).
    gap: Vec<f64>,
    /// The largest `|n|_1` of a collider's normal.
    n1: f64,
    /// `max |x_n|_inf` of the free vertices plus `max |p|_inf` of the
    /// planes' points, m: the scale of the rounding.
    scale: f64,
    thickness: f64,
    /// The vertices whose clearance is at most `limit`, in increasing
    /// order: an iteration whose threshold is at most `limit` skips every
    /// other vertex, so it visits these only (docs/design/contact.md,
    /// "Detection and the broad phase").
    near: Vec<usize>,
    limit: f64,
}

/// The step's `limit` is the threshold of this many times the first
/// iteration's motion: the later iterates of a step stay about as far
/// from `x_n` as the first (an iteration beyond it visits every vertex, so
/// the factor only trades the list's length against how often that
/// happens, never a verdict).
const NEAR_MOTION: f64 = 4.0;

impl Clearance {
    /// Takes every vertex's clearance at the step's start `x_n`
    /// (`free_index[v] == usize::MAX` for a fixed vertex) and lists the
    /// vertices near enough to be visited in an iteration whose motion is
    /// up to [`NEAR_MOTION`] times `motion` (m, the first iteration's).
    pub fn take(
        &mut self,
        settings: &ContactSettings,
        (x_n, motion): (&[Point], f64),
        free_index: &[usize],
        slots: &[Option<Slot>],
    ) {
        let thickness = settings.thickness;
        self.thickness = thickness;
        self.n1 = 0.0;
        let mut planes_scale = 0.0_f64;
        let mut all_planes = true;
        for c in &settings.colliders {
            match &c.shape {
                ColliderShape::Plane { point, normal } => {
                    self.n1 = self.n1.max(normal.abs().sum());
                    planes_scale = planes_scale.max(point.amax());
                }
                _ => all_planes = false,
            }
        }
        self.gap.clear();
        let mut scale = 0.0_f64;
        for (v, x) in x_n.iter().enumerate() {
            let clearance = if free_index[v] == usize::MAX {
                f64::INFINITY
            } else if slots[v].is_some() || !all_planes {
                f64::NEG_INFINITY
            } else {
                scale = scale.max(x.amax());
                least_gap(settings, x, thickness)
            };
            self.gap.push(clearance);
        }
        self.scale = scale + planes_scale;
        self.limit = self.threshold(NEAR_MOTION * motion);
        self.near.clear();
        // Allocates at the first step only.
        self.near.reserve(self.gap.len());
        for (v, &gap) in self.gap.iter().enumerate() {
            if gap <= self.limit {
                self.near.push(v);
            }
        }
    }

    /// The vertices an iteration of threshold `threshold` visits: with
    /// `near`, the `k`-th is `near[k]` for `k` below the count, otherwise
    /// `k` itself (every one of `vertices`). A vertex left out has a
    /// clearance above the limit, so above `threshold`: it is skipped
    /// anyway, and the order of the others is the same.
    pub fn visits(&self, threshold: f64, vertices: usize) -> (bool, usize) {
        if threshold <= self.limit {
            (true, self.near.len())
        } else {
            (false, vertices)
        }
    }

    /// The `k`-th vertex visited ([`Clearance::visits`]).
    #[inline]
    pub fn vertex(&self, k: usize, near: bool) -> usize {
        if near { self.near[k] } else { k }
    }

    /// The clearance above which a vertex is skipped in an iteration whose
    /// largest `|dx|_inf` is `motion` (m): infinite if anything is not
    /// finite.
    pub fn threshold(&self, motion: f64) -> f64 {
        let bound = self.n1 * motion * (1.0 + ROUNDING)
            + ROUNDING * (self.n1 * (self.scale + motion) + self.thickness);
        if bound.is_finite() {
            bound
        } else {
            f64::INFINITY
        }
    }

    /// Whether vertex `v` surely misses every collider in an iteration of
    /// threshold `threshold` ([`Clearance::threshold`]).
    #[inline]
    pub fn skips(&self, v: usize, threshold: f64) -> bool {
        self.gap[v] > threshold
    }

    /// Vertex `v` got a contact: it takes the full path from now on.
    pub fn hold(&mut self, v: usize) {
        self.gap[v] = f64::NEG_INFINITY;
    }
}

/// The least plane gap of `x` over the colliders (all planes), with the
/// expression of [`ColliderShape::misses`]; `-inf` if one is not finite
/// (NaN is never skipped).
fn least_gap(settings: &ContactSettings, x: &Point, thickness: f64) -> f64 {
    let mut least = f64::INFINITY;
    for c in &settings.colliders {
        if let ColliderShape::Plane { point, normal } = &c.shape {
            let gap = normal.dot(&(x - point)) - thickness;
            if !gap.is_finite() {
                return f64::NEG_INFINITY;
            }
            least = least.min(gap);
        }
    }
    least
}

/// The largest `|dx|_inf` over all vertices, m; infinite if a value is not
/// finite or a sum of the magnitudes overflows.
///
/// Two points (six values, contiguous) at a time, one accumulator per
/// value, so that the loop runs on pairs of lanes (docs/design/contact.md,
/// "Detection and the broad phase"); a plain comparison rather than `f64::max` (whose NaN
/// rule costs a branch per value): a NaN is caught by the sums. The
/// largest value is the same whatever the grouping (a maximum is exact);
/// a sum is finite only if every value it adds is, so any grouping is
/// conservative (a sum of finite values that overflows, above about
/// `1e308`, may be caught by one grouping and not by another: both answers
/// are bounds of the motion, so the verdicts they give are exact either
/// way).
pub(super) fn largest_motion(dx: &[Point]) -> f64 {
    let (mut largest, mut sum) = ([0.0_f64; 6], [0.0_f64; 6]);
    let mut pairs = dx.chunks_exact(2);
    for p in &mut pairs {
        let values = [p[0][0], p[0][1], p[0][2], p[1][0], p[1][1], p[1][2]];
        for k in 0..6 {
            let a = values[k].abs();
            largest[k] = if a > largest[k] { a } else { largest[k] };
            sum[k] += a;
        }
    }
    for d in pairs.remainder() {
        for k in 0..3 {
            let a = d[k].abs();
            largest[k] = if a > largest[k] { a } else { largest[k] };
            sum[k] += a;
        }
    }
    if sum.iter().sum::<f64>().is_finite() {
        largest.iter().fold(0.0, |m: f64, &a| m.max(a))
    } else {
        f64::INFINITY
    }
}

impl ContactState {
    /// With contact between bodies: detects the new collider contacts of
    /// every free vertex, then the new vertex-triangle pairs, and counts
    /// every vertex's contacts (the Uzawa steps are shared by them).
    /// `threshold` is the clearance above which a vertex surely misses
    /// ([`Clearance::threshold`] of `motion`, the largest
    /// `|dx|_inf`, m).
    pub(super) fn detect_bodies(
        &mut self,
        x_n: &[Point],
        dx: &[Point],
        (motion, threshold): (f64, f64),
    ) {
        self.occupied.clear();
        let (near, count) = self.clearance.visits(threshold, x_n.len());
        for k in 0..count {
            let v = self.clearance.vertex(k, near);
            if self.clearance.skips(v, threshold) || self.free_index[v] == usize::MAX {
                continue;
            }
            if self.slots[v].is_some() {
                self.occupied.push(v);
                continue;
            }
            let (a, b) = (x_n[v], x_n[v] + dx[v]);
            // The slot is empty: written only when a contact is found.
            if !self.misses_all(&a, &b)
                && let Some(slot) = self.detect(v, &a, &b)
            {
                self.slots[v] = Some(slot);
                self.clearance.hold(v);
                self.occupied.push(v);
            }
        }
        // `occupied` holds every vertex with a slot: fixed vertices never
        // get one, and a vertex with a slot is never skipped (its
        // clearance is `-inf`).
        if let Some(bodies) = &mut self.bodies {
            let thickness = self.settings.thickness;
            bodies.detect(x_n, dx, (thickness, motion), &self.occupied);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Collider;

    /// A skipped vertex is one the full test misses, over random planes,
    /// start points near them and motions up to and past the bound (the
    /// bound is tight: some vertices just past it do hit).
    #[test]
    fn a_skipped_vertex_misses_every_plane() {
        let mut seed = 7_u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let (mut skipped, mut near_hits, mut shortened) = (0, 0, 0);
        for _ in 0..400 {
            let plane = |next: &mut dyn FnMut() -> f64| {
                let normal = Point::new(next(), next(), next()).normalize();
                let point = Point::new(next(), next(), next()) * 0.5;
                Collider {
                    shape: ColliderShape::Plane { point, normal },
                    friction: 0.0,
                    restitution: 0.0,
                }
            };
            let settings = ContactSettings {
                colliders: vec![plane(&mut next), plane(&mut next)],
                thickness: 0.01 * (1.0 + next()),
            };
            let x_n: Vec<Point> = (0..50)
                .map(|_| Point::new(next(), next(), next()))
                .collect();
            let free_index: Vec<usize> = (0..50).collect();
            let motion = 0.2 * (1.0 + next());
            let dx: Vec<Point> = (0..50)
                .map(|_| Point::new(next(), next(), next()) * motion)
                .collect();
            // The step's first motion from 0.1 to 0.5 of this one's: the
            // near list serves about three iterations in four.
            let first = largest_motion(&dx) * (0.3 + 0.2 * next());
            let mut clearance = Clearance::default();
            clearance.take(&settings, (&x_n, first), &free_index, &vec![None; 50]);
            let threshold = clearance.threshold(largest_motion(&dx));
            // The visited vertices, in increasing order, hold every vertex
            // not skipped.
            let (near, count) = clearance.visits(threshold, 50);
            let visited: Vec<usize> = (0..count).map(|k| clearance.vertex(k, near)).collect();
            assert!(visited.windows(2).all(|w| w[0] < w[1]));
            let kept = |v: &&usize| !clearance.skips(**v, threshold);
            let unskipped: Vec<usize> = (0..50).filter(|v| kept(&v)).collect();
            assert_eq!(
                visited.iter().filter(kept).copied().collect::<Vec<_>>(),
                unskipped
            );
            shortened += usize::from(count < 50);
            for v in 0..50 {
                let (a, b) = (x_n[v], x_n[v] + dx[v]);
                let misses =
                    (settings.colliders.iter()).all(|c| c.shape.misses(&a, &b, settings.thickness));
                if clearance.skips(v, threshold) {
                    skipped += 1;
                    assert!(misses, "vertex {v} skipped but hits");
                } else if !misses && clearance.gap[v] > 0.5 * threshold {
                    near_hits += 1;
                }
            }
        }
        println!("{skipped} skipped, {near_hits} near hits, {shortened} shortened");
        assert!(
            skipped > 1000 && near_hits > 10 && shortened > 100,
            "{skipped} skipped, {near_hits}, {shortened}"
        );
    }

    /// The motion bound is the largest magnitude of any coordinate, for
    /// odd and even counts and wherever the largest sits, and infinite
    /// for a NaN or an infinity anywhere (a grouping that dropped one
    /// lane, or compared instead of summing, fails here).
    #[test]
    fn largest_motion_is_the_largest_magnitude() {
        let mut seed = 11_u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        for n in 0..9 {
            let dx: Vec<Point> = (0..n)
                .map(|_| Point::new(next(), next(), next()) * 1e-3)
                .collect();
            let plain = (dx.iter().flat_map(|p| p.iter())).fold(0.0_f64, |m, &a| m.max(a.abs()));
            assert_eq!(largest_motion(&dx), plain, "{n} points");
            for v in 0..n {
                for k in 0..3 {
                    for (value, expected) in [
                        (-0.5, 0.5),
                        (f64::NAN, f64::INFINITY),
                        (f64::NEG_INFINITY, f64::INFINITY),
                    ] {
                        let mut moved = dx.clone();
                        moved[v][k] = value;
                        assert_eq!(largest_motion(&moved), expected, "{n} {v} {k} {value}");
                    }
                }
            }
        }
    }

    /// Non-finite motion skips nothing; a fixed vertex is skipped.
    #[test]
    fn nan_motion_skips_nothing() {
        let settings = ContactSettings {
            colliders: vec![Collider {
                shape: ColliderShape::Plane {
                    point: Point::zeros(),
                    normal: Point::y(),
                },
                friction: 0.0,
                restitution: 0.0,
            }],
            thickness: 0.0,
        };
        let x_n = vec![Point::new(0.0, 1.0, 0.0); 2];
        let mut clearance = Clearance::default();
        clearance.take(&settings, (&x_n, 0.0), &[0, usize::MAX], &[None, None]);
        let dx = vec![Point::zeros(), Point::new(0.0, f64::NAN, 0.0)];
        assert_eq!(largest_motion(&dx), f64::INFINITY);
        assert!(!clearance.skips(0, clearance.threshold(largest_motion(&dx))));
        assert!(clearance.skips(0, clearance.threshold(0.5)));
        assert!(!clearance.skips(0, clearance.threshold(1.5)));
        assert!(clearance.skips(1, clearance.threshold(0.5)));
    }
}
