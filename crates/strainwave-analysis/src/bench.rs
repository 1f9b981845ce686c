//! Offline hybrid torque on the motor test bench (docs/physics.md §6, Stoß et al. (2022)): the models as
//! complex responses, the three ways of combining the torsion-shaft torque `T_TS` and the
//! accelerometer torque `T_acc`, and the check of a fused torque against a reference.
//!
//! - [`complementary`]: the online HOKA fusion of [`strainwave_core::fusion`] run over a
//!   record (`T = LP(T_TS) + HP(T_acc)`, filter phase included).
//! - [`online_corrected`]: the online model-corrected fusion of
//!   [`strainwave_core::fusion::OnlineCorrectedFusion`] run over a record (each path times
//!   the inverse of its bench model inside a fourth-order complementary pair).
//! - [`spectral_combination`]: the paper's post-processing: one FFT of each whole record,
//!   torsion bins below the crossover, accelerometer bins from it up, one inverse FFT.
//! - [`CorrectedFusion`]: beyond the paper (its future work). Each path is corrected by the
//!   regularized inverse of its frequency response (modelled, or measured as H1 against a
//!   model torque) inside its band, with zero-phase band weights that sum to one:
//!
//!   ```text
//!   W_LP(f) = 1 (f ≤ f_lo),  ½ (1 + cos(π (f − f_lo)/(f_hi − f_lo))),  0 (f ≥ f_hi);   W_HP = 1 − W_LP
//!   T = FIR_TS * (T_TS − mean T_TS) + FIR_acc * (T_acc − mean T_acc) + mean T_TS
//!   FIR_TS ≈ W_LP / H_TS,   FIR_acc ≈ W_HP / H_acc      (linear phase, delay removed offline)
//!   ```
//!
//!   so that the fused response `FIR_TS H_TS + FIR_acc H_acc ≈ W_LP + W_HP = 1`, flat in
//!   magnitude and phase across the crossover. The record's mean passes from the torsion
//!   shaft unscaled: in steady state the brake carries the mean torque, so the shaft sees
//!   all of it, whereas `H_TS(0) = J_B/(J_B+J_R)` holds for fluctuations.

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use strainwave_core::fusion::{ComplementaryFusion, OnlineCorrectedFusion};
use strainwave_core::iir::Complex as CoreComplex;

use crate::error::AnalysisError;
use crate::fir::{inverse_correction, Fir, FirWindow, SampledResponse};
use crate::frf::{h1, Frf};
use crate::psd::{check_finite, check_rate, invalid, SpectralConfig};

/// A core complex number as a `num_complex` one.
pub fn to_complex(c: CoreComplex<f64>) -> Complex<f64> {
    Complex::new(c.re, c.im)
}

fn same_length(torsion: &[f64], accel: &[f64]) -> Result<(), AnalysisError> {
    check_finite(torsion, "torsion")?;
    check_finite(accel, "accel")?;
    if torsion.len() != accel.len() {
        return Err(invalid("accel", format!("has {} samples, torsion {}", accel.len(), torsion.len())));
    }
    if torsion.is_empty() {
        return Err(AnalysisError::TooShort { what: "torsion", needed: 1, got: 0 });
    }
    Ok(())
}

/// The online complementary fusion over a record, started settled on the first samples.
///
/// ```
/// use strainwave_analysis::bench::complementary;
/// use strainwave_core::fusion::{ComplementaryFusion, OnlineCorrectedFusion};
/// let f = ComplementaryFusion::kit(20_000.0).unwrap();
/// let y = complementary(&[0.1; 100], &[0.0; 100], &f).unwrap();
/// assert!(y.iter().all(|v| (v - 0.1).abs() < 1e-9));
/// ```
pub fn complementary(
    torsion: &[f64],
    accel: &[f64],
    fusion: &ComplementaryFusion<f64>,
) -> Result<Vec<f64>, AnalysisError> {
    same_length(torsion, accel)?;
    let mut st = fusion.settled_state(torsion[0], accel[0]);
    Ok(torsion.iter().zip(accel).map(|(t, a)| fusion.step(&mut st, *t, *a)).collect())
}

