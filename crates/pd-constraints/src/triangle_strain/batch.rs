//! [`TriangleStrain`]'s lanes for the batched loop of [`crate::lane_rows`]:
//! as many triangles at a time as the CPU has f64 lanes (8 with AVX-512, 4
//! with AVX2), from the positions straight into the SIMD lanes and back,
//! as `tet_strain/batch.rs` does for tetrahedra.
//!
//! Per batch: gather the 3 x 2 gradients into structure-of-arrays lanes
//! (`F = G q` with lane-wide products and sums in the order of
//! `apply_operator`, so each lane's `F` is bit-identical to the scalar
//! one), run the scalar projection's operations on every lane (Gram-Schmidt,
//! [`thin_qr_lanes`]; then without limits the 2 x 2 closest rotation,
//! [`closest_orthonormal_lanes`], with limits the clamped 2 x 2 SVD in
//! closed form, [`clamped_stretch_lanes`], each lane with its own limits;
//! no trigonometry, no branch), and write each lane's two columns into its
//! output rows. A batch of triangles with and without limits computes both
//! forms and takes each lane's own. A lane for which the scalar function
//! would take another branch (a zero, non-finite or overflowing column
//! norm, a second column parallel to the first, a subnormal or
//! overflowing `e^2 + h^2`, or with limits `d^2 + g^2` neither normal nor
//! exactly 0) is projected by its triangle's scalar function after the
//! batch, so the results are those of
//! [`TriangleStrain::project`](crate::Constraint::project) to the bit in
//! every case.

use pd_mesh::Point;

use super::TriangleStrain;
use crate::lane_rows::LaneKind;
use crate::polar_batch::lane_sets::Lanes;
use crate::triangle_frame::REORTHOGONALIZE;
#[cfg(doc)]
use crate::triangle_frame::{clamped_stretch, closest_orthonormal};

/// One 3 x 2 matrix per lane; entry `3 c + j` is coordinate `j` of column
/// `c` (row `c` of `G q` or of the projection).
type Columns<S> = [<S as Lanes>::F; 6];

impl LaneKind<6> for TriangleStrain {
    #[inline(always)]
    fn one_at_a_time(&self) -> bool {
        false
    }

    #[inline(always)]
    fn gradients<S: Lanes>(s: S, batch: &[Self], q: &[Point]) -> Columns<S> {
        gradients(s, batch, q)
    }

    #[inline(always)]
    fn project_lanes<S: Lanes>(s: S, batch: &[Self], f: &Columns<S>) -> (Columns<S>, u32) {
        project_lanes(s, batch, f)
    }

    #[inline(always)]
    fn scatter<S: Lanes>(
        s: S,
        batch: &[Self],
        p: &Columns<S>,
        regular: u32,
        f: &Columns<S>,
        rows: &mut [Point],
    ) {
        scatter(s, batch, p, regular, f, rows);
    }
}

/// The gradients of a batch of triangles, one per lane: entry `3 c + j` of
/// lane `l` is `sum_k q[v_k][j] G[c][k]` of triangle `l`, summed from 0 in
/// the order `k = 0..3` exactly as `apply_operator` does (no fused
/// multiply-add), so every lane is bit-identical to the scalar `F`.
#[inline(always)]
fn gradients<S: Lanes>(s: S, elements: &[TriangleStrain], q: &[Point]) -> Columns<S> {
    let operator: [[S::F; 3]; 2] = [
        s.transpose(elements, |e| &e.operator[0][..]),
        s.transpose(elements, |e| &e.operator[1][..]),
    ];
    let mut f = [s.splat(0.0); 6];
    // Vertex by vertex: each entry still sums its terms in the order
    // `k = 0..3`, and only one vertex's three position lanes are live.
    for k in 0..3 {
        let positions: [S::F; 3] = s.transpose(elements, |e| q[e.vertices[k]].as_slice());
        for (j, p) in positions.into_iter().enumerate() {
            for (c, g) in operator.iter().enumerate() {
                let acc = &mut f[3 * c + j];
                *acc = s.add(*acc, s.mul(p, g[k]));
            }
        }
    }
    f
}

/// `(a_0 b_0 + a_1 b_1) + a_2 b_2`, nalgebra's dot product of 3-vectors
/// (and, with `a = b`, its `norm_squared`: adding that sum of squares onto
/// 0 changes no bit).
#[inline(always)]
fn dot<S: Lanes>(s: S, a: [S::F; 3], b: [S::F; 3]) -> S::F {
    s.add(
        s.add(s.mul(a[0], b[0]), s.mul(a[1], b[1])),
        s.mul(a[2], b[2]),
    )
}

