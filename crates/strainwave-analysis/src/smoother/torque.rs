//! The smoothed torque: the clean torque (measurement minus the smoothed ripple and
//! misalignment) smoothed as a level-and-rate torque state, with steps kept sharp.
//!
//! The canceller's own torque state is a random walk: it lags on ramps, so under fast
//! load changes its load-step test fires sample after sample and each firing cuts the
//! smoothing. Here the torque is an integrated random walk (level `τ`, rate `τ̇`), which
//! follows ramps without lag, seen in white noise of variance `r`:
//!
//! ```text
//! x(k+1) = F x(k) + w,   F = [1 1; 0 1],   Q = q [1/3 1/2; 1/2 1],   y(k) = τ(k) + v
//! ```
//!
//! smoothed in two-filter form: a forward filter ([`TorqueTrack::forward`]) and a
//! backward one on the time-reversed model (`F⁻¹`, same `Q`), combined per sample as
//!
//! ```text
//! P_s = (P_f⁻¹ + P_b⁻¹)⁻¹,   x_s = P_s (P_f⁻¹ x_f + P_b⁻¹ x_b)
//! ```
//!
//! with `x_f` filtered with `y(k)` and `x_b` predicted without it. Each filter restarts
//! at an innovation whose NIS exceeds the step limit: a step between `k − 1` and `k`
//! restarts the forward filter at `k` and the backward one at `k − 1`, whose prediction
//! across the step is then dropped; so nothing of one side reaches the other and the
//! step stays sharp. Both directions run in constant memory, which is what lets the
//! backward filter ride on the smoother's backward pass and the forward one on the
//! final in-order pass.

/// The bandwidth the smoothed torque is given, Hz (measured best of 30–50 Hz on the
/// twin's runs; see `docs/smoothing.md`).
pub const SMOOTHED_TORQUE_BANDWIDTH_HZ: f64 = 60.0;

/// The NIS above which either filter takes a sample as a step and restarts (a 4σ jump).
pub const SMOOTHED_TORQUE_STEP_NIS: f64 = 16.0;

/// Level-and-rate torque filter in one direction (see the module).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueTrack {
    q_nm2: f64,
    r_nm2: f64,
    step_nis: f64,
    /// `+1` forward, `−1` backward (the rate's sign in `F`).
    direction: f64,
    /// Level and rate (N·m, N·m per sample).
    mean: [f64; 2],
    /// `[P_ττ, P_ττ̇, P_τ̇τ̇]`.
    cov: [f64; 3],
    started: bool,
}

/// The rate's variance at a restart (it is unknown; large against any real rate).
const RATE_PRIOR_NM2: f64 = 1e6;

/// A Gaussian estimate of the torque's level and rate: mean `[τ, τ̇]` (N·m, N·m per
/// sample, the rate in forward time whichever way the filter runs) and covariance
/// `[P_ττ, P_ττ̇, P_τ̇τ̇]`; [`Self::NONE`]: no information.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueEstimate {
    /// `[τ, τ̇]`.
    pub mean: [f64; 2],
    /// `[P_ττ, P_ττ̇, P_τ̇τ̇]` (`P_ττ = ∞`: no information).
    pub cov: [f64; 3],
}

impl TorqueEstimate {
    /// No information.
    pub const NONE: Self = Self { mean: [0.0; 2], cov: [f64::INFINITY, 0.0, f64::INFINITY] };

    /// The level, N·m.
    pub fn level_nm(&self) -> f64 {
        self.mean[0]
    }

    /// The level's standard deviation, N·m (∞: no information).
    pub fn level_sd_nm(&self) -> f64 {
        self.cov[0].sqrt()
    }

    /// The information matrix `P⁻¹` and information vector `P⁻¹ x`, `None` without
    /// information (or a covariance that is not positive definite).
    fn information(&self) -> Option<([f64; 3], [f64; 2])> {
        let [a, b, c] = self.cov;
        let det = a * c - b * b;
        if !(a.is_finite() && c.is_finite() && b.is_finite() && a > 0.0 && det > 0.0) {
            return None;
        }
        let inv = [c / det, -b / det, a / det];
        Some((inv, [inv[0] * self.mean[0] + inv[1] * self.mean[1], inv[1] * self.mean[0] + inv[2] * self.mean[1]]))
    }

