//! Ignored timing and accuracy probes of the factor, run by hand on a quiet
//! machine (`cargo test --release -p pd-linalg --lib probes -- --ignored
//! --nocapture`): the fit of the solve's cost model
//! ([`super::SUPERNODE_COST`], `calibration.rs`), the solve split into its
//! parts (`solve_profile.rs`), and a single-precision factor's accuracy
//! (`precision.rs`). The design notes quote their output
//! (`docs/design/performance.md`).

mod calibration;
mod precision;
mod solve_profile;
