//! The part of [`BodyContact`] that computes a pair's force: the Uzawa
//! step of a pair ([`BodyContact::apply`]'s force update), its step size's
//! compliance, kept while the contact counts it depends on do not change
//! (docs/design/contact.md, "Contact's own cost"), and the scatter of a
//! pair's force into the right-hand side.

use pd_mesh::Point;

use super::{BodyContact, Pair};
use crate::collider_force::coulomb;

impl BodyContact {
    /// [`BodyContact::compliance`] with the contact counts (`shared`) of
    /// vertex `v`'s pair: taken again only when the count of one of its
    /// four vertices changed since the last time in this step. Its other
    /// inputs (masses, fixed vertices, the pair's triangle and weights)
    /// are constant while the pair lives, and a pair is made only at a
    /// step's start, a restore (both clear the stored values) or, for a
    /// vertex that had none, by detection: so the value is the one
    /// `compliance` would return, bit for bit, without its four divisions.
    pub(super) fn shared_compliance(&mut self, v: usize, tri: &[usize; 3], w: &[f64; 3]) -> f64 {
        let counts = [
            self.count[v],
            self.count[tri[0]],
            self.count[tri[1]],
            self.count[tri[2]],
        ];
        if let Some((stored, value)) = self.compliances[v]
            && stored == counts
        {
            return value;
        }
        let value = self.compliance(v, tri, w, true);
        self.compliances[v] = Some((counts, value));
        value
    }

    /// One projected Uzawa step of a pair's force at relative position `r`.
    pub(super) fn update_force(&self, pair: &Pair, r: &Point, rho: f64, thickness: f64) -> Point {
        let n = pair.normal;
        let normal_error = thickness - n.dot(r);
        let tangential_error = -(r - n * n.dot(r));
        let trial = pair.force + (tangential_error + n * normal_error) * rho;
        coulomb(&trial, &n, self.friction)
    }

    /// Every pair's force as it is into `rhs` at the free vertices
    /// (`free_index`): `f` at the vertex, `-w_i f` at the triangle's.
    pub(crate) fn add_forces(&self, free_index: &[usize], rhs: &mut [Point]) {
        for (v, pair) in self.pairs.iter().enumerate() {
            let Some(pair) = pair else { continue };
            let tri = self.faces[pair.face].vertices;
            add_pair_force(free_index, rhs, v, &tri, (&pair.weights, pair.force));
        }
    }
}

/// A pair's force `force` into `rhs` at the free vertices (`free_index`):
/// `f` at vertex `v`, `-w_i f` at the triangle `tri`'s vertices (weights
/// `w`).
pub(super) fn add_pair_force(
    free_index: &[usize],
    rhs: &mut [Point],
    v: usize,
    tri: &[usize; 3],
    (weights, force): (&[f64; 3], Point),
) {
    let mut add = |i: usize, f: Point| {
        if free_index[i] != usize::MAX {
            rhs[free_index[i]] += f;
        }
    };
    add(v, force);
    for (&i, &w) in tri.iter().zip(weights) {
        add(i, -force * w);
    }
}

/// `sum_k p_k w_k` with the operations of the iterator sum
/// `(0..3).map(|k| p[k] * w[k]).sum::<Point>()` (nalgebra's `Sum` folds
/// from zero: `((0 + a) + b) + c`, the `0 +` kept: it turns a `-0` into
/// `+0`), written out so that it is inlined.
#[inline]
pub(super) fn weighted(p: [Point; 3], w: &[f64; 3]) -> Point {
    Point::zeros() + p[0] * w[0] + p[1] * w[1] + p[2] * w[2]
}
