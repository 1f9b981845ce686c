//! What `report` keeps of a recording while it streams through it once, in memory that
//! does not grow with its length: per-column sums, a min/max decimation of each plotted
//! signal, averaged amplitude spectra and the speeds held.

use strainwave_analysis::spectrum::amplitude_spectrum;

/// Count, non-finite count, mean, mean square and largest magnitude of a column, kept so
/// that no finite input overflows them: the mean as a running mean, the squares scaled by
/// the largest magnitude so far.
#[derive(Debug, Clone, Copy, Default)]
pub struct ColumnStats {
    /// Finite values.
    pub finite: u64,
    /// Non-finite values.
    pub non_finite: u64,
    mean: f64,
    /// `Σ (x / max_abs)²`.
    scaled_sum_sq: f64,
    /// Largest |x|.
    pub max_abs: f64,
}

impl ColumnStats {
    /// Adds one value.
    pub fn push(&mut self, v: f64) {
        if !v.is_finite() {
            self.non_finite += 1;
            return;
        }
        self.finite += 1;
        let n = self.finite as f64;
        self.mean += v / n - self.mean / n;
        let a = v.abs();
        if a > self.max_abs {
            let r = self.max_abs / a;
            self.scaled_sum_sq = self.scaled_sum_sq * r * r + 1.0;
            self.max_abs = a;
        } else if a > 0.0 {
            let r = a / self.max_abs;
            self.scaled_sum_sq += r * r;
        }
    }

    /// Mean of the finite values (0 for none).
    pub fn mean(&self) -> f64 {
        self.mean
    }

    /// RMS of the finite values (0 for none).
    pub fn rms(&self) -> f64 {
        if self.finite == 0 {
            0.0
        } else {
            self.max_abs * (self.scaled_sum_sq / self.finite as f64).sqrt()
        }
    }
}

/// Min/max decimation for a line plot: consecutive rows are grouped into at most
/// `2 · columns` bins, each drawn as its minimum and maximum (in time order), so the
/// envelope of every spike survives. When the bins fill, neighbours merge and each
/// bin takes twice as many rows: memory stays at `2 · columns` bins.
#[derive(Debug, Clone)]
pub struct MinMaxDecimator {
    capacity: usize,
    rows_per_bin: u64,
    bins: Vec<Bin>,
    current: Option<Bin>,
    in_current: u64,
}

/// The extremes of a group of rows: `(time, value)` of the minimum and the maximum.
#[derive(Debug, Clone, Copy)]
struct Bin {
    min: (f64, f64),
    max: (f64, f64),
}

impl Bin {
    fn merge(self, o: Bin) -> Bin {
        Bin {
            min: if o.min.1 < self.min.1 { o.min } else { self.min },
            max: if o.max.1 > self.max.1 { o.max } else { self.max },
        }
    }
}

impl MinMaxDecimator {
    /// A decimator for a plot `columns` pixels wide.
    pub fn new(columns: usize) -> Self {
        let capacity = 2 * columns.max(1);
        Self { capacity, rows_per_bin: 1, bins: Vec::with_capacity(capacity), current: None, in_current: 0 }
    }

    /// Adds the value `y` at time `t` (non-finite values are left out of the plot).
    pub fn push(&mut self, t: f64, y: f64) {
        if y.is_finite() && t.is_finite() {
            let b = Bin { min: (t, y), max: (t, y) };
            self.current = Some(self.current.map_or(b, |c| c.merge(b)));
        }
        self.in_current += 1;
        if self.in_current == self.rows_per_bin {
            self.close();
        }
    }

    fn close(&mut self) {
        if let Some(b) = self.current.take() {
            self.bins.push(b);
        }
        self.in_current = 0;
        if self.bins.len() == self.capacity {
            let merged: Vec<Bin> = self.bins.chunks(2).map(|p| p.iter().copied().reduce(Bin::merge).unwrap()).collect();
            self.bins = merged;
            self.rows_per_bin *= 2;
        }
    }

    /// The points to draw, in time order.
    pub fn points(&self) -> (Vec<f64>, Vec<f64>) {
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for b in self.bins.iter().chain(&self.current) {
            let (a, c) = if b.min.0 <= b.max.0 { (b.min, b.max) } else { (b.max, b.min) };
            x.extend([a.0, c.0]);
            y.extend([a.1, c.1]);
        }
        (x, y)
    }
}

/// Averaged amplitude spectrum over Hann segments of `segment` samples with half
/// overlap (Welch), streaming; a recording shorter than one segment is taken whole.
/// Non-finite samples count as 0.
#[derive(Debug, Clone)]
pub struct WelchAmplitude {
    segment: usize,
    buf: Vec<f64>,
    /// Sum of squared amplitudes per bin, and the segments summed.
    power: Vec<f64>,
    segments: u64,
    /// Samples per segment summed.
    len: usize,
}

