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
//! If even `lambda = -min s_i^2 / 4` leaves `prod c_i > 1` (every principal
//! stretch above about 2: area x4, volume x8) the closest point lies on
//! another root branch; this code then returns the uniform rescaling
//! `s / (prod s)^(1/N)`, a point of the set but not the closest, with the
//! Jacobian of the main branch's limit set to infinity (`docs/constraints.md`
//! states the limitation).

/// `(c, dc/ds)` for `s` (`N` = 2 or 3, signed singular values allowed).
pub(crate) fn project<const N: usize>(s: &[f64; N]) -> ([f64; N], [[f64; N]; N]) {
    let inf_jacobian = [[f64::INFINITY; N]; N];
    if !s.iter().all(|x| x.is_finite()) {
        return ([f64::NAN; N], [[f64::NAN; N]; N]);
    }
    let root = |s: f64, lambda: f64| -> (f64, f64) {
        let d = (s * s + 4.0 * lambda).max(0.0).sqrt();
        // Written without cancellation for negative `s`.
        let c = if s >= 0.0 {
            0.5 * (s + d)
        } else {
            2.0 * lambda / (d - s)
        };
        (c, d)
    };
    let h = |lambda: f64| -> (f64, f64) {
        let mut value = 0.0;
        let mut slope = 0.0;
        for &si in s {
            let (c, d) = root(si, lambda);
            value += c.ln();
            slope += 1.0 / (c * d);
        }
        (value, slope)
    };
    // A negative `s_i` needs `lambda > 0` for a positive `c_i`.
    let lowest = if s.iter().any(|&x| x < 0.0) {
        0.0
    } else {
        -s.iter().map(|x| x * x).fold(f64::INFINITY, f64::min) / 4.0
    };
    if h(lowest).0 > 0.0 {
        let scale = s.iter().product::<f64>().powf(-1.0 / N as f64);
        return (s.map(|x| x * scale), inf_jacobian);
    }
    let mut lo = lowest;
    let mut hi = 1.0_f64;
    while h(hi).0 <= 0.0 {
        hi *= 4.0;
    }
    let mut lambda = 0.0_f64.clamp(lo, hi);
    for _ in 0..200 {
        let (value, slope) = h(lambda);
        if value == 0.0 {
            break;
        }
        if value < 0.0 {
            lo = lambda;
        } else {
            hi = lambda;
        }
        let newton = lambda - value / slope;
        let next = if newton > lo && newton < hi && slope.is_finite() {
            newton
        } else {
            0.5 * (lo + hi)
        };
        let converged = (next - lambda).abs() <= 4.0 * f64::EPSILON * (1.0 + lambda.abs());
        lambda = next;
        if converged || hi - lo <= 4.0 * f64::EPSILON * (1.0 + lambda.abs()) {
            break;
        }
    }
    let mut c = [0.0; N];
    let mut d = [0.0; N];
    for i in 0..N {
        (c[i], d[i]) = root(s[i], lambda);
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
            for i in 0..3 {
                for j in 0..3 {
                    assert!((jacobian[i][j] - jacobian[j][i]).abs() < 1e-12);
                }
            }
        }
        let (c, _) = project(&[1.5, 0.5]);
        assert!((c[0] * c[1] - 1.0).abs() < 1e-13);
    }
}