/// Each lane's projection by its own triangle
/// ([`TriangleStrain::project`](crate::Constraint::project):
/// [`closest_orthonormal`] without limits, [`clamped_stretch`] with), and
/// the bits of the lanes that hold it to the bit. A batch of one kind
/// computes that kind's form only; a mixed batch computes both and selects
/// per lane.
#[inline(always)]
fn project_lanes<S: Lanes>(s: S, batch: &[TriangleStrain], f: &Columns<S>) -> (Columns<S>, u32) {
    let qr = thin_qr_lanes(s, f);
    let limited = (batch.iter().enumerate()).fold(0u32, |bits, (l, t)| {
        bits | u32::from(t.limits.is_some()) << l
    });
    let all = (1u32 << S::WIDTH) - 1;
    if limited == 0 {
        let (p, regular) = closest_orthonormal_lanes(s, &qr);
        return (p, s.bits(s.and(qr.regular, regular)));
    }
    let mut bounds = [S::Values::default(); 2];
    for (l, t) in batch.iter().enumerate() {
        // Unlimited lanes of a mixed batch compute a clamp that is not
        // used: any valid limits do.
        let (min, max) = t.limits.unwrap_or((1.0, 1.0));
        bounds[0].as_mut()[l] = min;
        bounds[1].as_mut()[l] = max;
    }
    let (min, max) = (s.pack(bounds[0]), s.pack(bounds[1]));
    let (clamped, clamped_regular) = clamped_stretch_lanes(s, &qr, min, max);
    let qr_regular = s.bits(qr.regular);
    if limited == all {
        return (clamped, qr_regular & s.bits(clamped_regular));
    }
    let (rotation, rotation_regular) = closest_orthonormal_lanes(s, &qr);
    let mut flags = S::Values::default();
    for (l, v) in flags.as_mut().iter_mut().enumerate() {
        *v = f64::from(limited >> l & 1);
    }
    let mask = s.gt(s.pack(flags), s.splat(0.0));
    let p = std::array::from_fn(|i| s.select(mask, clamped[i], rotation[i]));
    let regular = (limited & s.bits(clamped_regular)) | (!limited & s.bits(rotation_regular));
    (p, qr_regular & regular)
}

/// The Gram-Schmidt factors `F = Q R` of every lane, and the lanes where
/// [`thin_qr`](crate::triangle_frame::thin_qr) takes its regular branch
/// (two columns of positive, finite norm), with its operations in its
/// order.
struct QrLanes<S: Lanes> {
    q0: [S::F; 3],
    q1: [S::F; 3],
    r00: S::F,
    r01: S::F,
    r11: S::F,
    regular: S::M,
}

#[inline(always)]
fn thin_qr_lanes<S: Lanes>(s: S, f: &Columns<S>) -> QrLanes<S> {
    let (zero, largest) = (s.splat(0.0), s.splat(f64::MAX));
    let finite_positive = |x: S::F| s.and(s.gt(x, zero), s.le(x, largest));
    let f0 = [f[0], f[1], f[2]];
    let f1 = [f[3], f[4], f[5]];
    // q0 = f0 / |f0|.
    let n0_squared = dot(s, f0, f0);
    let n0 = s.sqrt(n0_squared);
    let q0 = [s.div(f0[0], n0), s.div(f0[1], n0), s.div(f0[2], n0)];
    // The part of f1 orthogonal to q0, normalised.
    let r01 = dot(s, q0, f1);
    let rest = [
        s.sub(f1[0], s.mul(q0[0], r01)),
        s.sub(f1[1], s.mul(q0[1], r01)),
        s.sub(f1[2], s.mul(q0[2], r01)),
    ];
    let n1_squared = dot(s, rest, rest);
    let n1 = s.sqrt(n1_squared);
    let q1 = [s.div(rest[0], n1), s.div(rest[1], n1), s.div(rest[2], n1)];
    let (r00, r11) = (dot(s, q0, f0), dot(s, q1, f1));
    // `try_normalize(0.0)` succeeds where the norm is positive (finite
    // here, so that no lane carries inf or NaN into the rest); a rest
    // below `REORTHOGONALIZE` of `f1`, which `thin_qr` orthogonalises
    // twice, goes to the scalar path.
    let one_pass = s.ge(n1_squared, s.mul(s.splat(REORTHOGONALIZE), dot(s, f1, f1)));
    let regular = s.and(
        s.and(finite_positive(n0_squared), finite_positive(n1_squared)),
        one_pass,
    );
    QrLanes {
        q0,
        q1,
        r00,
        r01,
        r11,
        regular,
    }
}

