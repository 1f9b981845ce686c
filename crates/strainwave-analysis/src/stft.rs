//! Short-time Fourier transform and spectrogram, with the conventions of
//! `scipy.signal.spectrogram(x, fs, window, nperseg, noverlap, nfft, detrend,
//! return_onesided=True, scaling, mode='psd')`: the segments, windows, detrending and
//! scaling of [`crate::psd`] without the averaging, one spectrum per segment, the
//! segment centres `t_k = (k · step + nperseg / 2) / fs` as times. The default overlap is
//! `nperseg / 8` like scipy's (pass the window explicitly: scipy's default is a Tukey).
//!
//! [`stft`] gives the complex frames with an amplitude scaling (a sinusoid of amplitude
//! `A` on a bin reads `A`), which the Campbell diagram and order analysis use.

use realfft::num_complex::Complex;

use crate::error::AnalysisError;
use crate::psd::{check_finite, SegmentPlan, SpectralConfig};

/// A one-sided spectrogram: one power spectrum per segment.
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrogram {
    /// Bin frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// Segment centres, s.
    pub times_s: Vec<f64>,
    /// `power[frame][bin]`, unit²/Hz (`Density`) or unit² (`Spectrum`) — the transpose of
    /// scipy's `Sxx[bin, frame]`.
    pub power: Vec<Vec<f64>>,
}

/// Spectrogram of `x` (scipy `spectrogram(…, mode='psd')`).
///
/// ```
/// use strainwave_analysis::psd::{Scaling, SpectralConfig};
/// use strainwave_analysis::stft::spectrogram;
/// let fs = 1000.0;
/// let x: Vec<f64> = (0..2000).map(|k| (std::f64::consts::TAU * 250.0 * k as f64 / fs).cos()).collect();
/// let s = spectrogram(&x, fs, &SpectralConfig::new(100).with_scaling(Scaling::Spectrum)).unwrap();
/// assert_eq!(s.times_s[0], 0.05);
/// assert!((s.power[3][25] - 0.5).abs() < 1e-9);
/// ```
pub fn spectrogram(x: &[f64], sample_rate_hz: f64, cfg: &SpectralConfig) -> Result<Spectrogram, AnalysisError> {
    check_finite(x, "signal")?;
    let plan = SegmentPlan::new(cfg, x.len(), sample_rate_hz, 8)?;
    let mut power = Vec::with_capacity(plan.segments);
    plan.for_each_segment(x, |_, s| {
        power.push(s.iter().enumerate().map(|(i, c)| c.norm_sqr() * plan.scale * plan.one_sided_factor(i)).collect());
    });
    Ok(Spectrogram {
        freqs_hz: plan.freqs_hz(),
        times_s: (0..plan.segments).map(|k| plan.centre_s(k)).collect(),
        power,
    })
}

/// Complex one-sided STFT frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Stft {
    /// Bin frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// Segment centres, s.
    pub times_s: Vec<f64>,
    /// Index of the first sample of each segment.
    pub starts: Vec<usize>,
    /// Samples per segment.
    pub nperseg: usize,
    /// `frames[frame][bin]`, scaled so that `A cos(2π f_k t + φ)` on bin `k` (not DC or
    /// Nyquist) reads `A e^{jφ'}` with `φ'` the phase at the segment start: `2 X / Σw`.
    pub frames: Vec<Vec<Complex<f64>>>,
}

/// Amplitude-scaled STFT (window, detrend and segmentation of `cfg`; its scaling is
/// ignored).
///
/// ```
/// use strainwave_analysis::psd::SpectralConfig;
/// use strainwave_analysis::stft::stft;
/// let fs = 1000.0;
/// let x: Vec<f64> = (0..1000).map(|k| 3.0 * (std::f64::consts::TAU * 100.0 * k as f64 / fs).cos()).collect();
/// let s = stft(&x, fs, &SpectralConfig::new(200)).unwrap();
/// assert!((s.frames[2][20].norm() - 3.0).abs() < 1e-9);
/// ```
pub fn stft(x: &[f64], sample_rate_hz: f64, cfg: &SpectralConfig) -> Result<Stft, AnalysisError> {
    check_finite(x, "signal")?;
    let plan = SegmentPlan::new(cfg, x.len(), sample_rate_hz, 8)?;
    let gain = plan.window.iter().sum::<f64>();
    if gain.abs() < f64::MIN_POSITIVE {
        return Err(crate::psd::invalid("window", "sums to zero"));
    }
    let mut frames = Vec::with_capacity(plan.segments);
    plan.for_each_segment(x, |_, s| {
        frames.push(s.iter().enumerate().map(|(i, c)| c * (plan.one_sided_factor(i) / gain)).collect());
    });
    Ok(Stft {
        freqs_hz: plan.freqs_hz(),
        times_s: (0..plan.segments).map(|k| plan.centre_s(k)).collect(),
        starts: (0..plan.segments).map(|k| k * plan.step).collect(),
        nperseg: plan.nperseg,
        frames,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::psd::{welch, Window};

    #[test]
    fn mean_of_spectrogram_is_welch() {
        let x: Vec<f64> = (0..3000).map(|k| ((k * k) % 17) as f64 - 8.0 + (k as f64 * 0.01).sin()).collect();
        let cfg = SpectralConfig::new(256).with_noverlap(128);
        let s = spectrogram(&x, 2000.0, &cfg).unwrap();
        let w = welch(&x, 2000.0, &cfg).unwrap();
        for (i, p) in w.psd.iter().enumerate() {
            let m = s.power.iter().map(|r| r[i]).sum::<f64>() / s.power.len() as f64;
            assert!((m - p).abs() <= 1e-12 * p.abs().max(1e-300), "{i}");
        }
    }

    #[test]
    fn default_overlap_is_an_eighth() {
        let x = vec![1.0; 1000];
        let s = spectrogram(&x, 1.0, &SpectralConfig::new(64).with_window(Window::Rectangular)).unwrap();
        assert_eq!(s.times_s.len(), (1000 - 64) / 56 + 1);
        assert!(spectrogram(&x[..10], 1.0, &SpectralConfig::new(64)).is_err());
    }
}