impl WelchAmplitude {
    /// Segments of `segment` samples.
    pub fn new(segment: usize) -> Self {
        Self { segment, buf: Vec::with_capacity(segment), power: Vec::new(), segments: 0, len: 0 }
    }

    /// Adds one sample.
    pub fn push(&mut self, v: f64) {
        self.buf.push(if v.is_finite() { v } else { 0.0 });
        if self.buf.len() == self.segment {
            self.add(self.segment);
            self.buf.drain(..self.segment / 2);
        }
    }

    fn add(&mut self, n: usize) {
        // The sample rate only scales the frequency axis: 1 here, the real one at the end.
        if let Ok(s) = amplitude_spectrum(&self.buf[..n], 1.0) {
            if self.power.is_empty() {
                self.power = vec![0.0; s.amplitude.len()];
            }
            for (p, a) in self.power.iter_mut().zip(&s.amplitude) {
                *p += a * a;
            }
            self.segments += 1;
            self.len = n;
        }
    }

    /// Frequencies (Hz, for `sample_rate_hz`) and RMS-averaged amplitudes; `None` for
    /// fewer than 8 samples.
    pub fn finish(mut self, sample_rate_hz: f64) -> Option<(Vec<f64>, Vec<f64>)> {
        if self.segments == 0 {
            let n = self.buf.len();
            self.add(n);
        }
        if self.segments == 0 {
            return None;
        }
        let freqs = (0..self.power.len()).map(|k| k as f64 * sample_rate_hz / self.len as f64).collect();
        let amp = self.power.iter().map(|p| (p / self.segments as f64).sqrt()).collect();
        Some((freqs, amp))
    }
}

/// The speed a joint's relative angle (wave generator against flexspline) and its output
/// angle held longest (rad/s, either way): the fullest bin of a histogram of each
/// step's speed, weighted by the step's time, in bins 2 % wide from 10⁻³ to 10⁶ rad/s.
/// An order line is sharp where a run holds its speed, so that is where its marker goes
/// (a run that reverses has a mean angle rate near zero; one with ramps, a mean below its
/// plateau). Steps are wrapped to (−π, π], so angles given modulo a turn count the same;
/// non-finite values are stepped over.
#[derive(Debug, Clone)]
pub struct HeldSpeed {
    last: Option<(f64, f64, f64)>,
    relative: Vec<f64>,
    output: Vec<f64>,
}

/// Bins of [`HeldSpeed`]: the lowest speed, the ratio of one bin's edges, their number.
const SPEED_MIN_RAD_S: f64 = 1e-3;
const SPEED_BIN_RATIO: f64 = 1.02;
const SPEED_BINS: usize = 1047;

impl Default for HeldSpeed {
    fn default() -> Self {
        Self { last: None, relative: vec![0.0; SPEED_BINS], output: vec![0.0; SPEED_BINS] }
    }
}

impl HeldSpeed {
    /// Adds one row: time (s), relative and output angle (rad).
    pub fn push(&mut self, t: f64, relative_rad: f64, output_rad: f64) {
        if !(t.is_finite() && relative_rad.is_finite() && output_rad.is_finite()) {
            return;
        }
        if let Some((t0, r, o)) = self.last {
            let dt = t - t0;
            if dt > 0.0 {
                add(&mut self.relative, wrap_rad(relative_rad - r).abs() / dt, dt);
                add(&mut self.output, wrap_rad(output_rad - o).abs() / dt, dt);
            }
        }
        self.last = Some((t, relative_rad, output_rad));
    }

    /// The relative and output speeds held longest, rad/s (`None` for a joint that did
    /// not turn).
    pub fn speeds_rad_s(&self) -> Option<(f64, f64)> {
        Some((fullest(&self.relative)?, fullest(&self.output)?))
    }
}

/// Adds `weight` to the bin of `speed` (below the lowest bin: not counted).
fn add(bins: &mut [f64], speed: f64, weight: f64) {
    if speed >= SPEED_MIN_RAD_S {
        let k = ((speed / SPEED_MIN_RAD_S).ln() / SPEED_BIN_RATIO.ln()) as usize;
        bins[k.min(bins.len() - 1)] += weight;
    }
}

/// The centre of the fullest bin (`None` if all are empty).
fn fullest(bins: &[f64]) -> Option<f64> {
    let (k, w) = bins.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    (*w > 0.0).then(|| SPEED_MIN_RAD_S * SPEED_BIN_RATIO.powf(k as f64 + 0.5))
}

