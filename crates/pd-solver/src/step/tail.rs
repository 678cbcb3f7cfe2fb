//! The global step's tail: the solution becomes the new displacement, and
//! how far it moved is summed. In plain local-global iterations
//! ([`super::iteration::LocalGlobal`]) the tail also writes the next local
//! step's projection points `q = x_n + c2 dx`, so that the local step starts
//! with its parallel projection pass at once; on more threads a second
//! thread writes them and then stays awake until the tail ends, so that it
//! is ready to take its share of that pass (docs/design/performance.md, "Two
//! threads in the local step"). Every variant gives the same bits: the sums run
//! in the same sequential order, and each `q` is the same
//! expression of the same values.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use pd_mesh::Point;

use super::iteration::IterationChange;
use crate::system::GlobalStep;

/// How long the second thread waits, at most, for the tail to end after
/// writing `q` (a bound for a preempted or very long tail; the armadillo's
/// tail takes about 0.06 ms). Past it the thread returns to rayon, which
/// lets it fall asleep and wakes it for the local step as before.
const MAX_WAIT: Duration = Duration::from_millis(1);

/// Moves the solution of the last solve into `displacement` (free vertices
/// only) and returns the change in the mass norm, summed over the free
/// vertices in order.
pub(crate) fn take_solution(
    global: &GlobalStep,
    masses: &[f64],
    displacement: &mut [Point],
) -> IterationChange {
    take_solution_with(global, masses, displacement, |_, _| {})
}

/// [`take_solution`], calling `also(v, new)` with each free vertex's new
/// displacement after it is taken.
#[inline(always)]
fn take_solution_with(
    global: &GlobalStep,
    masses: &[f64],
    displacement: &mut [Point],
    mut also: impl FnMut(usize, Point),
) -> IterationChange {
    let mut change = IterationChange::default();
    for (f, &v) in global.free().iter().enumerate() {
        let new = global.solution(f);
        let m = masses[v];
        change.change_squared += m * (new - displacement[v]).norm_squared();
        change.displacement_squared += m * new.norm_squared();
        displacement[v] = new;
        also(v, new);
    }
    change
}

/// [`take_solution`], and `q[v] = x_n[v] + c2 dx[v]` at every free vertex
/// for the new displacement (fixed vertices keep theirs: their
/// displacement does not change in the iterations). On one thread in the
/// same loop; on more, `q` on a second thread (rayon's `join`, allocating
/// nothing), which then waits for the sums, spinning, at most
/// [`MAX_WAIT`].
pub(crate) fn take_solution_and_q(
    global: &GlobalStep,
    masses: &[f64],
    (x_n, c2): (&[Point], f64),
    displacement: &mut [Point],
    q: &mut [Point],
) -> IterationChange {
    if rayon::current_num_threads() <= 1 {
        return take_solution_with(global, masses, displacement, |v, new| {
            q[v] = x_n[v] + new * c2;
        });
    }
    let done = AtomicBool::new(false);
    let (change, ()) = rayon::join(
        || {
            let change = take_solution(global, masses, displacement);
            done.store(true, Ordering::Release);
            change
        },
        || {
            for (f, &v) in global.free().iter().enumerate() {
                q[v] = x_n[v] + global.solution(f) * c2;
            }
            wait_for(&done);
        },
    );
    change
}

/// Spins until `done` is set or [`MAX_WAIT`] has passed.
fn wait_for(done: &AtomicBool) {
    let start = Instant::now();
    let mut spins = 0u32;
    while !done.load(Ordering::Acquire) {
        std::hint::spin_loop();
        spins = spins.wrapping_add(1);
        // The clock is read once per 64 spins (a few hundred ns).
        if spins.is_multiple_of(64) && start.elapsed() > MAX_WAIT {
            return;
        }
    }
}
