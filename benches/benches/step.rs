//! One step of the benchmark cantilever (`pd_benches::Beam`, 10
//! iterations) for every damping model with backward Euler and implicit
//! midpoint, at about 2k, 20k and 100k vertices.
//!
//! Every timed step starts from the same state (the undamped beam after 5
//! steps), so the state-dependence of the projections does not leak into a
//! comparison of models. `PD_BENCH_SIZES=2k,20k` selects sizes; the smoke
//! run (`cargo bench -p pd-benches -- --test`) uses 2k only. The lagged
//! Rayleigh model is left out at 100k: its 3n x 3n system (about 290k
//! unknowns) is refactorised every step and needs several GB
//! (docs/design/performance.md).

use std::time::{Duration, Instant};

use criterion::{Criterion, SamplingMode, criterion_group, criterion_main};
use pd_benches::{Beam, INTEGRATORS, damping_models};
use pd_damping::registry::UNDAMPED;

fn step(c: &mut Criterion) {
    for (cells, label) in pd_benches::selected_sizes() {
        let mut group = c.benchmark_group(format!("step/{label}"));
        if label != "2k" {
            group.sampling_mode(SamplingMode::Flat);
            group.sample_size(10);
            group.warm_up_time(Duration::from_millis(100));
            group.measurement_time(Duration::from_secs(if label == "20k" { 5 } else { 30 }));
        } else {
            group.sample_size(20);
            group.warm_up_time(Duration::from_millis(300));
            group.measurement_time(Duration::from_secs(2));
        }
        let beam = Beam {
            cells,
            ..Beam::default()
        };
        for integrator in INTEGRATORS {
            let start = {
                let mut sim = beam.simulation(UNDAMPED, integrator).expect("beam builds");
                sim.run(5).expect("the beam steps");
                sim.state().clone()
            };
            for model in damping_models() {
                let lagged = pd_benches::damping(model)
                    .expect("a registry preset")
                    .implicit_matrix()
                    .is_lagged();
                if lagged && label == "100k" {
                    continue;
                }
                let mut sim = beam.simulation(model, integrator).expect("beam builds");
                group.bench_function(format!("{integrator}/{model}"), |b| {
                    b.iter_custom(|iters| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iters {
                            sim.set_state(start.clone()).expect("a valid state");
                            let t = Instant::now();
                            std::hint::black_box(sim.step().expect("the beam steps"));
                            total += t.elapsed();
                        }
                        total
                    })
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, step);
criterion_main!(benches);
