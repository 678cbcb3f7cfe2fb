//! Matrices and meshes the tests and the ignored timing probes share: the
//! pattern of a tet mesh's vertex graph, `I + graph Laplacian` on it, its
//! factor, and the TetGen armadillo beside the repository.

use crate::Point;
use crate::cholesky::{LowerPattern, NumericFactor, SymbolicFactor, dissection_candidates};

/// The lower pattern of a tet mesh's vertex graph (what the global matrix of
/// tet strain has), diagonal included.
pub(crate) fn tet_pattern(mesh: &pd_mesh::Mesh) -> LowerPattern {
    let n = mesh.num_vertices();
    let mut columns: Vec<Vec<usize>> = (0..n).map(|c| vec![c]).collect();
    for tet in mesh.tets() {
        for &a in tet {
            for &b in tet {
                if a > b {
                    columns[b].push(a);
                }
            }
        }
    }
    let (mut col_ptr, mut row_idx) = (vec![0], Vec::new());
    for mut column in columns {
        column.sort_unstable();
        column.dedup();
        row_idx.extend(column);
        col_ptr.push(row_idx.len());
    }
    LowerPattern {
        n,
        col_ptr,
        row_idx,
    }
}

/// Values of `I + graph Laplacian` on `pattern`: symmetric positive definite.
pub(crate) fn laplacian_values(p: &LowerPattern) -> Vec<f64> {
    let mut degree = vec![1.0; p.n];
    for c in 0..p.n {
        for &r in &p.row_idx[p.col_ptr[c]..p.col_ptr[c + 1]] {
            if r != c {
                degree[r] += 1.0;
                degree[c] += 1.0;
            }
        }
    }
    let mut values = vec![-1.0; p.row_idx.len()];
    for c in 0..p.n {
        values[p.col_ptr[c]] = degree[c]; // rows sorted: the diagonal first
    }
    values
}

/// `mesh`'s tet pattern analysed as pd analyses it (AMD against the
/// dissection candidates) and factorised with [`laplacian_values`].
pub(crate) fn laplacian_factor(mesh: &pd_mesh::Mesh) -> (SymbolicFactor, NumericFactor) {
    let pattern = tet_pattern(mesh);
    let candidates = dissection_candidates(&pattern, mesh.vertices());
    let mut factor = SymbolicFactor::analyse(pattern, &candidates).unwrap();
    let values = laplacian_values(factor.pattern());
    let numeric = factor.factorise(&values).expect("diagonally dominant");
    (factor, numeric)
}

/// The TetGen armadillo (`../shared/meshes/armadillo/armadillo.node` and
/// `.ele` beside the repository), or `None` (with a line saying so) when it
/// is absent. A test fixture only: it reads the two files' numbers without
/// the checks of pd-io's TetGen reader, which depends on this crate.
pub(crate) fn armadillo() -> Option<pd_mesh::Mesh> {
    let base = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/meshes/armadillo/armadillo");
    let read = |extension: &str| -> Option<Vec<Vec<f64>>> {
        let path = base.with_extension(extension);
        let text = std::fs::read_to_string(&path)
            .map_err(|e| println!("armadillo skipped: {}: {e}", path.display()))
            .ok()?;
        Some(
            text.lines()
                .map(|line| line.split('#').next().unwrap_or(""))
                .filter(|line| !line.trim().is_empty())
                .skip(1) // the header
                .map(|line| {
                    line.split_whitespace()
                        .map(|f| f.parse().unwrap())
                        .collect()
                })
                .collect(),
        )
    };
    let (nodes, elements) = (read("node")?, read("ele")?);
    let first = nodes.first()?[0] as usize; // 0- or 1-based numbering
    let vertices = nodes.iter().map(|r| Point::new(r[1], r[2], r[3])).collect();
    let tets = elements
        .iter()
        .map(|r| std::array::from_fn(|k| r[1 + k] as usize - first))
        .collect();
    Some(pd_mesh::Mesh::from_tets(vertices, tets).unwrap())
}