/// The online model-corrected fusion over a record, started settled on the first samples.
///
/// ```
/// use strainwave_analysis::bench::online_corrected;
/// use strainwave_core::fusion::{AccelerometerModel, OnlineCorrectedFusion, OnlineCorrectionConfig, TorsionShaftModel};
/// let f = OnlineCorrectedFusion::new(&TorsionShaftModel::kit(), &AccelerometerModel::kit(),
///     &OnlineCorrectionConfig::kit(), 20_000.0).unwrap();
/// let y = online_corrected(&[0.1; 100], &[0.0; 100], &f).unwrap();
/// assert!(y.iter().all(|v| (v - 0.1).abs() < 1e-9));
/// ```
pub fn online_corrected(
    torsion: &[f64],
    accel: &[f64],
    fusion: &OnlineCorrectedFusion<f64>,
) -> Result<Vec<f64>, AnalysisError> {
    same_length(torsion, accel)?;
    let mut st = fusion.settled_state(torsion[0], accel[0]);
    Ok(torsion.iter().zip(accel).map(|(t, a)| fusion.step(&mut st, *t, *a)).collect())
}

/// The paper's spectral combination: bins with `f < crossover_hz` from the torsion record,
/// the others from the accelerometer record (whole-record FFT, no window, no filter phase).
///
/// ```
/// use strainwave_analysis::bench::spectral_combination;
/// let fs = 1000.0;
/// let lo: Vec<f64> = (0..1000).map(|k| (std::f64::consts::TAU * 10.0 * k as f64 / fs).sin()).collect();
/// let hi: Vec<f64> = (0..1000).map(|k| (std::f64::consts::TAU * 300.0 * k as f64 / fs).sin()).collect();
/// let both: Vec<f64> = lo.iter().zip(&hi).map(|(a, b)| a + b).collect();
/// // Torsion sees both lines, accelerometers too: the result keeps each line once.
/// let y = spectral_combination(&both, &both, fs, 250.0).unwrap();
/// assert!(y.iter().zip(&both).all(|(a, b)| (a - b).abs() < 1e-9));
/// ```
pub fn spectral_combination(
    torsion: &[f64],
    accel: &[f64],
    sample_rate_hz: f64,
    crossover_hz: f64,
) -> Result<Vec<f64>, AnalysisError> {
    check_rate(sample_rate_hz)?;
    same_length(torsion, accel)?;
    if !(crossover_hz.is_finite() && crossover_hz > 0.0 && crossover_hz < sample_rate_hz / 2.0) {
        return Err(invalid("crossover_hz", format!("must be in (0, fs/2), got {crossover_hz}")));
    }
    let n = torsion.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(n);
    let inv = planner.plan_fft_inverse(n);
    let (mut a, mut b) = (torsion.to_vec(), accel.to_vec());
    let (mut fa, mut fb) = (fwd.make_output_vec(), fwd.make_output_vec());
    fwd.process(&mut a, &mut fa).map_err(|e| invalid("fft", e.to_string()))?;
    fwd.process(&mut b, &mut fb).map_err(|e| invalid("fft", e.to_string()))?;
    let df = sample_rate_hz / n as f64;
    let mut mix: Vec<Complex<f64>> = fa
        .iter()
        .zip(&fb)
        .enumerate()
        .map(|(k, (x, y))| if (k as f64) * df < crossover_hz { *x } else { *y })
        .collect();
    mix[0].im = 0.0;
    if n & 1 == 0 {
        let last = mix.len() - 1;
        mix[last].im = 0.0;
    }
    let mut out = inv.make_output_vec();
    inv.process(&mut mix, &mut out).map_err(|e| invalid("fft", e.to_string()))?;
    out.iter_mut().for_each(|v| *v /= n as f64);
    Ok(out)
}

/// The raised-cosine crossover band of [`CorrectedFusion`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossoverBand {
    /// Below: torsion only, Hz.
    pub lo_hz: f64,
    /// Above: accelerometers only, Hz.
    pub hi_hz: f64,
}

impl CrossoverBand {
    /// A band `0 ≤ lo_hz < hi_hz`.
    ///
    /// ```
    /// use strainwave_analysis::bench::CrossoverBand;
    /// let b = CrossoverBand::new(200.0, 300.0).unwrap();
    /// assert_eq!(b.lowpass_weight(250.0), 0.5);
    /// assert_eq!(b.lowpass_weight(100.0) + b.highpass_weight(100.0), 1.0);
    /// ```
    pub fn new(lo_hz: f64, hi_hz: f64) -> Result<Self, AnalysisError> {
        if !(lo_hz.is_finite() && hi_hz.is_finite() && lo_hz >= 0.0 && hi_hz > lo_hz) {
            return Err(invalid("crossover band", format!("needs 0 ≤ lo < hi, got {lo_hz} … {hi_hz}")));
        }
        Ok(Self { lo_hz, hi_hz })
    }

