//! Turning on contact of the bodies' surfaces: between bodies
//! (`contact.bodies`), within one body (`contact.self`), or both; one
//! vertex-triangle contact state for all of them (`bodies.rs`).

use super::{BodyContactSettings, ContactSettings, bodies};
use crate::SolverError;

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

impl crate::Simulation {
    /// Turns on contact of the bodies' surfaces: every surface vertex of a
    /// body (vertices of tet boundary faces, of cloth triangles) against
    /// the surface triangles (tet boundary faces, one-sided; cloth
    /// triangles, two-sided) that `pairs` admits, with the thickness of the
    /// contact settings (contact with no collider and zero thickness is
    /// turned on if [`Simulation::set_contact`](crate::Simulation::set_contact)
    /// was not called). Call it after `set_contact`, which replaces it.
    /// With neither kind of pair it does nothing.
    ///
    /// # Errors
    /// A negative or non-finite friction (`contact.friction`), or a
    /// position solver that cannot run with contact.
    pub fn set_surface_contact(
        &mut self,
        settings: BodyContactSettings,
        pairs: SurfacePairs,
    ) -> Result<(), SolverError> {
        if !(settings.friction.is_finite() && settings.friction >= 0.0) {
            return Err(SolverError::InvalidModel {
                reason: "contact.friction: must be finite and >= 0".into(),
            });
        }
        if !(pairs.between_bodies || pairs.self_contact) {
            return Ok(());
        }
        if self.contact.is_none() {
            self.set_contact(ContactSettings::default())?;
        }
        let surfaces = self
            .model
            .bodies()
            .iter()
            .map(|b| bodies::BodySurface {
                triangles: (b.mesh.surface_triangles().iter())
                    .map(|t| t.map(|v| v + b.offset))
                    .collect(),
                two_sided: b.mesh.tets().is_empty(),
            })
            .collect();
        let model = &self.model;
        if let Some(contact) = &mut self.contact {
            let thickness = contact.settings.thickness;
            contact.bodies = Some(bodies::BodyContact::new(
                surfaces,
                model.rest_positions(),
                (model.masses(), model.fixed()),
                (settings.friction, thickness),
                pairs,
            ));
        }
        Ok(())
    }
}
