//! The closest point `c` to singular values `s` on `{ c > 0, prod c_i = 1 }`
//! (area and volume preservation) and its Jacobian `dc/ds`.
//!
//! The Lagrange conditions `c_i - s_i = lambda prod_{j != i} c_j = lambda / c_i`
//! give each `c_i` as the positive root of `c^2 - s_i c - lambda = 0`,
//! `c_i(lambda) = (s_i + sqrt(s_i^2 + 4 lambda)) / 2`, increasing in
//! `lambda`; so `h(lambda) = sum ln c_i(lambda)` is increasing and its root
//! is unique on `lambda >= -min s_i^2 / 4`. It is found by Newton's method on
//! `h` safeguarded by bisection (`h' = sum 1 / (c_i d_i)`,
//! `d_i = sqrt(s_i^2 + 4 lambda)`). Differentiating the conditions,
//! `dc/ds = diag(c_i / d_i) - a a^T / S` with `a_i = 1 / d_i`,
//! `S = sum 1 / (c_i d_i)`: symmetric, as the Jacobian of a closest-point map
//! must be.
//!
//! If even `lambda = -min s_i^2 / 4` leaves `prod c_i > 1` (strongly
//! stretched, e.g. `s_0 s_1 > 2` in 2D with `s_0 = s_1 > 2`) the closest point lies on
//! the second root `c_k = (s_k - sqrt(s_k^2 + 4 lambda)) / 2` of the smallest
//! `|s_k|`, with `lambda` in `(-s_k^2/4, 0)`, where `h` goes from positive to
//! `-inf`; the same safeguarded iteration finds it, and the Jacobian formula
//! holds with the signed `d_k = 2 c_k - s_k < 0`. Checked against a brute
//! force search of the set for random `s` while writing this.

/// The flip eigenvalue of `dP/dF` for the pair `(a, b)`: the divided
/// difference `(c_a - c_b) / (s_a - s_b)` of the closest point `c` of `s`,
/// or `at_equal` (the Jacobian `dc/ds` along `e_a - e_b`, its limit) where
/// `s_a` and `s_b` agree to within `sqrt(u)` of their size.
///
/// Close to a repeated singular value the quotient is round-off, not a
/// slope: `c` comes from an iteration accurate to about `u |c|`, so the
/// quotient's error is about `u |c| / |s_a - s_b|`, of order 1 when the two
/// differ in the last bits, as at the rest shape (`F = I` up to rounding).
/// Taking the limit instead errs by about `|s_a - s_b|` times the second
/// derivative of `c`; the two errors are both about `sqrt(u)` at the
/// switch, and the Hessian at rest does not depend on where the element
/// sits (`tests/hessian_at_rest.rs`).
pub(crate) fn flip_slope(c: [f64; 2], s: [f64; 2], at_equal: f64) -> f64 {
    let gap = s[0] - s[1];
    if gap.abs() <= f64::EPSILON.sqrt() * s[0].abs().max(s[1].abs()) {
        at_equal
    } else {
        (c[0] - c[1]) / gap
    }
}

