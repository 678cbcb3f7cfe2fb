//! Robustness of the scene parser: `Scene::load` and `Scene::parse` answer
//! arbitrary bytes and mutated valid scenes (TOML and JSON) with `Ok` or an
//! error, never a panic (docs/design/validation.md, "Robustness").
//!
//! Bounded for CI (a second or so per target in the dev profile);
//! `PROPTEST_CASES=N` raises the count for a long run.

mod fuzz_support;

use std::path::Path;

use fuzz_support::{apply, config, mutations, repo_file, scratch_dir};
use pd_io::scene::{Scene, Syntax};
use proptest::prelude::*;

/// Every valid scene the repository ships, with its syntax.
fn seeds() -> Vec<(Vec<u8>, Syntax)> {
    [
        "scenes/cantilever.toml",
        "scenes/cantilever_release.toml",
        "scenes/spinning_body.toml",
        "crates/pd-io/tests/data/scenes/contract.toml",
        "crates/pd-io/tests/data/scenes/contract.json",
        "crates/pd-io/tests/data/scenes/tetgen_mesh.toml",
    ]
    .iter()
    .map(|name| {
        let path = repo_file(name);
        let text = std::fs::read(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        (text, Syntax::of(&path))
    })
    .collect()
}

/// The seeds parse, so the mutations start from valid input.
#[test]
fn seeds_are_valid() {
    for (text, syntax) in seeds() {
        let text = String::from_utf8(text).unwrap();
        Scene::parse(&text, syntax, Path::new("seed")).unwrap();
    }
}

/// Parses `bytes` both from a file (any bytes: `load` must reject
/// non-UTF-8 with an error) and, when they are UTF-8, as text in both
/// syntaxes. Errors must name the file.
fn check(bytes: &[u8], dir: &Path) {
    for (name, syntax) in [("scene.toml", Syntax::Toml), ("scene.json", Syntax::Json)] {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        if let Err(e) = Scene::load(&path) {
            let message = e.to_string();
            assert!(
                message.contains(name),
                "error does not name the file: {message}"
            );
        }
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = Scene::parse(text, syntax, &path);
        }
    }
}

proptest! {
    #![proptest_config(config(1000))]

    #[test]
    fn arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        check(&bytes, &scratch_dir("scene-bytes"));
    }

    #[test]
    fn arbitrary_text(text in "[ -~\n\t\\[\\]{}=\"#]{0,300}") {
        check(text.as_bytes(), &scratch_dir("scene-text"));
    }

    #[test]
    fn mutated_scenes(seed in any::<proptest::sample::Index>(), edits in mutations(6)) {
        let seeds = seeds();
        let (text, _) = &seeds[seed.index(seeds.len())];
        check(&apply(text, &edits), &scratch_dir("scene-mutated"));
    }
}
