//! The 64-bit FNV-1a hash (`pd_solver::hash`, re-exported): of a scene file's text in a checkpoint, and of a
//! simulation state's bits, with which the benchmarks and the hash
//! examples check that a change left results bit for bit as they were.
//!
//! ```
//! use pd_io::hash::Fnv1a;
//!
//! let mut h = Fnv1a::new();
//! h.write_bytes(b"a");
//! assert_eq!(h.finish(), 0xaf63_dc4c_8601_ec8c);
//! ```

pub use pd_solver::hash::Fnv1a;

/// FNV-1a over the bits of every position and velocity of `state`
/// (positions first, each vector's x, y, z): two runs with the same hash
/// ended in the same state bit for bit (how a change that must not move
/// results is checked).
pub fn state_hash(state: &pd_solver::State) -> u64 {
    let mut hash = Fnv1a::new();
    for p in state.positions.iter().chain(&state.velocities) {
        for &c in p.iter() {
            hash.write_f64(c);
        }
    }
    hash.finish()
}
