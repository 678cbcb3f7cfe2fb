//! The phases of a step alone, on the benchmark cantilever: the local step
//! with 1 and 2 threads, the global solve (right-hand side and the n x 3
//! solve), and the numeric Cholesky factorisation, at about 2k, 20k and
//! 100k vertices (`PD_BENCH_SIZES` selects; `--test` runs 2k only).

use std::time::Duration;

use criterion::{Criterion, SamplingMode, criterion_group, criterion_main};
use pd_benches::Beam;

fn phases(c: &mut Criterion) {
    for (cells, label) in pd_benches::selected_sizes() {
        let mut group = c.benchmark_group(format!("phases/{label}"));
        group.sample_size(10);
        group.warm_up_time(Duration::from_millis(200));
        group.measurement_time(Duration::from_secs(match label {
            "2k" => 1,
            "20k" => 3,
            _ => 20,
        }));
        if label != "2k" {
            group.sampling_mode(SamplingMode::Flat);
        }
        for threads in [1, 2] {
            let mut sim = Beam {
                cells,
                threads,
                ..Beam::default()
            }
            .simulation(pd_damping::registry::UNDAMPED, "be")
            .expect("beam builds");
            sim.run(2).expect("the beam steps");
            group.bench_function(format!("local/{threads}-threads"), |b| {
                b.iter(|| sim.profile_local_step())
            });
            if threads == 1 {
                group.bench_function("global-solve", |b| {
                    b.iter(|| sim.profile_global_solve().expect("factor cached"))
                });
                group.bench_function("numeric-factorisation", |b| {
                    b.iter(|| sim.profile_factorise().expect("positive definite"))
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, phases);
criterion_main!(benches);
