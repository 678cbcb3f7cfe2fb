//! The crates depend on each other as `docs/ARCHITECTURE.md` says, and the
//! computational crates stay free of presentation and file-format
//! dependencies: no plotting, image or serialisation-format crate and no
//! log subscriber may appear in their normal (non-dev) dependency trees.
//! (`serde`'s derive alone would be acceptable, but none of them uses it
//! today; formats live in `pd-io`, pictures in `pd-viz`, logging setup in
//! `pd-cli`.)

use std::process::Command;

const COMPUTATIONAL: [&str; 9] = [
    "pd-mesh",
    "pd-constraints",
    "pd-integrators",
    "pd-damping",
    "pd-solver",
    "pd-linalg",
    "pd-contact",
    "pd-modes",
    "pd-adjoint",
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

/// The direct dependencies of `krate` on other pd crates (normal
/// dependencies, default features), sorted.
fn pd_dependencies(krate: &str) -> Vec<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/../../Cargo.toml");
    let output = Command::new(&cargo)
        .args(["tree", "--offline", "--locked", "-e", "normal"])
        .args(["--depth", "1", "--prefix", "none", "-p", krate])
        .arg("--manifest-path")
        .arg(manifest)
        .output()
        .expect("cargo tree runs");
    assert!(output.status.success(), "cargo tree -p {krate}");
    let mut names: Vec<String> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .skip(1) // the crate itself
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name == "pd" || name.starts_with("pd-"))
        .map(str::to_owned)
        .collect();
    names.sort();
    names.dedup();
    names
}

/// The table "Crates and their dependencies" of `docs/ARCHITECTURE.md`:
/// each crate with the pd crates it depends on.
fn documented_graph() -> Vec<(String, Vec<String>)> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/ARCHITECTURE.md");
    let text = std::fs::read_to_string(path).expect("docs/ARCHITECTURE.md");
    let start = text
        .find("\n## Crates and their dependencies\n")
        .expect("the section");
    let section = &text[start + 1..];
    let section = &section[..section[1..].find("\n## ").map_or(section.len(), |e| e + 1)];
    let names = |cell: &str| -> Vec<String> {
        let mut names: Vec<String> = cell
            .split('`')
            .skip(1)
            .step_by(2)
            .map(str::to_owned)
            .collect();
        names.sort();
        names
    };
    section
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|row| {
            let cells: Vec<&str> = row.split('|').map(str::trim).collect();
            // | crate | concern | depends on |
            (cells[1].trim_matches('`').to_owned(), names(cells[3]))
        })
        .collect()
}

#[test]
fn the_crate_graph_is_the_documented_one() {
    let graph = documented_graph();
    // Every workspace crate has its row (a crate added without one fails).
    assert_eq!(graph.len(), 15, "{graph:?}");
    for (krate, documented) in &graph {
        assert_eq!(
            &pd_dependencies(krate),
            documented,
            "{krate}'s pd dependencies differ from docs/ARCHITECTURE.md"
        );
    }
}