/// Whether every lane of `x` is a normal, finite number.
#[inline(always)]
fn normal<S: Lanes>(s: S, x: S::F) -> S::M {
    s.and(
        s.ge(x, s.splat(f64::MIN_POSITIVE)),
        s.le(x, s.splat(f64::MAX)),
    )
}

/// `Q` times a 2 x 2 matrix `[p00, p10, p01, p11]` (column-major): the
/// columns `q0 p00 + q1 p10` and `q0 p01 + q1 p11`, per coordinate left to
/// right, as nalgebra evaluates them.
#[inline(always)]
fn times_q<S: Lanes>(s: S, qr: &QrLanes<S>, [p00, p10, p01, p11]: [S::F; 4]) -> Columns<S> {
    let (q0, q1) = (qr.q0, qr.q1);
    [
        s.add(s.mul(q0[0], p00), s.mul(q1[0], p10)),
        s.add(s.mul(q0[1], p00), s.mul(q1[1], p10)),
        s.add(s.mul(q0[2], p00), s.mul(q1[2], p10)),
        s.add(s.mul(q0[0], p01), s.mul(q1[0], p11)),
        s.add(s.mul(q0[1], p01), s.mul(q1[1], p11)),
        s.add(s.mul(q0[2], p01), s.mul(q1[2], p11)),
    ]
}

/// [`closest_orthonormal`] on every lane from its Gram-Schmidt factors,
/// with the operations of
/// [`closest_rotation_2x2`](crate::triangle_frame::closest_rotation_2x2)'s
/// quotient form in the same order, and the lanes where the scalar function
/// takes that form (a normal, finite `e^2 + h^2`). Those lanes of a regular
/// `qr` hold its result to the bit; the others must be projected by the
/// scalar function.
#[inline(always)]
fn closest_orthonormal_lanes<S: Lanes>(s: S, qr: &QrLanes<S>) -> (Columns<S>, S::M) {
    let e = s.mul(s.splat(0.5), s.add(qr.r00, qr.r11));
    let h = s.mul(s.splat(-0.5), qr.r01);
    let r_squared = s.add(s.mul(e, e), s.mul(h, h));
    let r = s.sqrt(r_squared);
    let (cos, sin) = (s.div(e, r), s.div(h, r));
    let (q0, q1) = (qr.q0, qr.q1);
    let p = [
        s.add(s.mul(q0[0], cos), s.mul(q1[0], sin)),
        s.add(s.mul(q0[1], cos), s.mul(q1[1], sin)),
        s.add(s.mul(q0[2], cos), s.mul(q1[2], sin)),
        s.sub(s.mul(q1[0], cos), s.mul(q0[0], sin)),
        s.sub(s.mul(q1[1], cos), s.mul(q0[1], sin)),
        s.sub(s.mul(q1[2], cos), s.mul(q0[2], sin)),
    ];
    (p, normal(s, r_squared))
}

