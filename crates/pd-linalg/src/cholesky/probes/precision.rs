//! What a single-precision factor would buy the global solve (ignored:
//! it times solves, so its numbers mean something only on a quiet
//! machine):
//!
//! ```sh
//! cargo test --release -p pd-linalg --lib precision_probe -- --ignored --nocapture
//! ```
//!
//! For the 80 x 14 x 14 beam, the 130 x 26 x 26 beam and the TetGen
//! armadillo (skipped if absent) it times, one thread, the minimum of
//! `PD_SOLVE_ROUNDS` (21) three-column solves by pd's supernodal solve
//! (f64), by faer's (f64) and by faer's on the same factor rounded to
//! f32, and prints the f32 solve's error against faer's f64 one, alone
//! and after each of two defect corrections (`x += solve32(b - A x)`, the
//! residual in f64), then the same for stiffer matrices (three
//! corrections).

use super::calibration::fastest;
use crate::Point;
use crate::cholesky::SymbolicFactor;
use crate::fixtures::{armadillo, laplacian_factor, laplacian_values};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::LltRef;
use faer::{Conj, Mat, Par};

/// The largest difference of `a` and `b` over the largest value of `b`.
fn max_rel(a: &[Point], b: &[Point]) -> f64 {
    let largest = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0, f64::max);
    largest(&mut a.iter().zip(b).map(|(a, b)| (a - b).amax()))
        / largest(&mut b.iter().map(|b| b.amax()))
}

fn to_mat<T: faer::traits::ComplexField>(points: &[Point], cast: impl Fn(f64) -> T) -> Mat<T> {
    Mat::from_fn(points.len(), 3, |i, j| cast(points[i][j]))
}

fn to_points<T: Copy>(m: &Mat<T>, cast: impl Fn(T) -> f64) -> Vec<Point> {
    (0..m.nrows())
        .map(|i| Point::new(cast(m[(i, 0)]), cast(m[(i, 1)]), cast(m[(i, 2)])))
        .collect()
}

/// The errors against the `f64` solve of `A x = b`, `A` with the lower
/// triangle `values` on `factor`'s pattern: of the solve with the factor
/// rounded to `f32`, then after each of `corrections` defect corrections
/// `x += solve_f32(b - A x)` (the residual in `f64`).
fn accuracy(
    factor: &mut SymbolicFactor,
    values: &[f64],
    b: &[Point],
    corrections: usize,
) -> Vec<f64> {
    let numeric = factor.factorise(values).expect("positive definite");
    let values64 = factor.faer_values(&numeric).into_owned();
    let values32: Vec<f32> = values64.iter().map(|&v| v as f32).collect();
    let symbolic = &factor.symbolic;
    let mut s64 = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
    let mut s32 = MemBuffer::new(symbolic.solve_in_place_scratch::<f32>(3, Par::Seq));
    let l32 = LltRef::<usize, f32>::new(symbolic, &values32);
    let mut solve32 = |rhs: &[Point]| {
        let mut w = to_mat(rhs, |v| v as f32);
        l32.solve_in_place_with_conj(Conj::No, w.as_mut(), Par::Seq, MemStack::new(&mut s32));
        to_points(&w, f64::from)
    };
    let mut w64 = to_mat(b, |v| v);
    LltRef::<usize, f64>::new(symbolic, &values64).solve_in_place_with_conj(
        Conj::No,
        w64.as_mut(),
        Par::Seq,
        MemStack::new(&mut s64),
    );
    let x64 = to_points(&w64, |v| v);
    let a = factor.pattern().to_symmetric(values);
    let mut x = solve32(b);
    let mut errors = vec![max_rel(&x, &x64)];
    let mut ax = vec![Point::zeros(); b.len()];
    for _ in 0..corrections {
        a.mul_points(&x, &mut ax);
        let residual: Vec<Point> = b.iter().zip(&ax).map(|(b, ax)| b - ax).collect();
        for (x, c) in x.iter_mut().zip(solve32(&residual)) {
            *x += c;
        }
        errors.push(max_rel(&x, &x64));
    }
    errors
}

