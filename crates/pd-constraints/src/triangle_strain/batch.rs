//! [`TriangleStrain`]'s lanes for the batched loop of [`crate::lane_rows`]:
//! as many triangles at a time as the CPU has f64 lanes (8 with AVX-512, 4
//! with AVX2), from the positions straight into the SIMD lanes and back,
//! as `tet_strain/batch.rs` does for tetrahedra.
//!
//! Per batch: gather the 3 x 2 gradients into structure-of-arrays lanes
//! (`F = G q` with lane-wide products and sums in the order of
//! `apply_operator`, so each lane's `F` is bit-identical to the scalar
//! one), run [`closest_orthonormal`]'s operations on every lane
//! ([`closest_orthonormal_lanes`]: Gram-Schmidt, then the 2 x 2 closest
//! rotation, no trigonometry, no branch), and write each lane's two
//! columns into its output rows. A lane for which the scalar function
//! would take another branch (a zero, non-finite or overflowing column
//! norm, a second column parallel to the first, a subnormal or
//! overflowing `e^2 + h^2`) is projected by the scalar
//! [`closest_orthonormal`], and a batch with a stretch-limited triangle
//! goes one at a time, so the results are those of
//! [`TriangleStrain::project`] to the bit in every case.

use pd_mesh::Point;

use super::TriangleStrain;
use crate::lane_rows::LaneKind;
use crate::polar_batch::lane_sets::Lanes;
use crate::triangle_frame::closest_orthonormal;

/// One 3 x 2 matrix per lane; entry `3 c + j` is coordinate `j` of column
/// `c` (row `c` of `G q` or of the projection).
type Columns<S> = [<S as Lanes>::F; 6];

impl LaneKind<6> for TriangleStrain {
    #[inline(always)]
    fn one_at_a_time(&self) -> bool {
        self.limits.is_some()
    }

    #[inline(always)]
    fn gradients<S: Lanes>(s: S, batch: &[Self], q: &[Point]) -> Columns<S> {
        gradients(s, batch, q)
    }

    #[inline(always)]
    fn project_lanes<S: Lanes>(s: S, f: &Columns<S>) -> (Columns<S>, u32) {
        let (p, regular) = closest_orthonormal_lanes(s, f);
        (p, s.bits(regular))
    }