    /// The paper's usable overlap, 200–300 Hz (centre 250 Hz).
    ///
    /// ```
    /// let b = strainwave_analysis::bench::CrossoverBand::kit();
    /// assert_eq!((b.lo_hz, b.hi_hz), (200.0, 300.0));
    /// ```
    pub fn kit() -> Self {
        Self { lo_hz: 200.0, hi_hz: 300.0 }
    }

    /// `W_LP(f)`.
    pub fn lowpass_weight(&self, freq_hz: f64) -> f64 {
        if freq_hz <= self.lo_hz {
            1.0
        } else if freq_hz >= self.hi_hz {
            0.0
        } else {
            0.5 * (1.0 + (std::f64::consts::PI * (freq_hz - self.lo_hz) / (self.hi_hz - self.lo_hz)).cos())
        }
    }

    /// `W_HP(f) = 1 − W_LP(f)`.
    pub fn highpass_weight(&self, freq_hz: f64) -> f64 {
        1.0 - self.lowpass_weight(freq_hz)
    }
}

/// Design parameters of [`CorrectedFusion`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrectionConfig {
    /// Taps of each FIR (odd). The frequency resolution is about `6 fs / n_taps`
    /// (Blackman): it must resolve the crossover band and the paths' features.
    pub n_taps: usize,
    /// Window of the design.
    pub window: FirWindow,
    /// Regularization `λ` of the inverse (response units).
    pub lambda: f64,
    /// Crossover band.
    pub band: CrossoverBand,
}

impl CorrectionConfig {
    /// Blackman, `λ = 10⁻³`, the 200–300 Hz band.
    ///
    /// ```
    /// let c = strainwave_analysis::bench::CorrectionConfig::new(8191);
    /// assert_eq!(c.band.hi_hz, 300.0);
    /// ```
    pub fn new(n_taps: usize) -> Self {
        Self { n_taps, window: FirWindow::Blackman, lambda: 1e-3, band: CrossoverBand::kit() }
    }
}

/// Fusion with each path corrected by the inverse of its response (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct CorrectedFusion {
    /// Correction of the torsion path, `≈ W_LP / H_TS`.
    pub torsion_fir: Fir,
    /// Correction of the accelerometer path, `≈ W_HP / H_acc`.
    pub accel_fir: Fir,
    /// The band.
    pub band: CrossoverBand,
}

impl CorrectedFusion {
    /// Designs both FIRs from the path responses `H_TS(f) = T_TS/T_e` and
    /// `H_acc(f) = T_acc/T_e` (modelled, or [`path_response`] from a measurement).
    ///
    /// ```
    /// use strainwave_analysis::bench::{to_complex, CorrectedFusion, CorrectionConfig};
    /// use strainwave_core::fusion::{AccelerometerModel, TorsionShaftModel};
    /// let (ts, acc) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
    /// let h_ts = |f: f64| to_complex(ts.response(f));
    /// let h_acc = |f: f64| to_complex(acc.torque_response(f));
    /// let fusion = CorrectedFusion::design(h_ts, h_acc, 20_000.0, &CorrectionConfig::new(4095)).unwrap();
    /// for f in [10.0, 250.0, 829.3, 3000.0] {
    ///     let r = fusion.response(f, h_ts(f), h_acc(f));
    ///     assert!((r.norm() - 1.0).abs() < 0.01 && r.arg().abs() < 0.01, "{f}: {r}");
    /// }
    /// ```
    pub fn design(
        torsion_path: impl Fn(f64) -> Complex<f64>,
        accel_path: impl Fn(f64) -> Complex<f64>,
        sample_rate_hz: f64,
        cfg: &CorrectionConfig,
    ) -> Result<Self, AnalysisError> {
        let band = cfg.band;
        if band.hi_hz >= sample_rate_hz / 2.0 {
            return Err(invalid("crossover band", format!("must end below fs/2, ends at {}", band.hi_hz)));
        }
        let torsion_fir = inverse_correction(
            torsion_path,
            |f| band.lowpass_weight(f),
            cfg.lambda,
            cfg.n_taps,
            sample_rate_hz,
            cfg.window,
        )?;
        let accel_fir = inverse_correction(
            accel_path,
            |f| band.highpass_weight(f),
            cfg.lambda,
            cfg.n_taps,
            sample_rate_hz,
            cfg.window,
        )?;
        Ok(Self { torsion_fir, accel_fir, band })
    }

