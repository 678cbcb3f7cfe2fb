//! The `contact` key of a checkpoint file: the contacts active at the end
//! of the saved step, with their warm-started forces, so that a resumed run
//! with contact is bit-identical (docs/design/contact.md, "Checkpoints"). JSON
//! numbers round-trip every bit (serde_json writes the shortest exact form).

use pd_solver::contact::{ContactCheckpoint, SavedContact};
use serde::{Deserialize, Serialize};

/// One saved contact: `[vertex, collider or triangle]`, force, normal.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSaved {
    vertex: usize,
    other: usize,
    force: [f64; 3],
    normal: [f64; 3],
    /// Written only when true; files without it load as false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    impact: bool,
}

/// The `contact` table.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawContact {
    colliders: Vec<RawSaved>,
    pairs: Vec<RawSaved>,
}

fn raw(c: &SavedContact) -> RawSaved {
    RawSaved {
        vertex: c.vertex,
        other: c.other,
        force: c.force,
        normal: c.normal,
        impact: c.impact,
    }
}

fn saved(c: &RawSaved) -> SavedContact {
    SavedContact {
        vertex: c.vertex,
        other: c.other,
        force: c.force,
        normal: c.normal,
        impact: c.impact,
    }
}

impl RawContact {
    /// `None` without active contacts (the key is then left out).
    pub(crate) fn of(contact: &ContactCheckpoint) -> Option<Self> {
        (!contact.is_empty()).then(|| Self {
            colliders: contact.colliders.iter().map(raw).collect(),
            pairs: contact.pairs.iter().map(raw).collect(),
        })
    }
}

impl From<RawContact> for ContactCheckpoint {
    fn from(raw: RawContact) -> Self {
        Self {
            colliders: raw.colliders.iter().map(saved).collect(),
            pairs: raw.pairs.iter().map(saved).collect(),
        }
    }
}
