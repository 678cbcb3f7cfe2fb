//! Tests of `supernodal_solve.rs` and the measurement helpers of
//! `solve_profile.rs` (kept apart so that file stays under 600 lines).

use super::super::{NumericFactor, SymbolicFactor};
use super::{Structure, SupernodalSolve};
use crate::Point;
use crate::fixtures::{armadillo, laplacian_factor};
use faer::sparse::linalg::cholesky::SymbolicCholesky;

/// Measurement helpers for `solve_profile.rs`.
impl SupernodalSolve {
    /// [`Self::solve`] in its four parts, timed: the permutation in, the
    /// forward and the backward substitution, the permutation out (seconds
    /// of `clock` each; `solve_profile.rs`).
    pub fn solve_timed(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
        factor: &NumericFactor,
        rhs: &mut [Point],
        clock: &dyn Fn() -> f64,
    ) -> [f64; 4] {
        let values = &factor.values[..];
        let structure = self.structure(symbolic, factor);
        let forward = symbolic.perm().map(|p| p.arrays().0);
        let t0 = clock();
        self.permute_in(forward, rhs);
        let t1 = clock();
        self.forward_substitution(&structure, values);
        let t2 = clock();
        self.backward_substitution(&structure, values);
        let t3 = clock();
        self.permute_out(forward, rhs);
        [t1 - t0, t2 - t1, t3 - t2, clock() - t3]
    }

    /// The stored values of the top of the tree and of each bin, for
    /// `solve_profile.rs`.
    pub fn split_values(&self, symbolic: &SymbolicCholesky<usize>) -> [usize; 3] {
        let structure = Structure::of(symbolic).expect("a supernodal factor");
        let values = |list: &[usize]| -> usize {
            list.iter()
                .map(|&s| structure.value_ptr[s + 1] - structure.value_ptr[s])
                .sum()
        };
        [
            values(&self.split.top),
            values(&self.split.bins[0]),
            values(&self.split.bins[1]),
        ]
    }

    /// The supernodes by width class `(widest width, count, values of the
    /// diagonal blocks' lower triangles, values below them)`, classes
    /// 1, 2-3, 4-7, ..., for `solve_profile.rs`.
    pub fn width_classes(symbolic: &SymbolicCholesky<usize>) -> Vec<(usize, usize, usize, usize)> {
        let structure = Structure::of(symbolic).expect("a supernodal factor");
        let mut classes = vec![(0, 0, 0, 0); 16];
        for s in 0..structure.begin.len() {
            let c = structure.end[s] - structure.begin[s];
            let class = &mut classes[c.ilog2() as usize];
            class.0 = class.0.max(c);
            class.1 += 1;
            class.2 += c * (c + 1) / 2;
            class.3 += c * structure.row_len[s];
        }
        classes.retain(|class| class.1 > 0);
        classes
    }
}

/// Prefetching changes no value: a beam's split solve (a factor below
/// the prefetch threshold, the prefetches forced on) gives the same
/// bits with and without them, on 1 and 2 threads.
#[test]
fn prefetches_change_no_bit() {
    let beam = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [40, 8, 8]).unwrap();
    let (mut factor, numeric) = laplacian_factor(&beam);
    let n = factor.pattern().n;
    let mut solve = factor.fast_solve.take().expect("a supernodal factor");
    assert!(solve.is_split(), "the beam's tree splits");
    let rhs: Vec<Point> = (0..n)
        .map(|i| Point::new((i % 13) as f64, (i % 7) as f64 - 3.0, (i % 5) as f64))
        .collect();
    let mut solved = |prefetch: bool, threads: usize| {
        solve.set_prefetch(prefetch);
        bits(&solved_on(threads, &mut solve, (&factor, &numeric), &rhs))
    };
    let plain = solved(false, 1);
    assert_eq!(plain, solved(true, 1));
    assert_eq!(plain, solved(true, 2));
    assert_eq!(plain, solved(false, 2));
}

/// The row-by-row update of narrow supernodes' rows below (`NARROW`) gives
/// the bits of the coordinate arrays' one-column passes: the beam (split,
/// most of its supernodes one column wide) and the armadillo (if present;
/// many of two to three columns), on 1 and 2 threads, in faer's layout and
/// packed.
#[test]
fn narrow_supernodes_change_no_bit() {
    for (factor, mut numeric, mut solve, rhs) in beam_and_armadillo_solves() {
        for packed in [false, true] {
            if packed {
                factor.pack(&mut numeric);
            }
            let mut solved = |narrow: usize, threads: usize| {
                solve.set_narrow(narrow);
                bits(&solved_on(threads, &mut solve, (&factor, &numeric), &rhs))
            };
            let passes = solved(0, 1);
            assert_eq!(passes, solved(4, 1), "packed: {packed}");
            assert_eq!(passes, solved(4, 2), "packed: {packed}");
            assert_eq!(passes, solved(0, 2), "packed: {packed}");
        }
    }
}

