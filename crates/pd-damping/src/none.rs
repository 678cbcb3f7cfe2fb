//! No damping.

use crate::Damping;

/// No damping at all: every default of [`Damping`]. With backward Euler the
/// integrator's own numerical damping remains.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoDamping;

impl Damping for NoDamping {
    fn name(&self) -> &'static str {
        "none"
    }
}