fn print_errors(label: &str, errors: &[f64]) {
    print!("  {label}: f32 error {:.2e}", errors[0]);
    for e in &errors[1..] {
        print!(", corrected {e:.2e}");
    }
    println!();
}

fn probe(label: &str, mesh: &pd_mesh::Mesh, rounds: usize) {
    let (mut factor, numeric) = laplacian_factor(mesh);
    let n = factor.pattern().n;
    let b: Vec<Point> = (0..n)
        .map(|i| Point::from_fn(|j, _| ((i * (j + 3)) % 17) as f64 - 8.0))
        .collect();
    println!(
        "{label}: {n} unknowns, {} values in A's lower triangle, {} stored values, {} supernodes",
        factor.pattern().row_idx.len(),
        factor.factor_len(),
        factor.supernodes()
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    pool.install(|| {
        // pd's own solve (f64), and faer's in f64 and f32.
        let mut points = b.clone();
        let ours = fastest(rounds, || {
            points.copy_from_slice(&b);
            factor.solve_points(&numeric, &mut points);
        });
        let symbolic = &factor.symbolic;
        let values64 = factor.faer_values(&numeric).into_owned();
        let values32: Vec<f32> = values64.iter().map(|&v| v as f32).collect();
        let mut s64 = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
        let mut s32 = MemBuffer::new(symbolic.solve_in_place_scratch::<f32>(3, Par::Seq));
        let l64 = LltRef::<usize, f64>::new(symbolic, &values64);
        let l32 = LltRef::<usize, f32>::new(symbolic, &values32);
        let (b64, b32) = (to_mat(&b, |v| v), to_mat(&b, |v| v as f32));
        let (mut w64, mut w32) = (b64.clone(), b32.clone());
        let faer64 = fastest(rounds, || {
            w64.copy_from(&b64);
            l64.solve_in_place_with_conj(Conj::No, w64.as_mut(), Par::Seq, MemStack::new(&mut s64));
        });
        let faer32 = fastest(rounds, || {
            w32.copy_from(&b32);
            l32.solve_in_place_with_conj(Conj::No, w32.as_mut(), Par::Seq, MemStack::new(&mut s32));
        });
        println!(
            "  min solve ms, 1 thread: pd f64 {:.3}, faer f64 {:.3}, faer f32 {:.3} \
             (faer f64/f32 {:.2}x, pd f64 / faer f32 {:.2}x)",
            ours * 1e3,
            faer64 * 1e3,
            faer32 * 1e3,
            faer64 / faer32,
            ours / faer32
        );
    });
    // The probe's matrix `I + L` (`L` the graph Laplacian), then stiffer
    // ones, `I + s L`: the f32 solve's error grows with the condition
    // number (about `1 + 16 s` here), and each defect correction shrinks
    // the error by about that error's size, so a matrix whose condition
    // nears 1 / eps_f32 (1.7e7) cannot be solved this way.
    let base = laplacian_values(factor.pattern());
    print_errors("I + L", &accuracy(&mut factor, &base, &b, 2));
    let p = factor.pattern().clone();
    for scale in [1e2, 1e4, 1e6] {
        let mut values = base.clone();
        for c in 0..p.n {
            for k in p.col_ptr[c]..p.col_ptr[c + 1] {
                values[k] = if p.row_idx[k] == c {
                    1.0 + scale * (base[k] - 1.0)
                } else {
                    scale * base[k]
                };
            }
        }
        print_errors(
            &format!("I + {scale:.0e} L"),
            &accuracy(&mut factor, &values, &b, 3),
        );
    }
}

#[test]
#[ignore = "timing: run on a quiet machine"]
fn precision_probe() {
    let rounds: usize = std::env::var("PD_SOLVE_ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(21);
    let beam = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [80, 14, 14]).unwrap();
    probe("beam 80 x 14 x 14", &beam, rounds);
    if let Some(mesh) = armadillo() {
        probe("armadillo", &mesh, rounds);
    }
    let large = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [130, 26, 26]).unwrap();
    probe("beam 130 x 26 x 26", &large, rounds.min(5));
}
