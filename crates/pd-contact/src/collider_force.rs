//! The forces of collider contacts: one projected Uzawa step
//! ([`update_force`]), the projection onto Coulomb's cone that the pairs
//! between surfaces share ([`coulomb`]), the end-of-step projection onto
//! the contact plane with its friction ([`project_onto_plane`]), and the
//! frozen-force mode of [`ContactState::freeze_forces`], a measurement aid
//! (docs/design/contact.md, "Contact's own cost").

use pd_mesh::Point;

use crate::{Collider, ContactState, Slot};

impl ContactState {
    /// With frozen forces: every contact's force, as it is, into `rhs` (one
    /// point per free vertex).
    pub(super) fn add_frozen_forces(&self, rhs: &mut [Point]) {
        for (slot, &f) in self.slots.iter().zip(&self.free_index) {
            if let (Some(slot), true) = (slot, f != usize::MAX) {
                rhs[f] += slot.force;
            }
        }
        if let Some(bodies) = &self.bodies {
            bodies.add_forces(&self.free_index, rhs);
        }
    }
}

/// One projected Uzawa step of a contact force at the iterate `x`.
#[inline]
pub(super) fn update_force(slot: &Slot, collider: &Collider, x: &Point, rho: f64, h: f64) -> Point {
    let n = slot.hit.normal;
    let anchor = slot.hit.point + collider.velocity(&slot.hit.point) * h;
    let to_anchor = anchor - x;
    let normal_error = slot.lift - n.dot(&(x - slot.hit.point));
    let tangential_error = to_anchor - n * n.dot(&to_anchor);
    let trial = slot.force + (tangential_error + n * normal_error) * rho;
    coulomb(&trial, &n, collider.friction)
}

/// The end-of-step projection ([`ContactState::project`]) of a contact
/// vertex `x` that the iterations left `depth` (m, > 0) behind its contact
/// plane: moved onto the plane along the normal. That move is a normal
/// impulse (`m depth / h`) the contact force did not carry, so it gets
/// Coulomb friction of its own: the vertex's displacement from its anchor
/// along the plane is shortened by at most `friction * depth`, never
/// reversed. Without it, a vertex held by the projection rather than by
/// its force slides without friction (docs/design/contact.md, "Sliding on
/// a curved collider").
#[inline]
pub(super) fn project_onto_plane(
    slot: &Slot,
    collider: &Collider,
    x: &mut Point,
    depth: f64,
    h: f64,
) {
    let n = slot.hit.normal;
    *x += n * depth;
    let anchor = slot.hit.point + collider.velocity(&slot.hit.point) * h;
    let from_anchor = *x - anchor;
    let along = from_anchor - n * n.dot(&from_anchor);
    let length = along.norm();
    if length > 0.0 {
        *x -= along * ((collider.friction * depth).min(length) / length);
    }
}

/// The projection of a trial force onto Coulomb's cone of coefficient
/// `friction` about the unit normal `n`: the normal part clamped at zero,
/// the tangential part scaled down to at most `friction` times it.
pub(super) fn coulomb(trial: &Point, n: &Point, friction: f64) -> Point {
    let normal_force = trial.dot(n).max(0.0);
    let mut tangential = trial - n * trial.dot(n);
    let limit = friction * normal_force;
    let norm = tangential.norm();
    if norm > limit {
        tangential *= if norm > 0.0 { limit / norm } else { 0.0 };
    }
    n * normal_force + tangential
}

impl ContactState {
    /// A measurement aid (docs/design/contact.md, "Contact's own cost"): with
    /// `frozen`, from the next step on every contact keeps its current
    /// force (N times `c1 c2`, the global step's right-hand-side units),
    /// added to every iteration as a constant load, and contact does
    /// nothing else (no start of step, detection, force update,
    /// projection or velocity filter; steps report no contacts). On a body
    /// resting in contact this is a baseline with the same deformation and
    /// iterations, without contact's work; the forces do not balance the
    /// load exactly, so it drifts (0.3 mm in 10 steps on the stacked cubes
    /// of `benches/examples/contact_case.rs`). Freeze after a step, not
    /// after a restore (a restore leaves pairs to be re-anchored by the
    /// next step's start). Without `frozen`, contact runs again.
    pub fn freeze_forces(&mut self, frozen: bool) {
        self.frozen = frozen;
    }
}
