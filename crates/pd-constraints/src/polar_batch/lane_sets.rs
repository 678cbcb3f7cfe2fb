//! The instruction sets the batched projections run on, behind one trait
//! ([`Lanes`]), so that the lane code is written once for every width: 8
//! f64 lanes with AVX-512 (F and DQ, through `core::arch`), 4 with AVX2
//! (`pulp`'s x86-64-v3), and the scalar path elsewhere. [`vectorize`] picks
//! the widest the CPU has at run time.
//!
//! Every operation is one correctly rounded IEEE operation per lane (no
//! fused multiply-add, no approximate reciprocal or square root), so a lane
//! computes the same bits at any width. AVX-512 comes from `core::arch`
//! rather than pulp's `x86-v4` feature: cargo unifies features, and faer's
//! kernels dispatch through pulp, so that feature could change the factor's
//! code paths (and bits); `core::arch` touches nothing outside this module.
//!
//! The AVX-512 intrinsics are `unsafe` to call outside a function compiled
//! with those features, hence this module's `unsafe` blocks (the
//! workspace's only `unsafe` besides the METIS FFI): each is sound because
//! an [`Avx512`] token exists only after the CPU has been checked.
#![allow(unsafe_code)]

use core::arch::x86_64::{
    __m512d, __mmask8, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _mm512_abs_pd,
    _mm512_add_pd, _mm512_cmp_pd_mask, _mm512_div_pd, _mm512_mask_blend_pd, _mm512_max_pd,
    _mm512_mul_pd, _mm512_set1_pd, _mm512_setr_pd, _mm512_sqrt_pd, _mm512_storeu_pd, _mm512_sub_pd,
    _mm512_xor_pd,
};

use pulp::x86::V3;
use pulp::{f64x4, m64, m64x4};

/// `WIDTH` f64 lanes and the operations the lane code needs, each the
/// correctly rounded IEEE operation per lane. Comparisons are ordered
/// (false where either side is NaN). Implemented by tokens that exist only
/// when the CPU has the instructions, so the methods are safe to call (the
/// code must still be inlined into a `#[target_feature]` function to be
/// compiled with them: see [`vectorize`]).
pub(crate) trait Lanes: Copy {
    /// Lanes per register.
    const WIDTH: usize;
    /// `WIDTH` f64 values.
    type F: Copy;
    /// A `WIDTH`-lane mask.
    type M: Copy;
    /// The lanes of an [`Self::F`] as an array.
    type Values: Copy + Default + AsRef<[f64]> + AsMut<[f64]>;

    fn splat(self, v: f64) -> Self::F;
    /// The lanes `v[0]`, `v[1]`, ... in one register.
    fn pack(self, v: Self::Values) -> Self::F;
    /// The lanes of `v` as an array (the inverse of [`Self::pack`]).
    fn values(self, v: Self::F) -> Self::Values;
    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    fn div(self, a: Self::F, b: Self::F) -> Self::F;
    fn sqrt(self, a: Self::F) -> Self::F;
    /// `|a|`: the sign bit cleared.
    fn abs(self, a: Self::F) -> Self::F;
    /// `vmaxpd a, b`: `b` where either is NaN or both are zero.
    fn max(self, a: Self::F, b: Self::F) -> Self::F;
    /// `-a`: the sign bit flipped.
    fn neg(self, a: Self::F) -> Self::F;
    fn gt(self, a: Self::F, b: Self::F) -> Self::M;
    fn lt(self, a: Self::F, b: Self::F) -> Self::M;
    fn ge(self, a: Self::F, b: Self::F) -> Self::M;
    fn le(self, a: Self::F, b: Self::F) -> Self::M;
    fn and(self, a: Self::M, b: Self::M) -> Self::M;
    fn or(self, a: Self::M, b: Self::M) -> Self::M;
    /// `a` and not `b`.
    fn and_not(self, a: Self::M, b: Self::M) -> Self::M;
    /// No lane set.
    fn none(self) -> Self::M;
    /// `if_true` in the lanes of `mask`, `if_false` elsewhere.
    fn select(self, mask: Self::M, if_true: Self::F, if_false: Self::F) -> Self::F;
    /// Bit `l` set where lane `l` of `mask` is.
    fn bits(self, mask: Self::M) -> u32;
}

/// An operation on lanes of any width, run by [`vectorize`].
pub(crate) trait WithLanes {
    type Output;
    /// The operation; must be `#[inline(always)]` (with everything it
    /// calls) so that it is compiled inside the dispatcher's
    /// `#[target_feature]` function.
    fn run<S: Lanes>(self, s: S) -> Self::Output;
}