/// The split 40 x 8 x 8 beam (most of its supernodes one column wide) and
/// the armadillo (if present; many of two to three columns): each one's
/// Laplacian factor, its supernodal solve and a varied right-hand side.
fn beam_and_armadillo_solves() -> Vec<(SymbolicFactor, NumericFactor, SupernodalSolve, Vec<Point>)>
{
    let beam = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [40, 8, 8]).unwrap();
    [Some(beam), armadillo()]
        .into_iter()
        .flatten()
        .map(|mesh| {
            let (mut factor, numeric) = laplacian_factor(&mesh);
            let n = factor.pattern().n;
            let solve = factor.fast_solve.take().expect("a supernodal factor");
            let rhs: Vec<Point> = (0..n)
                .map(|i| {
                    Point::new(
                        (i % 11) as f64 - 5.0,
                        (i % 7) as f64,
                        1.0 / (1 + i % 3) as f64,
                    )
                })
                .collect();
            (factor, numeric, solve, rhs)
        })
        .collect()
}

/// Every instruction set gives the same bits: the solve compiled for
/// AVX-512 (where the CPU has it), for AVX2 (explicit 4-wide dot products)
/// and plain, on the beam (split) and the armadillo (if present), on 1
/// and 2 threads. A reordered sum in any one path fails it.
#[cfg(target_arch = "x86_64")]
#[test]
fn every_instruction_set_gives_the_same_bits() {
    use crate::simd::{limit_width, widths};
    for (factor, numeric, mut solve, rhs) in beam_and_armadillo_solves() {
        let mut outcomes = Vec::new();
        for width in widths() {
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.broadcast(|_| limit_width(width));
                let mut x = rhs.clone();
                pool.install(|| solve.solve(&factor.symbolic, &numeric, &mut x));
                outcomes.push((width, threads, bits(&x)));
            }
        }
        let (_, _, first) = &outcomes[0];
        for (width, threads, x) in &outcomes {
            assert!(x == first, "{width} lanes on {threads} threads: other bits");
        }
    }
}

/// `b - L L^T x` and `|L| |L^T| |x|`, both in the factor's order, for the
/// supernodal factor `values` of `structure`, with the longest inner
/// product of either product (the most entries in a row or column of `L`).
fn residual(
    structure: &super::Structure<'_>,
    values: &[f64],
    b: &[Point],
    x: &[Point],
) -> (Vec<Point>, Vec<Point>, usize) {
    let n = x.len();
    let abs = |p: Point| Point::new(p.x.abs(), p.y.abs(), p.z.abs());
    // Every stored entry of L as (row, column, value).
    let mut entries = Vec::new();
    for s in 0..structure.begin.len() {
        let (begin, c) = (structure.begin[s], structure.end[s] - structure.begin[s]);
        let rows = &structure.row_idx[structure.row_ptr[s]..][..structure.row_len[s]];
        let ld = c + rows.len();
        for j in 0..c {
            let column = &values[structure.value_ptr[s] + j * ld..][..ld];
            for (i, &l) in column[..c].iter().enumerate().skip(j) {
                entries.push((begin + i, begin + j, l));
            }
            for (k, &row) in rows.iter().enumerate() {
                entries.push((row, begin + j, column[c + k]));
            }
        }
    }
    let (mut in_row, mut in_column) = (vec![0; n], vec![0; n]);
    let (mut w, mut w_abs) = (vec![Point::zeros(); n], vec![Point::zeros(); n]);
    for &(row, column, l) in &entries {
        in_row[row] += 1;
        in_column[column] += 1;
        w[column] += x[row] * l;
        w_abs[column] += abs(x[row]) * l.abs();
    }
    let (mut r, mut bound) = (b.to_vec(), vec![Point::zeros(); n]);
    for &(row, column, l) in &entries {
        r[row] -= w[column] * l;
        bound[row] += w_abs[column] * l.abs();
    }
    let m = in_row.iter().chain(&in_column).copied().max().unwrap_or(0);
    (r, bound, m)
}

