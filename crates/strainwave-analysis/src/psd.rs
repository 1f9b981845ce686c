//! Welch power spectral density and cross spectral density, with the conventions of
//! `scipy.signal.welch` / `scipy.signal.csd` (so results agree to rounding):
//!
//! - segments of `nperseg` samples start at `k · (nperseg − noverlap)`, `k = 0 … K−1`,
//!   `K = ⌊(N − nperseg) / step⌋ + 1` (no boundary extension, no padding; the tail that
//!   does not fill a segment is dropped);
//! - each segment is detrended (`Constant`: minus its mean; `Linear`: minus its
//!   least-squares line), multiplied by the window and transformed with `nfft ≥ nperseg`
//!   points (zero-padded);
//! - `P_xy = conj(X) Y · scale`, `scale = 1 / (fs Σw²)` (`Density`, unit²/Hz) or
//!   `1 / (Σw)²` (`Spectrum`, unit²); one-sided: every bin but DC (and Nyquist for even
//!   `nfft`) is doubled; the segments are averaged (mean);
//! - `Window::Hann` is scipy's default periodic Hann `w[n] = 0.5 − 0.5 cos(2π n / nperseg)`.
//!
//! Differences from scipy: a signal shorter than `nperseg` is an error (scipy shrinks
//! `nperseg` with a warning); signals of different lengths are an error (scipy pads).

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

use crate::error::AnalysisError;

/// A window over one segment.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Window {
    /// Periodic Hann (scipy `get_window('hann', n)`).
    #[default]
    Hann,
    /// All ones (scipy `'boxcar'`).
    Rectangular,
    /// Explicit coefficients; the length must equal `nperseg`.
    Custom(Vec<f64>),
}

impl Window {
    /// The coefficients for a segment of `n` samples.
    ///
    /// ```
    /// use strainwave_analysis::psd::Window;
    /// let w = Window::Hann.coefficients(4);
    /// assert!((w[2] - 1.0).abs() < 1e-15 && w[0].abs() < 1e-15);
    /// ```
    pub fn coefficients(&self, n: usize) -> Vec<f64> {
        match self {
            Window::Hann => (0..n).map(|k| 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / n as f64).cos()).collect(),
            Window::Rectangular => vec![1.0; n],
            Window::Custom(w) => w.clone(),
        }
    }
}

/// Detrending of each segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Detrend {
    /// None.
    None,
    /// Subtract the segment mean (scipy `'constant'`).
    #[default]
    Constant,
    /// Subtract the least-squares line (scipy `'linear'`).
    Linear,
}

/// Scaling of the spectra.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scaling {
    /// Power spectral density, unit²/Hz: `1 / (fs Σw²)`.
    #[default]
    Density,
    /// Power spectrum, unit²: `1 / (Σw)²` (a sinusoid of amplitude `A` on a bin shows `A²/2`).
    Spectrum,
}

impl std::str::FromStr for Detrend {
    type Err = String;

    /// `constant`, `linear` or `none` (scipy's names); the error lists them.
    fn from_str(name: &str) -> Result<Self, String> {
        let table = [("constant", Self::Constant), ("linear", Self::Linear), ("none", Self::None)];
        crate::choice::parse(name, &table, 3)
    }
}

impl std::str::FromStr for Scaling {
    type Err = String;

    /// `density` or `spectrum` (scipy's names); the error lists them.
    fn from_str(name: &str) -> Result<Self, String> {
        crate::choice::parse(name, &[("density", Self::Density), ("spectrum", Self::Spectrum)], 2)
    }
}

/// Segmentation, window, detrending and scaling (scipy's keyword arguments).
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralConfig {
    /// Samples per segment.
    pub nperseg: usize,
    /// Overlap in samples; `None`: `nperseg / 2` for Welch / CSD / H1, `nperseg / 8` for
    /// the spectrogram (scipy's defaults).
    pub noverlap: Option<usize>,
    /// FFT length (≥ `nperseg`); `None`: `nperseg`.
    pub nfft: Option<usize>,
    /// Window.
    pub window: Window,
    /// Detrending.
    pub detrend: Detrend,
    /// Scaling.
    pub scaling: Scaling,
}

