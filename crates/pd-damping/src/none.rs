//! No damping.

use crate::Damping;

/// The name scenes, the command line and the registry use for this model.
pub const NAME: &str = "none";

/// No damping at all: every default of [`Damping`]. With backward Euler the
/// integrator's own numerical damping remains.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoDamping;

impl Damping for NoDamping {
    fn name(&self) -> &'static str {
        NAME
    }
}
