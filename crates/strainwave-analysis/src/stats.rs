//! Basic statistics over slices (NaN-free input expected; an empty slice gives NaN).

/// Arithmetic mean.
pub fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

/// Root mean square.
pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Largest absolute value.
pub fn max_abs(x: &[f64]) -> f64 {
    if x.is_empty() {
        return f64::NAN;
    }
    x.iter().fold(0.0, |m, v| m.max(v.abs()))
}

/// Population standard deviation.
pub fn std_dev(x: &[f64]) -> f64 {
    let m = mean(x);
    (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64).sqrt()
}

/// Element-wise `a − b`.
pub fn diff(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

/// Indices `k` with `t0 ≤ time[k] < t1`, as a range (time must be increasing).
pub fn time_window(time: &[f64], t0: f64, t1: f64) -> std::ops::Range<usize> {
    let a = time.partition_point(|t| *t < t0);
    let b = time.partition_point(|t| *t < t1);
    a..b.max(a)
}

/// Histogram of finite values over `bins` equal bins spanning their range:
/// `(bin edges, counts)` with `bins + 1` edges. Empty input gives empty vectors.
pub fn histogram(values: &[f64], bins: usize) -> (Vec<f64>, Vec<u64>) {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() || bins == 0 {
        return (Vec::new(), Vec::new());
    }
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let mut hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi <= lo {
        hi = lo + 1.0;
    }
    let w = (hi - lo) / bins as f64;
    let mut counts = vec![0u64; bins];
    for v in finite {
        let k = (((v - lo) / w) as usize).min(bins - 1);
        counts[k] += 1;
    }
    ((0..=bins).map(|i| lo + i as f64 * w).collect(), counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basics() {
        let x = [3.0, -4.0];
        assert_eq!(mean(&x), -0.5);
        assert!((rms(&x) - (12.5f64).sqrt()).abs() < 1e-15);
        assert_eq!(max_abs(&x), 4.0);
        assert_eq!(std_dev(&x), 3.5);
        assert_eq!(time_window(&[0.0, 0.1, 0.2, 0.3], 0.1, 0.3), 1..3);
        assert!(max_abs(&[]).is_nan());
        let (e, c) = histogram(&[0.0, 0.1, 0.9, 1.0, f64::NAN], 2);
        assert_eq!(e, vec![0.0, 0.5, 1.0]);
        assert_eq!(c, vec![2, 2]);
    }
}