impl SpectralConfig {
    /// Hann, default overlap, constant detrend, density: scipy's defaults but the window.
    ///
    /// ```
    /// use strainwave_analysis::psd::{Scaling, SpectralConfig};
    /// let c = SpectralConfig::new(256).with_noverlap(192).with_scaling(Scaling::Spectrum);
    /// assert_eq!(c.noverlap, Some(192));
    /// ```
    pub fn new(nperseg: usize) -> Self {
        Self {
            nperseg,
            noverlap: None,
            nfft: None,
            window: Window::Hann,
            detrend: Detrend::Constant,
            scaling: Scaling::Density,
        }
    }
    /// With an explicit overlap.
    pub fn with_noverlap(mut self, noverlap: usize) -> Self {
        self.noverlap = Some(noverlap);
        self
    }
    /// With an FFT length.
    pub fn with_nfft(mut self, nfft: usize) -> Self {
        self.nfft = Some(nfft);
        self
    }
    /// With a window.
    pub fn with_window(mut self, window: Window) -> Self {
        self.window = window;
        self
    }
    /// With a detrending.
    pub fn with_detrend(mut self, detrend: Detrend) -> Self {
        self.detrend = detrend;
        self
    }
    /// With a scaling.
    pub fn with_scaling(mut self, scaling: Scaling) -> Self {
        self.scaling = scaling;
        self
    }
}

/// A validated segmentation.
#[derive(Debug, Clone)]
pub(crate) struct SegmentPlan {
    pub window: Vec<f64>,
    pub nperseg: usize,
    pub step: usize,
    pub nfft: usize,
    pub segments: usize,
    pub detrend: Detrend,
    /// `1/(fs Σw²)` or `1/(Σw)²`.
    pub scale: f64,
    pub sample_rate_hz: f64,
}

pub(crate) fn invalid(what: &'static str, why: impl Into<String>) -> AnalysisError {
    AnalysisError::Invalid { what, why: why.into() }
}

/// Error on a non-finite sample of `x`.
pub(crate) fn check_finite(x: &[f64], what: &'static str) -> Result<(), AnalysisError> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(AnalysisError::NonFinite { what, index }),
        None => Ok(()),
    }
}

/// Error unless `fs` is positive and finite.
pub(crate) fn check_rate(sample_rate_hz: f64) -> Result<(), AnalysisError> {
    if sample_rate_hz.is_finite() && sample_rate_hz > 0.0 {
        Ok(())
    } else {
        Err(invalid("sample_rate_hz", format!("must be positive and finite, got {sample_rate_hz}")))
    }
}

/// Longest FFT a segment is zero-padded to (2²⁴: 256 MiB of complex values); a segment
/// longer than that is transformed at its own length.
pub const MAX_PADDED_NFFT: usize = 1 << 24;

impl SegmentPlan {
    /// Validates `cfg` for a signal of `len` samples; `default_overlap_div` is 2 (Welch)
    /// or 8 (spectrogram).
    pub fn new(
        cfg: &SpectralConfig,
        len: usize,
        sample_rate_hz: f64,
        default_overlap_div: usize,
    ) -> Result<Self, AnalysisError> {
        check_rate(sample_rate_hz)?;
        let nperseg = cfg.nperseg;
        if nperseg < 1 {
            return Err(invalid("nperseg", "must be at least 1"));
        }
        let noverlap = cfg.noverlap.unwrap_or(nperseg / default_overlap_div);
        if noverlap >= nperseg {
            return Err(invalid("noverlap", format!("must be less than nperseg = {nperseg}, got {noverlap}")));
        }
        let nfft = cfg.nfft.unwrap_or(nperseg);
        if nfft < nperseg {
            return Err(invalid("nfft", format!("must be at least nperseg = {nperseg}, got {nfft}")));
        }
        if nfft > nperseg.max(MAX_PADDED_NFFT) {
            return Err(invalid("nfft", format!("zero padding beyond {MAX_PADDED_NFFT} points, got {nfft}")));
        }
        if len < nperseg {
            return Err(AnalysisError::TooShort { what: "signal", needed: nperseg, got: len });
        }
        let window = cfg.window.coefficients(nperseg);
        if window.len() != nperseg {
            return Err(invalid("window", format!("has {} coefficients, nperseg is {nperseg}", window.len())));
        }
        check_finite(&window, "window")?;
        let scale = match cfg.scaling {
            Scaling::Density => 1.0 / (sample_rate_hz * window.iter().map(|w| w * w).sum::<f64>()),
            Scaling::Spectrum => 1.0 / window.iter().sum::<f64>().powi(2),
        };
        if !scale.is_finite() {
            return Err(invalid("window", "its sum (of squares) is zero"));
        }
        let step = nperseg - noverlap;
        Ok(Self {
            window,
            nperseg,
            step,
            nfft,
            segments: (len - nperseg) / step + 1,
            detrend: cfg.detrend,
            scale,
            sample_rate_hz,
        })
    }

