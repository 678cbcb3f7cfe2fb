//! A step allocates nothing after the first (docs/design/performance.md,
//! "no heap allocation in a step after the first"): every buffer
//! is sized when the simulation is built, factorisations are cached (or, for
//! lagged models, recomputed into preallocated buffers).
//!
//! A counting global allocator counts heap allocations made by this thread
//! and the pool's workers while steps run (by every thread of the process,
//! so the file holds one `#[test]`, whose parts run one after the other,
//! and the simulations are never dropped). Implementing `GlobalAlloc` is
//! unsafe by nature; this file is the one place the workspace allows it.
#![allow(unsafe_code)]

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use common::{SCHEMES, Scheme, clamped_beam};
use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged};
use pd_mesh::Point;
use pd_solver::{Predictor, Settings, Simulation, SolverMethod, SolverSpec};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every method forwards to the system allocator unchanged; counting
// touches only an atomic.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            LARGEST.fetch_max(new_size, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn models() -> Vec<Box<dyn Damping>> {
    vec![
        Box::new(NoDamping),
        Box::new(EtherDrag::rate(1.0).unwrap()),
        Box::new(EtherDrag::implicit(1.0).unwrap()),
        Box::new(PbdDamping::new(0.1).unwrap()),
        Box::new(LaplacianDamping::new(0.01, 0.5, false).unwrap()),
        Box::new(LaplacianDamping::new(0.01, 0.0, true).unwrap()),
        Box::new(RayleighLagged::new(0.01, 0.5).unwrap()),
    ]
}

/// One test, in two parts: the counter counts every thread's allocations,
/// and the test harness allocates when a test ends and the next starts.
#[test]
fn steps_after_the_first_do_not_allocate() {
    every_damping_model_with_the_default_method();
    every_method_and_predictor();
    every_method_in_accuracy_mode();
}