/// [`clamped_stretch`] on every lane from its Gram-Schmidt factors and its
/// limits, with the operations of
/// [`clamped_stretch_2x2`](crate::triangle_frame::clamped_stretch_2x2)'s
/// closed form in the same order (`f64::clamp` as two selects, `max` with
/// 0 of a finite difference as `vmaxpd`), and the lanes where the scalar
/// function takes that form. Those lanes of a regular `qr` hold its result
/// to the bit; the others must be projected by the scalar function.
#[inline(always)]
fn clamped_stretch_lanes<S: Lanes>(
    s: S,
    qr: &QrLanes<S>,
    min: S::F,
    max: S::F,
) -> (Columns<S>, S::M) {
    let (zero, half) = (s.splat(0.0), s.splat(0.5));
    let e = s.mul(half, s.add(qr.r00, qr.r11));
    let d = s.mul(half, s.sub(qr.r00, qr.r11));
    let g = s.mul(half, qr.r01);
    let h = s.mul(s.splat(-0.5), qr.r01);
    let rot_squared = s.add(s.mul(e, e), s.mul(h, h));
    let refl_squared = s.add(s.mul(d, d), s.mul(g, g));
    let is_zero = |x: S::F| s.and(s.le(x, zero), s.ge(x, zero));
    let isotropic = s.and(is_zero(d), is_zero(g));
    let (rot, refl) = (s.sqrt(rot_squared), s.sqrt(refl_squared));
    let s0 = s.add(rot, refl);
    let s1 = s.max(s.sub(rot, refl), zero);
    let clamp = |x: S::F| {
        let x = s.select(s.lt(x, min), min, x);
        s.select(s.gt(x, max), max, x)
    };
    let (c0, c1) = (clamp(s0), clamp(s1));
    let a = s.div(s.mul(half, s.add(c0, c1)), rot);
    let b = s.select(isotropic, zero, s.div(s.mul(half, s.sub(c0, c1)), refl));
    let p2 = [
        s.add(s.mul(a, e), s.mul(b, d)),
        s.add(s.mul(a, h), s.mul(b, g)),
        s.sub(s.mul(b, g), s.mul(a, h)),
        s.sub(s.mul(a, e), s.mul(b, d)),
    ];
    let regular = s.and(
        normal(s, rot_squared),
        s.or(isotropic, normal(s, refl_squared)),
    );
    (times_q(s, qr, p2), regular)
}

