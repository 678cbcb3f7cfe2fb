//! A compressed-sparse-row matrix for the assembled operators, and the
//! triplets they are built from.

use pd_mesh::Point;

/// One entry `(row, column, value)` of a matrix under assembly; duplicates
/// are summed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triplet {
    /// Row index.
    pub row: usize,
    /// Column index.
    pub column: usize,
    /// Value.
    pub value: f64,
}

impl Triplet {
    /// A new entry.
    pub fn new(row: usize, column: usize, value: f64) -> Self {
        Self { row, column, value }
    }
}

/// A sparse matrix in compressed sparse row form, applied to vectors of
/// [`Point`]s (one matrix for the x, y and z columns alike). Each row is
/// computed independently, so a row-parallel product gives the same bits
/// whatever the thread count.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CsrMatrix {
    nrows: usize,
    ncols: usize,
    row_start: Vec<usize>,
    /// Column indices, 32-bit: the products' gathers are bound by memory
    /// traffic, and an index of half the width makes a stored entry 12
    /// bytes instead of 16 (the right-hand side's `B^T p` got 6 % faster
    /// on the armadillo, docs/performance.md "Element order").
    columns: Vec<u32>,
    values: Vec<f64>,
}

impl CsrMatrix {
    /// Assembles a `nrows x ncols` matrix, summing duplicate entries; within
    /// a row the columns are sorted. Entries outside the shape are a bug in
    /// the caller and panic, as does a matrix of more than `u32::MAX`
    /// columns (some 4e9 projection rows: beyond any memory this runs in).
    pub fn from_triplets(nrows: usize, ncols: usize, triplets: &[Triplet]) -> Self {
        Self::from_triplet_vec(nrows, ncols, triplets.to_vec())
    }

    /// [`CsrMatrix::from_triplets`] sorting the given vector in place: the
    /// same matrix, bit for bit, without a copy of the triplets (the
    /// assembly's peak memory is its triplet lists).
    pub fn from_triplet_vec(nrows: usize, ncols: usize, mut triplets: Vec<Triplet>) -> Self {
        assert!(
            u32::try_from(ncols).is_ok(),
            "a CsrMatrix has at most u32::MAX columns"
        );
        triplets.sort_unstable_by_key(|t| (t.row, t.column));
        let mut row_start = vec![0; nrows + 1];
        let mut columns = Vec::with_capacity(triplets.len());
        let mut values: Vec<f64> = Vec::with_capacity(triplets.len());
        let mut last: Option<(usize, usize)> = None;
        for t in &triplets {
            assert!(
                t.row < nrows && t.column < ncols,
                "triplet outside the matrix"
            );
            if last == Some((t.row, t.column)) {
                *values.last_mut().expect("a previous entry exists") += t.value;
            } else {
                columns.push(t.column as u32);
                values.push(t.value);
                row_start[t.row + 1] += 1;
                last = Some((t.row, t.column));
            }
        }
        drop(triplets);
        columns.shrink_to_fit();
        values.shrink_to_fit();
        for r in 0..nrows {
            row_start[r + 1] += row_start[r];
        }
        Self {
            nrows,
            ncols,
            row_start,
            columns,
            values,
        }
    }

    /// The symmetric matrix whose lower triangle (diagonal included) is
    /// this square matrix's: each entry below the diagonal is mirrored
    /// above it with the same bits. Entries above the diagonal are ignored.
    pub fn symmetric_from_lower(&self) -> Self {
        let n = self.nrows;
        let lower = |r: usize| self.row(r).filter(move |&(c, _)| c <= r);
        let mut count = vec![0usize; n + 1];
        for r in 0..n {
            for (c, _) in lower(r) {
                count[r + 1] += 1;
                if c != r {
                    count[c + 1] += 1;
                }
            }
        }
        for r in 0..n {
            count[r + 1] += count[r];
        }
        let row_start = count.clone();
        let mut next = count;
        let nnz = row_start[n];
        let (mut columns, mut values) = (vec![0u32; nnz], vec![0.0; nnz]);
        // Row r holds its own lower entries (columns <= r, ascending) and
        // then, as rows below it are visited in order, their entries in
        // column r (columns > r, ascending): sorted without a sort.
        for r in 0..n {
            for (c, v) in lower(r) {
                columns[next[r]] = c as u32;
                values[next[r]] = v;
                next[r] += 1;
            }
        }
        for r in 0..n {
            for (c, v) in lower(r).filter(|&(c, _)| c != r) {
                columns[next[c]] = r as u32;
                values[next[c]] = v;
                next[c] += 1;
            }
        }
        Self {
            nrows: n,
            ncols: self.ncols,
            row_start,
            columns,
            values,
        }
    }

