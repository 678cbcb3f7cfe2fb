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
    columns: Vec<usize>,
    values: Vec<f64>,
}

impl CsrMatrix {
    /// Assembles a `nrows x ncols` matrix, summing duplicate entries; within
    /// a row the columns are sorted. Entries outside the shape are a bug in
    /// the caller and panic.
    pub fn from_triplets(nrows: usize, ncols: usize, triplets: &[Triplet]) -> Self {
        let mut sorted: Vec<Triplet> = triplets.to_vec();
        sorted.sort_unstable_by_key(|t| (t.row, t.column));
        let mut row_start = vec![0; nrows + 1];
        let mut columns = Vec::with_capacity(sorted.len());
        let mut values: Vec<f64> = Vec::with_capacity(sorted.len());
        let mut last: Option<(usize, usize)> = None;
        for t in &sorted {
            assert!(
                t.row < nrows && t.column < ncols,
                "triplet outside the matrix"
            );
            if last == Some((t.row, t.column)) {
                *values.last_mut().expect("a previous entry exists") += t.value;
            } else {
                columns.push(t.column);
                values.push(t.value);
                row_start[t.row + 1] += 1;
                last = Some((t.row, t.column));
            }
        }
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
            .copied()
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