    /// The fused torque of a record (same length, finite).
    pub fn apply(&self, torsion: &[f64], accel: &[f64]) -> Result<Vec<f64>, AnalysisError> {
        same_length(torsion, accel)?;
        let mean_t = torsion.iter().sum::<f64>() / torsion.len() as f64;
        let mean_a = accel.iter().sum::<f64>() / accel.len() as f64;
        let t: Vec<f64> = torsion.iter().map(|v| v - mean_t).collect();
        let a: Vec<f64> = accel.iter().map(|v| v - mean_a).collect();
        let yt = self.torsion_fir.apply_zero_delay(&t)?;
        let ya = self.accel_fir.apply_zero_delay(&a)?;
        Ok(yt.iter().zip(&ya).map(|(x, y)| x + y + mean_t).collect())
    }

    /// The predicted fused response at `freq_hz` for path responses `h_ts`, `h_acc` there.
    pub fn response(&self, freq_hz: f64, h_ts: Complex<f64>, h_acc: Complex<f64>) -> Complex<f64> {
        self.torsion_fir.response(freq_hz) * h_ts + self.accel_fir.response(freq_hz) * h_acc
    }
}

/// A path response from an H1 estimate: the bins in `lo_hz ≤ f ≤ hi_hz` with coherence
/// ≥ `min_coherence` (and a finite, non-zero H1), interpolated between them.
pub fn path_response(frf: &Frf, lo_hz: f64, hi_hz: f64, min_coherence: f64) -> Result<SampledResponse, AnalysisError> {
    let bins: Vec<usize> = frf
        .bins_in(lo_hz, hi_hz, min_coherence)
        .into_iter()
        .filter(|&k| frf.h1[k].norm().is_finite() && frf.h1[k].norm() > 0.0)
        .collect();
    if bins.len() < 2 {
        return Err(AnalysisError::TooShort { what: "coherent bins of the H1 estimate", needed: 2, got: bins.len() });
    }
    SampledResponse::new(bins.iter().map(|&k| frf.freqs_hz[k]).collect(), bins.iter().map(|&k| frf.h1[k]).collect())
}

/// Worst deviation of a measured response from 1 (0 dB, 0°) over a band, after removing
/// a constant delay `τ`: the phase is that of `H(f) e^{j 2π f τ}`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResponseError {
    /// Largest `|20 log10 |H||`, dB.
    pub max_gain_db: f64,
    /// Frequency of it, Hz.
    pub worst_gain_hz: f64,
    /// Largest `|arg H e^{j2πfτ}|`, degrees.
    pub max_phase_deg: f64,
    /// Frequency of it, Hz.
    pub worst_phase_hz: f64,
    /// Bins checked.
    pub bins: usize,
    /// The delay `τ` removed, s (0 for [`ResponseError::of`]).
    pub delay_s: f64,
}

/// Steps of the coarse delay grid of [`ResponseError::with_best_delay`].
const DELAY_GRID: usize = 400;
/// Coarse grid points refined, and steps of each refinement.
const DELAY_REFINE: (usize, usize) = (3, 80);

impl ResponseError {
    /// Over the bins of `frf` in `lo_hz ≤ f ≤ hi_hz` with coherence ≥ `min_coherence`, no
    /// delay removed; `TooShort` when none qualifies.
    pub fn of(frf: &Frf, lo_hz: f64, hi_hz: f64, min_coherence: f64) -> Result<Self, AnalysisError> {
        Self::with_delay(frf, lo_hz, hi_hz, min_coherence, 0.0)
    }

    /// As [`ResponseError::of`] with the delay `delay_s` removed.
    pub fn with_delay(
        frf: &Frf,
        lo_hz: f64,
        hi_hz: f64,
        min_coherence: f64,
        delay_s: f64,
    ) -> Result<Self, AnalysisError> {
        let bins = frf.bins_in(lo_hz, hi_hz, min_coherence);
        if bins.is_empty() {
            return Err(AnalysisError::TooShort { what: "coherent bins in the band", needed: 1, got: 0 });
        }
        let mut e = ResponseError {
            max_gain_db: 0.0,
            worst_gain_hz: f64::NAN,
            max_phase_deg: 0.0,
            worst_phase_hz: f64::NAN,
            bins: bins.len(),
            delay_s,
        };
        for k in bins {
            let f = frf.freqs_hz[k];
            let g = frf.magnitude_db(k).abs();
            let p = delayed_phase_deg(frf.h1[k], f, delay_s).abs();
            // A NaN (a bin with no input power) counts as the worst.
            if g.is_nan() || g > e.max_gain_db {
                e.max_gain_db = g;
                e.worst_gain_hz = f;
            }
            if p.is_nan() || p > e.max_phase_deg {
                e.max_phase_deg = p;
                e.worst_phase_hz = f;
            }
        }
        Ok(e)
    }

