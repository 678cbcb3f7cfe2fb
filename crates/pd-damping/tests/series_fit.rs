//! The Caughey series fit (`pd_damping::ratio::RatioTarget::fit_series`) on
//! synthetic modal data whose series quotients are exact powers
//! `Q_k = q^(k-1)` (modes that are eigenvectors of `M^-1 L_d`), so that
//! the coefficients behind the ratios are known.

use pd_damping::ratio::{ModalData, RatioTarget, SeriesData, series_negative_at};

/// Modes with quotients `q`, `omega = sqrt(q) / 10` (rad/s), and their
/// series quotients up to four terms.
fn modes(q: &[f64]) -> (Vec<ModalData>, Vec<Vec<f64>>) {
    let data = q
        .iter()
        .map(|&q| ModalData {
            omega: q.sqrt() / 10.0,
            laplacian_quotient: q,
        })
        .collect();
    let quotients = q.iter().map(|&q| vec![1.0, q, q * q, q * q * q]).collect();
    (data, quotients)
}

/// The ratio the series `a` gives a mode of quotient `q`.
fn ratio(a: &[f64], q: f64) -> f64 {
    let c: f64 = a
        .iter()
        .enumerate()
        .map(|(k, a)| a * q.powi(k as i32))
        .sum();
    c / (2.0 * q.sqrt() / 10.0)
}

#[test]
fn three_and_four_ratios_recover_the_series_behind_them() {
    let q = [100.0, 400.0, 2500.0, 1e4, 4e4];
    let (data, quotients) = modes(&q);
    let series = SeriesData {
        quotients,
        spectrum_bound: 1e5,
    };
    for a in [vec![0.5, 2e-3, 1e-7], vec![0.5, 2e-3, 1e-7, 1e-12]] {
        let asked: Vec<usize> = (1..=a.len())
            .map(|i| if i == 1 { 1 } else { i + 1 })
            .collect();
        let ratios: Vec<f64> = asked.iter().map(|&m| ratio(&a, q[m - 1])).collect();
        let fit = RatioTarget::Series {
            modes: asked.clone(),
            ratios: ratios.clone(),
        }
        .fit_series(&data, &series)
        .unwrap();
        let got = fit.coefficients.all();
        println!("{a:?} -> {got:?}");
        assert_eq!(got.len(), a.len());
        // The column-scaled system has a condition number of at most about
        // 1e4 here (nodes q / q_max from 0.0025 to 1, degree 3), so QR
        // recovers each coefficient to ~1e4 u relative to the largest
        // column's contribution; 1e-9 leaves a margin of 1e3.
        // Each term's contribution at the largest asked quotient.
        let q_max = q[asked[a.len() - 1] - 1];
        let largest = (a.iter().enumerate())
            .map(|(k, a)| a.abs() * q_max.powi(k as i32))
            .fold(0.0, f64::max);
        for (k, (x, y)) in got.iter().zip(&a).enumerate() {
            assert!(
                (x - y).abs() * q_max.powi(k as i32) <= 1e-9 * largest,
                "a{}: {x} against {y}",
                k + 1
            );
        }
        for (r, achieved) in ratios.iter().zip(&fit.achieved) {
            assert!(
                (achieved.ratio - r).abs() <= 1e-9 * r,
                "{achieved:?} against {r}"
            );
        }
    }
}

#[test]
fn a_series_negative_inside_the_spectrum_is_refused_with_its_mode() {
    let q = [100.0, 400.0, 2500.0, 1e4, 4e4];
    let (data, quotients) = modes(&q);
    let series = SeriesData {
        quotients,
        spectrum_bound: 1e5,
    };
    // a3 < 0: p(s) = 0.5 + 2e-3 s - 1e-7 s^2 turns negative at s = 2.02e4,
    // between modes 4 and 5, so mode 5 would get a negative ratio.
    let a = [0.5, 2e-3, -1e-7];
    let fit = RatioTarget::Series {
        modes: vec![1, 2, 3],
        ratios: [100.0, 400.0, 2500.0]
            .iter()
            .map(|&q| ratio(&a, q))
            .collect(),
    }
    .fit_series(&data, &series)
    .unwrap_err()
    .to_string();
    assert!(fit.contains("ratios") && fit.contains("mode 5"), "{fit}");
    // The same polynomial is caught on [0, bound] without any mode there.
    assert!(series_negative_at(&a, 1e5).is_some());
    assert!(series_negative_at(&a, 1e4).is_none());
}

#[test]
fn a_band_fit_is_the_best_positive_series_over_its_modes() {
    let q: Vec<f64> = (1..=8).map(|i| 100.0 * (i * i) as f64).collect();
    let (data, quotients) = modes(&q);
    let series = SeriesData {
        quotients,
        spectrum_bound: 1e5,
    };
    // Frequencies sqrt(q) / (20 pi): modes 2 to 6 lie in [0.3, 1.0] Hz.
    let fit = RatioTarget::Band {
        band: [0.3, 1.0],
        ratio: 0.05,
    }
    .fit_series(&data, &series)
    .unwrap();
    let band: Vec<usize> = fit.achieved.iter().map(|a| a.mode).collect();
    assert_eq!(band, vec![2, 3, 4, 5, 6]);
    let a = fit.coefficients.all();
    assert!(series_negative_at(&a, 1e5).is_none(), "{a:?}");
    // Flat ratio means c = 0.1 omega = 0.01 sqrt(q), concave in q: the
    // three-term least squares needs a3 < 0, which goes negative at the top
    // of the spectrum, so the best positive series is the two-term least
    // squares a1 + a2 q, solved here by its normal equations on the
    // relative error (rows divided by the target 2 zeta omega_i).
    let (mut n11, mut n12, mut n22, mut r1, mut r2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &m in &band {
        let (qm, target) = (q[m - 1], 0.1 * q[m - 1].sqrt() / 10.0);
        let (u, v) = (1.0 / target, qm / target);
        n11 += u * u;
        n12 += u * v;
        n22 += v * v;
        r1 += u;
        r2 += v;
    }
    let det = n11 * n22 - n12 * n12;
    let expected = [(r1 * n22 - r2 * n12) / det, (n11 * r2 - n12 * r1) / det];
    println!("{a:?} against {expected:?}");
    assert_eq!(a.len(), 2, "{a:?}");
    // The normal equations square the scaled system's condition number
    // (at most ~1e2 here: q from 400 to 3600): ~1e4 u; 1e-9 leaves 1e3.
    for (x, y) in a.iter().zip(&expected) {
        assert!(
            (x - y).abs() <= 1e-9 * y.abs(),
            "{a:?} against {expected:?}"
        );
    }
}
