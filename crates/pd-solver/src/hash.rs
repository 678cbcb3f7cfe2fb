//! The 64-bit FNV-1a hash, the one hash of the workspace: of a model in its
//! fingerprint ([`crate::Model::fingerprint`]), and, through `pd_io::hash`,
//! of a scene file's text in a checkpoint and of a simulation state's bits.
//!
//! ```
//! use pd_solver::hash::Fnv1a;
//!
//! let mut h = Fnv1a::new();
//! h.write_bytes(b"a");
//! assert_eq!(h.finish(), 0xaf63_dc4c_8601_ec8c);
//! ```

/// A running 64-bit FNV-1a hash. It detects accidental edits and damage,
/// not deliberate tampering.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv1a(u64);

impl Fnv1a {
    /// The FNV-1a offset basis.
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    /// The 64-bit FNV prime.
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    /// The hash of nothing.
    pub fn new() -> Self {
        Self(Self::OFFSET)
    }

    /// Hashes `bytes`, in order.
    pub fn write_bytes(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.0 = (self.0 ^ u64::from(byte)).wrapping_mul(Self::PRIME);
        }
    }

    /// Hashes the bits of `value`, little-endian.
    pub fn write_f64(&mut self, value: f64) {
        self.write_bytes(&value.to_bits().to_le_bytes());
    }

    /// The hash of everything written so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

impl Default for Fnv1a {
    fn default() -> Self {
        Self::new()
    }
}
