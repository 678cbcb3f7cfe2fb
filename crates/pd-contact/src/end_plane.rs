//! A cheap, exact pre-test for the end-plane test of body contact
//! (`BodyContact::end_fraction`, docs/design/contact.md, "Detection and the broad phase"): most
//! candidate entries that reach it in an iteration end farther than the
//! thickness from the triangle's plane, and the full test spends a square
//! root and three divisions (the unit normal) to say so. [`surely_beyond`]
//! says it from the unnormalised normal with multiplications only, and
//! only where rounding cannot change the verdict.
//!
//! Why it is exact. Let `c` be the computed cross product of the end
//! triangle's edges (the expression of `plane`, so the same floats),
//! `q = b - t0` the computed vector from its first corner to the vertex,
//! `u = 2^-53`. The full test computes `s = sqrt(|c|^2)` (within `2.5 u`
//! of `|c|`), `n1_i = c_i / s` (so `n1_i = (c_i / |c|)(1 + e_i)`, `|e_i| <=
//! 4 u`), turns `n1` to the side of `n0` if `n1 . n0 < 0` (computed), and
//! rejects if `d1 = n1 . q >= thickness` (computed).
//!
//! - *The side.* With `g` the computed `c . n0` and `A = sum |c_i n0_i|`,
//!   `|g - c . n0| <= 3.1 u A`, and the computed `n1 . n0` is within
//!   `7.2 u A / |c|` of `(c . n0) / |c|`. If `|g| > 1e-12 A`, both have the
//!   sign of `g` (and are not zero): the full test turns `n1` by `sigma =
//!   sign(g)`. (`g^2 >= 1e-200 |c|^2` keeps `n1 . n0` far above the
//!   subnormal range, where absolute errors of `2^-1074` would count.)
//! - *The distance.* The computed `d1` is within `7.3 u |q|_2` of `sigma (c
//!   . q) / |c|`, and `H`, the computed `sigma (c . q)`, within `3.1 u |c|
//!   |q|_2` of it; so `d1 >= H / |c| - 10.4 u |q|_2`. With
//!   `S = thickness + 1e-12 |q|_1` (`|q|_1 >= |q|_2`; `1e-12` is about
//!   9000 `u`), `H > 0` and `H^2 >= S^2 |c|^2` give `d1 >= thickness`. The test compares the
//!   computed `H^2` with `S^2 |c|^2 (1 + 1e-12)`, the factor covering the
//!   few roundings of both sides (each within `4 u` relative); both sides
//!   must be finite and `H^2 >= 1e-250` (no overflow, no underflow in the
//!   products).
//!
//! Anything else (NaN, a degenerate triangle, a vertex near the thickened
//! plane) returns `false`: the full test runs, as before.

use pd_mesh::Point;

/// Relative slack for rounding (see the module's header).
const ROUNDING: f64 = 1e-12;

