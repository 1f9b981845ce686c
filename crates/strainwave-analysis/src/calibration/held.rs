//! Quasi-static (held) rows of a step-loading recording: the embedded-sensor article fitted its static
//! model on held loads only, not on the ramps between them.

use std::collections::VecDeque;

use super::{check_columns, invalid, CalibrationError};

/// Marks the rows at which the reference torque has been held for `hold_s` seconds:
///
/// ```text
/// held_i  ⇔  t_i − t_0 ≥ hold_s  and  max_W r − min_W r ≤ band_nm,   W = { j : t_i − hold_s ≤ t_j ≤ t_i }
/// ```
///
/// so a step contributes its last part, after the load has settled for `hold_s`, and
/// ramps contribute nothing. `band_nm` must exceed the reference's own noise
/// (peak to peak over the window, about 6σ for a few hundred samples). O(n) with
/// monotone queues. Time must be non-decreasing.
///
/// Errors: columns of different lengths, a non-finite row (named), time going backwards
/// (row named), `hold_s` or `band_nm` not positive and finite.
///
/// ```
/// use strainwave_analysis::calibration::held_rows;
/// // 0 N·m for 1 s, a 0.2-s ramp to 5 N·m, then held; 10 ms samples.
/// let t: Vec<f64> = (0..300).map(|k| k as f64 * 0.01).collect();
/// let r: Vec<f64> = t.iter().map(|&t| (5.0 * (t - 1.0) / 0.2).clamp(0.0, 5.0)).collect();
/// let held = held_rows(&t, &r, 0.5, 0.05).unwrap();
/// assert!(!held[40] && held[60] && !held[110] && !held[165] && held[175]);
/// ```
pub fn held_rows(
    time_s: &[f64],
    reference_nm: &[f64],
    hold_s: f64,
    band_nm: f64,
) -> Result<Vec<bool>, CalibrationError> {
    let what = "held rows";
    let n = check_columns(what, &[("time_s", time_s), ("reference_nm", reference_nm)])?;
    if !(hold_s.is_finite() && hold_s > 0.0) {
        return Err(invalid("hold_s", format!("must be a positive duration, got {hold_s}")));
    }
    if !(band_nm.is_finite() && band_nm > 0.0) {
        return Err(invalid("band_nm", format!("must be a positive torque, got {band_nm}")));
    }
    if let Some(row) = (1..n).find(|&i| time_s[i] < time_s[i - 1]) {
        return Err(invalid(
            what,
            format!("row {row}: time goes backwards ({} s after {} s)", time_s[row], time_s[row - 1]),
        ));
    }
    // Indices of window maxima (values decreasing) and minima (values increasing).
    let (mut hi, mut lo): (VecDeque<usize>, VecDeque<usize>) = (VecDeque::new(), VecDeque::new());
    let mut start = 0;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        while hi.back().is_some_and(|&j| reference_nm[j] <= reference_nm[i]) {
            hi.pop_back();
        }
        hi.push_back(i);
        while lo.back().is_some_and(|&j| reference_nm[j] >= reference_nm[i]) {
            lo.pop_back();
        }
        lo.push_back(i);
        while time_s[start] < time_s[i] - hold_s {
            start += 1;
        }
        while hi.front().is_some_and(|&j| j < start) {
            hi.pop_front();
        }
        while lo.front().is_some_and(|&j| j < start) {
            lo.pop_front();
        }
        let (max, min) = (reference_nm[hi[0]], reference_nm[lo[0]]);
        out.push(time_s[i] - time_s[0] >= hold_s && max - min <= band_nm);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The brute-force definition.
    fn naive(t: &[f64], r: &[f64], hold: f64, band: f64) -> Vec<bool> {
        (0..t.len())
            .map(|i| {
                let w: Vec<f64> = (0..=i).filter(|&j| t[j] >= t[i] - hold).map(|j| r[j]).collect();
                let spread = w.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                    - w.iter().copied().fold(f64::INFINITY, f64::min);
                t[i] - t[0] >= hold && spread <= band
            })
            .collect()
    }

    #[test]
    fn matches_the_definition_on_noisy_steps() {
        // Steps of 2 N·m every 1.5 s with 0.3-s ramps, deterministic "noise" of ±0.03 N·m.
        let t: Vec<f64> = (0..6000).map(|k| k as f64 * 1e-3).collect();
        let r: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                let steps = (0..4).map(|s| (2.0 * (t - 1.0 - 1.5 * s as f64) / 0.3).clamp(0.0, 2.0)).sum::<f64>();
                steps + 0.03 * ((k * 7919 % 101) as f64 / 50.0 - 1.0)
            })
            .collect();
        let fast = held_rows(&t, &r, 0.6, 0.1).unwrap();
        assert_eq!(fast, naive(&t, &r, 0.6, 0.1));
        // 0.6–1.0 s before the first ramp (400 rows), the last 0.6 s of the three full
        // 1.2-s holds (3 × 600), and about 10 rows at each ramp's ends where the ramp is
        // still inside the band: 2200 + ≈ 70.
        let count = fast.iter().filter(|&&h| h).count();
        assert!((2200..=2300).contains(&count), "{count}");
        assert!(!fast[1150] && fast[2450] && !fast[2600]);
    }

    #[test]
    fn errors_name_the_problem() {
        assert!(matches!(
            held_rows(&[0.0, 1.0], &[0.0, f64::NAN], 0.5, 0.1),
            Err(CalibrationError::NonFiniteRow { row: 1, column: "reference_nm", .. })
        ));
        let err = held_rows(&[0.0, 1.0, 0.5], &[0.0; 3], 0.5, 0.1).unwrap_err();
        assert!(err.to_string().contains("row 2"), "{err}");
        assert!(held_rows(&[0.0], &[0.0], 0.0, 0.1).is_err());
        assert!(held_rows(&[0.0], &[0.0], 1.0, -0.1).is_err());
    }
}
