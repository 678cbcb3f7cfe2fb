//! Assembly of the rest stiffness `K` for the sparse eigensolvers: the
//! pattern from the constraint stencils (every pair of free vertices that
//! share a constraint gives a 3 x 3 block), then each element Hessian added
//! into its slots in element order. The triplet sort of the dense path
//! (`assemble` in `lib.rs`, kept there so that small models keep their
//! bits) cost about as much as the factorisation on the test beams; this
//! costs one pass over the Hessians and a binary search per vertex pair.
//! Entries that end exactly zero off the diagonal are dropped, as the
//! triplet assembly never stores them.

use pd_constraints::ConstraintBlock;

use super::Stiffness;
use pd_linalg::cholesky::LowerPattern;

/// `K` over the free dofs (`3 f + a` for free vertex `f`, axis `a`), lower
/// triangle, diagonal first in each column. `free_index[v]` is vertex
/// `v`'s free index (`usize::MAX` if fixed), `free` the inverse.
pub(super) fn assemble(
    rest: &[pd_mesh::Point],
    blocks: &[Box<dyn ConstraintBlock>],
    free_index: &[usize],
    free: Vec<usize>,
    mass: Vec<f64>,
) -> Stiffness {
    let nf = free.len();
    // Each free vertex's free neighbours of higher or equal index, sorted.
    let mut below: Vec<Vec<usize>> = (0..nf).map(|f| vec![f]).collect();
    for block in blocks {
        for e in 0..block.len() {
            let stencil = block.stencil(e);
            for &u in &stencil {
                for &v in &stencil {
                    let (fu, fv) = (free_index[u], free_index[v]);
                    if fu != usize::MAX && fv != usize::MAX && fu > fv {
                        below[fv].push(fu);
                    }
                }
            }
        }
    }
    for list in &mut below {
        list.sort_unstable();
        list.dedup();
    }
    // Column 3 f + b holds rows 3 f + b..3 f + 3, then 3 rows per neighbour.
    let nd = 3 * nf;
    let mut col_ptr = vec![0; nd + 1];
    for (f, list) in below.iter().enumerate() {
        for b in 0..3 {
            col_ptr[3 * f + b + 1] = col_ptr[3 * f + b] + (3 - b) + 3 * (list.len() - 1);
        }
    }
    let mut row_idx = vec![0; col_ptr[nd]];
    for (f, list) in below.iter().enumerate() {
        for b in 0..3 {
            let mut slot = col_ptr[3 * f + b];
            for a in b..3 {
                row_idx[slot] = 3 * f + a;
                slot += 1;
            }
            for &g in &list[1..] {
                for a in 0..3 {
                    row_idx[slot] = 3 * g + a;
                    slot += 1;
                }
            }
        }
    }
    let mut values = vec![0.0; row_idx.len()];
    // The slot of dof pair (3 fi + a, 3 fj + b), fi >= fj.
    let slot = |fi: usize, a: usize, fj: usize, b: usize| -> usize {
        let start = col_ptr[3 * fj + b];
        if fi == fj {
            start + a - b
        } else {
            let k = below[fj].binary_search(&fi).expect("a stencil pair");
            start + (3 - b) + 3 * (k - 1) + a
        }
    };
    super::for_each_lower_hessian_entry(rest, blocks, free_index, |r, col, value| {
        values[slot(r / 3, r % 3, col / 3, col % 3)] += value;
    });
    compact(nd, col_ptr, row_idx, values, mass, free)
}

/// Drops off-diagonal entries that are exactly zero.
fn compact(
    nd: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    mass: Vec<f64>,
    free: Vec<usize>,
) -> Stiffness {
    let mut kept_ptr = vec![0; nd + 1];
    let mut kept_rows = Vec::with_capacity(row_idx.len());
    let mut kept_values = Vec::with_capacity(values.len());
    for c in 0..nd {
        for s in col_ptr[c]..col_ptr[c + 1] {
            if row_idx[s] == c || values[s] != 0.0 {
                kept_rows.push(row_idx[s]);
                kept_values.push(values[s]);
            }
        }
        kept_ptr[c + 1] = kept_rows.len();
    }
    Stiffness {
        pattern: LowerPattern {
            n: nd,
            col_ptr: kept_ptr,
            row_idx: kept_rows,
        },
        values: kept_values,
        mass,
        free,
    }
}

#[cfg(test)]
mod tests {
    use pd_mesh::{VertexSelection, generators};

    use pd_solver::Model;

    use crate::assemble;

    /// The scattered `K` is the triplet-assembled `K`: the same pattern and
    /// the same values up to the order of summation (each entry sums at
    /// most 24 element contributions; 1e-13 of the largest entry of its
    /// column is a few hundred ulps).
    #[test]
    fn scattered_assembly_matches_the_triplets() {
        let mesh = generators::box_tets([0.4, 0.1, 0.1], [8, 2, 2]).unwrap();
        let clamp = VertexSelection::Box {
            min: [-1.0; 3],
            max: [1e-9, 1.0, 1.0],
        }
        .resolve(&mesh)
        .unwrap();
        let masses = mesh.lumped_masses(1000.0).unwrap();
        let mut model = Model::new();
        let body = model.add_body(mesh, masses).unwrap();
        model.add_tet_strain(body, 1.0e6, None).unwrap();
        model.add_springs(body, 1.0e3).unwrap();
        model.fix_vertices(body, &clamp).unwrap();
        let blocks = model.constraint_blocks();
        let triplets = assemble(&model, &blocks, false).unwrap();
        let scattered = assemble(&model, &blocks, true).unwrap();
        assert_eq!(triplets.pattern.col_ptr, scattered.pattern.col_ptr);
        assert_eq!(triplets.pattern.row_idx, scattered.pattern.row_idx);
        assert_eq!(triplets.mass, scattered.mass);
        assert_eq!(triplets.free, scattered.free);
        for c in 0..triplets.pattern.n {
            let range = triplets.pattern.col_ptr[c]..triplets.pattern.col_ptr[c + 1];
            let largest = triplets.values[range.clone()]
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            for s in range {
                let (a, b) = (triplets.values[s], scattered.values[s]);
                assert!((a - b).abs() <= 1e-13 * largest, "column {c}: {a} vs {b}");
            }
        }
    }
}