    /// Number of rows.
    pub fn nrows(&self) -> usize {
        self.nrows
    }

    /// Number of columns.
    pub fn ncols(&self) -> usize {
        self.ncols
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// The stored entries of row `row` as `(column, value)` pairs.
    pub fn row(&self, row: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let range = self.row_start[row]..self.row_start[row + 1];
        self.columns[range.clone()]
            .iter()
            .map(|&c| c as usize)
            .zip(self.values[range].iter().copied())
    }

    /// `(A x)[row]` for a vector of points.
    #[inline]
    pub fn row_dot(&self, row: usize, x: &[Point]) -> Point {
        self.row(row)
            .fold(Point::zeros(), |acc, (c, v)| acc + x[c] * v)
    }

    /// `sum_j A[row][j] (x_j - centre)`: `(A x)[row]` for a row whose
    /// entries sum to zero in exact arithmetic (a Laplacian of
    /// translation-invariant constraints), evaluated on differences. A
    /// uniform `x` then gives exactly zero, and round-off scales with the
    /// spread of `x` over the row's stencil rather than with `|x|` (the
    /// assembled entries' own rounding, which makes the stored row sum a few
    /// ulps off zero, is not multiplied by `|x|`).
    #[inline]
    pub fn row_dot_relative(&self, row: usize, centre: Point, x: &[Point]) -> Point {
        self.row(row)
            .fold(Point::zeros(), |acc, (c, v)| acc + (x[c] - centre) * v)
    }

    /// `y = A x`, sequentially.
    pub fn mul_points(&self, x: &[Point], y: &mut [Point]) {
        for (row, out) in y.iter_mut().enumerate() {
            *out = self.row_dot(row, x);
        }
    }

    /// The matrix made of the given rows, in the given order (columns kept).
    pub fn select_rows(&self, rows: &[usize]) -> CsrMatrix {
        let mut row_start = Vec::with_capacity(rows.len() + 1);
        row_start.push(0);
        let mut columns = Vec::new();
        let mut values = Vec::new();
        for &r in rows {
            let range = self.row_start[r]..self.row_start[r + 1];
            columns.extend_from_slice(&self.columns[range.clone()]);
            values.extend_from_slice(&self.values[range]);
            row_start.push(columns.len());
        }
        CsrMatrix {
            nrows: rows.len(),
            ncols: self.ncols,
            row_start,
            columns,
            values,
        }
    }

    /// Iterates over all entries as triplets.
    pub fn triplets(&self) -> impl Iterator<Item = Triplet> + '_ {
        (0..self.nrows).flat_map(move |r| self.row(r).map(move |(c, v)| Triplet::new(r, c, v)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetric_from_lower_equals_mirroring_the_triplets() {
        // A lower triangle with scattered entries (and one above the
        // diagonal, which must be ignored).
        let n = 7;
        let mut lower = Vec::new();
        for r in 0..n {
            for c in 0..=r {
                if (r * 3 + c * 5) % 4 != 1 {
                    lower.push(Triplet::new(r, c, (r * 10 + c) as f64 + 0.5));
                }
            }
        }
        let mut with_upper = lower.clone();
        with_upper.push(Triplet::new(1, 5, 99.0));
        let built = CsrMatrix::from_triplets(n, n, &with_upper).symmetric_from_lower();
        let mut mirrored = lower.clone();
        mirrored.extend(
            lower
                .iter()
                .filter(|t| t.row != t.column)
                .map(|t| Triplet::new(t.column, t.row, t.value)),
        );
        assert_eq!(built, CsrMatrix::from_triplets(n, n, &mirrored));
    }

    #[test]
    fn duplicates_are_summed_and_rows_sorted() {
        let m = CsrMatrix::from_triplets(
            2,
            3,
            &[
                Triplet::new(1, 2, 1.0),
                Triplet::new(0, 1, 2.0),
                Triplet::new(1, 0, 3.0),
                Triplet::new(1, 2, 4.0),
            ],
        );
        assert_eq!(m.nnz(), 3);
        assert_eq!(m.row(1).collect::<Vec<_>>(), vec![(0, 3.0), (2, 5.0)]);
        let x = [Point::x(), Point::y(), Point::z()];
        let mut y = [Point::zeros(); 2];
        m.mul_points(&x, &mut y);
        assert_eq!(y[0], Point::new(0.0, 2.0, 0.0));
        assert_eq!(y[1], Point::new(3.0, 0.0, 5.0));
    }
}