    /// Number of one-sided bins, `nfft/2 + 1`.
    pub fn bins(&self) -> usize {
        self.nfft / 2 + 1
    }

    /// Bin frequencies `k fs / nfft`, Hz.
    pub fn freqs_hz(&self) -> Vec<f64> {
        (0..self.bins()).map(|k| k as f64 * self.sample_rate_hz / self.nfft as f64).collect()
    }

    /// Factor of the one-sided spectrum at bin `k` (1 at DC and at an even `nfft`'s Nyquist).
    pub fn one_sided_factor(&self, k: usize) -> f64 {
        if k == 0 || (self.nfft & 1 == 0 && k == self.nfft / 2) {
            1.0
        } else {
            2.0
        }
    }

    /// Centre of segment `k`, s (scipy's `t`).
    pub fn centre_s(&self, k: usize) -> f64 {
        (k * self.step) as f64 / self.sample_rate_hz + self.nperseg as f64 / 2.0 / self.sample_rate_hz
    }

    /// Calls `f(k, spectrum)` with the unscaled one-sided FFT of every detrended, windowed
    /// segment of `x`.
    pub fn for_each_segment(&self, x: &[f64], mut f: impl FnMut(usize, &[Complex<f64>])) {
        let mut t = SegmentTransform::new(self);
        for k in 0..self.segments {
            f(k, t.transform(self, x, k));
        }
    }
}

/// FFT plan and buffers for the segments of one [`SegmentPlan`].
pub(crate) struct SegmentTransform {
    fft: std::sync::Arc<dyn realfft::RealToComplex<f64>>,
    input: Vec<f64>,
    out: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

impl SegmentTransform {
    pub fn new(plan: &SegmentPlan) -> Self {
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(plan.nfft);
        let (input, out, scratch) = (fft.make_input_vec(), fft.make_output_vec(), fft.make_scratch_vec());
        Self { fft, input, out, scratch }
    }

