//! The few statistics the suites are judged with: rates with their Wilson interval,
//! means with a normal-approximation interval, paired differences, percentiles.

/// Half the 95 % confidence interval of the mean of `xs` (normal approximation); NaN
/// under two values.
pub fn half_95(xs: &[f64]) -> f64 {
    let n = xs.len() as f64;
    if xs.len() < 2 {
        return f64::NAN;
    }
    let mean = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    1.96 * (var / n).sqrt()
}

/// The mean of `xs`; NaN when empty.
pub fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// The 95 % Wilson score interval of a rate `p` over `n` trials: it stays inside [0, 1]
/// and is not empty at 0 % or 100 % (every world of 64 reaching the goal says only that
/// the rate is likely over 94 %).
pub fn wilson_95(p: f64, n: usize) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let (z, n) = (1.96_f64, n as f64);
    let centre = (p + z * z / (2.0 * n)) / (1.0 + z * z / n);
    let half = z / (1.0 + z * z / n) * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// The `q` quantile (0..=1) of `xs` by nearest rank; None when empty.
pub fn quantile(xs: &[f64], q: f64) -> Option<f64> {
    if xs.is_empty() {
        return None;
    }
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    Some(v[rank - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_is_not_empty_at_the_ends() {
        let (lo, hi) = wilson_95(1.0, 64);
        assert!(lo > 0.94 && lo < 0.95 && hi == 1.0, "{lo} {hi}");
        let (lo, hi) = wilson_95(0.0, 100);
        assert!(lo == 0.0 && hi > 0.03 && hi < 0.04, "{lo} {hi}");
    }

    #[test]
    fn quantiles_by_nearest_rank() {
        let xs = [5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(quantile(&xs, 0.5), Some(3.0));
        assert_eq!(quantile(&xs, 0.95), Some(5.0));
        assert_eq!(quantile(&xs, 0.0), Some(1.0));
        assert_eq!(quantile(&[], 0.5), None);
    }
}
