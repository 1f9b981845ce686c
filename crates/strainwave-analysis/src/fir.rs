//! FIR correction of a measured or modelled frequency response: the inverse of the
//! response within a pass band, designed by frequency sampling with a window and applied
//! offline with its linear-phase delay compensated (Stoß et al. (2022) §V, future work).
//!
//! Design of an `N`-tap filter (`N` odd, delay `D = (N − 1)/2`) for a desired zero-delay
//! response `G(f)`, `0 ≤ f ≤ fs/2`:
//!
//! ```text
//! 1. sample G on M ≥ 4N points:  G_k = G(k fs / M), k = 0 … M/2 (DC and Nyquist real)
//! 2. g[n] = IDFT_M(G)[n]          (zero-centred, circular)
//! 3. h[i] = g[(i − D) mod M] w[i],  i = 0 … N−1   (w: symmetric window)
//! ```
//!
//! so `H(f) ≈ G(f) e^{−j 2π f D / fs}`; [`Fir::apply_zero_delay`] advances the output by
//! `D` samples, [`Fir::response`] reports the response without the delay. The window
//! smooths `G` over its main lobe (Blackman: ±3 fs/N): features of `G` narrower than that
//! are not followed.
//!
//! Inverse: `G(f) = W(f) conj(H) / (|H|² + λ²)` — the regularized (Tikhonov) inverse of the
//! path response `H`, weighted by the path's band `W` (see [`crate::bench`]).

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

use crate::error::AnalysisError;
use crate::psd::{check_finite, check_rate, invalid};

/// Symmetric window over the taps.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum FirWindow {
    /// All ones (plain truncation).
    Rectangular,
    /// `0.5 − 0.5 cos(2π i/(N−1))`.
    Hann,
    /// `0.42 − 0.5 cos(2π i/(N−1)) + 0.08 cos(4π i/(N−1))` (sidelobes −58 dB).
    #[default]
    Blackman,
    /// Kaiser with shape `beta` (`I0(β √(1 − r²)) / I0(β)`, `r = 2i/(N−1) − 1`).
    Kaiser {
        /// Shape parameter (≈ 8.6 for −90 dB sidelobes).
        beta: f64,
    },
}

/// Modified Bessel function of the first kind, order 0 (power series).
fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term) = (1.0, 1.0);
    let q = x * x / 4.0;
    for k in 1..500 {
        term *= q / (k as f64 * k as f64);
        sum += term;
        if term < 1e-17 * sum {
            break;
        }
    }
    sum
}

impl FirWindow {
    /// The `n` coefficients (symmetric; `n = 1` gives `[1]`).
    ///
    /// ```
    /// use strainwave_analysis::fir::FirWindow;
    /// let w = FirWindow::Hann.coefficients(5);
    /// assert_eq!(w[2], 1.0);
    /// assert!(w[0].abs() < 1e-15 && (w[1] - w[3]).abs() < 1e-15);
    /// ```
    pub fn coefficients(&self, n: usize) -> Vec<f64> {
        if n <= 1 {
            return vec![1.0; n];
        }
        let m = (n - 1) as f64;
        let tau = std::f64::consts::TAU;
        (0..n)
            .map(|i| {
                let x = i as f64 / m;
                match *self {
                    FirWindow::Rectangular => 1.0,
                    FirWindow::Hann => 0.5 - 0.5 * (tau * x).cos(),
                    FirWindow::Blackman => 0.42 - 0.5 * (tau * x).cos() + 0.08 * (2.0 * tau * x).cos(),
                    FirWindow::Kaiser { beta } => {
                        let r = 2.0 * x - 1.0;
                        bessel_i0(beta * (1.0 - r * r).max(0.0).sqrt()) / bessel_i0(beta)
                    }
                }
            })
            .collect()
    }
}

/// A linear-phase-delay FIR filter for offline use.
#[derive(Debug, Clone, PartialEq)]
pub struct Fir {
    taps: Vec<f64>,
    delay: usize,
    sample_rate_hz: f64,
}

impl Fir {
    /// A filter from explicit taps whose reference instant is tap `delay_samples`.
    ///
    /// ```
    /// use strainwave_analysis::fir::Fir;
    /// let f = Fir::from_taps(vec![0.25, 0.5, 0.25], 1, 100.0).unwrap();
    /// assert!((f.response(0.0).re - 1.0).abs() < 1e-15);
    /// assert!(f.response(50.0).norm() < 1e-15);
    /// ```
    pub fn from_taps(taps: Vec<f64>, delay_samples: usize, sample_rate_hz: f64) -> Result<Self, AnalysisError> {
        check_rate(sample_rate_hz)?;
        if taps.is_empty() {
            return Err(AnalysisError::TooShort { what: "taps", needed: 1, got: 0 });
        }
        check_finite(&taps, "taps")?;
        if delay_samples >= taps.len() {
            return Err(invalid("delay_samples", format!("must be below the tap count {}", taps.len())));
        }
        Ok(Self { taps, delay: delay_samples, sample_rate_hz })
    }

