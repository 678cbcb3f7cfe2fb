//! Assembly of the constant PD operators from a list of constraint blocks:
//! the system Laplacian `L_sys = sum_i w_i G_i^T G_i`, the damping Laplacian
//! `L_d` (translation-invariant constraints only) and the projection operator
//! `B = sum_i w_i G_i^T S_i` that maps stacked projections to forces.

use crate::{ConstraintBlock, CsrMatrix, Triplet};

/// Which constraints a Laplacian is assembled from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaplacianKind {
    /// Every constraint: the system Laplacian `L_sys` of the global step.
    System,
    /// Only translation-invariant (elastic) constraints: the damping
    /// Laplacian `L_d`, for which `L_d 1 = 0`.
    Damping,
    /// Only the constraints that are not translation-invariant
    /// (attachments): `L_sys - L_d`.
    Anchoring,
}

/// Assembles the n x n Laplacian of `blocks` over `num_vertices` vertices.
///
/// The result is symmetric bit for bit: each off-diagonal value is summed
/// once, over the lower triangle, and mirrored. (Summing the triplets of
/// `(i, j)` and of `(j, i)` separately can round differently.) The step
/// relies on it: for a symmetric `L` with zero row sums in exact arithmetic,
/// `sum_i sum_j L_ij (x_j - x_i)` is exactly `sum_j (colsum_j - rowsum_j) x_j
/// = 0`, so the difference form of `L x` moves no momentum whatever `|x|`;
/// an asymmetry of `eps |L|` would move it by `eps |L| |x|`.
pub fn laplacian(
    blocks: &[Box<dyn ConstraintBlock>],
    num_vertices: usize,
    kind: LaplacianKind,
) -> CsrMatrix {
    // Only the lower triangle is ever stored: the same list, in the same
    // order, as filtering the full one (so the same sort and the same sums).
    let mut triplets: Vec<Triplet> = Vec::new();
    for block in blocks {
        let wanted = match kind {
            LaplacianKind::System => true,
            LaplacianKind::Damping => block.translation_invariant(),
            LaplacianKind::Anchoring => !block.translation_invariant(),
        };
        if wanted {
            block.add_lower_laplacian(&mut triplets);
        }
    }
    CsrMatrix::from_triplet_vec(num_vertices, num_vertices, triplets).symmetric_from_lower()
}

/// First projection row of each block and the total number of rows, for a
/// stacked projection vector holding every block's rows in order.
pub fn projection_offsets(blocks: &[Box<dyn ConstraintBlock>]) -> (Vec<usize>, usize) {
    let mut offsets = Vec::with_capacity(blocks.len());
    let mut total = 0;
    for block in blocks {
        offsets.push(total);
        total += block.len() * block.rows_per_constraint();
    }
    (offsets, total)
}

/// Assembles the n x R projection operator `B = sum_i w_i G_i^T S_i`, so that
/// `B p` is the constraint part of the global step's right-hand side for
/// stacked projections `p` (R rows, block by block).
pub fn projection_operator(blocks: &[Box<dyn ConstraintBlock>], num_vertices: usize) -> CsrMatrix {
    let every: Vec<usize> = (0..num_vertices).collect();
    projection_operator_rows(blocks, num_vertices, &every)
}

/// The rows of the projection operator `B` ([`projection_operator`]) of the
/// given vertices (`rows`, distinct), in that order: the same matrix, bit
/// for bit, as selecting them from the full `B`
/// ([`CsrMatrix::select_rows`]), built in place without a triplet list.
/// Every block's entries come vertex by vertex with their projection rows
/// ascending, and no entry repeats when no stencil names a vertex twice,
/// so nothing needs sorting or summing; anything else falls back to the
/// triplet assembly. (The triplets were the setup's peak memory: 24 bytes
/// for each of the 12 entries of a tet, against 12 bytes stored.)
pub fn projection_operator_rows(
    blocks: &[Box<dyn ConstraintBlock>],
    num_vertices: usize,
    rows: &[usize],
) -> CsrMatrix {
    let (offsets, total) = projection_offsets(blocks);
    const NOT_A_ROW: usize = usize::MAX;
    let mut row_of = vec![NOT_A_ROW; num_vertices];
    let mut distinct = true;
    for (i, &v) in rows.iter().enumerate() {
        distinct &= row_of[v] == NOT_A_ROW;
        row_of[v] = i;
    }
    let streamed = distinct
        .then(|| {
            CsrMatrix::from_entry_stream(rows.len(), total, |entry| {
                for (block, &first_row) in blocks.iter().zip(&offsets) {
                    block.for_each_projection_entry(first_row, &mut |vertex, column, value| {
                        let row = row_of[vertex];
                        if row != NOT_A_ROW {
                            entry(row, column, value);
                        }
                    });
                }
            })
        })
        .flatten();
    streamed.unwrap_or_else(|| {
        let mut triplets = Vec::new();
        for (block, &first_row) in blocks.iter().zip(&offsets) {
            block.add_projection_operator(first_row, &mut triplets);
        }
        CsrMatrix::from_triplet_vec(num_vertices, total, triplets).into_rows(rows)
    })
}

#[cfg(test)]
mod tests {
    use pd_mesh::{Point, generators};

    use super::*;
    use crate::{ConstraintSet, TetStrain};

