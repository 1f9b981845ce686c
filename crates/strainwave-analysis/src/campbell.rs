//! Campbell diagrams and order slices from a speed channel (docs/physics.md §6, Stoß et al. (2022) Figs. 8–9).
//!
//! - [`campbell`]: an amplitude-scaled STFT of the signal ([`crate::stft::stft`]); each
//!   frame gets the mean of the speed channel over its samples; frames are then averaged
//!   into a regular grid of speed bins (frequency × speed, amplitude in signal units).
//!   Order `k` (cycles per revolution) lies on the line `f = k n / 60`, `n` in rpm.
//! - [`order_slice`]: amplitude and phase of one order against speed by demodulation in
//!   the angle domain. The angle `θ` (revolutions) is the integral of the speed channel
//!   (trapezoid); blocks of `B` revolutions (half overlapping) give
//!
//!   ```text
//!   X = Σ_n w(θ_n) v_n x_n e^{−j 2π k θ_n} / Σ_n w(θ_n) v_n   (v_n dt = dθ; w: Hann over the block)
//!   A = 2 |X|,   φ = arg X      (x = A cos(2π k θ + φ) reads (A, φ))
//!   ```
//!
//!   summed over the time samples of the block (an integral over the angle), so nothing
//!   is resampled and no content aliases. Orders `k'` with `|k' − k| B ≥ 2` fall on the Hann window's zeros.
//!
//! Speed is in rpm, mechanical, forward. Slightly negative samples (noise at standstill)
//! are tolerated: frames with a mean speed ≤ 0 go to the lowest speed bin, and the angle
//! of the order slices is made non-decreasing. A reverse run is an error (negate it):
//! [`campbell`] needs a frame with a positive mean speed, [`order_slice`] an angle of at
//! least one block. For electrical orders of a machine with `p` pole pairs use `k = p k_el`.

use realfft::num_complex::Complex;

use crate::error::AnalysisError;
use crate::psd::{check_finite, check_rate, invalid, SpectralConfig};
use crate::stft::stft;

/// Frequency of order `order` at `speed_rpm`, Hz: `k n / 60`.
///
/// ```
/// assert_eq!(strainwave_analysis::campbell::order_hz(36.0, 3200.0), 1920.0);
/// ```
pub fn order_hz(order: f64, speed_rpm: f64) -> f64 {
    order * speed_rpm / 60.0
}

fn check_speed(signal: &[f64], speed_rpm: &[f64]) -> Result<(), AnalysisError> {
    check_finite(signal, "signal")?;
    check_finite(speed_rpm, "speed_rpm")?;
    if speed_rpm.len() != signal.len() {
        return Err(invalid("speed_rpm", format!("has {} samples, the signal {}", speed_rpm.len(), signal.len())));
    }
    Ok(())
}

/// Most speed bins of a Campbell grid: a wider speed range (a glitched speed sample, a
/// tiny bin width) is an error rather than an allocation sized by the glitch.
pub const MAX_SPEED_BINS: usize = 4096;
/// Most cells (speed bins × frequency bins) of a Campbell grid (128 MiB of `f64`).
pub const MAX_GRID_CELLS: usize = 1 << 24;

/// Segmentation and speed grid of a Campbell diagram.
#[derive(Debug, Clone, PartialEq)]
pub struct CampbellConfig {
    /// STFT segmentation (Hann by default; its scaling is ignored).
    pub spectral: SpectralConfig,
    /// Width of a speed bin of the grid, rpm.
    pub speed_bin_rpm: f64,
}

impl CampbellConfig {
    /// `nperseg`-sample Hann frames with 75 % overlap, speed bins of `speed_bin_rpm`.
    ///
    /// ```
    /// let c = strainwave_analysis::campbell::CampbellConfig::new(4096, 50.0);
    /// assert_eq!(c.spectral.noverlap, Some(3072));
    /// ```
    pub fn new(nperseg: usize, speed_bin_rpm: f64) -> Self {
        Self { spectral: SpectralConfig::new(nperseg).with_noverlap(nperseg * 3 / 4), speed_bin_rpm }
    }
}