/// Writes lane `l`'s projection into rows `2 l`, `2 l + 1` of `rows`: the
/// lanes' columns where `regular` has bit `l`, else the scalar projection
/// of the lane's `F` by `batch[l]`.
#[inline(always)]
fn scatter<S: Lanes>(
    s: S,
    batch: &[TriangleStrain],
    p: &Columns<S>,
    regular: u32,
    f: &Columns<S>,
    rows: &mut [Point],
) {
    let mut values = [S::Values::default(); 6];
    for (v, x) in values.iter_mut().zip(p) {
        *v = s.values(*x);
    }
    for (l, rows) in rows.chunks_exact_mut(2).enumerate().take(S::WIDTH) {
        if regular >> l & 1 == 1 {
            for (c, row) in rows.iter_mut().enumerate() {
                *row = Point::new(
                    values[3 * c].as_ref()[l],
                    values[3 * c + 1].as_ref()[l],
                    values[3 * c + 2].as_ref()[l],
                );
            }
        } else {
            let mut gradient = nalgebra::Matrix3x2::zeros();
            for (g, x) in gradient.iter_mut().zip(f) {
                *g = s.values(*x).as_ref()[l];
            }
            let target = batch[l].target(&gradient);
            for (c, row) in rows.iter_mut().enumerate() {
                *row = target.column(c).into_owned();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3x2, Vector2};
    use proptest::prelude::*;

    use super::*;
    use crate::lane_rows::test_support::assert_all_bit_identical;
    use crate::polar_batch::lane_sets::{WithLanes, vectorize};
    use crate::signed_svd::test_support::uniform_sequence;
    use crate::triangle_frame::test_support::{from_singular_values, gradient, special_gradients};
    use pd_linalg::simd::for_each_simd_width;

    /// Limits of every kind, `None` (the rotation form) among them.
    const LIMITS: [Option<(f64, f64)>; 5] = [
        None,
        Some((0.9, 1.1)),
        Some((0.95, 1.05)),
        Some((0.0, 1.0)),
        Some((1.0, 1.0)),
    ];

    /// A triangle per gradient, each on its own three vertices: the rest
    /// triangle `(0, 0, 0), (1, 0, 0), (0, 1, 0)`, whose operator
    /// `[[-1, 1, 0], [-1, 0, 1]]` is exact, and positions `0, f0, f1`, so
    /// that `G q` is `f` itself (zero and parallel columns exactly so);
    /// triangle `i` with stretch limits `limits(i)`.
    fn unit_triangles(
        gradients: &[Matrix3x2<f64>],
        limits: impl Fn(usize) -> Option<(f64, f64)>,
    ) -> (Vec<TriangleStrain>, Vec<Point>) {
        let mut rest = Vec::new();
        let mut q = Vec::new();
        let mut constraints = Vec::new();
        for (i, f) in gradients.iter().enumerate() {
            rest.extend([Point::zeros(), Point::x(), Point::y()]);
            q.extend([Point::zeros(), f.column(0).into(), f.column(1).into()]);
            let t = [3 * i, 3 * i + 1, 3 * i + 2];
            constraints.push(TriangleStrain::new(&rest, t, 10.0, limits(i)).unwrap());
        }
        (constraints, q)
    }

    /// Triangle `i`'s limits in the list shifted by `shift`.
    type LimitsOf = dyn Fn(usize, usize) -> Option<(f64, f64)>;

    /// Every special gradient (degenerate, non-finite, extreme scales,
    /// isotropic, ...) in every lane position of 4 and 8 lanes next to
    /// every other, in lists with and without a remainder, in batches
    /// without limits, all with the same limits, with one limited
    /// triangle, and with limits of every kind mixed.
    #[test]
    fn every_gradient_class_in_every_lane_position() {
        let m = |f0: [f64; 3], f1: [f64; 3]| Matrix3x2::from_columns(&[f0.into(), f1.into()]);
        let mut cases = special_gradients();
        cases.extend([
            // Equal singular values exactly (`d = g = 0`), inside and
            // outside the limits, and at the extreme scales.
            m([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            m([0.0, 0.0, 1.2], [1.2, 0.0, 0.0]),
            m([0.6, 0.8, 0.0], [-0.8, 0.6, 0.0]),
            m([0.5, 0.0, 0.0], [0.0, 0.0, 0.5]),
            m([1e-140, 0.0, 0.0], [0.0, 1e-140, 0.0]),
            m([1e150, 0.0, 0.0], [0.0, 1e150, 0.0]),
            // Anisotropy whose `d^2` is subnormal, and one whose `d^2`
            // underflows to 0 with `d != 0`: the scalar angle form.
            m([1e-150 + 2e-157, 0.0, 0.0], [0.0, 1e-150, 0.0]),
            m([1e-150 + 2e-163, 0.0, 0.0], [0.0, 1e-150, 0.0]),
            // Stretched and compressed beyond both limits.
            m([1.5, 0.1, 0.0], [0.0, 0.5, 0.2]),
            m([3.0, 0.0, 0.0], [0.0, 0.0, 2.0]),
            m([0.1, 0.0, 0.0], [0.0, 0.2, 0.0]),
        ]);
        let n = cases.len();
        let every: [&LimitsOf; 4] = [
            &|_, _| None,
            &|_, _| Some((0.9, 1.1)),
            &|i, shift| (i == shift % 11).then_some((0.9, 1.1)),
            &|i, shift| LIMITS[(i + shift) % LIMITS.len()],
        ];
        for shift in 0..n {
            let shifted: Vec<_> = (0..n).map(|l| cases[(l + shift) % n]).collect();
            for len in [n, n - 3, 16, 8] {
                let (constraints, q) = unit_triangles(&shifted[..len], |_| None);
                // `G q` is a finite gradient to the bit (an infinite entry
                // times a 0 in the operator makes NaN: still non-finite).
                let mut gx = [Point::zeros(); 2];
                for (c, f) in constraints.iter().zip(&shifted) {
                    crate::constraint::apply_operator(c, &q, &mut gx);
                    if f.iter().all(|x| x.is_finite()) {
                        assert_eq!(Matrix3x2::from_columns(&gx), *f);
                    }
                }
                for limits in every {
                    let (constraints, q) = unit_triangles(&shifted[..len], |i| limits(i, shift));
                    assert_all_bit_identical(&constraints, &q);
                }
            }
        }
    }

    /// A rest triangle's corners, the gradient it is deformed by, the
    /// position of its first corner and its limits (an index into
    /// [`LIMITS`]).
    type Placed = ([[f64; 3]; 3], Matrix3x2<f64>, [f64; 3], usize);

    /// Rest triangles of any shape, positions `x0 + F (local rest
    /// coordinates)` (so that `G q` is `F` up to round-off, of every
    /// class [`gradient`] draws), from 1 to 40 triangles (full batches and
    /// remainders), each with limits of one of the kinds of [`LIMITS`],
    /// drawn from the first `kinds` of them (1: none; 2: none or one
    /// pair; all: mixed).
    fn triangles_from(items: &[Placed], kinds: usize) -> (Vec<TriangleStrain>, Vec<Point>) {
        let mut rest = Vec::new();
        let mut q = Vec::new();
        let mut constraints = Vec::new();
        for (corners, f, offset, limits) in items {
            let [x0, x1, x2] = corners.map(Point::from);
            let t = [rest.len(), rest.len() + 1, rest.len() + 2];
            rest.extend([x0, x1, x2]);
            let limits = LIMITS[limits % kinds];
            let Ok(c) = TriangleStrain::new(&rest, t, 3.0, limits) else {
                // A degenerate rest triangle: its vertices stay unused.
                q.extend([Point::zeros(); 3]);
                continue;
            };
            // Local coordinates of the corners in the rest frame.
            let (e1, e2) = (x1 - x0, x2 - x0);
            let b1 = e1.normalize();
            let along = b1.dot(&e2);
            let across = (e2 - b1 * along).norm();
            let origin = Point::from(*offset);
            for local in [
                Vector2::zeros(),
                Vector2::new(e1.norm(), 0.0),
                Vector2::new(along, across),
            ] {
                q.push(origin + f * local);
            }
            constraints.push(c);
        }
        (constraints, q)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, max_shrink_iters: 300, ..ProptestConfig::default() })]

        #[test]
        fn gathered_batches_are_bit_identical(
            items in prop::collection::vec(
                (
                    prop::array::uniform3(prop::array::uniform3(-1.0..1.0f64)),
                    gradient(),
                    prop::array::uniform3(-2.0..2.0f64),
                    0usize..LIMITS.len(),
                ),
                1..40,
            ),
            kinds in 1usize..=LIMITS.len(),
        ) {
            let (constraints, q) = triangles_from(&items, kinds);
            assert_all_bit_identical(&constraints, &q);
            // All limited, with the limits of the first kind drawn.
            let limited: Vec<Placed> = items.iter().map(|&(c, f, o, _)| (c, f, o, 1)).collect();
            let (constraints, q) = triangles_from(&limited, LIMITS.len());
            assert_all_bit_identical(&constraints, &q);
        }
    }

    /// The lanes, not the scalar fallback, project typical triangles (the
    /// bit-identity tests above would pass with every lane sent to the
    /// scalar path): batches of near-rotations with stretches of a few
    /// percent, unlimited, limited and mixed, report every lane regular,
    /// at every lane width this CPU has.
    #[test]
    fn typical_triangles_take_the_lanes() {
        struct Regular<'a>(&'a [TriangleStrain], &'a [Point]);
        impl WithLanes for Regular<'_> {
            type Output = (usize, u32);
            #[inline(always)]
            fn run<S: Lanes>(self, s: S) -> (usize, u32) {
                let batch = &self.0[..S::WIDTH];
                let f = gradients(s, batch, self.1);
                (S::WIDTH, project_lanes(s, batch, &f).1)
            }
        }
        let gradients: Vec<_> = (0..8)
            .map(|i| {
                let t = i as f64;
                let s = [1.0 + 0.03 * (t - 3.5) / 3.5, 0.98 + 0.01 * t / 7.0];
                from_singular_values([0.3, -0.2 + 0.1 * t, 1.0], 0.4 * t, 1.1 - 0.3 * t, s)
            })
            .collect();
        let kinds: [&dyn Fn(usize) -> Option<(f64, f64)>; 3] =
            [&|_| None, &|_| Some((0.99, 1.01)), &|i| {
                LIMITS[i % LIMITS.len()]
            }];
        for limits in kinds {
            let (constraints, q) = unit_triangles(&gradients, limits);
            for_each_simd_width(|width| {
                let (lanes, regular) =
                    vectorize(Regular(&constraints, &q)).expect("this width's lanes");
                assert_eq!(lanes, width);
                assert_eq!(
                    regular,
                    (1u32 << width) - 1,
                    "lanes sent to the scalar path"
                );
            });
        }
    }

    /// Many random stretch-limited triangles near the cloth scenes' state
    /// (stretches of a few percent, rotations of every angle), all
    /// limited and mixed, against one at a time.
    #[test]
    fn many_limited_triangles_are_bit_identical() {
        let mut uniform = uniform_sequence(0x9E37_79B9_7F4A_7C15);
        let mut gradients = Vec::new();
        for i in 0..4000 {
            let spread = [0.02, 0.1, 0.5][i % 3];
            let s = [1.0 + spread * uniform(), 1.0 + spread * uniform()];
            let axis = [uniform(), uniform(), uniform()];
            gradients.push(from_singular_values(
                axis,
                3.2 * uniform(),
                3.2 * uniform(),
                s,
            ));
        }
        let (constraints, q) = unit_triangles(&gradients, |_| Some((0.95, 1.05)));
        assert_all_bit_identical(&constraints, &q);
        let (constraints, q) = unit_triangles(&gradients, |i| LIMITS[i * 7 % LIMITS.len()]);
        assert_all_bit_identical(&constraints, &q);
    }
}
