//! Robustness of the state-file reader: `read_state` answers arbitrary
//! bytes and mutated valid state files with `Ok` or an error naming the
//! file, never a panic (docs/design/validation.md, "Robustness").
//!
//! Bounded for CI; `PROPTEST_CASES=N` raises the count for a long run.

mod fuzz_support;

use std::path::Path;

use fuzz_support::{apply, config, mutations, repo_file, scratch_dir};
use pd_io::state::read_state;
use proptest::prelude::*;

/// A small valid state file, and the bundled one (525 vertices).
fn seeds() -> Vec<Vec<u8>> {
    let small = br#"{
  "positions": [[0.0, 0.0, 0.0], [1.0, 0.5, -2.0e-3], [0.25, 1e10, 3]],
  "velocities": [[0.0, 0.0, 0.0], [-1.5, 0.0, 7.0], [0, 0, 0]]
}
"#
    .to_vec();
    let bundled = std::fs::read(repo_file("scenes/states/cantilever_bent.json")).unwrap();
    let test_data = std::fs::read(repo_file("crates/pd-io/tests/data/scenes/state.json")).unwrap();
    vec![small, test_data, bundled]
}

fn check(bytes: &[u8], dir: &Path) {
    let path = dir.join("state.json");
    std::fs::write(&path, bytes).unwrap();
    match read_state(&path) {
        Ok(state) => {
            // Whatever is accepted is what the reader promises.
            let (p, v) = (state.positions_as_points(), state.velocities_as_points());
            assert!(v.is_empty() || v.len() == p.len());
            assert!(p.iter().chain(&v).all(|x| x.iter().all(|c| c.is_finite())));
        }
        Err(e) => {
            let message = e.to_string();
            assert!(
                message.contains("state.json"),
                "error does not name the file: {message}"
            );
        }
    }
}

#[test]
fn seeds_are_valid() {
    let dir = scratch_dir("state-seeds");
    for seed in seeds() {
        let path = dir.join("state.json");
        std::fs::write(&path, &seed).unwrap();
        read_state(&path).unwrap();
    }
}

proptest! {
    #![proptest_config(config(1000))]

    #[test]
    fn arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        check(&bytes, &scratch_dir("state-bytes"));
    }

    #[test]
    fn arbitrary_json_like_text(text in "[-0-9.eE,\\[\\]{}\": a-z\n]{0,200}") {
        check(text.as_bytes(), &scratch_dir("state-text"));
    }

    #[test]
    fn mutated_state_files(seed in any::<proptest::sample::Index>(), edits in mutations(6)) {
        let seeds = seeds();
        check(&apply(&seeds[seed.index(seeds.len())], &edits), &scratch_dir("state-mutated"));
    }
}
