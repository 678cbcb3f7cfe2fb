//! Contact (docs/design/contact.md), with the `contact` feature: its items
//! are pd-contact's, re-exported here, and a [`Simulation`] turns it on
//! and holds its [`ContactState`], whose hooks the step calls (start of
//! step, every iteration's right-hand side, end of step, velocity filter,
//! checkpoints). Contact's errors become [`SolverError`]s with the same
//! reason: invalid settings an `InvalidModel`, an unfitting checkpoint an
//! `InvalidState`.

pub use pd_contact::*;

use crate::{Simulation, SolverError};

impl From<ContactError> for SolverError {
    fn from(error: ContactError) -> Self {
        let reason = error.reason().to_owned();
        match error {
            ContactError::InvalidCheckpoint { .. } => SolverError::InvalidState { reason },
            _ => SolverError::InvalidModel { reason },
        }
    }
}

impl Simulation {
    /// Turns on contact with `settings`' colliders (replacing any earlier
    /// contact settings). A simulation without it runs no contact code.
    ///
    /// # Errors
    /// An invalid value ([`ContactSettings::validated`]).
    pub fn set_contact(&mut self, settings: ContactSettings) -> Result<(), SolverError> {
        self.check_solver_handles_contact()?;
        let settings = settings.validated()?;
        self.contact = Some(ContactState::new(
            settings,
            self.state.positions.len(),
            self.global.free(),
        ));
        Ok(())
    }

    /// Caps the memory the collider contacts' Delassus solve (the contact
    /// solve of a step with an accuracy target) may hold in one step at
    /// `bytes` ([`DEFAULT_DELASSUS_MEMORY`] by default); a step whose
    /// contacts would need more takes one projected Uzawa step per contact
    /// and iteration instead and says so in
    /// [`crate::StepStats::contact_solve_fallback`]. Call it after
    /// [`Simulation::set_contact`], which resets it.
    ///
    /// # Errors
    /// [`SolverError::InvalidSetting`] without contact.
    pub fn set_delassus_memory(&mut self, bytes: usize) -> Result<(), SolverError> {
        let Some(contact) = &mut self.contact else {
            return Err(SolverError::InvalidSetting {
                field: "contact",
                reason: "set_delassus_memory needs contact (set_contact first)".into(),
            });
        };
        contact.set_delassus_memory(bytes);
        Ok(())
    }

    /// Turns on contact between bodies: every vertex of a body's surface
    /// against the surface triangles (tet boundary faces; cloth triangles,
    /// two-sided) of every other body, with the thickness of the contact
    /// settings (contact with no collider and zero thickness is turned on
    /// if [`Simulation::set_contact`](crate::Simulation::set_contact) was
    /// not called). Call it after `set_contact`, which replaces it.
    ///
    /// # Errors
    /// A negative or non-finite friction (`contact.friction`), or a
    /// position solver that cannot run with contact.
    pub fn set_body_contact(&mut self, settings: BodyContactSettings) -> Result<(), SolverError> {
        let between = SurfacePairs {
            between_bodies: true,
            self_contact: false,
        };
        self.set_surface_contact(settings, between)
    }

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
        let settings = settings.validated()?;
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
            .map(|b| BodySurface {
                triangles: (b.mesh.surface_triangles().iter())
                    .map(|t| t.map(|v| v + b.offset))
                    .collect(),
                two_sided: b.mesh.tets().is_empty(),
            })
            .collect();
        let model = &self.model;
        if let Some(contact) = &mut self.contact {
            let (rest, masses, fixed) = (model.rest_positions(), model.masses(), model.fixed());
            contact.set_surfaces(surfaces, rest, (masses, fixed), &settings, pairs);
        }
        Ok(())
    }

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
    /// next step's start). Without `frozen`, contact runs again. Returns
    /// `false` (and does nothing) if contact is off.
    pub fn freeze_contact_forces(&mut self, frozen: bool) -> bool {
        match &mut self.contact {
            Some(contact) => {
                contact.freeze_forces(frozen);
                true
            }
            None => false,
        }
    }

    /// `Unsupported` if the position solver cannot run with colliders
    /// ([`crate::PositionSolver::handles_contact`]).
    pub(crate) fn check_solver_handles_contact(&self) -> Result<(), SolverError> {
        if self.position_solver.handles_contact() {
            return Ok(());
        }
        Err(SolverError::Unsupported {
            what: format!(
                "the {} position solver with colliders: contact forces are not part of the step \
                 objective it judges iterates by; use local-global (docs/design/contact.md)",
                self.position_solver.name()
            ),
        })
    }

    /// The contact settings, if contact is on.
    pub fn contact(&self) -> Option<&ContactSettings> {
        self.contact.as_ref().map(ContactState::settings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Contact's errors read as the solver's own, with the same reason.
    #[test]
    fn contact_errors_keep_their_reason() {
        let settings = ContactError::InvalidSettings {
            reason: "contact.thickness: must be finite and >= 0".into(),
        };
        assert_eq!(
            SolverError::from(settings).to_string(),
            "invalid model: contact.thickness: must be finite and >= 0"
        );
        let checkpoint = ContactError::InvalidCheckpoint {
            reason: "contact with a collider: a non-finite value".into(),
        };
        assert_eq!(
            SolverError::from(checkpoint).to_string(),
            "invalid state: contact with a collider: a non-finite value"
        );
    }
}
