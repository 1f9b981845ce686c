//! Frequency-response estimate `H1 = P_xy / P_xx` with the magnitude-squared coherence
//! `γ² = |P_xy|² / (P_xx P_yy)`, from Welch-averaged spectra with the conventions of
//! `scipy.signal.csd` / `welch` / `coherence` (`P_xy = E[conj(X) Y]`, see [`crate::psd`]).
//!
//! `x` is the input (e.g. the model torque), `y` the output (e.g. a sensor torque). H1 is
//! unbiased by noise on the output; noise on the input biases it low, which the coherence
//! shows. A bin where `P_xx = 0` gives NaN (as scipy does).

use realfft::num_complex::Complex;

use crate::error::AnalysisError;
use crate::psd::{cross_spectra, SpectralConfig};

/// An estimated frequency response.
#[derive(Debug, Clone, PartialEq)]
pub struct Frf {
    /// Bin frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// `H1 = P_xy / P_xx` per bin.
    pub h1: Vec<Complex<f64>>,
    /// Magnitude-squared coherence per bin, 0…1.
    pub coherence: Vec<f64>,
    /// Input auto spectrum.
    pub pxx: Vec<f64>,
    /// Output auto spectrum.
    pub pyy: Vec<f64>,
    /// Cross spectrum `E[conj(X) Y]`.
    pub pxy: Vec<Complex<f64>>,
    /// Segments averaged.
    pub segments: usize,
}

/// H1 estimate from `input` to `output` (equal lengths, at least one segment).
///
/// ```
/// use strainwave_analysis::frf::h1;
/// use strainwave_analysis::psd::SpectralConfig;
/// // y = 2 x[n−1]: |H| = 2, phase −ω/fs.
/// let mut s = 1u64;
/// let x: Vec<f64> = (0..4096)
///     .map(|_| {
///         s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
///         (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
///     })
///     .collect();
/// let y: Vec<f64> = (0..4096).map(|k| if k == 0 { 0.0 } else { 2.0 * x[k - 1] }).collect();
/// let f = h1(&x, &y, 1000.0, &SpectralConfig::new(512)).unwrap();
/// assert!((f.h1[64].norm() - 2.0).abs() < 0.02);
/// assert!((f.h1[64].arg() + std::f64::consts::TAU * f.freqs_hz[64] / 1000.0).abs() < 0.01);
/// assert!(f.coherence[64] > 0.99);
/// ```
pub fn h1(input: &[f64], output: &[f64], sample_rate_hz: f64, cfg: &SpectralConfig) -> Result<Frf, AnalysisError> {
    let (plan, pxx, pyy, pxy) = cross_spectra(input, output, sample_rate_hz, cfg)?;
    let h1 = pxx.iter().zip(&pxy).map(|(a, c)| c / *a).collect();
    let coherence = pxx.iter().zip(&pyy).zip(&pxy).map(|((a, b), c)| c.norm_sqr() / a / b).collect();
    Ok(Frf { freqs_hz: plan.freqs_hz(), h1, coherence, pxx, pyy, pxy, segments: plan.segments })
}

/// Magnitude-squared coherence (scipy `coherence(x, y, …)`): `(freqs_hz, γ²)`.
///
/// ```
/// use strainwave_analysis::frf::coherence;
/// use strainwave_analysis::psd::SpectralConfig;
/// let x: Vec<f64> = (0..2048).map(|k| (k as f64 * 0.37).sin() + ((k * 13) % 7) as f64).collect();
/// let (_, c) = coherence(&x, &x, 1.0, &SpectralConfig::new(256)).unwrap();
/// assert!(c[1..].iter().all(|v| (v - 1.0).abs() < 1e-9));
/// ```
pub fn coherence(
    x: &[f64],
    y: &[f64],
    sample_rate_hz: f64,
    cfg: &SpectralConfig,
) -> Result<(Vec<f64>, Vec<f64>), AnalysisError> {
    let f = h1(x, y, sample_rate_hz, cfg)?;
    Ok((f.freqs_hz, f.coherence))
}

impl Frf {
    /// `20 log10 |H1|` at bin `k`, dB.
    pub fn magnitude_db(&self, k: usize) -> f64 {
        20.0 * self.h1[k].norm().log10()
    }

    /// `arg H1` at bin `k`, degrees in `(−180, 180]`.
    pub fn phase_deg(&self, k: usize) -> f64 {
        self.h1[k].arg().to_degrees()
    }

    /// Bins with `lo_hz ≤ f ≤ hi_hz` and coherence of at least `min_coherence`.
    pub fn bins_in(&self, lo_hz: f64, hi_hz: f64, min_coherence: f64) -> Vec<usize> {
        (0..self.freqs_hz.len())
            .filter(|&k| self.freqs_hz[k] >= lo_hz && self.freqs_hz[k] <= hi_hz && self.coherence[k] >= min_coherence)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_noise_lowers_coherence_not_h1() {
        let mut s = 7u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let x: Vec<f64> = (0..1 << 16).map(|_| rnd()).collect();
        let y: Vec<f64> = x.iter().map(|v| 0.5 * v + 0.5 * rnd()).collect();
        let f = h1(&x, &y, 1.0, &SpectralConfig::new(1024)).unwrap();
        let mid: Vec<usize> = (10..500).collect();
        let mean_h = mid.iter().map(|&k| f.h1[k].re).sum::<f64>() / mid.len() as f64;
        let mean_c = mid.iter().map(|&k| f.coherence[k]).sum::<f64>() / mid.len() as f64;
        assert!((mean_h - 0.5).abs() < 0.01, "{mean_h}");
        // γ² = 0.25 / (0.25 + 0.25) for equal signal and noise power.
        assert!((mean_c - 0.5).abs() < 0.03, "{mean_c}");
    }
}