    /// The two-filter combination of two independent estimates of the same state,
    /// level and rate together (`P = (P_a⁻¹ + P_b⁻¹)⁻¹`, `x = P (P_a⁻¹ x_a + P_b⁻¹ x_b)`),
    /// `None` when neither has information. Combining the levels alone would throw away
    /// what each side's rate says about the level: on a curved load both sides lag the
    /// same way, and only the joint combination cancels it.
    pub fn combine(self, other: Self) -> Option<Self> {
        match (self.information(), other.information()) {
            (None, None) => None,
            (Some(_), None) => Some(self),
            (None, Some(_)) => Some(other),
            (Some((ia, va)), Some((ib, vb))) => {
                let i = [ia[0] + ib[0], ia[1] + ib[1], ia[2] + ib[2]];
                let v = [va[0] + vb[0], va[1] + vb[1]];
                let det = i[0] * i[2] - i[1] * i[1];
                if !(det > 0.0 && det.is_finite()) {
                    return None;
                }
                let cov = [i[2] / det, -i[1] / det, i[0] / det];
                Some(Self { mean: [cov[0] * v[0] + cov[1] * v[1], cov[1] * v[0] + cov[2] * v[1]], cov })
            }
        }
    }
}

impl TorqueTrack {
    /// The forward filter: rate noise `q_nm2` (N·m² per sample³), measurement noise
    /// variance `r_nm2` (N·m²), restart above `step_nis`.
    pub fn forward(q_nm2: f64, r_nm2: f64, step_nis: f64) -> Self {
        Self { q_nm2, r_nm2, step_nis, direction: 1.0, mean: [0.0; 2], cov: [0.0; 3], started: false }
    }

    /// The backward filter (fed from the last sample to the first).
    pub fn backward(q_nm2: f64, r_nm2: f64, step_nis: f64) -> Self {
        Self { direction: -1.0, ..Self::forward(q_nm2, r_nm2, step_nis) }
    }

    /// The forward and backward filters for the measurement noise `noise_nm` (1σ, N·m,
    /// as the canceller's) at `sample_rate_hz`, with [`SMOOTHED_TORQUE_BANDWIDTH_HZ`] and
    /// [`SMOOTHED_TORQUE_STEP_NIS`].
    pub fn pair(noise_nm: f64, sample_rate_hz: f64) -> (Self, Self) {
        let r_nm2 = noise_nm * noise_nm;
        let q = Self::q_for_bandwidth(SMOOTHED_TORQUE_BANDWIDTH_HZ, sample_rate_hz, r_nm2);
        (Self::forward(q, r_nm2, SMOOTHED_TORQUE_STEP_NIS), Self::backward(q, r_nm2, SMOOTHED_TORQUE_STEP_NIS))
    }

    /// `q` for a filter of about `bandwidth_hz` at `sample_rate_hz` on noise `r_nm2`:
    /// the steady-state filter's natural frequency is `(q / r)^{1/4}` rad per sample.
    pub fn q_for_bandwidth(bandwidth_hz: f64, sample_rate_hz: f64, r_nm2: f64) -> f64 {
        r_nm2 * (std::f64::consts::TAU * bandwidth_hz / sample_rate_hz).powi(4)
    }

    /// The state predicted for the next sample, before it is seen (`F x`, `F P Fᵀ + Q`).
    pub fn predicted(&self) -> TorqueEstimate {
        if !self.started {
            return TorqueEstimate::NONE;
        }
        let (d, q) = (self.direction, self.q_nm2);
        let [p00, p01, p11] = self.cov;
        TorqueEstimate {
            mean: [self.mean[0] + d * self.mean[1], self.mean[1]],
            cov: [p00 + 2.0 * d * p01 + p11 + q / 3.0, p01 + d * p11 + d * q / 2.0, p11 + q],
        }
    }

    /// The state filtered with the last sample.
    pub fn filtered(&self) -> TorqueEstimate {
        if !self.started {
            return TorqueEstimate::NONE;
        }
        TorqueEstimate { mean: self.mean, cov: self.cov }
    }

