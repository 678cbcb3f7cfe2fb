//! The instruction sets the batched projections run on, behind one trait
//! ([`Lanes`]), so that the lane code is written once for every width: 8
//! f64 lanes with AVX-512 (F, DQ and VL, through `core::arch`), 4 with AVX2
//! (`pulp`'s x86-64-v3), and the scalar path elsewhere. [`vectorize`] picks
//! the widest the CPU has at run time.
//!
//! Every operation is one correctly rounded IEEE operation per lane (no
//! fused multiply-add, no approximate reciprocal or square root), so a lane
//! computes the same bits at any width. AVX-512 comes from `core::arch`
//! rather than pulp's `x86-v4` feature, for the reason
//! [`pd_linalg::simd`] gives; the dispatch is that module's.
//!
//! The AVX-512 intrinsics are `unsafe` to call outside a function compiled
//! with those features, hence this module's `unsafe` blocks (the
//! workspace's only `unsafe` besides the METIS FFI and pd-linalg's SIMD
//! dispatch): each is sound
//! because an [`Avx512`] token exists only after the CPU has been checked.
//!
//! The `_mm512_*` intrinsics are stable since Rust 1.89, the workspace's
//! declared `rust-version`.
#![allow(unsafe_code)]

use core::arch::x86_64::{
    __m256d, __m512d, __mmask8, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _MM_HINT_ET0,
    _MM_HINT_T0, _mm_prefetch, _mm256_maskz_loadu_pd, _mm256_setzero_pd, _mm512_abs_pd,
    _mm512_add_pd, _mm512_castpd256_pd512, _mm512_cmp_pd_mask, _mm512_div_pd, _mm512_insertf64x4,
    _mm512_loadu_pd, _mm512_mask_blend_pd, _mm512_max_pd, _mm512_mul_pd, _mm512_permutex2var_pd,
    _mm512_set1_pd, _mm512_setr_epi64, _mm512_setr_pd, _mm512_shuffle_f64x2, _mm512_sqrt_pd,
    _mm512_storeu_pd, _mm512_sub_pd, _mm512_unpackhi_pd, _mm512_unpacklo_pd, _mm512_xor_pd,
};

use pd_linalg::simd::{Avx512, Isa, Kernel, dispatch};
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

    /// `N` values of each of `WIDTH` items moved into lanes: lane `l` of
    /// register `i` is `row(&items[l])[i]` (each row must hold at least
    /// `N` values). Only loads and shuffles, so the values keep their bits.
    #[inline(always)]
    fn transpose<'a, T, const N: usize>(
        self,
        items: &'a [T],
        row: impl Fn(&'a T) -> &'a [f64],
    ) -> [Self::F; N] {
        transpose_by_value(self, items, row)
    }

    /// A hint that the cache lines of the bytes `range` will be read
    /// (`WRITE`: written) soon; no effect on any value, and the addresses
    /// need not be valid. Nothing by default.
    #[inline(always)]
    fn prefetch<const WRITE: bool>(self, _range: core::ops::Range<*const u8>) {}
}