/// A Campbell diagram.
#[derive(Debug, Clone, PartialEq)]
pub struct Campbell {
    /// Bin frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// Frame centres, s.
    pub frame_time_s: Vec<f64>,
    /// Mean speed over each frame, rpm.
    pub frame_speed_rpm: Vec<f64>,
    /// `frame_amplitude[frame][bin]`: peak amplitude, signal units.
    pub frame_amplitude: Vec<Vec<f64>>,
    /// Centres of the speed bins, rpm (`(i + ½) · speed_bin_rpm`).
    pub speed_axis_rpm: Vec<f64>,
    /// `grid[speed bin][bin]`: mean amplitude of the frames in the speed bin; NaN where no
    /// frame fell.
    pub grid: Vec<Vec<f64>>,
}

/// A point of an order's ridge: the strongest bin near the order line in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RidgePoint {
    /// Frame index.
    pub frame: usize,
    /// Frame speed, rpm.
    pub speed_rpm: f64,
    /// Order line `k n / 60`, Hz.
    pub expected_hz: f64,
    /// Frequency of the strongest bin in the search range, Hz.
    pub peak_hz: f64,
    /// Its amplitude, signal units.
    pub amplitude: f64,
}

/// Campbell diagram of `signal` against `speed_rpm` (same length, ≥ 0, finite).
///
/// ```
/// use strainwave_analysis::campbell::{campbell, CampbellConfig};
/// let fs = 2000.0;
/// let n = 20_000;
/// // Constant 600 rpm; order 5 at 50 Hz with amplitude 0.3.
/// let speed = vec![600.0; n];
/// let x: Vec<f64> = (0..n).map(|k| 0.3 * (std::f64::consts::TAU * 50.0 * k as f64 / fs).cos()).collect();
/// let c = campbell(&x, &speed, fs, &CampbellConfig::new(400, 100.0)).unwrap();
/// let r = c.order_ridge(5.0, 2);
/// assert!(r.iter().all(|p| p.peak_hz == 50.0 && (p.amplitude - 0.3).abs() < 1e-9));
/// assert_eq!(c.speed_axis_rpm[6], 650.0);
/// ```
pub fn campbell(
    signal: &[f64],
    speed_rpm: &[f64],
    sample_rate_hz: f64,
    cfg: &CampbellConfig,
) -> Result<Campbell, AnalysisError> {
    check_rate(sample_rate_hz)?;
    check_speed(signal, speed_rpm)?;
    if !(cfg.speed_bin_rpm.is_finite() && cfg.speed_bin_rpm > 0.0) {
        return Err(invalid("speed_bin_rpm", format!("must be positive, got {}", cfg.speed_bin_rpm)));
    }
    let s = stft(signal, sample_rate_hz, &cfg.spectral)?;
    let frame_speed_rpm: Vec<f64> =
        s.starts.iter().map(|&a| speed_rpm[a..a + s.nperseg].iter().sum::<f64>() / s.nperseg as f64).collect();
    let frame_amplitude: Vec<Vec<f64>> = s.frames.iter().map(|f| f.iter().map(|c| c.norm()).collect()).collect();
    let top = frame_speed_rpm.iter().cloned().fold(0.0, f64::max);
    if top <= 0.0 {
        return Err(invalid("speed_rpm", "no frame has a positive mean speed (negate a reverse run)".to_string()));
    }
    let nf = s.freqs_hz.len();
    let bins = (top / cfg.speed_bin_rpm).floor() + 1.0;
    let limit = MAX_SPEED_BINS.min(MAX_GRID_CELLS / nf.max(1));
    if bins.is_nan() || bins > limit as f64 {
        return Err(invalid(
            "speed_bin_rpm",
            format!(
                "speeds up to {top} rpm in bins of {} rpm need {bins} bins, more than the {limit} allowed (a glitch in the speed?)",
                cfg.speed_bin_rpm
            ),
        ));
    }
    let nbins = bins as usize;
    let mut sum = vec![vec![0.0; nf]; nbins];
    let mut count = vec![0usize; nbins];
    for (v, amp) in frame_speed_rpm.iter().zip(&frame_amplitude) {
        let i = ((v.max(0.0) / cfg.speed_bin_rpm).floor() as usize).min(nbins - 1);
        count[i] += 1;
        sum[i].iter_mut().zip(amp).for_each(|(a, b)| *a += b);
    }
    let grid = sum
        .into_iter()
        .zip(&count)
        .map(|(row, &c)| if c == 0 { vec![f64::NAN; nf] } else { row.into_iter().map(|a| a / c as f64).collect() })
        .collect();
    Ok(Campbell {
        freqs_hz: s.freqs_hz,
        frame_time_s: s.times_s,
        frame_speed_rpm,
        frame_amplitude,
        speed_axis_rpm: (0..nbins).map(|i| (i as f64 + 0.5) * cfg.speed_bin_rpm).collect(),
        grid,
    })
}

