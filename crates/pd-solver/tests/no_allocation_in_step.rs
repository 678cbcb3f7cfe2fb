//! A step allocates nothing after the first (DESIGN.md 4.3): every buffer
//! is sized when the simulation is built, factorisations are cached (or, for
//! lagged models, recomputed into preallocated buffers).
//!
//! A counting global allocator counts heap allocations made by this thread
//! and the pool's workers while steps run. Implementing `GlobalAlloc` is
//! unsafe by nature; this file is the one place the workspace allows it.
#![allow(unsafe_code)]

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use common::{SCHEMES, clamped_beam};
use pd_damping::{Damping, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged};
use pd_mesh::Point;
use pd_solver::{Settings, Simulation};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every method forwards to the system allocator unchanged; counting
// touches only an atomic.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
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

#[test]
fn steps_after_the_first_do_not_allocate() {
    // Every simulation stays alive to the end. A dropped simulation's
    // thread pool shuts down asynchronously, and an exiting worker hands its
    // crossbeam-epoch garbage bag to a global queue, a ~2 KB allocation. On
    // a loaded machine that landed inside a later simulation's counting
    // window (1 allocation of 2072 bytes, not on this thread), which is not
    // an allocation of the step being measured.
    let mut alive = Vec::new();
    for threads in [1, 2] {
        for scheme in SCHEMES {
            for damping in models() {
                let name = damping.name();
                let (mut model, _) = clamped_beam([6, 2, 2], [0.6, 0.2, 0.2], 9, 1e5);
                let mesh = model.bodies()[0].mesh.clone();
                let masses = model.masses().to_vec();
                // A free second body, so rigid-motion code paths run too.
                let free = model
                    .add_body(mesh.translated(Point::new(0.0, 1.0, 0.0)), masses)
                    .unwrap();
                model.add_tet_strain(free, 1e5, None).unwrap();
                let settings = Settings {
                    dt: 0.01,
                    iterations: 5,
                    tolerance: 1e-6,
                    threads,
                    ..Settings::default()
                };
                let mut sim =
                    Simulation::new(model, scheme.integrator(), damping, settings).unwrap();
                sim.add_rigid_velocity(1, Point::new(0.1, 0.0, 0.0), Point::new(0.0, 0.0, 2.0));
                // Two steps: BDF-2's second step uses its own coefficients
                // (a second cached factorisation) and fills its history.
                sim.run(2).unwrap();
                ALLOCATIONS.store(0, Ordering::SeqCst);
                COUNTING.store(true, Ordering::SeqCst);
                for _ in 0..5 {
                    sim.step().unwrap();
                }
                COUNTING.store(false, Ordering::SeqCst);
                let count = ALLOCATIONS.load(Ordering::SeqCst);
                assert_eq!(
                    count, 0,
                    "{scheme:?} + {name}, {threads} thread(s): {count} allocations in 5 steps"
                );
                alive.push(sim);
            }
        }
    }
}