    /// The unscaled one-sided FFT of segment `k` of `x` (detrended, windowed).
    pub fn transform(&mut self, plan: &SegmentPlan, x: &[f64], k: usize) -> &[Complex<f64>] {
        let seg = &x[k * plan.step..k * plan.step + plan.nperseg];
        self.input.iter_mut().for_each(|v| *v = 0.0);
        detrend_into(seg, plan.detrend, &mut self.input[..plan.nperseg]);
        for (v, w) in self.input.iter_mut().zip(&plan.window) {
            *v *= w;
        }
        // Lengths come from the plan itself, so this cannot fail; on failure the output
        // would hold zeros.
        if self.fft.process_with_scratch(&mut self.input, &mut self.out, &mut self.scratch).is_err() {
            self.out.iter_mut().for_each(|c| *c = Complex::new(0.0, 0.0));
        }
        &self.out
    }
}

/// Writes `seg` minus its trend into `out` (same length).
pub(crate) fn detrend_into(seg: &[f64], detrend: Detrend, out: &mut [f64]) {
    let n = seg.len() as f64;
    match detrend {
        Detrend::None => out.copy_from_slice(seg),
        Detrend::Constant => {
            let m = seg.iter().sum::<f64>() / n;
            out.iter_mut().zip(seg).for_each(|(o, v)| *o = v - m);
        }
        Detrend::Linear => {
            // Least squares on t = 0..n−1 about its mean.
            let tm = (n - 1.0) / 2.0;
            let m = seg.iter().sum::<f64>() / n;
            let (mut stt, mut sty) = (0.0, 0.0);
            for (i, v) in seg.iter().enumerate() {
                let t = i as f64 - tm;
                stt += t * t;
                sty += t * (v - m);
            }
            let slope = if stt > 0.0 { sty / stt } else { 0.0 };
            out.iter_mut().zip(seg.iter().enumerate()).for_each(|(o, (i, v))| *o = v - m - slope * (i as f64 - tm));
        }
    }
}

/// A one-sided power spectral density (or power spectrum).
#[derive(Debug, Clone, PartialEq)]
pub struct Psd {
    /// Bin frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// Power per bin, unit²/Hz (`Density`) or unit² (`Spectrum`).
    pub psd: Vec<f64>,
    /// Segments averaged.
    pub segments: usize,
}

/// Welch's averaged periodogram of `x` (scipy `welch(x, fs, window, nperseg, noverlap,
/// nfft, detrend, return_onesided=True, scaling, average='mean')`).
///
/// ```
/// use strainwave_analysis::psd::{welch, Scaling, SpectralConfig};
/// let fs = 1000.0;
/// let x: Vec<f64> = (0..4096).map(|k| 2.0 * (std::f64::consts::TAU * 125.0 * k as f64 / fs).sin()).collect();
/// let p = welch(&x, fs, &SpectralConfig::new(256).with_scaling(Scaling::Spectrum)).unwrap();
/// // A sinusoid on bin 32 of a Hann spectrum: A²/2 there.
/// assert!((p.psd[32] - 2.0).abs() < 1e-9);
/// ```
pub fn welch(x: &[f64], sample_rate_hz: f64, cfg: &SpectralConfig) -> Result<Psd, AnalysisError> {
    check_finite(x, "signal")?;
    let plan = SegmentPlan::new(cfg, x.len(), sample_rate_hz, 2)?;
    let mut acc = vec![0.0; plan.bins()];
    plan.for_each_segment(x, |_, s| {
        for (a, c) in acc.iter_mut().zip(s) {
            *a += c.norm_sqr();
        }
    });
    let k = plan.segments as f64;
    let psd = acc.iter().enumerate().map(|(i, a)| a * plan.scale * plan.one_sided_factor(i) / k).collect();
    Ok(Psd { freqs_hz: plan.freqs_hz(), psd, segments: plan.segments })
}

/// A one-sided cross spectral density `P_xy = E[conj(X) Y]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Csd {
    /// Bin frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// Cross spectrum per bin.
    pub csd: Vec<Complex<f64>>,
    /// Segments averaged.
    pub segments: usize,
}

/// The plan and `(P_xx, P_yy, P_xy)` of [`cross_spectra`].
pub(crate) type CrossSpectra = (SegmentPlan, Vec<f64>, Vec<f64>, Vec<Complex<f64>>);

/// The auto and cross spectra of two equally long signals in one pass:
/// `(P_xx, P_yy, P_xy)`, scaled and one-sided like scipy.
pub(crate) fn cross_spectra(
    x: &[f64],
    y: &[f64],
    sample_rate_hz: f64,
    cfg: &SpectralConfig,
) -> Result<CrossSpectra, AnalysisError> {
    check_finite(x, "x")?;
    check_finite(y, "y")?;
    if x.len() != y.len() {
        return Err(invalid("y", format!("has {} samples, x has {}", y.len(), x.len())));
    }
    let plan = SegmentPlan::new(cfg, x.len(), sample_rate_hz, 2)?;
    let nb = plan.bins();
    let (mut tx, mut ty) = (SegmentTransform::new(&plan), SegmentTransform::new(&plan));
    let (mut pxx, mut pyy, mut pxy) = (vec![0.0; nb], vec![0.0; nb], vec![Complex::new(0.0, 0.0); nb]);
    for k in 0..plan.segments {
        let sx = tx.transform(&plan, x, k);
        let sy = ty.transform(&plan, y, k);
        for i in 0..nb {
            pxx[i] += sx[i].norm_sqr();
            pyy[i] += sy[i].norm_sqr();
            pxy[i] += sx[i].conj() * sy[i];
        }
    }
    let k = plan.segments as f64;
    for i in 0..nb {
        let f = plan.scale * plan.one_sided_factor(i) / k;
        pxx[i] *= f;
        pyy[i] *= f;
        pxy[i] *= f;
    }
    Ok((plan, pxx, pyy, pxy))
}

