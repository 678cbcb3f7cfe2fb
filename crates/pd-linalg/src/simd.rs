//! The one run-time SIMD dispatch of the workspace: a [`Kernel`] handed to
//! [`dispatch`] runs compiled for the widest instruction set the CPU has,
//! AVX-512 (F, DQ and VL), else AVX2 (`pulp`'s x86-64-v3), else the plain
//! path, and is told which one through [`Isa`]. The local step's batched
//! projections (pd-constraints) and the supernodal solve
//! ([`crate::cholesky`]) both go through it.
//!
//! Every kernel of the workspace computes each value with the same IEEE
//! operations in the same order at every width (Rust never contracts
//! `a * b + c` into a fused multiply-add), so every path gives the same
//! bits; [`limit_width`] lets a test check that on one CPU.
//!
//! AVX-512 comes from a `#[target_feature]` function of this module rather
//! than pulp's `x86-v4` feature: cargo unifies features, and faer's kernels
//! dispatch through pulp, so that feature could change the factor's code
//! paths (and bits). Hence the module's `unsafe`: the one call is sound
//! because an [`Avx512`] token exists only after the CPU was found to have
//! the features.
#![allow(unsafe_code)]

use std::cell::Cell;

/// The AVX2 instruction set (with FMA, BMI and the rest of x86-64-v3), as
/// pulp's token: exists only when the CPU has it.
#[cfg(target_arch = "x86_64")]
pub type Avx2 = pulp::x86::V3;
/// No AVX2 off x86-64: the type has no value.
#[cfg(not(target_arch = "x86_64"))]
#[derive(Clone, Copy, Debug)]
pub enum Avx2 {}

/// Proof that the CPU has AVX-512 F, DQ and VL.
#[derive(Clone, Copy, Debug)]
pub struct Avx512 {
    _detected: (),
}

impl Avx512 {
    /// The token, if the CPU has the features.
    #[inline(always)]
    pub fn try_new() -> Option<Self> {
        #[cfg(target_arch = "x86_64")]
        {
            (std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512dq")
                && std::arch::is_x86_feature_detected!("avx512vl"))
            .then_some(Self { _detected: () })
        }
        #[cfg(not(target_arch = "x86_64"))]
        None
    }
}

/// The instruction set a [`Kernel`] was compiled for by [`dispatch`].
#[derive(Clone, Copy, Debug)]
pub enum Isa {
    /// AVX-512 F, DQ and VL, and AVX2 (the kernel may use either's
    /// explicit operations).
    Avx512(Avx512, Avx2),
    /// AVX2.
    Avx2(Avx2),
    /// No explicit SIMD.
    Plain,
}

impl Isa {
    /// The AVX2 token, on either SIMD path.
    #[inline(always)]
    pub fn avx2(self) -> Option<Avx2> {
        match self {
            Isa::Avx512(_, avx2) | Isa::Avx2(avx2) => Some(avx2),
            Isa::Plain => None,
        }
    }
}

/// An operation compiled for the instruction set [`dispatch`] picks.
pub trait Kernel {
    /// What the operation returns.
    type Output;
    /// The operation; must be `#[inline(always)]` (with everything it
    /// calls) so that it is compiled inside the dispatcher's
    /// `#[target_feature]` function.
    fn run(self, isa: Isa) -> Self::Output;
}

/// Runs `kernel` compiled for the widest instruction set the CPU has
/// (checked at run time) and allowed on this thread ([`limit_width`]).
#[inline(always)]
pub fn dispatch<K: Kernel>(kernel: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    if allowed(4)
        && let Some(avx2) = Avx2::try_new()
    {
        if allowed(8)
            && let Some(avx512) = Avx512::try_new()
        {
            // SAFETY: the `Avx512` token and pulp's `V3` prove that the CPU
            // has every feature `run_avx512` is compiled with.
            return unsafe { run_avx512(kernel, avx512, avx2) };
        }
        struct Adapter<K>(K, Avx2);
        impl<K: Kernel> pulp::WithSimd for Adapter<K> {
            type Output = K::Output;
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, _: S) -> K::Output {
                self.0.run(Isa::Avx2(self.1))
            }
        }
        return pulp::Simd::vectorize(avx2, Adapter(kernel, avx2));
    }
    kernel.run(Isa::Plain)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512dq,avx512vl")]
unsafe fn run_avx512<K: Kernel>(kernel: K, avx512: Avx512, avx2: Avx2) -> K::Output {
    kernel.run(Isa::Avx512(avx512, avx2))
}

/// Runs `f` through [`dispatch`], handing it the AVX2 token on both SIMD
/// paths (for kernels written with explicit 4-lane operations, which the
/// AVX-512 path runs too, with the compiler's loops eight rows wide) or
/// `None` for the plain path. With AVX-512 the compiler's loops run eight
/// rows per instruction with 32 registers (no spilled broadcasts): the
/// supernodal solve is 4-11 % faster than with AVX2 on the beams, with the
/// same bits (docs/design/performance.md, "pd's own supernodal solve").
#[inline(always)]
pub fn vectorized(f: impl FnOnce(Option<Avx2>)) {
    struct Closure<F>(F);
    impl<F: FnOnce(Option<Avx2>)> Kernel for Closure<F> {
        type Output = ();
        #[inline(always)]
        fn run(self, isa: Isa) {
            (self.0)(isa.avx2())
        }
    }
    dispatch(Closure(f))
}

thread_local! {
    static WIDEST: Cell<usize> = const { Cell::new(usize::MAX) };
}

/// Whether [`dispatch`] may use lanes of `width` f64 values on this thread.
#[inline(always)]
fn allowed(width: usize) -> bool {
    WIDEST.get() >= width
}

/// Limits [`dispatch`] on this thread to lanes of at most `width` values
/// (8: AVX-512, 4: AVX2, 1: the plain path; `usize::MAX`: no limit), so
/// that a test can run every path on one CPU. Changes no result, only
/// which instructions compute it.
pub fn limit_width(width: usize) {
    WIDEST.set(width);
}

/// The widths [`dispatch`] can run at on this CPU, widest first, the plain
/// path (1) last; says on stderr which ones this CPU cannot test.
pub fn widths() -> Vec<usize> {
    let mut widths = Vec::new();
    #[cfg(target_arch = "x86_64")]
    for (width, present) in [
        (8, Avx512::try_new().is_some()),
        (4, Avx2::try_new().is_some()),
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

/// Runs `check` once per SIMD width this CPU has (8, then 4, not the
/// plain path), with [`dispatch`] limited to that width on this thread.
pub fn for_each_simd_width(mut check: impl FnMut(usize)) {
    for width in widths().into_iter().filter(|&w| w > 1) {
        limit_width(width);
        check(width);
        limit_width(usize::MAX);
    }
}
