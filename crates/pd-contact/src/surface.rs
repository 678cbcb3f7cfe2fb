//! Turning on contact of the bodies' surfaces: between bodies
//! (`contact.bodies`), within one body (`contact.self`), or both; one
//! vertex-triangle contact state for all of them (`bodies.rs`).

use pd_mesh::Point;

use crate::bodies::{BodyContact, BodySurface};
use crate::{BodyContactSettings, ContactState};

/// Which vertex-triangle pairs of the bodies' surfaces are in contact
/// (docs/design/contact.md): the two combine independently.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SurfacePairs {
    /// A vertex of one body against the surface triangles of every other
    /// body (`contact.bodies = true`).
    pub between_bodies: bool,
    /// A vertex against the surface triangles of its own body, except its
    /// rest neighbours: the triangles within one mean surface edge plus the
    /// thickness of it in the rest configuration (`contact.self = true`).
    pub self_contact: bool,
}

impl ContactState {
    /// Turns on contact of the bodies' surfaces (replacing any earlier):
    /// every vertex of `surfaces` against the triangles of `surfaces`
    /// (one-sided, or two-sided for a cloth) that `pairs` admits, with the
    /// thickness of the contact settings and `settings`' friction
    /// (validated: [`BodyContactSettings::validated`]). `rest` holds every
    /// vertex's rest position (the self-contact neighbourhood's), `masses`
    /// and `fixed` every vertex's mass and whether it is fixed.
    pub fn set_surfaces(
        &mut self,
        surfaces: Vec<BodySurface>,
        rest: &[Point],
        (masses, fixed): (&[f64], &[bool]),
        settings: &BodyContactSettings,
        pairs: SurfacePairs,
    ) {
        let thickness = self.settings.thickness;
        self.bodies = Some(BodyContact::new(
            surfaces,
            rest,
            (masses, fixed),
            (settings.friction, thickness),
            pairs,
        ));
    }
}
