//! The computational crates stay free of presentation and file-format
//! dependencies: no plotting, image or serialisation-format crate and no
//! log subscriber may appear in their normal (non-dev) dependency trees.
//! (`serde`'s derive alone would be acceptable, but none of them uses it
//! today; formats live in `pd-io`, pictures in `pd-viz`, logging setup in
//! `pd-cli`.)

use std::process::Command;

const COMPUTATIONAL: [&str; 5] = [
    "pd-mesh",
    "pd-constraints",
    "pd-integrators",
    "pd-damping",
    "pd-solver",
];

const FORBIDDEN: [&str; 15] = [
    "plotters",
    "plotters-bitmap",
    "plotters-svg",
    "tiny-skia",
    "png",
    "gif",
    "image",
    "ab_glyph",
    "serde_json",
    "toml",
    "serde_yaml",
    "ron",
    "bincode",
    "tracing-subscriber",
    "pd-viz",
];

/// The crate names in `cargo tree -e normal -p krate`, the crate first.
fn dependencies(krate: &str) -> Vec<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/../../Cargo.toml");
    let output = Command::new(&cargo)
        .args([
            "tree",
            "--offline",
            "--locked",
            "-e",
            "normal",
            "--prefix",
            "none",
            "-p",
        ])
        .arg(krate)
        .arg("--manifest-path")
        .arg(manifest)
        .output()
        .expect("cargo tree runs");
    assert!(
        output.status.success(),
        "cargo tree -p {krate}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let names: Vec<String> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .collect();
    // The tree lists the crate itself first: a check of the parse.
    assert_eq!(names.first().map(String::as_str), Some(krate), "{names:?}");
    names
}

#[test]
fn computational_crates_do_not_depend_on_formats_or_pictures() {
    for krate in COMPUTATIONAL {
        let names = dependencies(krate);
        for name in &names {
            assert!(
                !FORBIDDEN.contains(&name.as_str()),
                "{krate} depends on {name}: {names:?}"
            );
        }
    }
}

#[test]
fn the_check_sees_forbidden_crates_where_they_are() {
    // A positive control: the picture crate does depend on some.
    let names = dependencies("pd-viz");
    for expected in ["plotters", "png", "gif"] {
        assert!(names.iter().any(|n| n == expected), "{names:?}");
    }
}
