//! Where a 3-column supernodal solve spends its time (ignored: it times
//! solves, so its numbers mean something only on a quiet machine):
//!
//! ```sh
//! cargo test -p pd-linalg --lib solve_profile -- --ignored --nocapture
//! ```
//!
//! For the 80 x 14 x 14 beam of the bench report's limits section and the
//! TetGen armadillo (skipped if absent) it prints the supernodes by width
//! class (how many, the values of their diagonal blocks' lower triangles and
//! below them) and the minimum and median wall time (one thread) of the solve's four parts: the
//! permutation in, the forward and backward substitutions, the permutation
//! out (docs/design/performance.md, "The solve against the machine"), and a
//! hash of one solve's bits (a kernel change that keeps the summation
//! order keeps it), then the minimum forward and backward times with the
//! diagonal blocks tiled from several widths (`solve_diagonal.rs`;
//! `usize::MAX`: never, the column-by-column order). `PD_SOLVE_WIDTH=4`
//! (or `1`) times the AVX2 (or plain) path on a CPU with AVX-512.

use crate::cholesky::supernodal::SupernodalSolve;
use crate::fixtures::{armadillo, laplacian_factor};

fn profile(label: &str, mesh: &pd_mesh::Mesh) {
    let (mut factor, numeric) = laplacian_factor(mesh);
    let n = factor.pattern().n;
    println!(
        "{label}: {n} unknowns, {} stored values ({:.1} MB), {} supernodes",
        factor.factor_len(),
        8.0 * factor.factor_len() as f64 / 1e6,
        factor.supernodes()
    );
    println!("  width <= | supernodes | diagonal values | below values");
    for (widest, count, diagonal, below) in SupernodalSolve::width_classes(&factor.symbolic) {
        println!("  {widest:>8} | {count:>10} | {diagonal:>15} | {below:>12}");
    }
    let mut rhs: Vec<pd_mesh::Point> = (0..n)
        .map(|i| pd_mesh::Point::new((i % 13) as f64, (i % 7) as f64, (i % 5) as f64))
        .collect();
    let mut solve = factor.fast_solve.take().expect("a supernodal factor");
    let [top, bin0, bin1] = solve.split_values(&factor.symbolic);
    println!("  stored values: top of the tree {top}, bins {bin0} and {bin1}");
    // The bits of one solve, to compare kernels that must not change them.
    let mut once = rhs.clone();
    solve.solve(&factor.symbolic, &numeric, &mut once);
    println!("  solution bits: {:016x}", bits_hash(&once));
    // `PD_SOLVE_ROUNDS` solves (41 unless set): more rounds find quieter
    // moments on a busy machine.
    let rounds: usize = std::env::var("PD_SOLVE_ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(41);
    let mut parts: [Vec<f64>; 4] = Default::default();
    // One thread (the bins run one after the other); wall time against a
    // fixed start, read as a minimum over the rounds on a busy machine.
    let start = std::time::Instant::now();
    let clock = || start.elapsed().as_secs_f64();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    // `PD_SOLVE_WIDTH=4` (or 1): the AVX2 (or plain) path on a CPU with
    // AVX-512.
    #[cfg(target_arch = "x86_64")]
    if let Some(width) = std::env::var("PD_SOLVE_WIDTH")
        .ok()
        .and_then(|w| w.parse().ok())
    {
        pool.broadcast(|_| crate::simd::limit_width(width));
        println!("  lanes limited to {width}");
    }
    pool.install(|| {
        for _ in 0..rounds {
            let timed = solve.solve_timed(&factor.symbolic, &numeric, &mut rhs, &clock);
            for (part, t) in parts.iter_mut().zip(timed) {
                part.push(t);
            }
        }
    });
    // The narrowest blocks solved by tiles (`solve_diagonal.rs`), swept.
    let sweep: &[[usize; 2]] = &[
        [usize::MAX, usize::MAX],
        [8, usize::MAX],
        [16, usize::MAX],
        [32, usize::MAX],
        [16, 16],
        [16, 32],
        [16, 64],
        [16, 128],
    ];
    for &blocked in sweep {
        solve.set_blocked(blocked);
        let mut times: [Vec<f64>; 2] = Default::default();
        pool.install(|| {
            for _ in 0..rounds {
                let t = solve.solve_timed(&factor.symbolic, &numeric, &mut rhs, &clock);
                times[0].push(t[1]);
                times[1].push(t[2]);
            }
        });
        let [f, b] = times.map(|v| v.into_iter().fold(f64::INFINITY, f64::min) * 1e3);
        println!("  tiles from {blocked:?} columns: min forward {f:.3} ms, backward {b:.3} ms");
    }
    let [a, b, c, d] = parts.each_mut().map(|v| {
        v.sort_by(f64::total_cmp);
        (v[0] * 1e3, v[v.len() / 2] * 1e3)
    });
    println!(
        "  ms min / median, 1 thread: permute in {:.3} / {:.3}, forward {:.3} / {:.3}, \
         backward {:.3} / {:.3}, permute out {:.3} / {:.3}",
        a.0, a.1, b.0, b.1, c.0, c.1, d.0, d.1
    );
}

/// FNV-1a over the bits of every coordinate.
fn bits_hash(points: &[pd_mesh::Point]) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325_u64;
    for v in points.iter().flat_map(|p| [p.x, p.y, p.z]) {
        for byte in v.to_bits().to_le_bytes() {
            hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    hash
}

#[test]
#[ignore = "timing: run on a quiet machine"]
fn solve_profile() {
    let beam = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [80, 14, 14]).unwrap();
    profile("beam 80 x 14 x 14", &beam);
    if let Some(mesh) = armadillo() {
        profile("armadillo", &mesh);
    }
}