/// Every method stopped by an accuracy target (the estimate's sums, and
/// L-BFGS's and Newton's first step by plain local-global, which measures
/// the contraction their estimate needs), on 1 and 2 threads.
fn every_method_in_accuracy_mode() {
    let mut alive = Vec::new();
    let mut failures = Vec::new();
    for threads in [1, 2] {
        for method in SolverMethod::ALL {
            let damping = Box::new(NoDamping);
            let mut sim = two_beams(Scheme::ImplicitMidpoint, damping, threads, 10_000, 0.01);
            let spec = SolverSpec {
                method,
                ..SolverSpec::default()
            };
            sim.set_position_solver(spec.create().unwrap());
            sim.run(2).unwrap();
            let count = allocations_in(&mut sim, 8);
            if count != 0 {
                failures.push(format!(
                    "{} in accuracy mode, {threads} thread(s): {count} allocations in 8 steps",
                    method.name()
                ));
            }
            alive.push(sim);
        }
    }
    keep_alive(alive);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The default method and predictor with every damping model and
/// integrator, on 1 and 2 threads.
fn every_damping_model_with_the_default_method() {
    // Every simulation stays alive to the end. A dropped simulation's
    // thread pool shuts down asynchronously, and an exiting worker hands its
    // crossbeam-epoch garbage bag to a global queue, a ~2 KB allocation. On
    // a loaded machine that landed inside a later simulation's counting
    // window (1 allocation of 2072 bytes, not on this thread), which is not
    // an allocation of the step being measured. They are never dropped
    // ([`keep_alive`]), since the second part counts after this one.
    let mut alive = Vec::new();
    for threads in [1, 2] {
        for scheme in SCHEMES {
            for damping in models() {
                let name = damping.name();
                let mut sim = two_beams(scheme, damping, threads, 5, 0.0);
                // Two steps: BDF-2's second step uses its own coefficients
                // (a second cached factorisation) and fills its history.
                sim.run(2).unwrap();
                let count = allocations_in(&mut sim, 5);
                assert_eq!(
                    count, 0,
                    "{scheme:?} + {name}, {threads} thread(s): {count} allocations in 5 steps"
                );
                alive.push(sim);
            }
        }
    }
    keep_alive(alive);
}

/// Leaks `simulations`, so that their thread pools never shut down: an
/// exiting pool worker allocates (see above), and the two parts of the test
/// count one after the other.
fn keep_alive(simulations: Vec<Simulation>) {
    std::mem::forget(simulations);
}

/// A clamped 6 x 2 x 2 beam and a free copy of it spinning beside it (so
/// that rigid-motion code paths run too), `iterations` a step, tolerance
/// 1e-6, or with `accuracy` > 0 that target instead.
fn two_beams(
    scheme: Scheme,
    damping: Box<dyn Damping>,
    threads: usize,
    iterations: usize,
    accuracy: f64,
) -> Simulation {
    let (mut model, _) = clamped_beam([6, 2, 2], [0.6, 0.2, 0.2], 9, 1e5);
    let mesh = model.bodies()[0].mesh.clone();
    let masses = model.masses().to_vec();
    let free = model
        .add_body(mesh.translated(Point::new(0.0, 1.0, 0.0)), masses)
        .unwrap();
    model.add_tet_strain(free, 1e5, None).unwrap();
    let settings = Settings {
        dt: 0.01,
        iterations,
        tolerance: if accuracy > 0.0 { 0.0 } else { 1e-6 },
        accuracy,
        threads,
        ..Settings::default()
    };
    let mut sim = Simulation::new(model, scheme.integrator(), damping, settings).unwrap();
    sim.add_rigid_velocity(1, Point::new(0.1, 0.0, 0.0), Point::new(0.0, 0.0, 2.0))
        .unwrap();
    sim
}

/// Heap allocations (and reallocations) made while `sim` takes `steps`
/// steps.
fn allocations_in(sim: &mut Simulation, steps: usize) -> usize {
    ALLOCATIONS.store(0, Ordering::SeqCst);
    LARGEST.store(0, Ordering::SeqCst);
    COUNTING.store(true, Ordering::SeqCst);
    for _ in 0..steps {
        sim.step().unwrap();
    }
    COUNTING.store(false, Ordering::SeqCst);
    ALLOCATIONS.load(Ordering::SeqCst)
}

/// Every iteration method with every predictor, integrator, no damping and
/// Laplacian damping, on 1 and 2 threads: no allocation after the first
/// two steps (BDF-2's second step caches its own factorisation, and every
/// predictor forgets the first step's correction, which is of backward
/// Euler's kind, so BDF-2's first predicted step is its third). 12 counted
/// steps: every buffer of the methods (Anderson's and L-BFGS's rings,
/// Newton's Hessian system) and of the predictors (the stored corrections,
/// the safeguard's scratch, the fitted predictor's Gram cache) is sized in
/// the first step. The fitted predictor runs with its default order 4 over
/// 8 steps (12 stored corrections: the history grows during the counted
/// steps and fits from its 8th) and with order 2 over 3 steps (5 stored:
/// it fills, then wraps around). The fit itself is the one exception
/// (below).
fn every_method_and_predictor() {
    let predictors = [
        Predictor::Inertial,
        Predictor::Extrapolated,
        Predictor::Linear,
        Predictor::FITTED,
        Predictor::Fitted {
            order: 2,
            equations: 3,
        },
    ];
    let mut alive = Vec::new();
    let mut failures = Vec::new();
    for threads in [1, 2] {
        for scheme in SCHEMES {
            for laplacian in [false, true] {
                for method in SolverMethod::ALL {
                    for predictor in predictors {
                        let damping: Box<dyn Damping> = if laplacian {
                            Box::new(LaplacianDamping::new(0.01, 0.5, false).unwrap())
                        } else {
                            Box::new(NoDamping)
                        };
                        let name = damping.name();
                        // 12 iterations: Chebyshev's first step
                        // estimates `rho` after 4 plain iterations (its
                        // later steps accelerate from the 2nd), its Ritz
                        // window fills at the 10th and starts again, and
                        // the methods' rings wrap.
                        let mut sim = two_beams(scheme, damping, threads, 12, 0.0);
                        let spec = SolverSpec {
                            method,
                            window: 3,
                            ..SolverSpec::default()
                        };
                        sim.set_position_solver(spec.create().unwrap());
                        sim.set_predictor(predictor);
                        sim.run(2).unwrap();
                        let count = allocations_in(&mut sim, 12);
                        let largest = LARGEST.load(Ordering::SeqCst);
                        if let Predictor::Fitted { order, .. } = predictor {
                            // The exception: the fit's k x k normal
                            // equations (step/fitted.rs) go through
                            // nalgebra's SymmetricEigen, which takes and
                            // returns heap matrices (its input, its
                            // internal buffers, and G a in the residual).
                            // Nothing larger than one of them (8 k^2
                            // bytes; the history's Gram matrix is
                            // 8 (k + m)^2, a correction 24 bytes a vertex)
                            // and at most 10 a step (measured: 76 in the 12
                            // steps for k = 2, which fits from the 5th
                            // step; 48 for k = 4, from the 9th: 8 a fit).
                            let bound = 8 * usize::from(order).pow(2);
                            if largest > bound || count > 10 * 12 {
                                failures.push(format!(
                                    "{} + {predictor:?} + {scheme:?} + {name}, {threads} \
                                     thread(s): {count} allocations in 12 steps, the \
                                     largest {largest} bytes (at most {bound})",
                                    method.name()
                                ));
                            }
                        } else if count != 0 {
                            failures.push(format!(
                                "{} + {predictor:?} + {scheme:?} + {name}, {threads} thread(s): \
                                 {count} allocations in 12 steps",
                                method.name()
                            ));
                        }
                        alive.push(sim);
                    }
                }
            }
        }
    }
    keep_alive(alive);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