    /// Frequency-sampling design of `n_taps` (odd, ≥ 3) taps for the zero-delay response
    /// `desired(f_hz)`, `0 ≤ f ≤ fs/2` (see the module doc). A non-finite desired value is
    /// an error.
    ///
    /// ```
    /// use realfft::num_complex::Complex;
    /// use strainwave_analysis::fir::{Fir, FirWindow};
    /// // A gain of 2 below 100 Hz, 0 above 200 Hz, raised-cosine in between.
    /// let g = |f: f64| {
    ///     let w = if f <= 100.0 { 1.0 } else if f >= 200.0 { 0.0 } else { 0.5 + 0.5 * (std::f64::consts::PI * (f - 100.0) / 100.0).cos() };
    ///     Complex::new(2.0 * w, 0.0)
    /// };
    /// let fir = Fir::frequency_sampling(1001, 2000.0, FirWindow::Blackman, g).unwrap();
    /// assert!((fir.response(50.0).re - 2.0).abs() < 1e-3);
    /// assert!(fir.response(400.0).norm() < 1e-3);
    /// ```
    pub fn frequency_sampling(
        n_taps: usize,
        sample_rate_hz: f64,
        window: FirWindow,
        desired: impl Fn(f64) -> Complex<f64>,
    ) -> Result<Self, AnalysisError> {
        check_rate(sample_rate_hz)?;
        if n_taps < 3 || n_taps & 1 == 0 {
            return Err(invalid("n_taps", format!("must be odd and at least 3, got {n_taps}")));
        }
        let m = (4 * n_taps).next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        let ifft = planner.plan_fft_inverse(m);
        let mut spec = ifft.make_input_vec();
        for (k, s) in spec.iter_mut().enumerate() {
            let g = desired(k as f64 * sample_rate_hz / m as f64);
            if !(g.re.is_finite() && g.im.is_finite()) {
                return Err(AnalysisError::NonFinite { what: "desired response", index: k });
            }
            *s = g;
        }
        spec[0].im = 0.0;
        let last = spec.len() - 1;
        spec[last].im = 0.0;
        let mut g = ifft.make_output_vec();
        ifft.process(&mut spec, &mut g).map_err(|e| invalid("fft", e.to_string()))?;
        let d = (n_taps - 1) / 2;
        let w = window.coefficients(n_taps);
        let taps = (0..n_taps).map(|i| g[(i + m - d) % m] / m as f64 * w[i]).collect();
        Self::from_taps(taps, d, sample_rate_hz)
    }

    /// The taps.
    pub fn taps(&self) -> &[f64] {
        &self.taps
    }

    /// The delay the offline application removes, samples.
    pub fn delay_samples(&self) -> usize {
        self.delay
    }

    /// Sample rate, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }

    /// `Σ h[i] e^{−jω(i − D)/fs}`: the response with the delay removed.
    pub fn response(&self, freq_hz: f64) -> Complex<f64> {
        let w = -std::f64::consts::TAU * freq_hz / self.sample_rate_hz;
        self.taps.iter().enumerate().fold(Complex::new(0.0, 0.0), |acc, (i, h)| {
            acc + Complex::from_polar(*h, w * (i as f64 - self.delay as f64))
        })
    }

    /// `y[n] = Σ h[i] x[n + D − i]` for `n = 0 … len−1` (samples outside `x` count as 0):
    /// the filtered signal aligned with `x`, by FFT convolution.
    ///
    /// ```
    /// use strainwave_analysis::fir::Fir;
    /// let f = Fir::from_taps(vec![0.0, 0.0, 1.0, 0.0, 0.0], 2, 1.0).unwrap();
    /// let y = f.apply_zero_delay(&[1.0, 2.0, 3.0]).unwrap();
    /// assert!((y[0] - 1.0).abs() < 1e-12 && (y[2] - 3.0).abs() < 1e-12);
    /// ```
    pub fn apply_zero_delay(&self, x: &[f64]) -> Result<Vec<f64>, AnalysisError> {
        check_finite(x, "signal")?;
        if x.is_empty() {
            return Ok(Vec::new());
        }
        let n = (x.len() + self.taps.len() - 1).next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        let fwd = planner.plan_fft_forward(n);
        let inv = planner.plan_fft_inverse(n);
        let mut a = fwd.make_input_vec();
        a[..x.len()].copy_from_slice(x);
        let mut b = fwd.make_input_vec();
        b[..self.taps.len()].copy_from_slice(&self.taps);
        let (mut fa, mut fb) = (fwd.make_output_vec(), fwd.make_output_vec());
        fwd.process(&mut a, &mut fa).map_err(|e| invalid("fft", e.to_string()))?;
        fwd.process(&mut b, &mut fb).map_err(|e| invalid("fft", e.to_string()))?;
        for (p, q) in fa.iter_mut().zip(&fb) {
            *p *= q / n as f64;
        }
        fa[0].im = 0.0;
        let last = fa.len() - 1;
        fa[last].im = 0.0;
        let mut c = inv.make_output_vec();
        inv.process(&mut fa, &mut c).map_err(|e| invalid("fft", e.to_string()))?;
        Ok(c[self.delay..self.delay + x.len()].to_vec())
    }
}