/// The tiled diagonal solves (`solve_diagonal.rs`) change the summation
/// order, so the check is the backward error every triangular solve
/// meets whatever the order of its inner products (Higham, "Accuracy and
/// Stability of Numerical Algorithms", Thm 8.5): the computed `x` of
/// `L y = b`, `L^T x = y` satisfies `(L + E1)(L^T + E2) x = b` with
/// `|Ei| <= g |L|`, `g = m u / (1 - m u)`, `m` the longest inner product.
/// So `|b - L L^T x| <= (2 g + g^2) |L| |L^T| |x|`; evaluating the
/// residual in floating point adds at most `(2 g + g^2) |L| |L^T| |x|`
/// for its two products and `u (|b| + |L L^T x|)` for the subtraction, in
/// all at most `5 g |L| |L^T| |x| + u |b|` for `m >= 2`. Checked
/// componentwise on the 40 x 8 x 8 beam's pattern and the armadillo's
/// (skipped if absent), for the tiled solve and the column-by-column one,
/// on 1 and 2 threads (the same bits). A lost tile or a wrong column
/// would leave residuals the size of `|L| |L^T| |x|` itself.
#[test]
fn blocked_diagonal_solves_are_backward_stable() {
    let beam = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [40, 8, 8]).unwrap();
    check_backward_error("beam 40 x 8 x 8", &beam);
    if let Some(mesh) = armadillo() {
        check_backward_error("armadillo", &mesh);
    }
}

fn check_backward_error(label: &str, mesh: &pd_mesh::Mesh) {
    let (mut factor, numeric) = laplacian_factor(mesh);
    let mut packed = laplacian_factor(mesh).1;
    factor.pack(&mut packed);
    assert!(
        packed.values.len() < numeric.values.len(),
        "{label}: packing drops the diagonal blocks' upper triangles"
    );
    println!(
        "{label}: {} stored values in faer's layout, {} packed",
        numeric.values.len(),
        packed.values.len()
    );
    let n = factor.pattern().n;
    let mut solve = factor.fast_solve.take().expect("a supernodal factor");
    let structure = super::Structure::of(&factor.symbolic).unwrap();
    let widest = (0..structure.begin.len())
        .map(|s| structure.end[s] - structure.begin[s])
        .max()
        .unwrap_or(0);
    assert!(
        widest
            >= super::BLOCKED_DIAGONAL.into_iter().max().unwrap()
                + super::super::solve_kernels::TILE,
        "{label}: a diagonal block of {widest} columns has no whole tile with rows below it"
    );
    let rhs: Vec<Point> = (0..n)
        .map(|i| Point::new((i % 13) as f64 - 6.0, (i % 7) as f64 - 3.0, (i % 5) as f64))
        .collect();
    let forward = factor.symbolic.perm().map(|p| p.arrays().0);
    let permuted = |v: &[Point]| -> Vec<Point> {
        match forward {
            Some(f) => f.iter().map(|&old| v[old]).collect(),
            None => v.to_vec(),
        }
    };
    let u = f64::EPSILON / 2.0;
    for blocked in [super::BLOCKED_DIAGONAL, [usize::MAX; 2]] {
        solve.set_blocked(blocked);
        let solved: Vec<Vec<Point>> = [1, 2]
            .map(|threads| solved_on(threads, &mut solve, (&factor, &numeric), &rhs))
            .into();
        assert_eq!(
            bits(&solved[0]),
            bits(&solved[1]),
            "{label}: 1 and 2 threads"
        );
        // The packed layout: the same values read in the same order.
        for threads in [1, 2] {
            assert_eq!(
                bits(&solved[0]),
                bits(&solved_on(threads, &mut solve, (&factor, &packed), &rhs)),
                "{label}: packed, {threads} threads"
            );
        }
        let (b, x) = (permuted(&rhs), permuted(&solved[0]));
        let (r, bound, m) = residual(&structure, &numeric.values, &b, &x);
        let g = m as f64 * u / (1.0 - m as f64 * u);
        let mut worst = 0.0_f64;
        for i in 0..n {
            for k in 0..3 {
                let limit = 5.0 * g * bound[i][k] + u * b[i][k].abs();
                assert!(
                    r[i][k].abs() <= limit,
                    "{label}, tiles from {blocked:?} columns: row {i} coordinate {k}: \
                     residual {:e} above {limit:e}",
                    r[i][k]
                );
                worst = worst.max(r[i][k].abs() / limit);
            }
        }
        println!(
            "{label}, tiles from {blocked:?} columns: m = {m}, worst residual / bound {worst:.3e}"
        );
    }
}

/// `rhs` solved with `solve` and the factor on a pool of `threads` threads.
fn solved_on(
    threads: usize,
    solve: &mut SupernodalSolve,
    (factor, numeric): (&SymbolicFactor, &NumericFactor),
    rhs: &[Point],
) -> Vec<Point> {
    let mut x = rhs.to_vec();
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| solve.solve(&factor.symbolic, numeric, &mut x));
    x
}

/// The bits of every coordinate of `x`, in order.
fn bits(x: &[Point]) -> Vec<u64> {
    x.iter()
        .flat_map(|p| [p.x, p.y, p.z].map(f64::to_bits))
        .collect()
}