/// Whether the full end-plane test surely finds the vertex `q = b - t0`
/// (m) at least `thickness` (m) in front of the plane of the triangle
/// whose edge cross product is `cross` (`area2 = |cross|^2`, both as the
/// full test computes them), with the normal turned to the side of `n0`.
#[inline]
pub(super) fn surely_beyond(
    cross: &Point,
    area2: f64,
    q: &Point,
    n0: &Point,
    thickness: f64,
) -> bool {
    let g = cross.dot(n0);
    let a = (cross[0] * n0[0]).abs() + (cross[1] * n0[1]).abs() + (cross[2] * n0[2]).abs();
    let h = cross.dot(q);
    let h = if g >= 0.0 { h } else { -h };
    let s = thickness + ROUNDING * (q[0].abs() + q[1].abs() + q[2].abs());
    let (lhs, rhs) = (h * h, s * s * area2 * (1.0 + ROUNDING));
    // `&`, not `&&`: one branch (all are cheap; NaN makes each false).
    (g.abs() > ROUNDING * a)
        & (g * g >= 1e-200 * area2)
        & (h > 0.0)
        & (lhs >= 1e-250)
        & lhs.is_finite()
        & rhs.is_finite()
        & (lhs >= rhs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The full end-plane test as it was written before the pre-test:
    /// the unit normal, turned to `n0`'s side, and whether `d1 >=
    /// thickness` (`None` for a degenerate triangle).
    fn full_rejects(t: &[Point; 3], b: &Point, n0: &Point, thickness: f64) -> Option<bool> {
        let cross = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let area2 = cross.norm_squared();
        if !(area2 > 0.0) {
            return None;
        }
        let n1 = cross / area2.sqrt();
        let n1 = if n1.dot(n0) >= 0.0 { n1 } else { -n1 };
        Some(n1.dot(&(b - t[0])) >= thickness)
    }

    /// A pre-test that says yes always agrees with the full test, over
    /// random triangles, normals `n0` of either side and vertices placed
    /// at distances around the thickness (down to a few units in the last
    /// place from it: the pre-test must refuse those), off the origin and
    /// near it; and it says yes for most of the clear cases.
    #[test]
    fn a_surely_beyond_vertex_is_rejected_by_the_full_test() {
        let mut seed = 11_u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let (mut said, mut clear, mut refused_close) = (0, 0, 0);
        for k in 0..20_000 {
            let origin = Point::new(next(), next(), next()) * if k % 2 == 0 { 3.0 } else { 1e-3 };
            let t = [0, 1, 2].map(|_| origin + Point::new(next(), next(), next()) * 0.05);
            let cross = (t[1] - t[0]).cross(&(t[2] - t[0]));
            let area2 = cross.norm_squared();
            let normal = cross / area2.sqrt();
            let n0 =
                (normal * next().signum() + Point::new(next(), next(), next()) * 0.3).normalize();
            let thickness = if k % 5 == 0 {
                0.0
            } else {
                1e-3 * (1.0 + next())
            };
            // A distance from the plane along the normal: far, near, or a
            // few ulps from the thickness.
            let side = if normal.dot(&n0) >= 0.0 { 1.0 } else { -1.0 };
            let distance = match k % 4 {
                0 => thickness + 0.05 * next(),
                1 => thickness + 1e-6 * next(),
                2 => thickness * (1.0 + 4e-16 * next()),
                _ => thickness + 1e-13 * next(),
            };
            let tangent = (t[1] - t[0]) * (0.5 * next()) + (t[2] - t[0]) * (0.5 * next());
            let b = t[0] + tangent + normal * (side * distance);
            let q = b - t[0];
            let pre = surely_beyond(&cross, area2, &q, &n0, thickness);
            let full = full_rejects(&t, &b, &n0, thickness).expect("non-degenerate");
            if pre {
                said += 1;
                assert!(full, "case {k}: pre-test rejects, the full test does not");
            }
            if full && distance > thickness + 1e-9 {
                clear += 1;
                assert!(pre, "case {k}: a clear case ({distance} m) not caught");
            }
            if full && !pre && (distance - thickness).abs() < 1e-12 {
                refused_close += 1;
            }
        }
        assert!(said > 5000 && clear > 4000 && refused_close > 1000);
    }

    /// Non-finite or degenerate input is never taken.
    #[test]
    fn nan_and_degenerate_input_are_left_to_the_full_test() {
        let (cross, q, n0) = (Point::y(), Point::new(0.0, 1.0, 0.0), Point::y());
        assert!(surely_beyond(&cross, 1.0, &q, &n0, 0.5));
        assert!(!surely_beyond(&cross, 1.0, &q, &n0, 1.5));
        assert!(!surely_beyond(&cross, f64::NAN, &q, &n0, 0.5));
        assert!(!surely_beyond(&(cross * f64::NAN), 1.0, &q, &n0, 0.5));
        assert!(!surely_beyond(&cross, 1.0, &(q * f64::NAN), &n0, 0.5));
        assert!(!surely_beyond(&Point::zeros(), 0.0, &q, &n0, 0.0));
        // The side is not decidable: `n0` perpendicular to the normal.
        assert!(!surely_beyond(&cross, 1.0, &q, &Point::x(), 0.5));
        // Overflow of the squares.
        assert!(!surely_beyond(
            &(cross * 1e200),
            f64::INFINITY,
            &q,
            &n0,
            0.5
        ));
    }
}