/// `a` wrapped to (−π, π].
fn wrap_rad(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    a - tau * (a / tau).round()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_a_single_spike_and_stays_bounded() {
        let mut d = MinMaxDecimator::new(100);
        for k in 0..1_000_000u64 {
            d.push(k as f64, if k == 777_777 { 5.0 } else { (k as f64 * 1e-3).sin() });
        }
        let (x, y) = d.points();
        assert!(x.len() <= 400, "{}", x.len());
        assert!(x.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(y.iter().cloned().fold(f64::MIN, f64::max), 5.0);
        assert_eq!(x[y.iter().position(|v| *v == 5.0).unwrap()], 777_777.0);
    }

    /// Before: the sum of squares of `1e308` overflowed, and `report` printed an rms of
    /// `inf` for a column of finite values.
    #[test]
    fn column_stats_are_finite_for_finite_values_and_match_the_plain_sums() {
        let mut s = ColumnStats::default();
        for v in [1e308, -1e308, 1e308, f64::NAN, 0.0] {
            s.push(v);
        }
        assert_eq!((s.finite, s.non_finite, s.max_abs), (4, 1, 1e308));
        assert!((s.mean() - 0.25e308).abs() <= 1e293, "{}", s.mean());
        assert!((s.rms() - 3f64.sqrt() / 2.0 * 1e308).abs() <= 1e294, "{}", s.rms());
        let xs: Vec<f64> = (0..10_000).map(|k| (k as f64 * 0.37).sin() * 3.0 + 0.5).collect();
        let mut s = ColumnStats::default();
        xs.iter().for_each(|&v| s.push(v));
        let n = xs.len() as f64;
        let (mean, rms) = (xs.iter().sum::<f64>() / n, (xs.iter().map(|v| v * v).sum::<f64>() / n).sqrt());
        assert!((s.mean() - mean).abs() < 1e-12 && (s.rms() - rms).abs() < 1e-12, "{} {}", s.mean(), s.rms());
        assert_eq!((ColumnStats::default().mean(), ColumnStats::default().rms()), (0.0, 0.0));
    }

    #[test]
    fn welch_finds_the_amplitude_of_a_sine() {
        let fs = 1000.0;
        let mut w = WelchAmplitude::new(4096);
        for k in 0..100_000 {
            w.push(0.5 * (std::f64::consts::TAU * 125.0 * k as f64 / fs).sin());
        }
        let (f, a) = w.finish(fs).unwrap();
        let k = a.iter().enumerate().max_by(|x, y| x.1.total_cmp(y.1)).unwrap().0;
        assert!((f[k] - 125.0).abs() < 0.25, "{}", f[k]);
        assert!((a[k] - 0.5).abs() < 0.01, "{}", a[k]);
    }

    #[test]
    fn a_short_recording_is_one_whole_segment() {
        let mut w = WelchAmplitude::new(4096);
        for k in 0..1000 {
            w.push((std::f64::consts::TAU * 50.0 * k as f64 / 1000.0).cos());
        }
        let (f, a) = w.finish(1000.0).unwrap();
        let k = a.iter().enumerate().max_by(|x, y| x.1.total_cmp(y.1)).unwrap().0;
        assert_eq!(f[k], 50.0);
        assert!((a[k] - 1.0).abs() < 1e-9);
    }

    #[test]
    fn held_speed_is_the_plateau_of_a_run_that_ramps_and_reverses() {
        // 1 s ramps to 150 rad/s, 2 s held, reversed the same way, at 1 kHz: the mean
        // angle rate is 0 and the mean speed 100 rad/s; the speed held is 150. Wrapped
        // angles give the same; a NaN row is stepped over.
        let profile = |t: f64| {
            let one_way = |t: f64| if t < 1.0 { 75.0 * t * t } else { 75.0 + 150.0 * (t - 1.0) };
            if t < 3.0 {
                one_way(t)
            } else {
                one_way(3.0) - one_way(t - 3.0)
            }
        };
        let (mut plain, mut wrapped) = (HeldSpeed::default(), HeldSpeed::default());
        for k in 0..=6000 {
            let t = k as f64 * 1e-3;
            let a = profile(t);
            plain.push(t, a, -a / 50.0);
            wrapped.push(t, a.rem_euclid(std::f64::consts::TAU), (-a / 50.0).rem_euclid(std::f64::consts::TAU));
            if k == 50 {
                plain.push(t + 1e-4, f64::NAN, 0.0);
            }
        }
        for h in [plain, wrapped] {
            let (rel, out) = h.speeds_rad_s().unwrap();
            assert!((rel / 150.0 - 1.0).abs() < 0.02, "{rel}");
            assert!((out / 3.0 - 1.0).abs() < 0.02, "{out}");
        }
        assert_eq!(HeldSpeed::default().speeds_rad_s(), None);
    }
}
