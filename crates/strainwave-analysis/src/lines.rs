//! Finding expected spectral lines (orders) in a signal: for each expected frequency,
//! the strongest bin within a tolerance, its amplitude and the offset in bins.

use crate::error::AnalysisError;
use crate::spectrum::amplitude_spectrum;

/// An expected line and what the spectrum shows there.
#[derive(Debug, Clone, PartialEq)]
pub struct LineMatch {
    /// Label, e.g. `2× relative`.
    pub label: String,
    /// Expected frequency, Hz.
    pub expected_hz: f64,
    /// Frequency of the strongest bin within the tolerance, Hz.
    pub found_hz: f64,
    /// Amplitude there, signal units.
    pub amplitude: f64,
    /// `found − expected` in bins.
    pub offset_bins: f64,
    /// Spectral resolution, Hz.
    pub resolution_hz: f64,
    /// Whether the found bin is a local maximum standing above the median level ×10.
    pub is_peak: bool,
}

/// Looks for each `(label, frequency)` within `tolerance_bins` bins.
///
/// ```
/// use strainwave_analysis::lines::find_lines;
/// let fs = 1000.0;
/// let x: Vec<f64> = (0..2000).map(|k| (std::f64::consts::TAU * 100.0 * k as f64 / fs).sin()).collect();
/// let m = find_lines(&x, fs, &[("line".into(), 100.2)], 2).unwrap();
/// assert_eq!(m[0].found_hz, 100.0);
/// assert!(m[0].is_peak);
/// ```
pub fn find_lines(
    signal: &[f64],
    sample_rate_hz: f64,
    expected: &[(String, f64)],
    tolerance_bins: usize,
) -> Result<Vec<LineMatch>, AnalysisError> {
    let spec = amplitude_spectrum(signal, sample_rate_hz)?;
    let mut sorted = spec.amplitude.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let n = spec.amplitude.len();
    Ok(expected
        .iter()
        .map(|(label, f)| {
            let k0 = (f / spec.resolution_hz).round() as isize;
            let lo = (k0 - tolerance_bins as isize).clamp(0, n as isize - 1) as usize;
            let hi = (k0 + tolerance_bins as isize).clamp(0, n as isize - 1) as usize;
            let k = (lo..=hi).max_by(|&a, &b| spec.amplitude[a].total_cmp(&spec.amplitude[b])).unwrap_or(lo);
            let a = spec.amplitude[k];
            let local_max = (k == 0 || a >= spec.amplitude[k - 1]) && (k + 1 >= n || a >= spec.amplitude[k + 1]);
            LineMatch {
                label: label.clone(),
                expected_hz: *f,
                found_hz: spec.freqs_hz[k],
                amplitude: a,
                offset_bins: (spec.freqs_hz[k] - f) / spec.resolution_hz,
                resolution_hz: spec.resolution_hz,
                is_peak: local_max && a > 10.0 * median,
            }
        })
        .collect())
}