/// Runs `op` on the widest lanes the CPU offers (8 with AVX-512 F and DQ,
/// 4 with AVX2), or returns `None` without running it.
pub(crate) fn vectorize<Op: WithLanes>(op: Op) -> Option<Op::Output> {
    if allowed(Avx512::WIDTH)
        && let Some(s) = Avx512::try_new()
    {
        // SAFETY: the token proves the CPU has the features `run_avx512`
        // is compiled with.
        return Some(unsafe { run_avx512(s, op) });
    }
    if allowed(V3::WIDTH)
        && let Some(s) = V3::try_new()
    {
        struct Adapter<Op>(V3, Op);
        impl<Op: WithLanes> pulp::WithSimd for Adapter<Op> {
            type Output = Op::Output;
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, _: S) -> Op::Output {
                self.1.run(self.0)
            }
        }
        return Some(pulp::Simd::vectorize(s, Adapter(s, op)));
    }
    None
}

#[target_feature(enable = "avx512f,avx512dq")]
unsafe fn run_avx512<Op: WithLanes>(s: Avx512, op: Op) -> Op::Output {
    op.run(s)
}

#[cfg(not(test))]
#[inline(always)]
fn allowed(_width: usize) -> bool {
    true
}

#[cfg(test)]
thread_local! {
    static WIDEST: std::cell::Cell<usize> = const { std::cell::Cell::new(usize::MAX) };
}

#[cfg(test)]
fn allowed(width: usize) -> bool {
    WIDEST.get() >= width
}

/// Runs `check` once per SIMD width this CPU has (8, then 4), with
/// [`vectorize`] limited to that width on this thread; says on stderr
/// which widths could not be exercised here.
#[cfg(test)]
pub(crate) fn for_each_width(mut check: impl FnMut(usize)) {
    for (width, present) in [
        (8, Avx512::try_new().is_some()),
        (4, V3::try_new().is_some()),
    ] {
        if !present {
            eprintln!("this CPU lacks the {width}-lane instructions: that path was not tested");
            continue;
        }
        WIDEST.set(width);
        check(width);
        WIDEST.set(usize::MAX);
    }
}

/// Proof that the CPU has AVX-512 F and DQ.
#[derive(Clone, Copy)]
pub(crate) struct Avx512 {
    _detected: (),
}

impl Avx512 {
    pub(crate) fn try_new() -> Option<Self> {
        (is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512dq"))
            .then_some(Self { _detected: () })
    }
}

// SAFETY (every `unsafe` block below): an `Avx512` exists only when the CPU
// has AVX-512 F and DQ, which these intrinsics need.
impl Lanes for Avx512 {
    const WIDTH: usize = 8;
    type F = __m512d;
    type M = __mmask8;
    type Values = [f64; 8];

    #[inline(always)]
    fn splat(self, v: f64) -> __m512d {
        unsafe { _mm512_set1_pd(v) }
    }
    #[inline(always)]
    fn pack(self, v: [f64; 8]) -> __m512d {
        unsafe { _mm512_setr_pd(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]) }
    }
    #[inline(always)]
    fn values(self, v: __m512d) -> [f64; 8] {
        let mut out = [0.0; 8];
        unsafe { _mm512_storeu_pd(out.as_mut_ptr(), v) };
        out
    }
    #[inline(always)]
    fn add(self, a: __m512d, b: __m512d) -> __m512d {
        unsafe { _mm512_add_pd(a, b) }
    }
    #[inline(always)]
    fn sub(self, a: __m512d, b: __m512d) -> __m512d {
        unsafe { _mm512_sub_pd(a, b) }
    }
    #[inline(always)]
    fn mul(self, a: __m512d, b: __m512d) -> __m512d {
        unsafe { _mm512_mul_pd(a, b) }
    }
    #[inline(always)]
    fn div(self, a: __m512d, b: __m512d) -> __m512d {
        unsafe { _mm512_div_pd(a, b) }
    }
    #[inline(always)]
    fn sqrt(self, a: __m512d) -> __m512d {
        unsafe { _mm512_sqrt_pd(a) }
    }
    #[inline(always)]
    fn abs(self, a: __m512d) -> __m512d {
        unsafe { _mm512_abs_pd(a) }
    }
    #[inline(always)]
    fn max(self, a: __m512d, b: __m512d) -> __m512d {
        unsafe { _mm512_max_pd(a, b) }
    }
    #[inline(always)]
    fn neg(self, a: __m512d) -> __m512d {
        unsafe { _mm512_xor_pd(a, _mm512_set1_pd(-0.0)) }
    }
    #[inline(always)]
    fn gt(self, a: __m512d, b: __m512d) -> __mmask8 {
        unsafe { _mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, b) }
    }
    #[inline(always)]
    fn lt(self, a: __m512d, b: __m512d) -> __mmask8 {
        unsafe { _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a, b) }
    }
    #[inline(always)]
    fn ge(self, a: __m512d, b: __m512d) -> __mmask8 {
        unsafe { _mm512_cmp_pd_mask::<_CMP_GE_OQ>(a, b) }
    }
    #[inline(always)]
    fn le(self, a: __m512d, b: __m512d) -> __mmask8 {
        unsafe { _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b) }
    }
    #[inline(always)]
    fn and(self, a: __mmask8, b: __mmask8) -> __mmask8 {
        a & b
    }
    #[inline(always)]
    fn or(self, a: __mmask8, b: __mmask8) -> __mmask8 {
        a | b
    }
    #[inline(always)]
    fn and_not(self, a: __mmask8, b: __mmask8) -> __mmask8 {
        a & !b
    }
    #[inline(always)]
    fn none(self) -> __mmask8 {
        0
    }
    #[inline(always)]
    fn select(self, mask: __mmask8, if_true: __m512d, if_false: __m512d) -> __m512d {
        // `blend(k, a, b)` takes `b` where `k` is set.
        unsafe { _mm512_mask_blend_pd(mask, if_false, if_true) }
    }
    #[inline(always)]
    fn bits(self, mask: __mmask8) -> u32 {
        u32::from(mask)
    }
}

