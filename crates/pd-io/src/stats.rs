//! Order statistics of timing samples, shared by the recorder, `pd
//! compare`, the benchmarks and xtask's reports.

/// The median of `values` (the mean of the two middle ones for an even
/// count); NaN for none. Used for the step-time medians of `summary.json`,
/// `pd compare` and the benchmarks.
pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mid = sorted.len() / 2;
    if sorted.len() % 2 == 1 {
        sorted[mid]
    } else {
        0.5 * (sorted[mid - 1] + sorted[mid])
    }
}

/// The upper median of `values`: the middle one of an odd count, the upper
/// of the two middle ones of an even count, always one of the samples; NaN
/// for none. Used by the contact benchmark and the machine-limits report.
pub fn upper_median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN)
}

#[cfg(test)]
mod median_tests {
    use super::{median, upper_median};

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn upper_median_is_a_sample() {
        assert_eq!(upper_median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(upper_median(&[4.0, 1.0, 2.0, 3.0]), 3.0);
        assert!(upper_median(&[]).is_nan());
    }
}