    #[inline(always)]
    fn scatter<S: Lanes>(s: S, p: &Columns<S>, regular: u32, f: &Columns<S>, rows: &mut [Point]) {
        scatter(s, p, regular, f, rows);
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

/// [`closest_orthonormal`] on every lane, with the operations of its
/// regular branch ([`thin_qr`](crate::triangle_frame::thin_qr) on two
/// columns of positive, finite norm, then
/// [`closest_rotation_2x2`](crate::triangle_frame::closest_rotation_2x2)
/// from a normal, finite `e^2 + h^2`) in the same order, and the lanes where
/// the scalar function takes that branch. Those lanes hold its result to
/// the bit; the others must be projected by the scalar function.
#[inline(always)]
fn closest_orthonormal_lanes<S: Lanes>(s: S, f: &Columns<S>) -> (Columns<S>, S::M) {
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
    // The closest rotation to R: (e, h) / sqrt(e^2 + h^2).
    let e = s.mul(s.splat(0.5), s.add(r00, r11));
    let h = s.mul(s.splat(-0.5), r01);
    let r_squared = s.add(s.mul(e, e), s.mul(h, h));
    let r = s.sqrt(r_squared);
    let (cos, sin) = (s.div(e, r), s.div(h, r));
    let p = [
        s.add(s.mul(q0[0], cos), s.mul(q1[0], sin)),
        s.add(s.mul(q0[1], cos), s.mul(q1[1], sin)),
        s.add(s.mul(q0[2], cos), s.mul(q1[2], sin)),
        s.sub(s.mul(q1[0], cos), s.mul(q0[0], sin)),
        s.sub(s.mul(q1[1], cos), s.mul(q0[1], sin)),
        s.sub(s.mul(q1[2], cos), s.mul(q0[2], sin)),
    ];
    // The scalar branches: `try_normalize(0.0)` succeeds where the norm is
    // positive (finite here, so that no lane carries inf or NaN into the
    // rest), and the quotient form needs a normal, finite `e^2 + h^2`.
    let regular = s.and(
        s.and(finite_positive(n0_squared), finite_positive(n1_squared)),
        s.and(
            s.ge(r_squared, s.splat(f64::MIN_POSITIVE)),
            s.le(r_squared, largest),
        ),
    );
    (p, regular)
}

/// Writes lane `l`'s projection into rows `2 l`, `2 l + 1` of `rows`: the
/// lanes' columns where `regular` has bit `l`, else the scalar
/// [`closest_orthonormal`] of the lane's `F`.
#[inline(always)]
fn scatter<S: Lanes>(s: S, p: &Columns<S>, regular: u32, f: &Columns<S>, rows: &mut [Point]) {
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
            let target = closest_orthonormal(&gradient);
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
    use crate::triangle_frame::test_support::{gradient, special_gradients};

    /// A triangle per gradient, each on its own three vertices: the rest
    /// triangle `(0, 0, 0), (1, 0, 0), (0, 1, 0)`, whose operator
    /// `[[-1, 1, 0], [-1, 0, 1]]` is exact, and positions `0, f0, f1`, so
    /// that `G q` is `f` itself (zero and parallel columns exactly so);
    /// stretch limits on the triangles `limited` names.
    fn unit_triangles(
        gradients: &[Matrix3x2<f64>],
        limited: impl Fn(usize) -> bool,
    ) -> (Vec<TriangleStrain>, Vec<Point>) {
        let mut rest = Vec::new();
        let mut q = Vec::new();
        let mut constraints = Vec::new();
        for (i, f) in gradients.iter().enumerate() {
            rest.extend([Point::zeros(), Point::x(), Point::y()]);
            q.extend([Point::zeros(), f.column(0).into(), f.column(1).into()]);
            let limits = limited(i).then_some((0.9, 1.1));
            let t = [3 * i, 3 * i + 1, 3 * i + 2];
            constraints.push(TriangleStrain::new(&rest, t, 10.0, limits).unwrap());
        }
        (constraints, q)
    }

    /// Every special gradient (degenerate, non-finite, extreme scales, ...)
    /// in every lane position of 4 and 8 lanes next to every other, in
    /// lists with and without a remainder, and with a stretch-limited
    /// triangle in some batches.
    #[test]
    fn every_gradient_class_in_every_lane_position() {
        let cases = special_gradients();
        let n = cases.len();
        for shift in 0..n {
            let shifted: Vec<_> = (0..n).map(|l| cases[(l + shift) % n]).collect();
            for len in [n, n - 3, 16, 8] {
                let (constraints, q) = unit_triangles(&shifted[..len], |_| false);
                // `G q` is a finite gradient to the bit (an infinite entry
                // times a 0 in the operator makes NaN: still non-finite).
                let mut gx = [Point::zeros(); 2];
                for (c, f) in constraints.iter().zip(&shifted) {
                    crate::constraint::apply_operator(c, &q, &mut gx);
                    if f.iter().all(|x| x.is_finite()) {
                        assert_eq!(Matrix3x2::from_columns(&gx), *f);
                    }
                }
                assert_all_bit_identical(&constraints, &q);
                let (constraints, q) = unit_triangles(&shifted[..len], |i| i == shift % 11);
                assert_all_bit_identical(&constraints, &q);
            }
        }
    }

    /// A rest triangle's corners, the gradient it is deformed by and the
    /// position of its first corner.
    type Placed = ([[f64; 3]; 3], Matrix3x2<f64>, [f64; 3]);

    /// Rest triangles of any shape, positions `x0 + F (local rest
    /// coordinates)` (so that `G q` is `F` up to round-off, of every
    /// class [`gradient`] draws), from 1 to 40 triangles (full batches and
    /// remainders), with one stretch-limited triangle at a random place
    /// (or none).
    fn triangles_from(items: &[Placed], limited: usize) -> (Vec<TriangleStrain>, Vec<Point>) {
        let mut rest = Vec::new();
        let mut q = Vec::new();
        let mut constraints = Vec::new();
        for (i, (corners, f, offset)) in items.iter().enumerate() {
            let [x0, x1, x2] = corners.map(Point::from);
            let t = [rest.len(), rest.len() + 1, rest.len() + 2];
            rest.extend([x0, x1, x2]);
            let limits = (i == limited).then_some((0.9, 1.1));
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
                ),
                1..40,
            ),
            limited in 0usize..80,
        ) {
            let (constraints, q) = triangles_from(&items, limited);
            assert_all_bit_identical(&constraints, &q);
        }
    }
}
