//! The measurement behind [`crate::cholesky::SUPERNODE_COST`] (ignored: it times
//! solves, so its numbers mean something only on a quiet machine):
//!
//! ```sh
//! cargo test --release -p pd-linalg --lib calibration -- --ignored --nocapture
//! ```
//!
//! For the 95,499-, 18,225- and 19,456-vertex beams and the TetGen armadillo (read
//! from `../shared/meshes/armadillo` beside the repository, skipped if
//! absent) it prints, for AMD, the geometric dissection and METIS, the
//! stored values, the supernodes, the modelled cost, and the measured
//! numeric factorisation and 3-column solves: faer's hot, and pd's own
//! (`solve_points`) hot and cold (64 MiB streamed through the caches
//! first, as the local step does in a time step). It ends with the fit of
//! `time = a stored + b supernodes` to pd's solves, hot and cold, that
//! docs/design/performance.md quotes.

use crate::cholesky::*;
use crate::fixtures::{armadillo, laplacian_values, tet_pattern};

/// This thread's time on a CPU so far, in seconds (Linux's schedstat; wall
/// time elsewhere): time spent waiting for a core on a loaded machine does
/// not count, so the numbers stay comparable while other work runs.
fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or_else(
            || {
                static START: std::sync::LazyLock<std::time::Instant> =
                    std::sync::LazyLock::new(std::time::Instant::now);
                START.elapsed().as_secs_f64()
            },
            |ns| ns * 1e-9,
        )
}

/// The symbolic analysis of `pattern` in the elimination order `order`
/// (old indices in pivot order), whatever AMD would cost, and the order's
/// inverse (`inverse[old] = new`).
fn forced(pattern: &LowerPattern, order: &[usize]) -> (Vec<usize>, SymbolicCholesky<usize>) {
    let mut inverse = vec![0; order.len()];
    for (new, &old) in order.iter().enumerate() {
        inverse[old] = new;
    }
    let perm = faer::perm::PermRef::new_checked(order, &inverse, pattern.n);
    let symbolic = factorize_symbolic_cholesky(
        pattern.symbolic(),
        Side::Lower,
        SymmetricOrdering::Custom(perm),
        CholeskySymbolicParams::default(),
    )
    .unwrap();
    (inverse, symbolic)
}

/// MiB streamed through the caches before each cold solve, as `pd-probe
/// phases --evict-mib 64` does: in a step the local step streams the
/// elements between two solves, so the solve reads its factor cold.
const EVICT_MIB: usize = 64;

/// One ordering's solve measured: the factor's stored values and
/// supernodes, and pd's 3-column solve (`solve_points`) median in ms, hot
/// (repeated back to back) and cold (after [`EVICT_MIB`] MiB streamed).
struct Sample {
    stored: f64,
    supernodes: f64,
    hot: f64,
    cold: f64,
}

/// (min, median) in ms of `reps` runs of `f`, which returns the time of
/// the part it times, in seconds.
fn timed(reps: usize, mut f: impl FnMut() -> f64) -> (f64, f64) {
    let mut times: Vec<f64> = (0..reps).map(|_| f()).collect();
    times.sort_by(f64::total_cmp);
    (times[0] * 1e3, times[times.len() / 2] * 1e3)
}

/// The fastest of `repetitions` wall times of `f`, s.
pub(super) fn fastest(repetitions: usize, mut f: impl FnMut()) -> f64 {
    let times = (0..repetitions).map(|_| wall_time(&mut f));
    times.fold(f64::INFINITY, f64::min)
}

/// The wall time of `f`, in seconds. Not [`cpu_seconds`]: this machine's
/// schedstat advances in 4 ms ticks, and pd's solve may hand half the tree
/// to a rayon worker, whose time this thread's clock would not count (the
/// fit runs on a 1-thread pool, as a 1-thread step does).
pub(super) fn wall_time(f: impl FnOnce()) -> f64 {
    let start = std::time::Instant::now();
    f();
    start.elapsed().as_secs_f64()
}