/// Cross spectral density (scipy `csd(x, y, …)`, `P_xy = conj(X) Y`).
///
/// ```
/// use strainwave_analysis::psd::{csd, SpectralConfig};
/// let x: Vec<f64> = (0..1024).map(|k| (k as f64 * 0.3).sin()).collect();
/// let c = csd(&x, &x, 100.0, &SpectralConfig::new(128)).unwrap();
/// assert!(c.csd.iter().all(|v| v.im.abs() < 1e-12));
/// ```
pub fn csd(x: &[f64], y: &[f64], sample_rate_hz: f64, cfg: &SpectralConfig) -> Result<Csd, AnalysisError> {
    let (plan, _, _, pxy) = cross_spectra(x, y, sample_rate_hz, cfg)?;
    Ok(Csd { freqs_hz: plan.freqs_hz(), csd: pxy, segments: plan.segments })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parseval_density_integrates_to_variance() {
        // White-ish deterministic noise: ∫ PSD df ≈ variance (Hann, 50 % overlap).
        let mut s = 1u64;
        let x: Vec<f64> = (0..1 << 15)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let p = welch(&x, 1000.0, &SpectralConfig::new(512)).unwrap();
        let df = p.freqs_hz[1];
        let integral: f64 = p.psd.iter().sum::<f64>() * df;
        let var = crate::stats::std_dev(&x).powi(2);
        assert!((integral / var - 1.0).abs() < 0.02, "{integral} vs {var}");
        assert_eq!(p.segments, (x.len() - 512) / 256 + 1);
    }

    #[test]
    fn rejects_bad_input() {
        let cfg = SpectralConfig::new(64);
        assert!(matches!(welch(&[0.0; 10], 1.0, &cfg), Err(AnalysisError::TooShort { needed: 64, got: 10, .. })));
        let mut x = vec![0.0; 100];
        x[7] = f64::NAN;
        assert!(matches!(welch(&x, 1.0, &cfg), Err(AnalysisError::NonFinite { index: 7, .. })));
        assert!(welch(&[0.0; 100], 0.0, &cfg).is_err());
        assert!(welch(&[0.0; 100], 1.0, &cfg.clone().with_noverlap(64)).is_err());
        assert!(welch(&[0.0; 100], 1.0, &cfg.clone().with_nfft(32)).is_err());
        // Zero padding to 2⁴⁰ or 2⁶² points is refused before anything is allocated.
        for nfft in [1 << 40, 1 << 62, usize::MAX] {
            let e = welch(&[0.0; 100], 1.0, &cfg.clone().with_nfft(nfft)).unwrap_err().to_string();
            assert!(e.contains("nfft") && e.contains("zero padding beyond 16777216 points"), "{e}");
        }
        assert!(welch(&[0.0; 100], 1.0, &cfg.clone().with_nfft(1 << 12)).is_ok());
        assert!(welch(&[0.0; 100], 1.0, &cfg.clone().with_window(Window::Custom(vec![1.0; 3]))).is_err());
        assert!(csd(&[0.0; 100], &[0.0; 99], 1.0, &cfg).is_err());
    }

    #[test]
    fn linear_detrend_removes_a_ramp() {
        let seg: Vec<f64> = (0..10).map(|i| 3.0 + 0.5 * i as f64).collect();
        let mut out = vec![0.0; 10];
        detrend_into(&seg, Detrend::Linear, &mut out);
        assert!(out.iter().all(|v| v.abs() < 1e-12));
    }
}