    /// As [`ResponseError::of`] after removing the constant delay `0 ≤ τ ≤ max_delay_s`
    /// that minimizes the worst phase error over the band (a grid of 400 delays, the
    /// best three refined 80-fold).
    ///
    /// ```
    /// use realfft::num_complex::Complex;
    /// use strainwave_analysis::bench::ResponseError;
    /// use strainwave_analysis::frf::Frf;
    /// // A pure delay of 0.3 ms, gain 1: nothing left once it is removed.
    /// let freqs_hz: Vec<f64> = (0..400).map(|k| k as f64 * 10.0).collect();
    /// let h1: Vec<Complex<f64>> = freqs_hz.iter().map(|f| Complex::from_polar(1.0, -std::f64::consts::TAU * f * 3e-4)).collect();
    /// let n = freqs_hz.len();
    /// let frf = Frf { freqs_hz, h1, coherence: vec![1.0; n], pxx: vec![1.0; n], pyy: vec![1.0; n], pxy: vec![Complex::new(0.0, 0.0); n], segments: 1 };
    /// let e = ResponseError::with_best_delay(&frf, 1.0, 3000.0, 0.5, 1e-3).unwrap();
    /// assert!((e.delay_s - 3e-4).abs() < 1e-8 && e.max_phase_deg < 0.01);
    /// assert!(ResponseError::of(&frf, 1.0, 3000.0, 0.5).unwrap().max_phase_deg > 170.0);
    /// ```
    pub fn with_best_delay(
        frf: &Frf,
        lo_hz: f64,
        hi_hz: f64,
        min_coherence: f64,
        max_delay_s: f64,
    ) -> Result<Self, AnalysisError> {
        if !(max_delay_s.is_finite() && max_delay_s >= 0.0) {
            return Err(invalid("max_delay_s", format!("must be finite and ≥ 0, got {max_delay_s}")));
        }
        let bins: Vec<(f64, Complex<f64>)> =
            frf.bins_in(lo_hz, hi_hz, min_coherence).into_iter().map(|k| (frf.freqs_hz[k], frf.h1[k])).collect();
        if bins.is_empty() {
            return Err(AnalysisError::TooShort { what: "coherent bins in the band", needed: 1, got: 0 });
        }
        let worst = |tau: f64| {
            bins.iter().map(|(f, h)| delayed_phase_deg(*h, *f, tau).abs()).fold(0.0, |a: f64, p| {
                if p.is_nan() {
                    f64::INFINITY
                } else {
                    a.max(p)
                }
            })
        };
        let step = max_delay_s / DELAY_GRID as f64;
        let mut coarse: Vec<(f64, f64)> = (0..=DELAY_GRID).map(|i| (worst(i as f64 * step), i as f64 * step)).collect();
        coarse.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best = coarse[0];
        for &(_, centre) in coarse.iter().take(DELAY_REFINE.0) {
            let n = DELAY_REFINE.1;
            for j in 0..=n {
                let tau = (centre - step + 2.0 * step * j as f64 / n as f64).clamp(0.0, max_delay_s);
                let w = worst(tau);
                if w < best.0 {
                    best = (w, tau);
                }
            }
        }
        Self::with_delay(frf, lo_hz, hi_hz, min_coherence, best.1)
    }
}

/// `arg(h e^{j 2π f τ})` in degrees, `(−180, 180]`.
fn delayed_phase_deg(h: Complex<f64>, freq_hz: f64, delay_s: f64) -> f64 {
    (h * Complex::from_polar(1.0, std::f64::consts::TAU * freq_hz * delay_s)).arg().to_degrees()
}

/// H1 from `reference` (the true torque) to `measured` and its [`ResponseError`] over
/// `lo_hz … hi_hz` (bins with coherence ≥ `min_coherence`).
pub fn response_error(
    reference: &[f64],
    measured: &[f64],
    sample_rate_hz: f64,
    cfg: &SpectralConfig,
    lo_hz: f64,
    hi_hz: f64,
    min_coherence: f64,
) -> Result<(Frf, ResponseError), AnalysisError> {
    let frf = h1(reference, measured, sample_rate_hz, cfg)?;
    let e = ResponseError::of(&frf, lo_hz, hi_hz, min_coherence)?;
    Ok((frf, e))
}

mod accuracy;
pub use accuracy::{accuracy_report, AccuracyConfig, AccuracyReport, BenchRecord, MethodAccuracy, METHODS};

#[cfg(test)]
mod tests;