/// Regularized inverse `conj(h) / (|h|² + λ²)`: `1/h` where `|h| ≫ λ`, bounded by `1/(2λ)`.
///
/// ```
/// use realfft::num_complex::Complex;
/// use strainwave_analysis::fir::regularized_inverse;
/// let g = regularized_inverse(Complex::new(0.0, 2.0), 1e-6);
/// assert!((g - Complex::new(0.0, -0.5)).norm() < 1e-12);
/// assert!(regularized_inverse(Complex::new(0.0, 0.0), 1e-3).norm() == 0.0);
/// ```
pub fn regularized_inverse(h: Complex<f64>, lambda: f64) -> Complex<f64> {
    h.conj() / (h.norm_sqr() + lambda * lambda)
}

/// A frequency response known at increasing frequencies (a model sampled, or an H1
/// estimate), interpolated linearly in log-magnitude and unwrapped phase; outside the
/// sampled range the edge values hold.
#[derive(Debug, Clone, PartialEq)]
pub struct SampledResponse {
    freqs_hz: Vec<f64>,
    log_mag: Vec<f64>,
    phase_rad: Vec<f64>,
}

impl SampledResponse {
    /// From strictly increasing finite frequencies and finite, non-zero values.
    ///
    /// ```
    /// use realfft::num_complex::Complex;
    /// use strainwave_analysis::fir::SampledResponse;
    /// let r = SampledResponse::new(vec![1.0, 3.0], vec![Complex::new(1.0, 0.0), Complex::new(0.0, 4.0)]).unwrap();
    /// assert!((r.at(2.0).norm() - 2.0).abs() < 1e-12);
    /// assert!((r.at(2.0).arg() - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
    /// ```
    pub fn new(freqs_hz: Vec<f64>, values: Vec<Complex<f64>>) -> Result<Self, AnalysisError> {
        if freqs_hz.is_empty() || freqs_hz.len() != values.len() {
            return Err(invalid("values", format!("{} values for {} frequencies", values.len(), freqs_hz.len())));
        }
        check_finite(&freqs_hz, "freqs_hz")?;
        if freqs_hz.windows(2).any(|w| w[1] <= w[0]) {
            return Err(invalid("freqs_hz", "must be strictly increasing"));
        }
        let mut log_mag = Vec::with_capacity(values.len());
        let mut phase_rad: Vec<f64> = Vec::with_capacity(values.len());
        for (k, v) in values.iter().enumerate() {
            let m = v.norm();
            if !(m.is_finite() && m > 0.0) {
                return Err(AnalysisError::NonFinite { what: "values (zero or non-finite)", index: k });
            }
            log_mag.push(m.ln());
            let p = v.arg();
            let unwrapped = match phase_rad.last() {
                Some(prev) => p + std::f64::consts::TAU * ((prev - p) / std::f64::consts::TAU).round(),
                None => p,
            };
            phase_rad.push(unwrapped);
        }
        Ok(Self { freqs_hz, log_mag, phase_rad })
    }

    /// From a function sampled at `freqs_hz`.
    ///
    /// ```
    /// use realfft::num_complex::Complex;
    /// let r = strainwave_analysis::fir::SampledResponse::from_fn(vec![1.0, 2.0], |f| Complex::new(f, 0.0)).unwrap();
    /// assert!((r.at(4.0).re - 2.0).abs() < 1e-12);
    /// ```
    pub fn from_fn(freqs_hz: Vec<f64>, f: impl Fn(f64) -> Complex<f64>) -> Result<Self, AnalysisError> {
        let values = freqs_hz.iter().map(|&x| f(x)).collect();
        Self::new(freqs_hz, values)
    }

    /// Sampled frequencies, Hz.
    pub fn freqs_hz(&self) -> &[f64] {
        &self.freqs_hz
    }

