//! What contact carries from one step to the next, for checkpoints: the
//! warm-started forces of the contacts active at the end of a step (docs/design/contact.md,
//! "Checkpoints").

use pd_mesh::Point;

use crate::bodies::Pair;
use crate::geometry::Hit;
use crate::{ContactError, ContactState, Slot};

/// One contact active at the end of a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SavedContact {
    /// The vertex (global index).
    pub vertex: usize,
    /// The collider's index (collider contacts) or the surface triangle's
    /// index among all bodies' surface triangles (contacts between bodies).
    pub other: usize,
    /// The warm-started force, in the right-hand side's units (`A dx`).
    pub force: [f64; 3],
    /// The contact normal (unit).
    pub normal: [f64; 3],
    /// A collider contact that began in the saved step as an impact
    /// without restitution: the next step still belongs to the impact
    /// ([`ContactState::stopped`]). Always `false` between bodies.
    pub impact: bool,
}

/// The contact state a checkpoint carries: empty without contact.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ContactCheckpoint {
    /// Active contacts with colliders.
    pub colliders: Vec<SavedContact>,
    /// Active contacts between bodies.
    pub pairs: Vec<SavedContact>,
}

impl ContactCheckpoint {
    /// Whether it holds no contact.
    pub fn is_empty(&self) -> bool {
        self.colliders.is_empty() && self.pairs.is_empty()
    }
}

fn saved(vertex: usize, other: usize, force: &Point, normal: &Point) -> SavedContact {
    SavedContact {
        vertex,
        other,
        force: (*force).into(),
        normal: (*normal).into(),
        impact: false,
    }
}

impl ContactState {
    /// The contacts that the next step keeps (the active ones).
    pub fn save(&self) -> ContactCheckpoint {
        let colliders = (self.slots.iter().enumerate())
            .filter_map(|(v, s)| s.filter(Slot::active).map(|s| (v, s)))
            .map(|(v, s)| SavedContact {
                impact: s.impact && !s.warm,
                ..saved(v, s.collider, &s.force, &s.hit.normal)
            })
            .collect();
        let pairs = self.bodies.as_ref().map_or_else(Vec::new, |b| {
            (b.pairs.iter().enumerate())
                .filter_map(|(v, p)| p.filter(Pair::active).map(|p| (v, p)))
                .map(|(v, p)| saved(v, p.face, &p.force, &p.normal))
                .collect()
        });
        ContactCheckpoint { colliders, pairs }
    }

    /// Replaces the contacts by the saved ones.
    ///
    /// # Errors
    /// A vertex, collider or triangle out of range, a non-finite value, or
    /// contacts between bodies for a simulation without them; the state is
    /// then unchanged.
    pub fn load(&mut self, saved: &ContactCheckpoint) -> Result<(), ContactError> {
        let n = self.slots.len();
        let faces = self.bodies.as_ref().map_or(0, |b| b.faces());
        let check = |what: &str, c: &SavedContact, others: usize| {
            let invalid = |reason| Err(ContactError::InvalidCheckpoint { reason });
            if c.vertex >= n || c.other >= others {
                return invalid(format!(
                    "contact {what}: vertex {} or index {} out of range",
                    c.vertex, c.other
                ));
            }
            if !c.force.iter().chain(&c.normal).all(|x| x.is_finite()) {
                return invalid(format!("contact {what}: a non-finite value"));
            }
            Ok(())
        };
        let colliders = self.settings.colliders.len();
        for c in &saved.colliders {
            check("with a collider", c, colliders)?;
        }
        for c in &saved.pairs {
            check("between bodies", c, faces)?;
        }
        self.slots.iter_mut().for_each(|s| *s = None);
        for c in &saved.colliders {
            self.slots[c.vertex] = Some(Slot {
                collider: c.other,
                hit: Hit {
                    t: 0.0,
                    point: Point::zeros(),
                    normal: Point::from(c.normal),
                },
                force: Point::from(c.force),
                lift: 0.0,
                bounce: 0.0,
                // As if just detected, so that `begin_step` carries it on.
                impact: c.impact,
                projected: false,
                warm: !c.impact,
            });
        }
        if let Some(bodies) = &mut self.bodies {
            bodies.load(&saved.pairs);
        }
        Ok(())
    }
}