    /// Tets of a box whose vertices are moved off the grid, so that element
    /// weights and operators differ and round differently.
    fn blocks() -> (Vec<Box<dyn ConstraintBlock>>, usize) {
        let mesh = generators::box_tets([1.0, 0.7, 0.4], [3, 2, 2]).unwrap();
        let rest: Vec<Point> = mesh
            .vertices()
            .iter()
            .enumerate()
            .map(|(i, p)| {
                p + Point::new(0.01 * (i as f64).sin(), 0.013 * (i as f64 * 1.7).cos(), 0.0)
            })
            .collect();
        let tets = mesh
            .tets()
            .iter()
            .map(|&t| TetStrain::new(&rest, t, 1.7e5, None).unwrap())
            .collect();
        (vec![Box::new(ConstraintSet::new(tets))], rest.len())
    }

    /// The blocks of [`blocks`] plus attachments and an energy element
    /// (which goes through the trait's default methods), in one list.
    fn mixed_blocks() -> (Vec<Box<dyn ConstraintBlock>>, usize) {
        let (mut blocks, n) = blocks();
        let mesh = generators::box_tets([1.0, 0.7, 0.4], [3, 2, 2]).unwrap();
        let attachments = [0, 5, 7]
            .iter()
            .map(|&v| crate::Attachment::new(v, Point::new(0.1, 0.2, 0.3), 1e3).unwrap())
            .collect();
        blocks.push(Box::new(ConstraintSet::new(attachments)));
        let tets = mesh.tets()[..4]
            .iter()
            .map(|&t| crate::MaterialTet::new(mesh.vertices(), t).unwrap())
            .collect();
        let material =
            crate::MaterialSet::new(crate::MaterialKind::NeoHookean, 1e5, 0.3, tets).unwrap();
        blocks.push(Box::new(material));
        (blocks, n)
    }

    fn same_triplets(a: &[Triplet], b: &[Triplet]) {
        let bits = |t: &[Triplet]| {
            t.iter()
                .map(|t| (t.row, t.column, t.value.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(a), bits(b));
    }

    #[test]
    fn the_lower_laplacian_is_the_filtered_full_list() {
        let (blocks, _) = mixed_blocks();
        for block in &blocks {
            let mut full = Vec::new();
            block.add_laplacian(&mut full);
            full.retain(|t| t.row >= t.column);
            let mut lower = vec![Triplet::new(0, 0, 7.0)];
            block.add_lower_laplacian(&mut lower);
            assert_eq!(lower[0], Triplet::new(0, 0, 7.0), "{}", block.kind());
            same_triplets(&lower[1..], &full);
        }
    }

    #[test]
    fn projection_rows_are_the_rows_of_the_triplet_assembly() {
        let (blocks, n) = mixed_blocks();
        let (offsets, total) = projection_offsets(&blocks);
        let mut triplets = Vec::new();
        for (block, &first_row) in blocks.iter().zip(&offsets) {
            let mut streamed = Vec::new();
            block.for_each_projection_entry(first_row, &mut |r, c, v| {
                streamed.push(Triplet::new(r, c, v));
            });
            let before = triplets.len();
            block.add_projection_operator(first_row, &mut triplets);
            same_triplets(&streamed, &triplets[before..]);
        }
        let full = CsrMatrix::from_triplets(n, total, &triplets);
        let every: Vec<usize> = (0..n).collect();
        let some: Vec<usize> = (0..n).filter(|v| v % 3 != 1).collect();
        let reordered: Vec<usize> = some.iter().rev().copied().collect();
        let twice = vec![2, 4, 2];
        for rows in [&every, &some, &reordered, &twice] {
            assert!(projection_operator_rows(&blocks, n, rows).bitwise_eq(&full.select_rows(rows)));
        }
        assert!(projection_operator(&blocks, n).bitwise_eq(&full));
    }

    #[test]
    fn laplacians_are_symmetric_bit_for_bit() {
        let (blocks, n) = blocks();
        for kind in [LaplacianKind::System, LaplacianKind::Damping] {
            let l = laplacian(&blocks, n, kind);
            for t in l.triplets() {
                let mirror = l.row(t.column).find(|&(c, _)| c == t.row).map(|(_, v)| v);
                assert_eq!(mirror.map(f64::to_bits), Some(t.value.to_bits()), "{t:?}");
            }
        }
        assert_eq!(
            laplacian(&blocks, n, LaplacianKind::Anchoring)
                .triplets()
                .count(),
            0
        );
    }

    #[test]
    fn difference_form_is_exact_on_a_uniform_vector_far_away() {
        // L 1 = 0 in exact arithmetic; on differences a uniform vector gives
        // exactly zero, where the plain product leaves row-sum round-off
        // times |x|.
        let (blocks, n) = blocks();
        let l = laplacian(&blocks, n, LaplacianKind::Damping);
        let far = vec![Point::new(1.0e5, -3.0e4, 7.0e3); n];
        let mut plain_error = 0.0f64;
        for row in 0..n {
            assert_eq!(l.row_dot_relative(row, far[row], &far), Point::zeros());
            plain_error = plain_error.max(l.row_dot(row, &far).amax());
        }
        assert!(plain_error > 0.0, "the control should show round-off");
    }
}
