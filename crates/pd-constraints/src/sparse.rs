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
    /// on the armadillo, docs/design/performance.md "Element order").
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
        // Exactly sized: the Laplacians' lists hold each entry some five
        // times over, and a list-sized output would add half the list's
        // memory to the assembly's peak.
        let unique = triplets
            .iter()
            .zip(triplets.iter().skip(1))
            .filter(|(a, b)| (a.row, a.column) != (b.row, b.column))
            .count()
            + usize::from(!triplets.is_empty());
        let mut row_start = vec![0; nrows + 1];
        let mut columns = Vec::with_capacity(unique);
        let mut values: Vec<f64> = Vec::with_capacity(unique);
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

    /// Builds a `nrows x ncols` matrix from the entries `(row, column,
    /// value)` that `visit` hands to its argument, without a list of them:
    /// `visit` runs twice (counting, then filling) and must produce the same
    /// entries both times. The storage is sized exactly. Returns `None`
    /// when within some row the columns do not strictly increase in the
    /// order they come (a duplicate, or entries out of order): this
    /// constructor neither sorts nor sums, so such a caller falls back to
    /// [`CsrMatrix::from_triplet_vec`]. When it succeeds the matrix is the
    /// one `from_triplet_vec` builds from the same entries, bit for bit
    /// (with no duplicate there is nothing to sum). Entries outside the
    /// shape are a bug in the caller and panic.
    pub fn from_entry_stream(
        nrows: usize,
        ncols: usize,
        mut visit: impl FnMut(&mut dyn FnMut(usize, usize, f64)),
    ) -> Option<Self> {
        assert!(
            u32::try_from(ncols).is_ok(),
            "a CsrMatrix has at most u32::MAX columns"
        );
        let mut row_start = vec![0usize; nrows + 1];
        visit(&mut |row, column, _| {
            assert!(row < nrows && column < ncols, "entry outside the matrix");
            row_start[row + 1] += 1;
        });
        for r in 0..nrows {
            row_start[r + 1] += row_start[r];
        }
        let nnz = row_start[nrows];
        let mut next = row_start[..nrows].to_vec();
        let (mut columns, mut values) = (vec![0u32; nnz], vec![0.0; nnz]);
        let mut consistent = true;
        visit(&mut |row, column, value| {
            assert!(row < nrows && column < ncols, "entry outside the matrix");
            let at = next[row];
            // More entries than counted, or a column not above the row's
            // previous one: not a stream this constructor takes.
            if at == row_start[row + 1] || (at > row_start[row] && column as u32 <= columns[at - 1])
            {
                consistent = false;
                return;
            }
            columns[at] = column as u32;
            values[at] = value;
            next[row] += 1;
        });
        let filled = next.iter().zip(&row_start[1..]).all(|(n, end)| n == end);
        (consistent && filled).then_some(Self {
            nrows,
            ncols,
            row_start,
            columns,
            values,
        })
    }

    /// The matrix made of the given rows, in the given order (columns
    /// kept), consuming this one: when `rows` is every row in order (no
    /// fixed vertex) the storage is kept as it is instead of copied.
    pub fn into_rows(self, rows: &[usize]) -> CsrMatrix {
        let identity = rows.len() == self.nrows && rows.iter().enumerate().all(|(i, &r)| i == r);
        if identity {
            self
        } else {
            self.select_rows(rows)
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
pub(crate) mod tests {
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

    /// Shape, pattern and value bits of two matrices agree (`==` on the
    /// values would let `-0.0` pass for `0.0`).
    pub(crate) fn assert_same_bits(a: &CsrMatrix, b: &CsrMatrix) {
        assert_eq!(
            (a.nrows(), a.ncols(), a.nnz()),
            (b.nrows(), b.ncols(), b.nnz())
        );
        for r in 0..a.nrows() {
            let bits = |m: &CsrMatrix| m.row(r).map(|(c, v)| (c, v.to_bits())).collect::<Vec<_>>();
            assert_eq!(bits(a), bits(b), "row {r}");
        }
    }

    #[test]
    fn an_entry_stream_builds_the_triplet_matrix_and_refuses_what_needs_summing() {
        // Rows interleaved in the stream, columns ascending within each row,
        // a negative zero and an empty row.
        let entries = [
            (2, 0, 1.5),
            (0, 1, -0.0),
            (2, 3, 2.5),
            (0, 4, 3.0),
            (3, 2, 0.1),
            (2, 4, 1e-300),
        ];
        let stream = |list: &[(usize, usize, f64)]| {
            let list = list.to_vec();
            move |entry: &mut dyn FnMut(usize, usize, f64)| {
                for &(r, c, v) in &list {
                    entry(r, c, v);
                }
            }
        };
        let triplets: Vec<Triplet> = entries
            .iter()
            .map(|&(r, c, v)| Triplet::new(r, c, v))
            .collect();
        let built = CsrMatrix::from_entry_stream(5, 6, stream(&entries)).unwrap();
        assert_same_bits(&built, &CsrMatrix::from_triplets(5, 6, &triplets));
        assert_eq!(built.row_start, vec![0, 2, 2, 5, 6, 6]);

        // A duplicate would need summing, a column out of order sorting.
        let mut duplicate = entries.to_vec();
        duplicate.push((3, 2, 1.0));
        assert!(CsrMatrix::from_entry_stream(5, 6, stream(&duplicate)).is_none());
        let mut unsorted = entries.to_vec();
        unsorted.push((0, 2, 1.0));
        assert!(CsrMatrix::from_entry_stream(5, 6, stream(&unsorted)).is_none());
        // A second pass that differs from the first is refused too.
        let mut pass = 0;
        let shrinking = |entry: &mut dyn FnMut(usize, usize, f64)| {
            pass += 1;
            for &(r, c, v) in &entries[..entries.len() + 1 - pass] {
                entry(r, c, v);
            }
        };
        assert!(CsrMatrix::from_entry_stream(5, 6, shrinking).is_none());
    }

    #[test]
    fn into_rows_keeps_every_row_and_selects_the_others() {
        let m = CsrMatrix::from_triplets(
            3,
            3,
            &[
                Triplet::new(0, 0, 1.0),
                Triplet::new(1, 2, 2.0),
                Triplet::new(2, 1, 3.0),
            ],
        );
        assert_same_bits(&m.clone().into_rows(&[0, 1, 2]), &m);
        assert_same_bits(&m.clone().into_rows(&[2, 0]), &m.select_rows(&[2, 0]));
        assert_same_bits(&m.clone().into_rows(&[0, 1]), &m.select_rows(&[0, 1]));
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
