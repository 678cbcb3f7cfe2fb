//! What contact refuses: settings out of their domain, and checkpoints
//! that do not fit the contact state.

/// An error of contact's settings or of a checkpoint's contacts. The
/// solver reports both as its own invalid-model and invalid-checkpoint
/// errors with the same `reason`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ContactError {
    /// A contact setting is out of its domain, naming it
    /// (`collider[2].normal: zero vector`).
    #[error("invalid contact settings: {reason}")]
    InvalidSettings {
        /// The setting and what is wrong with it.
        reason: String,
    },
    /// A checkpoint's contacts do not fit this contact state.
    #[error("invalid contact checkpoint: {reason}")]
    InvalidCheckpoint {
        /// What is wrong.
        reason: String,
    },
}

impl ContactError {
    /// What is wrong, without the kind of error.
    pub fn reason(&self) -> &str {
        match self {
            ContactError::InvalidSettings { reason }
            | ContactError::InvalidCheckpoint { reason } => reason,
        }
    }
}
