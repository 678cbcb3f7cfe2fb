//! Robustness of the TetGen reader: `read_tetgen` and `read_tetgen_base`
//! answer arbitrary bytes and mutated valid `.node`/`.ele` pairs with `Ok`
//! or an error naming a file, never a panic (docs/design/validation.md,
//! "Robustness").
//!
//! Bounded for CI; `PROPTEST_CASES=N` raises the count for a long run.

mod fuzz_support;

use std::path::Path;

use fuzz_support::{apply, config, mutations, repo_file, scratch_dir};
use pd_io::tetgen::{read_tetgen, read_tetgen_base};
use proptest::prelude::*;

/// Valid `(node, ele)` pairs: the test fixtures (1-based, with markers and
/// region attributes) and a small 0-based pair.
fn seeds() -> Vec<(Vec<u8>, Vec<u8>)> {
    let read = |name: &str| std::fs::read(repo_file(name)).unwrap();
    vec![
        (
            read("crates/pd-io/tests/data/cube.1.node"),
            read("crates/pd-io/tests/data/cube.1.ele"),
        ),
        (
            read("crates/pd-io/tests/data/cube_regions.1.node"),
            read("crates/pd-io/tests/data/cube_regions.1.ele"),
        ),
        (
            read("crates/pd-io/tests/data/scenes/meshes/two_tets.1.node"),
            read("crates/pd-io/tests/data/scenes/meshes/two_tets.1.ele"),
        ),
        (
            b"# a tet\n4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n".to_vec(),
            b"1 4 0\n0 0 1 2 3 # the tet\n".to_vec(),
        ),
    ]
}

fn check(node: &[u8], ele: &[u8], dir: &Path) {
    let (node_path, ele_path) = (dir.join("mesh.node"), dir.join("mesh.ele"));
    std::fs::write(&node_path, node).unwrap();
    std::fs::write(&ele_path, ele).unwrap();
    match read_tetgen(&node_path, &ele_path) {
        Ok(mesh) => {
            // Accepted meshes satisfy the mesh invariants the reader promises.
            let n = mesh.num_vertices();
            assert!(mesh.tets().iter().flatten().all(|&v| v < n));
            assert!(
                mesh.vertices()
                    .iter()
                    .all(|p| p.iter().all(|c| c.is_finite()))
            );
        }
        Err(e) => {
            let message = e.to_string();
            assert!(
                message.contains("mesh.node") || message.contains("mesh.ele"),
                "error does not name a file: {message}"
            );
        }
    }
    let _ = read_tetgen_base(&dir.join("mesh"));
}

#[test]
fn seeds_are_valid() {
    let dir = scratch_dir("tetgen-seeds");
    for (node, ele) in seeds() {
        std::fs::write(dir.join("mesh.node"), node).unwrap();
        std::fs::write(dir.join("mesh.ele"), ele).unwrap();
        read_tetgen_base(&dir.join("mesh")).unwrap();
    }
}

proptest! {
    #![proptest_config(config(1000))]

    #[test]
    fn arbitrary_bytes(
        node in proptest::collection::vec(any::<u8>(), 0..256),
        ele in proptest::collection::vec(any::<u8>(), 0..256),
    ) {
        check(&node, &ele, &scratch_dir("tetgen-bytes"));
    }

    #[test]
    fn arbitrary_numeric_text(
        node in "[-0-9 .e#\n]{0,200}",
        ele in "[-0-9 .e#\n]{0,120}",
    ) {
        check(node.as_bytes(), ele.as_bytes(), &scratch_dir("tetgen-text"));
    }

    #[test]
    fn mutated_meshes(
        seed in any::<proptest::sample::Index>(),
        node_edits in mutations(4),
        ele_edits in mutations(4),
        which in 0u8..3,
    ) {
        let seeds = seeds();
        let (node, ele) = &seeds[seed.index(seeds.len())];
        // Mutate the .node file, the .ele file, or both.
        let node = if which != 1 { apply(node, &node_edits) } else { node.clone() };
        let ele = if which != 0 { apply(ele, &ele_edits) } else { ele.clone() };
        check(&node, &ele, &scratch_dir("tetgen-mutated"));
    }
}
