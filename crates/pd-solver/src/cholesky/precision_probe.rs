//! What a single-precision factor would buy the global solve (ignored:
//! it times solves, so its numbers mean something only on a quiet
//! machine):
//!
//! ```sh
//! cargo test --release -p pd-solver --lib precision_probe -- --ignored --nocapture
//! ```
//!
//! For the 80 x 14 x 14 beam, the 130 x 26 x 26 beam and the TetGen
//! armadillo (skipped if absent) it times, one thread, the minimum of
//! `PD_SOLVE_ROUNDS` (21) three-column solves by pd's supernodal solve
//! (f64), by faer's (f64) and by faer's on the same factor rounded to
//! f32, and prints the f32 solve's error against the f64 one's, alone and
//! after each of two defect corrections (`x += solve32(b - A x)`, the
//! residual in f64).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::LltRef;
use faer::{Conj, Mat, Par};

use super::calibration::{armadillo, laplacian_factor};

fn min_time(rounds: usize, mut f: impl FnMut()) -> f64 {
    (0..rounds)
        .map(|_| {
            let t = std::time::Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// `y = A x` for the scalar lower pattern `p` with `values`, 3 columns.
fn product(p: &super::LowerPattern, values: &[f64], x: &Mat<f64>) -> Mat<f64> {
    let mut y = Mat::<f64>::zeros(p.n, 3);
    for c in 0..p.n {
        let range = p.col_ptr[c]..p.col_ptr[c + 1];
        for (&r, &v) in p.row_idx[range.clone()].iter().zip(&values[range]) {
            for j in 0..3 {
                y[(r, j)] += v * x[(c, j)];
                if r != c {
                    y[(c, j)] += v * x[(r, j)];
                }
            }
        }
    }
    y
}

fn max_rel(a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    let mut num = 0.0f64;
    let mut den = 0.0f64;
    for j in 0..3 {
        for i in 0..a.nrows() {
            num = num.max((a[(i, j)] - b[(i, j)]).abs());
            den = den.max(b[(i, j)].abs());
        }
    }
    num / den
}

fn probe(label: &str, mesh: &pd_mesh::Mesh, rounds: usize) {
    let (mut factor, numeric) = laplacian_factor(mesh);
    let b = Mat::<f64>::from_fn(factor.pattern().n, 3, |i, j| {
        ((i * (j + 3)) % 17) as f64 - 8.0
    });
    let n = factor.pattern().n;
    let values64 = factor.faer_values(&numeric).into_owned();
    let values32: Vec<f32> = values64.iter().map(|&v| v as f32).collect();
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
        // pd's own solve (f64).
        let mut points: Vec<pd_mesh::Point> = (0..n)
            .map(|i| pd_mesh::Point::new(b[(i, 0)], b[(i, 1)], b[(i, 2)]))
            .collect();
        let original = points.clone();
        let ours = min_time(rounds, || {
            points.copy_from_slice(&original);
            factor.solve_points(&numeric, &mut points);
        });
        let x64 = Mat::<f64>::from_fn(n, 3, |i, j| points[i][j]);
        // faer's solve, f64 and f32.
        let symbolic = &factor.symbolic;
        let mut s64 = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
        let mut s32 = MemBuffer::new(symbolic.solve_in_place_scratch::<f32>(3, Par::Seq));
        let l64 = LltRef::<usize, f64>::new(symbolic, &values64);
        let l32 = LltRef::<usize, f32>::new(symbolic, &values32);
        let mut w64 = b.clone();
        let faer64 = min_time(rounds, || {
            w64.copy_from(&b);
            l64.solve_in_place_with_conj(Conj::No, w64.as_mut(), Par::Seq, MemStack::new(&mut s64));
        });
        let b32 = Mat::<f32>::from_fn(n, 3, |i, j| b[(i, j)] as f32);
        let mut w32 = b32.clone();
        let faer32 = min_time(rounds, || {
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
        // Accuracy: the f32 solve, then defect corrections in f64.
        let a_values = super::calibration::laplacian_values(factor.pattern());
        let mut x = Mat::<f64>::from_fn(n, 3, |i, j| w32[(i, j)] as f64);
        print!("  f32 error against f64: {:.2e}", max_rel(&x, &x64));
        for _ in 0..2 {
            let ax = product(factor.pattern(), &a_values, &x);
            let mut r = Mat::<f32>::from_fn(n, 3, |i, j| (b[(i, j)] - ax[(i, j)]) as f32);
            l32.solve_in_place_with_conj(Conj::No, r.as_mut(), Par::Seq, MemStack::new(&mut s32));
            x += Mat::<f64>::from_fn(n, 3, |i, j| r[(i, j)] as f64);
            print!(", corrected {:.2e}", max_rel(&x, &x64));
        }
        println!();
    });
    // Stiffer matrices, `I + s L` (`L` the graph Laplacian): the f32
    // solve's error grows with the condition number (about `1 + 16 s`
    // here), and each defect correction shrinks the error by about that
    // error's size, so a matrix whose condition nears 1 / eps_f32 (1.7e7)
    // cannot be solved this way.
    let base = super::calibration::laplacian_values(factor.pattern());
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
        let numeric = factor.factorise(&values).expect("positive definite");
        let values64 = factor.faer_values(&numeric).into_owned();
        let values32: Vec<f32> = values64.iter().map(|&v| v as f32).collect();
        let l64 = LltRef::<usize, f64>::new(&factor.symbolic, &values64);
        let l32 = LltRef::<usize, f32>::new(&factor.symbolic, &values32);
        let mut s64 = MemBuffer::new(factor.symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
        let mut s32 = MemBuffer::new(factor.symbolic.solve_in_place_scratch::<f32>(3, Par::Seq));
        let mut x64 = b.clone();
        l64.solve_in_place_with_conj(Conj::No, x64.as_mut(), Par::Seq, MemStack::new(&mut s64));
        let mut w32 = Mat::<f32>::from_fn(n, 3, |i, j| b[(i, j)] as f32);
        l32.solve_in_place_with_conj(Conj::No, w32.as_mut(), Par::Seq, MemStack::new(&mut s32));
        let mut x = Mat::<f64>::from_fn(n, 3, |i, j| w32[(i, j)] as f64);
        print!("  I + {scale:.0e} L: f32 error {:.2e}", max_rel(&x, &x64));
        for _ in 0..3 {
            let ax = product(&p, &values, &x);
            let mut r = Mat::<f32>::from_fn(n, 3, |i, j| (b[(i, j)] - ax[(i, j)]) as f32);
            l32.solve_in_place_with_conj(Conj::No, r.as_mut(), Par::Seq, MemStack::new(&mut s32));
            x += Mat::<f64>::from_fn(n, 3, |i, j| r[(i, j)] as f64);
            print!(", corrected {:.2e}", max_rel(&x, &x64));
        }
        println!();
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