impl Campbell {
    /// Frequency resolution, Hz.
    pub fn resolution_hz(&self) -> f64 {
        self.freqs_hz.get(1).copied().unwrap_or(f64::NAN)
    }

    /// The order line over the speed axis: `(speed_rpm, k n / 60)`.
    pub fn order_line(&self, order: f64) -> Vec<(f64, f64)> {
        self.speed_axis_rpm.iter().map(|&n| (n, order_hz(order, n))).collect()
    }

    /// Per frame whose order line lies inside the spectrum, the strongest bin within
    /// `halfwidth_bins` of the line.
    pub fn order_ridge(&self, order: f64, halfwidth_bins: usize) -> Vec<RidgePoint> {
        let df = self.resolution_hz();
        let nf = self.freqs_hz.len();
        let mut out = Vec::new();
        for (frame, (&n, amp)) in self.frame_speed_rpm.iter().zip(&self.frame_amplitude).enumerate() {
            let f = order_hz(order, n);
            let k0 = (f / df).round();
            if !(k0 >= 0.0 && (k0 as usize) < nf) {
                continue;
            }
            let k0 = k0 as usize;
            let lo = k0.saturating_sub(halfwidth_bins);
            let hi = (k0 + halfwidth_bins).min(nf - 1);
            let k = (lo..=hi).max_by(|&a, &b| amp[a].total_cmp(&amp[b])).unwrap_or(k0);
            out.push(RidgePoint { frame, speed_rpm: n, expected_hz: f, peak_hz: self.freqs_hz[k], amplitude: amp[k] });
        }
        out
    }
}

/// Angle (revolutions) from a speed channel in rpm by the trapezoid rule, starting at
/// `initial_rev`.
///
/// ```
/// let a = strainwave_analysis::campbell::integrate_angle_rev(&[60.0, 60.0, 60.0], 10.0, 0.0);
/// assert!((a[2] - 0.2).abs() < 1e-15);
/// ```
pub fn integrate_angle_rev(speed_rpm: &[f64], sample_rate_hz: f64, initial_rev: f64) -> Vec<f64> {
    let h = 0.5 / 60.0 / sample_rate_hz;
    let mut out = Vec::with_capacity(speed_rpm.len());
    let mut acc = initial_rev;
    for (i, v) in speed_rpm.iter().enumerate() {
        if i > 0 {
            acc += h * (speed_rpm[i - 1] + v);
        }
        out.push(acc);
    }
    out
}

/// Block length and angle reference of an order slice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrderSliceConfig {
    /// Revolutions per block `B` (≥ 1); blocks overlap by half.
    pub revs_per_block: f64,
    /// Angle at the first sample, revolutions (phase reference).
    pub initial_angle_rev: f64,
}

impl Default for OrderSliceConfig {
    fn default() -> Self {
        Self { revs_per_block: 8.0, initial_angle_rev: 0.0 }
    }
}

/// Amplitude and phase of one order against speed.
#[derive(Debug, Clone, PartialEq)]
pub struct OrderSlice {
    /// Order, cycles per revolution.
    pub order: f64,
    /// Block centres (by angle), s.
    pub time_s: Vec<f64>,
    /// Mean speed of each block, rpm.
    pub speed_rpm: Vec<f64>,
    /// Amplitude, signal units.
    pub amplitude: Vec<f64>,
    /// Phase of `cos(2π k θ + φ)`, rad.
    pub phase_rad: Vec<f64>,
}

