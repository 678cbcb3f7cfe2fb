//! Tests of `supernodal_solve.rs` (kept apart so that file stays under
//! 600 lines).

use super::super::calibration::{laplacian_values, tet_pattern};
use super::super::{SymbolicFactor, dissection_candidates};
use pd_mesh::Point;

/// Prefetching changes no value: a beam's split solve (a factor below
/// the prefetch threshold, the prefetches forced on) gives the same
/// bits with and without them, on 1 and 2 threads.
#[test]
fn prefetches_change_no_bit() {
    let beam = pd_mesh::generators::box_tets([1.0, 0.2, 0.2], [40, 8, 8]).unwrap();
    let pattern = tet_pattern(&beam);
    let candidates = dissection_candidates(&pattern, beam.vertices());
    let mut factor = SymbolicFactor::analyse(pattern, &candidates).unwrap();
    let values = laplacian_values(factor.pattern());
    let numeric = factor.factorise(&values).expect("diagonally dominant");
    let n = factor.pattern().n;
    let mut solve = factor.fast_solve.take().expect("a supernodal factor");
    assert!(solve.is_split(), "the beam's tree splits");
    let rhs: Vec<Point> = (0..n)
        .map(|i| Point::new((i % 13) as f64, (i % 7) as f64 - 3.0, (i % 5) as f64))
        .collect();
    let mut solved = |prefetch: bool, threads: usize| {
        solve.set_prefetch(prefetch);
        let mut x = rhs.clone();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| solve.solve(&factor.symbolic, &numeric.values, &mut x));
        x.iter()
            .flat_map(|p| [p.x, p.y, p.z].map(f64::to_bits))
            .collect::<Vec<_>>()
    };
    let plain = solved(false, 1);
    assert_eq!(plain, solved(true, 1));
    assert_eq!(plain, solved(true, 2));
    assert_eq!(plain, solved(false, 2));
}