/// `(c, dc/ds)` for `s` (`N` = 2 or 3, signed singular values allowed).
pub(crate) fn project<const N: usize>(s: &[f64; N]) -> ([f64; N], [[f64; N]; N]) {
    if !s.iter().all(|x| x.is_finite()) {
        return ([f64::NAN; N], [[f64::NAN; N]; N]);
    }
    // The component with the smallest |s_k|: the one that switches root.
    let k = (0..N)
        .min_by(|&a, &b| (s[a] * s[a]).total_cmp(&(s[b] * s[b])))
        .unwrap_or(0);
    // Root `c_i(lambda)` of `c^2 - s_i c - lambda = 0` and `d_i = 2 c_i - s_i`,
    // written without cancellation.
    let root = |i: usize, lambda: f64, second: bool| -> (f64, f64) {
        let si = s[i];
        let d = (si * si + 4.0 * lambda).max(0.0).sqrt();
        if second && i == k {
            let c = if si + d > 0.0 {
                -2.0 * lambda / (si + d)
            } else {
                0.0
            };
            (c, -d)
        } else if si >= 0.0 {
            (0.5 * (si + d), d)
        } else {
            (
                if d - si > 0.0 {
                    2.0 * lambda / (d - si)
                } else {
                    0.0
                },
                d,
            )
        }
    };
    let h = |lambda: f64, second: bool| -> (f64, f64) {
        let (mut value, mut slope) = (0.0, 0.0);
        for i in 0..N {
            let (c, d) = root(i, lambda, second);
            value += c.ln();
            slope += 1.0 / (c * d);
        }
        (value, slope)
    };
    // A negative `s_i` needs `lambda > 0` for a positive `c_i`.
    let negative = s.iter().any(|&x| x < 0.0);
    let lowest = if negative { 0.0 } else { -s[k] * s[k] / 4.0 };
    let second = !negative && h(lowest, false).0 > 0.0;
    // `h` increases on the first branch (root in `[lowest, hi]`) and goes
    // from positive to `-inf` on the second (root in `(lowest, 0)`).
    let (mut lo, mut hi) = (lowest, 0.0_f64);
    if !second {
        hi = 1.0;
        while h(hi, false).0 <= 0.0 {
            hi *= 4.0;
        }
    }
    let mut lambda = if second { 0.5 * lowest } else { lo.max(0.0) };
    for _ in 0..300 {
        let (value, slope) = h(lambda, second);
        if value == 0.0 {
            break;
        }
        if (value < 0.0) != second {
            lo = lambda;
        } else {
            hi = lambda;
        }
        let newton = lambda - value / slope;
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        let tolerance = 4.0 * f64::EPSILON * (1.0 + lambda.abs());
        let converged = (next - lambda).abs() <= tolerance;
        lambda = next;
        if converged || hi - lo <= tolerance {
            break;
        }
    }
    let mut c = [0.0; N];
    let mut d = [0.0; N];
    for i in 0..N {
        (c[i], d[i]) = root(i, lambda, second);
    }
    let sum: f64 = (0..N).map(|i| 1.0 / (c[i] * d[i])).sum();
    let mut jacobian = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            let diagonal = if i == j { c[i] / d[i] } else { 0.0 };
            jacobian[i][j] = diagonal - 1.0 / (d[i] * d[j] * sum);
        }
    }
    (c, jacobian)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_have_unit_product_and_normal_offsets() {
        let cases: [[f64; 3]; 5] = [
            [1.0, 1.0, 1.0],
            [1.2, 0.9, 0.8],
            [1.5, 1.0, -0.5],
            [0.3, 0.2, 0.0],
            [0.0, 0.0, 0.0],
        ];
        for s in cases {
            let (c, jacobian) = project(&s);
            let product: f64 = c.iter().product();
            // The Newton iteration stops at a few ulps of lambda.
            assert!((product - 1.0).abs() < 1e-13, "{s:?} -> {c:?}");
            // s - c is along the normal (1/c_i) of the surface at c.
            let lambda = (c[0] - s[0]) * c[0];
            for i in 0..3 {
                assert!(((c[i] - s[i]) * c[i] - lambda).abs() < 1e-12, "{s:?}");
            }
            let j = nalgebra::Matrix3::from_fn(|a, b| jacobian[a][b]);
            assert!((j - j.transpose()).amax() < 1e-12);
        }
        // Second branch (strongly stretched): still on the set, and the
        // offset along the normal.
        for s in [[1.9, 1.24], [3.0, 3.0]] {
            let (c, _) = project(&s);
            assert!((c[0] * c[1] - 1.0).abs() < 1e-13, "{s:?} -> {c:?}");
            let lambda = (c[0] - s[0]) * c[0];
            assert!(((c[1] - s[1]) * c[1] - lambda).abs() < 1e-12);
            assert!(lambda < 0.0);
        }
    }
}