/// [`Lanes::transpose`] one value at a time.
#[inline(always)]
fn transpose_by_value<'a, S: Lanes, T, const N: usize>(
    s: S,
    items: &'a [T],
    row: impl Fn(&'a T) -> &'a [f64],
) -> [S::F; N] {
    let mut lanes = [S::Values::default(); N];
    for (l, item) in items.iter().enumerate().take(S::WIDTH) {
        for (lane, v) in lanes.iter_mut().zip(&row(item)[..N]) {
            lane.as_mut()[l] = *v;
        }
    }
    let mut out = [s.splat(0.0); N];
    for (out, lane) in out.iter_mut().zip(lanes) {
        *out = s.pack(lane);
    }
    out
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
/// 4 with AVX2), through the workspace's one SIMD dispatch
/// ([`pd_linalg::simd::dispatch`]), or returns `None` without running it.
pub(crate) fn vectorize<Op: WithLanes>(op: Op) -> Option<Op::Output> {
    struct OnLanes<Op>(Op);
    impl<Op: WithLanes> Kernel for OnLanes<Op> {
        type Output = Option<Op::Output>;
        #[inline(always)]
        fn run(self, isa: Isa) -> Self::Output {
            match isa {
                Isa::Avx512(s, _) => Some(self.0.run(s)),
                Isa::Avx2(s) => Some(self.0.run(s)),
                Isa::Plain => None,
            }
        }
    }
    dispatch(OnLanes(op))
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

    #[inline(always)]
    fn prefetch<const WRITE: bool>(self, range: core::ops::Range<*const u8>) {
        let (start, end) = (range.start.cast::<i8>(), range.end.cast::<i8>());
        // From the start of the first cache line, one prefetch per line.
        let mut at = start.wrapping_sub(start as usize % 64);
        while at < end {
            // SAFETY: a prefetch never faults and changes no value.
            unsafe {
                if WRITE {
                    _mm_prefetch::<_MM_HINT_ET0>(at);
                } else {
                    _mm_prefetch::<_MM_HINT_T0>(at);
                }
            }
            at = at.wrapping_add(64);
        }
    }

    /// 8 x 8 and 8 x 3 transposes in registers for the two shapes the
    /// projection gathers (an element's 9 operator values, a vertex's 3
    /// coordinates): whole rows loaded at once and shuffled, about half
    /// the shuffles of building each register from 8 scalars.
    #[inline(always)]
    fn transpose<'a, T, const N: usize>(
        self,
        items: &'a [T],
        row: impl Fn(&'a T) -> &'a [f64],
    ) -> [__m512d; N] {
        let Ok(items8) = <&[T; 8]>::try_from(items) else {
            return transpose_by_value(self, items, row);
        };
        let rows = [
            row(&items8[0]),
            row(&items8[1]),
            row(&items8[2]),
            row(&items8[3]),
            row(&items8[4]),
            row(&items8[5]),
            row(&items8[6]),
            row(&items8[7]),
        ];
        let mut out = [self.splat(0.0); N];
        if N >= 8 && rows.iter().all(|r| r.len() >= N) {
            let mut r = [self.splat(0.0); 8];
            for (r, row) in r.iter_mut().zip(&rows) {
                // SAFETY: every row holds at least the 8 values loaded.
                *r = unsafe { _mm512_loadu_pd(row.as_ptr()) };
            }
            out[..8].copy_from_slice(&transpose8(r));
            for (i, out) in out.iter_mut().enumerate().skip(8) {
                let mut v = [0.0; 8];
                for (v, r) in v.iter_mut().zip(&rows) {
                    *v = r[i];
                }
                *out = self.pack(v);
            }
            return out;
        }
        if N == 3 && rows.iter().all(|r| r.len() >= 3) {
            let mut p = [unsafe { _mm256_setzero_pd() }; 8];
            for (p, row) in p.iter_mut().zip(&rows) {
                // SAFETY: the mask loads only the 3 values each row holds.
                *p = unsafe { _mm256_maskz_loadu_pd(0b111, row.as_ptr()) };
            }
            out.copy_from_slice(&transpose8x3(p));
            return out;
        }
        transpose_by_value(self, items, row)
    }
}

/// Columns of the 8 x 8 matrix whose rows are `r`.
#[inline(always)]
fn transpose8(r: [__m512d; 8]) -> [__m512d; 8] {
    // SAFETY: only called below `run_avx512` (AVX-512 F present).
    unsafe {
        // Pairs of rows interleaved: `t[2 j]` holds the even entries of
        // rows `2 j` and `2 j + 1`, `t[2 j + 1]` the odd ones.
        let t = [
            _mm512_unpacklo_pd(r[0], r[1]),
            _mm512_unpackhi_pd(r[0], r[1]),
            _mm512_unpacklo_pd(r[2], r[3]),
            _mm512_unpackhi_pd(r[2], r[3]),
            _mm512_unpacklo_pd(r[4], r[5]),
            _mm512_unpackhi_pd(r[4], r[5]),
            _mm512_unpacklo_pd(r[6], r[7]),
            _mm512_unpackhi_pd(r[6], r[7]),
        ];
        // 128-bit lanes 0 and 2 (`0x88`) or 1 and 3 (`0xDD`) of each.
        let (u0, u2) = (
            _mm512_shuffle_f64x2::<0x88>(t[0], t[2]),
            _mm512_shuffle_f64x2::<0xDD>(t[0], t[2]),
        );
        let (u4, u6) = (
            _mm512_shuffle_f64x2::<0x88>(t[4], t[6]),
            _mm512_shuffle_f64x2::<0xDD>(t[4], t[6]),
        );
        let (u1, u3) = (
            _mm512_shuffle_f64x2::<0x88>(t[1], t[3]),
            _mm512_shuffle_f64x2::<0xDD>(t[1], t[3]),
        );
        let (u5, u7) = (
            _mm512_shuffle_f64x2::<0x88>(t[5], t[7]),
            _mm512_shuffle_f64x2::<0xDD>(t[5], t[7]),
        );
        [
            _mm512_shuffle_f64x2::<0x88>(u0, u4),
            _mm512_shuffle_f64x2::<0x88>(u1, u5),
            _mm512_shuffle_f64x2::<0x88>(u2, u6),
            _mm512_shuffle_f64x2::<0x88>(u3, u7),
            _mm512_shuffle_f64x2::<0xDD>(u0, u4),
            _mm512_shuffle_f64x2::<0xDD>(u1, u5),
            _mm512_shuffle_f64x2::<0xDD>(u2, u6),
            _mm512_shuffle_f64x2::<0xDD>(u3, u7),
        ]
    }
}

/// The x, y and z lanes of 8 points `[x y z 0]`.
#[inline(always)]
fn transpose8x3(p: [__m256d; 8]) -> [__m512d; 3] {
    // SAFETY: only called below `run_avx512` (AVX-512 F present).
    unsafe {
        let pair = |a, b| _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(a), b);
        // `[p0 | p4]`, `[p1 | p5]`, `[p2 | p6]`, `[p3 | p7]`.
        let a = [
            pair(p[0], p[4]),
            pair(p[1], p[5]),
            pair(p[2], p[6]),
            pair(p[3], p[7]),
        ];
        // (x0 x1) (z0 z1) (x4 x5) (z4 z5) and (y0 y1) (0 0) (y4 y5) (0 0);
        // the same for points 2, 3, 6, 7.
        let (xz01, y01) = (
            _mm512_unpacklo_pd(a[0], a[1]),
            _mm512_unpackhi_pd(a[0], a[1]),
        );
        let (xz23, y23) = (
            _mm512_unpacklo_pd(a[2], a[3]),
            _mm512_unpackhi_pd(a[2], a[3]),
        );
        let first = _mm512_setr_epi64(0, 1, 8, 9, 4, 5, 12, 13);
        let second = _mm512_setr_epi64(2, 3, 10, 11, 6, 7, 14, 15);
        [
            _mm512_permutex2var_pd(xz01, first, xz23),
            _mm512_permutex2var_pd(y01, first, y23),
            _mm512_permutex2var_pd(xz01, second, xz23),
        ]
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