/// Order slice of `signal` for order `order` (see the module doc). Blocks in which the
/// order reaches the Nyquist frequency are left out (what they hold is an alias); an order
/// above it at every speed is an error.
///
/// ```
/// use strainwave_analysis::campbell::{order_slice, OrderSliceConfig};
/// let fs = 5000.0;
/// // 0 → 1200 rpm over 10 s; order 3 with amplitude 0.5 and phase 0.4 rad.
/// let speed: Vec<f64> = (0..50_000).map(|k| 1200.0 * k as f64 / 50_000.0).collect();
/// let theta = strainwave_analysis::campbell::integrate_angle_rev(&speed, fs, 0.0);
/// let x: Vec<f64> = theta.iter().map(|t| 0.5 * (std::f64::consts::TAU * 3.0 * t + 0.4).cos()).collect();
/// let s = order_slice(&x, &speed, fs, 3.0, &OrderSliceConfig::default()).unwrap();
/// assert!(s.amplitude.iter().all(|a| (a - 0.5).abs() < 1e-3));
/// assert!(s.phase_rad.iter().all(|p| (p - 0.4).abs() < 1e-3));
/// ```
pub fn order_slice(
    signal: &[f64],
    speed_rpm: &[f64],
    sample_rate_hz: f64,
    order: f64,
    cfg: &OrderSliceConfig,
) -> Result<OrderSlice, AnalysisError> {
    check_rate(sample_rate_hz)?;
    check_speed(signal, speed_rpm)?;
    if !(order.is_finite() && order > 0.0) {
        return Err(invalid("order", format!("must be positive, got {order}")));
    }
    // Above the Nyquist frequency at the slowest turning sample, the order aliases in
    // every block: nothing of it can be measured.
    let slowest_rpm = speed_rpm.iter().copied().filter(|v| *v > 0.0).fold(f64::INFINITY, f64::min);
    let nyquist_hz = 0.5 * sample_rate_hz;
    if slowest_rpm.is_finite() && order * slowest_rpm / 60.0 >= nyquist_hz {
        return Err(invalid(
            "order",
            format!(
                "above the Nyquist frequency ({nyquist_hz} Hz) at every speed of the recording \
                 (slowest {slowest_rpm:.3} rpm)"
            ),
        ));
    }
    let b = cfg.revs_per_block;
    if !(b.is_finite() && b >= 1.0) {
        return Err(invalid("revs_per_block", format!("must be at least 1, got {b}")));
    }
    if !cfg.initial_angle_rev.is_finite() {
        return Err(invalid("initial_angle_rev", "must be finite"));
    }
    let mut theta = integrate_angle_rev(speed_rpm, sample_rate_hz, cfg.initial_angle_rev);
    // Noise at standstill: keep the angle non-decreasing so that blocks are well defined.
    for i in 1..theta.len() {
        theta[i] = theta[i].max(theta[i - 1]);
    }
    let (first, last) = (theta[0], theta[theta.len() - 1]);
    if last - first < b {
        return Err(invalid(
            "speed_rpm",
            format!("the recording covers {:.3} revolutions, one block needs {b:?}", last - first),
        ));
    }
    let blocks = ((last - first - b) / (0.5 * b)).floor();
    if blocks.is_nan() || blocks >= (1u64 << 52) as f64 {
        return Err(invalid(
            "speed_rpm",
            format!("the recording covers {:e} revolutions (a glitch in the speed?)", last - first),
        ));
    }
    // Each sample lies in at most two blocks, so at most 2n blocks hold samples; empty
    // ones (a speed glitch makes many) are jumped over, never counted or allocated.
    let cap = (2 * theta.len()).min(blocks as usize + 1);
    let mut out = OrderSlice {
        order,
        time_s: Vec::with_capacity(cap),
        speed_rpm: Vec::with_capacity(cap),
        amplitude: Vec::with_capacity(cap),
        phase_rad: Vec::with_capacity(cap),
    };
    let mut j = 0.0f64;
    while j <= blocks {
        let a = first + 0.5 * b * j;
        let i0 = theta.partition_point(|t| *t < a);
        let i1 = theta.partition_point(|t| *t < a + b);
        if i1 <= i0 {
            // The first block that reaches the next sample.
            let next = match theta.get(i0) {
                Some(t) => ((t - first - b) / (0.5 * b)).floor() + 1.0,
                None => break,
            };
            j = next.max(j + 1.0);
            continue;
        }
        j += 1.0;
        let (mut x, mut wsum, mut vsum, mut fastest) = (Complex::new(0.0, 0.0), 0.0, 0.0, 0.0f64);
        for i in i0..i1 {
            let u = (theta[i] - a) / b;
            // dθ = v dt: the weights make the sum an integral over the angle.
            let w = (0.5 - 0.5 * (std::f64::consts::TAU * u).cos()) * speed_rpm[i].max(0.0);
            x += Complex::from_polar(w * signal[i], -std::f64::consts::TAU * order * theta[i]);
            wsum += w;
            vsum += speed_rpm[i];
            fastest = fastest.max(speed_rpm[i]);
        }
        // A block in which the order reaches the Nyquist frequency holds an alias of it.
        if wsum <= 0.0 || order * fastest / 60.0 >= nyquist_hz {
            continue;
        }
        let x = x / wsum;
        let centre = a + 0.5 * b;
        let ic = theta.partition_point(|t| *t < centre).min(theta.len() - 1);
        out.time_s.push(ic as f64 / sample_rate_hz);
        out.speed_rpm.push(vsum / (i1 - i0) as f64);
        out.amplitude.push(2.0 * x.norm());
        out.phase_rad.push(x.arg());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_speed() {
        let x = vec![0.0; 1000];
        let cfg = CampbellConfig::new(128, 10.0);
        let v = vec![100.0; 1000];
        let reverse = vec![-100.0; 1000];
        assert!(matches!(campbell(&x, &reverse, 1000.0, &cfg), Err(AnalysisError::Invalid { what: "speed_rpm", .. })));
        assert!(matches!(
            order_slice(&x, &reverse, 1000.0, 1.0, &OrderSliceConfig::default()),
            Err(AnalysisError::Invalid { what: "speed_rpm", .. })
        ));
        assert!(campbell(&x, &v[..999], 1000.0, &cfg).is_err());
        assert!(campbell(&x[..100], &v[..100], 1000.0, &cfg).is_err());
        let zero = vec![0.0; 1000];
        assert!(matches!(
            order_slice(&x, &zero, 1000.0, 1.0, &OrderSliceConfig::default()),
            Err(AnalysisError::Invalid { what: "speed_rpm", .. })
        ));
        let mut bad = x.clone();
        bad[5] = f64::INFINITY;
        assert!(matches!(
            order_slice(&bad, &vec![600.0; 1000], 1000.0, 1.0, &OrderSliceConfig::default()),
            Err(AnalysisError::NonFinite { index: 5, .. })
        ));
    }

    #[test]
    fn an_order_above_nyquist_at_every_speed_is_refused_one_below_at_some_is_not() {
        // 600 → 1200 rpm at 1 kHz: Nyquist 500 Hz is order 50 at 600 rpm, 25 at 1200 rpm.
        let v: Vec<f64> = (0..20_000).map(|k| 600.0 + 600.0 * k as f64 / 20_000.0).collect();
        let x = vec![0.0; v.len()];
        let cfg = OrderSliceConfig::default();
        for order in [50.0, 1e300] {
            let e = order_slice(&x, &v, 1000.0, order, &cfg).unwrap_err();
            assert!(matches!(e, AnalysisError::Invalid { what: "order", .. }), "{e}");
            assert!(e.to_string().contains("Nyquist"), "{e}");
        }
        // Order 40 reaches Nyquist at 750 rpm: the blocks beyond are aliases, not shown.
        let s = order_slice(&x, &v, 1000.0, 40.0, &cfg).unwrap();
        assert!(!s.speed_rpm.is_empty());
        assert!(s.speed_rpm.iter().all(|v| *v < 750.0), "{:?}", s.speed_rpm.last());
    }
}