impl Lanes for V3 {
    const WIDTH: usize = 4;
    type F = f64x4;
    type M = m64x4;
    type Values = [f64; 4];

    #[inline(always)]
    fn splat(self, v: f64) -> f64x4 {
        self.splat_f64x4(v)
    }
    #[inline(always)]
    fn pack(self, [a, b, c, d]: [f64; 4]) -> f64x4 {
        f64x4(a, b, c, d)
    }
    #[inline(always)]
    fn values(self, v: f64x4) -> [f64; 4] {
        [v.0, v.1, v.2, v.3]
    }
    #[inline(always)]
    fn add(self, a: f64x4, b: f64x4) -> f64x4 {
        self.add_f64x4(a, b)
    }
    #[inline(always)]
    fn sub(self, a: f64x4, b: f64x4) -> f64x4 {
        self.sub_f64x4(a, b)
    }
    #[inline(always)]
    fn mul(self, a: f64x4, b: f64x4) -> f64x4 {
        self.mul_f64x4(a, b)
    }
    #[inline(always)]
    fn div(self, a: f64x4, b: f64x4) -> f64x4 {
        self.div_f64x4(a, b)
    }
    #[inline(always)]
    fn sqrt(self, a: f64x4) -> f64x4 {
        self.sqrt_f64x4(a)
    }
    #[inline(always)]
    fn abs(self, a: f64x4) -> f64x4 {
        self.abs_f64x4(a)
    }
    #[inline(always)]
    fn max(self, a: f64x4, b: f64x4) -> f64x4 {
        pulp::Simd::max_f64s(self, a, b)
    }
    #[inline(always)]
    fn neg(self, a: f64x4) -> f64x4 {
        pulp::Simd::xor_f64s(self, a, self.splat_f64x4(-0.0))
    }
    #[inline(always)]
    fn gt(self, a: f64x4, b: f64x4) -> m64x4 {
        self.cmp_gt_f64x4(a, b)
    }
    #[inline(always)]
    fn lt(self, a: f64x4, b: f64x4) -> m64x4 {
        self.cmp_lt_f64x4(a, b)
    }
    #[inline(always)]
    fn ge(self, a: f64x4, b: f64x4) -> m64x4 {
        self.cmp_ge_f64x4(a, b)
    }
    #[inline(always)]
    fn le(self, a: f64x4, b: f64x4) -> m64x4 {
        self.cmp_le_f64x4(a, b)
    }
    #[inline(always)]
    fn and(self, a: m64x4, b: m64x4) -> m64x4 {
        self.and_m64x4(a, b)
    }
    #[inline(always)]
    fn or(self, a: m64x4, b: m64x4) -> m64x4 {
        self.or_m64x4(a, b)
    }
    #[inline(always)]
    fn and_not(self, a: m64x4, b: m64x4) -> m64x4 {
        self.and_m64x4(a, self.not_m64x4(b))
    }
    #[inline(always)]
    fn none(self) -> m64x4 {
        self.splat_m64x4(m64::new(false))
    }
    #[inline(always)]
    fn select(self, mask: m64x4, if_true: f64x4, if_false: f64x4) -> f64x4 {
        self.select_f64x4(mask, if_true, if_false)
    }
    #[inline(always)]
    fn bits(self, mask: m64x4) -> u32 {
        // A mask lane is all ones or all zeros: its sign bit says which.
        self.avx._mm256_movemask_pd(pulp::cast(mask)) as u32
    }
}