/// Prints one ordering's line: structure, modelled cost, measured times
/// (faer's solve hot; pd's `solve_points` hot and cold), and returns the
/// sample for the fit.
fn measure(name: &str, mut factor: SymbolicFactor, evict: &mut [f64]) -> Sample {
    let values = laplacian_values(factor.pattern());
    let n = factor.pattern().n;
    let start = cpu_seconds();
    let numeric = factor.factorise(&values).expect("diagonally dominant");
    let factorise = cpu_seconds() - start;
    let mut rhs = faer::Mat::<f64>::from_fn(n, 3, |i, j| ((i * 7 + j) % 13) as f64);
    let fast = factor.fast_solve.take();
    let faer = timed(15, || {
        wall_time(|| factor.solve_in_place(&numeric, rhs.as_mut()))
    });
    factor.fast_solve = fast;
    let b: Vec<pd_mesh::Point> = (0..n)
        .map(|i| pd_mesh::Point::new((i % 13) as f64, (i % 7) as f64, 1.0))
        .collect();
    let mut x = b.clone();
    let hot = timed(15, || {
        x.copy_from_slice(&b);
        wall_time(|| factor.solve_points(&numeric, &mut x))
    });
    let cold = timed(15, || {
        x.copy_from_slice(&b);
        for v in evict.iter_mut() {
            *v = std::hint::black_box(*v + 1.0);
        }
        wall_time(|| factor.solve_points(&numeric, &mut x))
    });
    println!(
        "  {name:<10} stored {:>10} supernodes {:>6} cost {:>10}  factorise {:>8.1} ms  solve min/median: faer hot {:>7.2}/{:>7.2}, pd hot {:>7.2}/{:>7.2}, pd cold {:>7.2}/{:>7.2} ms",
        factor.factor_len(),
        factor.supernodes(),
        solve_cost(&factor.symbolic),
        factorise * 1e3,
        faer.0,
        faer.1,
        hot.0,
        hot.1,
        cold.0,
        cold.1,
    );
    Sample {
        stored: factor.factor_len() as f64,
        supernodes: factor.supernodes() as f64,
        hot: hot.1,
        cold: cold.1,
    }
}

/// The least-squares fit, in relative errors, of `time = a stored + b
/// supernodes` to `samples` (`time` picked by `pick`, ms): prints a (ns
/// per stored value), b (us per supernode), b / a (the `SUPERNODE_COST`
/// it implies) and each sample's relative residual.
fn fit(regime: &str, samples: &[Sample], pick: fn(&Sample) -> f64) {
    // Rows (stored / t, supernodes / t) against 1: the normal equations.
    let (mut ss, mut sk, mut kk, mut s1, mut k1) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for sample in samples {
        let t = pick(sample);
        let (s, k) = (sample.stored / t, sample.supernodes / t);
        (ss, sk, kk, s1, k1) = (ss + s * s, sk + s * k, kk + k * k, s1 + s, k1 + k);
    }
    let det = ss * kk - sk * sk;
    let a = (s1 * kk - k1 * sk) / det;
    let b = (ss * k1 - sk * s1) / det;
    let residuals: Vec<String> = samples
        .iter()
        .map(|x| {
            format!(
                "{:+.0}%",
                100.0 * ((a * x.stored + b * x.supernodes) / pick(x) - 1.0)
            )
        })
        .collect();
    println!(
        "fit {regime}: a = {:.3} ns per stored value, b = {:.3} us per supernode, b / a = {:.0} values; residuals {}",
        a * 1e6,
        b * 1e3,
        b / a,
        residuals.join(" ")
    );
}