    /// Takes sample `y_nm` (prediction, then update); `cut`: a step is known to lie
    /// just before this sample (in the filter's direction). A non-finite `y_nm` is a
    /// time update only. Returns whether the filter restarted here (a step: its NIS
    /// exceeded the limit, or `cut`).
    pub fn push(&mut self, y_nm: f64, cut: bool) -> bool {
        if self.started {
            let p = self.predicted();
            (self.mean, self.cov) = (p.mean, p.cov);
        }
        if !y_nm.is_finite() {
            return false;
        }
        let e = y_nm - self.mean[0];
        let s = self.cov[0] + self.r_nm2;
        let restart = !self.started || cut || s.is_nan() || s <= 0.0 || e * e / s > self.step_nis;
        if restart {
            self.mean = [y_nm, 0.0];
            self.cov = [self.r_nm2, 0.0, RATE_PRIOR_NM2];
            let was = self.started;
            self.started = true;
            return was;
        }
        let [p00, p01, p11] = self.cov;
        let (g0, g1) = (p00 / s, p01 / s);
        self.mean = [self.mean[0] + g0 * e, self.mean[1] + g1 * e];
        self.cov = [p00 - g0 * p00, p01 - g0 * p01, p11 - g1 * p01];
        false
    }
}

/// Smooths a whole series in memory with the (forward, backward) filters, the same two
/// the command line runs over its passes: per sample the smoothed level and its
/// standard deviation. `cuts[k]`: a known step just before sample `k`.
pub fn smooth_torque(y_nm: &[f64], cuts: &[bool], (mut fwd, mut back): (TorqueTrack, TorqueTrack)) -> Vec<(f64, f64)> {
    let n = y_nm.len();
    let cut = |k: usize| cuts.get(k).copied().unwrap_or(false);
    let mut predicted = vec![TorqueEstimate::NONE; n];
    for k in (0..n).rev() {
        let p = back.predicted();
        // A step just after k (cut at k + 1) is just before k in reverse time.
        if !back.push(y_nm[k], cut(k + 1)) {
            predicted[k] = p;
        }
    }
    (0..n)
        .map(|k| {
            fwd.push(y_nm[k], cut(k));
            fwd.filtered().combine(predicted[k]).map_or((y_nm[k], f64::NAN), |e| (e.level_nm(), e.level_sd_nm()))
        })
        .collect()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Standard normal draws from a seeded generator (shared with the ripple smoother's tests).
    pub(crate) fn gaussians(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        let mut uniform = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        move || (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos()
    }

    pub(crate) fn rms(v: impl Iterator<Item = f64>) -> f64 {
        let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (s / n.max(1) as f64).sqrt()
    }

    /// Truth drawn from the model itself: the error matches σ and the band covers 68 %.
    #[test]
    fn honest_when_the_model_is_right() {
        let (r_nm2, fs) = (0.02f64.powi(2), 1000.0);
        let q = TorqueTrack::q_for_bandwidth(20.0, fs, r_nm2);
        let mut g = gaussians(5);
        let (mut level, mut rate) = (2.0, 0.0);
        let (mut truth, mut y) = (Vec::new(), Vec::new());
        for _ in 0..60_000 {
            truth.push(level);
            y.push(level + r_nm2.sqrt() * g());
            // Q = q [1/3 1/2; 1/2 1]: rate noise w1, level noise w1/2 + w2/√12.
            let (w1, w2) = (q.sqrt() * g(), q.sqrt() * g());
            level += rate + w1 / 2.0 + w2 / 12f64.sqrt();
            rate += w1;
        }
        // No restarts wanted: a limit no Gaussian sample reaches here.
        let tracks = (TorqueTrack::forward(q, r_nm2, 1e9), TorqueTrack::backward(q, r_nm2, 1e9));
        let out = smooth_torque(&y, &[], tracks);
        let from = 1000;
        let err = rms((from..y.len()).map(|k| out[k].0 - truth[k]));
        let sd = rms((from..y.len()).map(|k| out[k].1));
        let covered = (from..y.len()).filter(|&k| (out[k].0 - truth[k]).abs() <= out[k].1).count();
        let coverage = covered as f64 / (y.len() - from) as f64;
        assert!((err / sd - 1.0).abs() < 0.05, "RMS error {err} vs σ {sd}");
        assert!((coverage - 0.683).abs() < 0.02, "coverage {coverage}");
        let mut fwd = TorqueTrack::forward(q, r_nm2, 1e9);
        let filtered: Vec<f64> = y.iter().map(|v| (fwd.push(*v, false), fwd.filtered().level_nm()).1).collect();
        let err_f = rms((from..y.len()).map(|k| filtered[k] - truth[k]));
        assert!(err < 0.85 * err_f, "smoothed {err} vs filtered {err_f}");
        assert!(err < 0.5 * r_nm2.sqrt(), "smoothed {err} vs noise {}", r_nm2.sqrt());
    }

    /// A 1 N·m step on a ramp, and a known cut: both sides keep their own level to the
    /// sample; a non-finite sample is bridged.
    #[test]
    fn steps_stay_sharp_and_gaps_are_bridged() {
        let (r_nm2, fs) = (0.02f64.powi(2), 1000.0);
        let mut g = gaussians(8);
        let (k0, k1, n) = (3000, 4500, 6000);
        let truth: Vec<f64> = (0..n)
            .map(|k| 0.001 * k as f64 + if k >= k0 { 1.0 } else { 0.0 } + if k >= k1 { 0.05 } else { 0.0 })
            .collect();
        let mut y: Vec<f64> = truth.iter().map(|t| t + r_nm2.sqrt() * g()).collect();
        y[1000] = f64::NAN;
        let mut cuts = vec![false; n];
        cuts[k1] = true;
        let out = smooth_torque(&y, &cuts, TorqueTrack::pair(r_nm2.sqrt(), fs));
        for k in (k0 - 20..k0 + 20).chain(k1 - 20..k1 + 20).chain(990..1010) {
            assert!((out[k].0 - truth[k]).abs() < 5.0 * out[k].1, "sample {k}: {:?} vs {}", out[k], truth[k]);
            assert!((out[k].0 - truth[k]).abs() < 0.04, "sample {k}: {:?} vs {}", out[k], truth[k]);
        }
        assert!(out[1000].0.is_finite() && out[1000].1 > out[999].1, "the gap is bridged with less certainty");
        assert!(smooth_torque(&[], &[], TorqueTrack::pair(r_nm2.sqrt(), fs)).is_empty());
        let none = smooth_torque(&[f64::NAN; 3], &[], TorqueTrack::pair(r_nm2.sqrt(), fs));
        assert!(none.iter().all(|(t, sd)| t.is_nan() && sd.is_nan()));
    }

    #[test]
    fn combining_weights_by_information() {
        // Uncorrelated level and rate: each combines on its own.
        let a = TorqueEstimate { mean: [1.0, 0.0], cov: [1.0, 0.0, 1.0] };
        let b = TorqueEstimate { mean: [4.0, 3.0], cov: [2.0, 0.0, 2.0] };
        let c = a.combine(b).unwrap();
        assert!((c.mean[0] - 2.0).abs() < 1e-12 && (c.cov[0] - 2.0 / 3.0).abs() < 1e-12);
        assert!((c.mean[1] - 1.0).abs() < 1e-12 && c.cov[1].abs() < 1e-12);
        assert_eq!(a.combine(TorqueEstimate::NONE), Some(a));
        assert_eq!(TorqueEstimate::NONE.combine(TorqueEstimate::NONE), None);
        // Correlated: a rate that disagrees moves the level (what the levels alone miss).
        let f = TorqueEstimate { mean: [0.0, 0.0], cov: [1.0, 0.9, 1.0] };
        let g = TorqueEstimate { mean: [0.0, 1.0], cov: [1.0, 0.0, 1.0] };
        assert!(f.combine(g).unwrap().mean[0] > 0.1);
    }

    /// A noiseless parabola (constant curvature, as at a sinusoidal load's peaks): each
    /// filter lags it the same way, and the joint combination cancels the lag.
    #[test]
    fn no_bias_on_a_curved_load() {
        let (r_nm2, fs) = (0.0162f64.powi(2), 1000.0);
        let truth: Vec<f64> = (0..4000).map(|k| 7e-4 * 0.5 * (k as f64 - 2000.0).powi(2) * 1e-3).collect();
        let tracks = || {
            let q = TorqueTrack::q_for_bandwidth(40.0, fs, r_nm2);
            (TorqueTrack::forward(q, r_nm2, 1e9), TorqueTrack::backward(q, r_nm2, 1e9))
        };
        let out = smooth_torque(&truth, &[], tracks());
        let err = rms((500..3500).map(|k| out[k].0 - truth[k]));
        // The filtered (one-sided) lag on the same curvature, for scale.
        let mut fwd = tracks().0;
        let lag = rms((0..4000)
            .map(|k| (fwd.push(truth[k], false), fwd.filtered().level_nm() - truth[k]).1)
            .skip(500)
            .take(3000));
        assert!(err < 1e-3 * lag.max(1e-9) + 1e-9, "smoothed {err} vs filtered lag {lag}");
    }
}