    /// The interpolated response at `freq_hz`.
    pub fn at(&self, freq_hz: f64) -> Complex<f64> {
        let f = &self.freqs_hz;
        let n = f.len();
        let (lm, ph) = if n == 1 || freq_hz.is_nan() || freq_hz <= f[0] {
            (self.log_mag[0], self.phase_rad[0])
        } else if freq_hz >= f[n - 1] {
            (self.log_mag[n - 1], self.phase_rad[n - 1])
        } else {
            let i = f.partition_point(|x| *x <= freq_hz) - 1;
            let t = (freq_hz - f[i]) / (f[i + 1] - f[i]);
            (
                self.log_mag[i] + t * (self.log_mag[i + 1] - self.log_mag[i]),
                self.phase_rad[i] + t * (self.phase_rad[i + 1] - self.phase_rad[i]),
            )
        };
        Complex::from_polar(lm.exp(), ph)
    }
}

/// The correction FIR of one path: `G(f) = band(f) · conj(H) / (|H|² + λ²)`.
///
/// ```
/// use realfft::num_complex::Complex;
/// use strainwave_analysis::fir::{inverse_correction, FirWindow};
/// // A path with a gain of 0.905 and a small lag, corrected below 300 Hz.
/// let h = |f: f64| Complex::from_polar(0.905, -f * 1e-4);
/// let band = |f: f64| if f < 300.0 { 1.0 } else if f > 400.0 { 0.0 } else { 0.5 + 0.5 * (std::f64::consts::PI * (f - 300.0) / 100.0).cos() };
/// let fir = inverse_correction(h, band, 1e-3, 2001, 20_000.0, FirWindow::Blackman).unwrap();
/// let total = fir.response(100.0) * h(100.0);
/// assert!((total - Complex::new(1.0, 0.0)).norm() < 1e-4);
/// ```
pub fn inverse_correction(
    response: impl Fn(f64) -> Complex<f64>,
    band: impl Fn(f64) -> f64,
    lambda: f64,
    n_taps: usize,
    sample_rate_hz: f64,
    window: FirWindow,
) -> Result<Fir, AnalysisError> {
    if !(lambda.is_finite() && lambda >= 0.0) {
        return Err(invalid("lambda", format!("must be ≥ 0 and finite, got {lambda}")));
    }
    Fir::frequency_sampling(n_taps, sample_rate_hz, window, |f| {
        let w = band(f);
        if w == 0.0 {
            Complex::new(0.0, 0.0)
        } else {
            regularized_inverse(response(f), lambda) * w
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_delay_application_matches_direct_convolution() {
        let taps = vec![0.1, -0.2, 0.7, 0.3, 0.05];
        let f = Fir::from_taps(taps.clone(), 2, 1.0).unwrap();
        let x: Vec<f64> = (0..50).map(|k| ((k * 31) % 13) as f64 - 6.0).collect();
        let y = f.apply_zero_delay(&x).unwrap();
        for (n, got) in y.iter().enumerate() {
            let mut want = 0.0;
            for (i, h) in taps.iter().enumerate() {
                let j = n as isize + 2 - i as isize;
                if j >= 0 && (j as usize) < x.len() {
                    want += h * x[j as usize];
                }
            }
            assert!((got - want).abs() < 1e-12, "{n}");
        }
    }

    #[test]
    fn designed_delay_is_removed() {
        // A gain of 1.5 with a phase of −30° (real at DC and Nyquist) is realized without delay
        // away from the band edges.
        let g = Complex::from_polar(1.5, -std::f64::consts::FRAC_PI_6);
        let fir = Fir::frequency_sampling(255, 1000.0, FirWindow::Kaiser { beta: 8.6 }, |f| {
            if f > 0.0 && f < 500.0 {
                g
            } else {
                Complex::new(g.re, 0.0)
            }
        })
        .unwrap();
        let r = fir.response(200.0);
        assert!((r.norm() - 1.5).abs() < 0.05 && (r.arg() + std::f64::consts::FRAC_PI_6).abs() < 0.05, "{r}");
    }

    #[test]
    fn rejects_bad_designs() {
        assert!(Fir::frequency_sampling(4, 1.0, FirWindow::Hann, |_| Complex::new(1.0, 0.0)).is_err());
        assert!(Fir::frequency_sampling(5, 1.0, FirWindow::Hann, |_| Complex::new(f64::NAN, 0.0)).is_err());
        assert!(Fir::from_taps(vec![], 0, 1.0).is_err());
        assert!(Fir::from_taps(vec![1.0], 1, 1.0).is_err());
        assert!(SampledResponse::new(vec![1.0, 1.0], vec![Complex::new(1.0, 0.0); 2]).is_err());
        assert!(SampledResponse::new(vec![1.0], vec![Complex::new(0.0, 0.0)]).is_err());
    }
}