#[test]
#[ignore = "timing: run on a quiet machine"]
fn solve_cost_calibration() {
    let mut meshes = vec![
        (
            "beam 130 x 26 x 26",
            pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [130, 26, 26]).unwrap(),
        ),
        (
            "beam 80 x 14 x 14",
            pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [80, 14, 14]).unwrap(),
        ),
        (
            "beam 75 x 15 x 15",
            pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [75, 15, 15]).unwrap(),
        ),
    ];
    meshes.extend(armadillo().map(|mesh| ("armadillo", mesh)));
    let mut evict = vec![1.0f64; EVICT_MIB * 1024 * 1024 / 8];
    let mut samples = Vec::new();
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for (label, mesh) in meshes {
        let pattern = tet_pattern(&mesh);
        println!("{label}: {} vertices", pattern.n);
        let candidates = dissection_candidates(&pattern, mesh.vertices());
        let names = ["geometric", "metis"];
        let amd = SymbolicFactor::analyse(pattern.clone(), &[]).unwrap();
        samples.push(one_thread.install(|| measure("amd", amd, &mut evict)));
        for (name, order) in names.iter().zip(&candidates) {
            // Forced: the candidate alone, even where AMD is cheaper.
            let (_, symbolic) = forced(&pattern, order);
            let factor = SymbolicFactor::with_symbolic(pattern.clone().into(), symbolic);
            samples.push(one_thread.install(|| measure(name, factor, &mut evict)));
        }
        let chosen = SymbolicFactor::analyse(pattern.clone(), &candidates).unwrap();
        println!(
            "  chosen: {} stored, {} supernodes",
            chosen.factor_len(),
            chosen.supernodes()
        );
    }
    fit("hot", &samples, |s| s.hot);
    fit("cold", &samples, |s| s.cold);
}

/// How much METIS's fill depends on its random seed and on the number of
/// separators it tries per level, on the 95,499-vertex beam (the fill target
/// compares nnz(L) with CHOLMOD's, which also runs METIS):
/// prints nnz(L), stored values, supernodes and the modelled solve cost
/// per option set. docs/design/performance.md ("Choosing the ordering",
/// "METIS's seed") quotes the output.
///
/// ```sh
/// cargo test -p pd-linalg --lib metis_option_fill -- --ignored --nocapture
/// ```
#[cfg(feature = "metis")]
#[test]
#[ignore = "measurement: prints a table, about 10 s"]
fn metis_option_fill() {
    let mesh = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [130, 26, 26]).unwrap();
    let pattern = tet_pattern(&mesh);
    let (start, neighbours) = adjacency(&pattern);
    let seed = metis_sys::moptions_et_METIS_OPTION_SEED;
    let nseps = metis_sys::moptions_et_METIS_OPTION_NSEPS;
    let mut runs: Vec<(String, Vec<(i32, i32)>)> = vec![("default".into(), vec![])];
    runs.extend((1..9).map(|s| (format!("seed {s}"), vec![(seed, s)])));
    runs.extend((2..4).map(|k| (format!("nseps {k}"), vec![(nseps, k)])));
    // METIS's other ordering options (defaults: niter 10, ufactor 200,
    // iptype EDGE, rtype SEP1SIDED, ctype SHEM, compress 1, ccorder 0).
    let niter = metis_sys::moptions_et_METIS_OPTION_NITER;
    let ufactor = metis_sys::moptions_et_METIS_OPTION_UFACTOR;
    runs.extend([20, 50].map(|k| (format!("niter {k}"), vec![(niter, k)])));
    runs.extend([30, 100, 400].map(|k| (format!("ufactor {k}"), vec![(ufactor, k)])));
    runs.extend([
        (
            "iptype node".to_string(),
            vec![(metis_sys::moptions_et_METIS_OPTION_IPTYPE, 3)],
        ),
        (
            "rtype 2-sided".to_string(),
            vec![(metis_sys::moptions_et_METIS_OPTION_RTYPE, 2)],
        ),
        (
            "ctype rm".to_string(),
            vec![(metis_sys::moptions_et_METIS_OPTION_CTYPE, 0)],
        ),
        (
            "ccorder 1".to_string(),
            vec![(metis_sys::moptions_et_METIS_OPTION_CCORDER, 1)],
        ),
        (
            "compress 0".to_string(),
            vec![(metis_sys::moptions_et_METIS_OPTION_COMPRESS, 0)],
        ),
    ]);
    for (name, overrides) in runs {
        let start_time = std::time::Instant::now();
        let order = crate::cholesky::metis::node_nd_with(&start, &neighbours, &overrides).unwrap();
        let seconds = start_time.elapsed().as_secs_f64();
        let (inverse, symbolic) = forced(&pattern, &order);
        let nnz = exact_factor_nnz(&pattern, &inverse);
        println!(
            "{name:<10} nnz {nnz:>10} stored {:>10} supernodes {:>6} cost {:>10} metis {seconds:.3} s",
            symbolic.len_val(),
            supernode_count(&symbolic),
            solve_cost(&symbolic),
        );
    }
}
