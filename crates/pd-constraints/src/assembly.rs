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
    let mut triplets: Vec<Triplet> = Vec::new();
    for block in blocks {
        let wanted = match kind {
            LaplacianKind::System => true,
            LaplacianKind::Damping => block.translation_invariant(),
            LaplacianKind::Anchoring => !block.translation_invariant(),
        };
        if wanted {
            block.add_laplacian(&mut triplets);
        }
    }
    triplets.retain(|t| t.row >= t.column);
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
    let (offsets, total) = projection_offsets(blocks);
    let mut triplets = Vec::new();
    for (block, first_row) in blocks.iter().zip(offsets) {
        block.add_projection_operator(first_row, &mut triplets);
    }
    CsrMatrix::from_triplet_vec(num_vertices, total, triplets)
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
