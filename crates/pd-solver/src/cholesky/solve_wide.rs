//! The solve's AVX-512 path: the function [`vectorized`](super::vectorized)
//! runs the kernels in when the CPU has AVX-512 F, DQ and VL.
//!
//! Like `pd-constraints`' `polar_batch/lane_sets.rs`, this uses a
//! `#[target_feature]` function of its own rather than pulp's `x86-v4`
//! feature, which cargo would unify into faer's kernels. Hence the
//! module's `unsafe`: the one call is sound because an [`Avx512`] token
//! exists only after the CPU was found to have the features.
#![allow(unsafe_code)]

use super::Simd;

/// Proof that the CPU has AVX-512 F, DQ and VL.
#[derive(Clone, Copy)]
pub(super) struct Avx512 {
    _detected: (),
}

impl Avx512 {
    /// The token, if the CPU has the features.
    #[inline(always)]
    pub fn try_new() -> Option<Self> {
        (std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512vl"))
        .then_some(Self { _detected: () })
    }
}

/// Runs `f` compiled with AVX-512 (and AVX2, whose kernels it also calls).
#[inline(always)]
pub(super) fn run(f: impl FnOnce(Option<Simd>), simd: Simd, _: Avx512) {
    // SAFETY: the `Avx512` token and pulp's `V3` prove that the CPU has
    // every feature `run_avx512` is compiled with.
    unsafe { run_avx512(f, simd) }
}

#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512dq,avx512vl")]
unsafe fn run_avx512(f: impl FnOnce(Option<Simd>), simd: Simd) {
    f(Some(simd))
}

/// The widest lanes [`vectorized`](super::vectorized) may use on this
/// thread: always all of them outside tests.
#[cfg(not(test))]
#[inline(always)]
pub(super) fn allowed(_width: usize) -> bool {
    true
}

#[cfg(test)]
thread_local! {
    static WIDEST: std::cell::Cell<usize> = const { std::cell::Cell::new(usize::MAX) };
}

#[cfg(test)]
pub(super) fn allowed(width: usize) -> bool {
    WIDEST.get() >= width
}

/// Limits [`vectorized`](super::vectorized) on this thread to lanes of at
/// most `width` values (8: AVX-512, 4: AVX2, 1: the plain path;
/// `usize::MAX`: no limit).
#[cfg(test)]
pub(crate) fn limit_width(width: usize) {
    WIDEST.set(width);
}

/// The widths [`vectorized`](super::vectorized) can run at on this CPU,
/// widest first; says on stderr which ones this CPU cannot test.
#[cfg(test)]
pub(crate) fn widths() -> Vec<usize> {
    let mut widths = Vec::new();
    for (width, present) in [
        (8, Avx512::try_new().is_some()),
        (4, pulp::x86::V3::try_new().is_some()),
    ] {
        if present {
            widths.push(width);
        } else {
            eprintln!("this CPU lacks the {width}-lane instructions: that path was not tested");
        }
    }
    widths.push(1);
    widths
}
