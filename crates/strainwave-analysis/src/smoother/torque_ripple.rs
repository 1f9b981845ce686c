//! The smoothed torque with the ripple the canceller left: the level-and-rate torque of
//! [`super::torque`] and, beside it, one slowly varying oscillator per ripple order, all
//! smoothed together, so that residual ripple is removed offline and its uncertainty
//! counts in the band.
//!
//! State `x = [τ, τ̇, a₁, b₁, …, a_J, b_J]`, seen in white noise of variance `r`:
//!
//! ```text
//! y(k) = τ(k) + Σ_j [a_j(k) cos ψ_j(k) + b_j(k) sin ψ_j(k)] + v(k),   ψ_j = n_j φ(k)
//! τ, τ̇: integrated random walk (q, as in [`super::torque`]);  a_j, b_j: random walks (q_r)
//! ```
//!
//! with `φ` the reference angle of the canceller's order `j` (its phase, not a rotation:
//! the coefficients live in that order's rotating frame, so the backward model is the
//! same as the forward one but for the rate's sign). Two filters, forward and backward,
//! are combined per sample in information form over the whole state,
//!
//! ```text
//! P_s = (P_f⁻¹ + P_b⁻¹)⁻¹,   x_s = P_s (P_f⁻¹ x_f + P_b⁻¹ x_b)
//! ```
//!
//! and a step (NIS above the limit) restarts the level and rate of the filter that meets
//! it, keeping what it knows of the ripple. Without orders (`J = 0`) this is exactly
//! [`super::torque::TorqueTrack`].

// Small dense matrix algebra: index loops read as the formulas.
#![allow(clippy::needless_range_loop)]

use super::spd::inverse_spd;
use super::torque::{SMOOTHED_TORQUE_BANDWIDTH_HZ, SMOOTHED_TORQUE_STEP_NIS};

/// A residual ripple order is modelled when its line lies above this fraction of the
/// torque's bandwidth (measured on the twin: at the full bandwidth the 50 Hz 2× line of
/// the taghirad joint was left out, and its residual with it).
pub const RESIDUAL_LINE_FRACTION: f64 = 0.5;

/// At most this many ripple orders.
pub const MAX_RIPPLE_ORDERS: usize = 3;
/// State length at most: level, rate and two per order.
pub(super) const MAX_N: usize = 2 + 2 * MAX_RIPPLE_ORDERS;
/// The rate's variance at a restart (as in [`super::torque`]).
const RATE_PRIOR_NM2: f64 = 1e6;
/// Prior variance of each residual ripple coefficient, N·m² (1σ 0.05 N·m: what a
/// commissioned canceller leaves is well below).
const RIPPLE_PRIOR_NM2: f64 = 2.5e-3;
/// How fast the residual ripple may change: the coefficients' random walk has this
/// bandwidth against the noise, Hz.
pub const RESIDUAL_RIPPLE_BANDWIDTH_HZ: f64 = 0.5;

/// A Gaussian estimate of the state (mean, covariance; [`Self::none`]: no information),
/// with the part of its error covariance that the measurement noise alone causes.
///
/// The estimate is linear in the data, `x̂ = Σ W_k y_k`, so its error given the true
/// torque is `Σ W_k v_k` (the noise's share, covariance `N`) plus what the weights make
/// of the torque's own motion (the lag). The model's covariance `P` counts the lag of a
/// torque that moves as its 60 Hz random walk allows, all the time. The twin's loads move
/// that fast only around steps and on the steep parts of a sinusoid: elsewhere the
/// error is the noise's share, about 70 % of `P` in variance, and a band of `√P` covered
/// the truth 72–76 % of the time. The band is therefore `√N`; around fast transients the
/// lag adds to it, and those samples fall outside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleTorqueEstimate {
    n: usize,
    mean: [f64; MAX_N],
    cov: [[f64; MAX_N]; MAX_N],
    noise: [[f64; MAX_N]; MAX_N],
    informative: bool,
}

impl RippleTorqueEstimate {
    /// No information, state length `n`.
    pub fn none(n: usize) -> Self {
        Self { n, mean: [0.0; MAX_N], cov: [[0.0; MAX_N]; MAX_N], noise: [[0.0; MAX_N]; MAX_N], informative: false }
    }

    /// The level, N·m.
    pub fn level_nm(&self) -> f64 {
        self.mean[0]
    }

    /// The level's band: the standard deviation of the noise's share of its error, N·m
    /// (∞ without information; see the type).
    pub fn level_sd_nm(&self) -> f64 {
        if self.informative {
            self.noise[0][0].max(0.0).sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// The level's standard deviation under the model (lag of a torque moving as the
    /// model allows included), N·m (∞ without information).
    pub fn level_model_sd_nm(&self) -> f64 {
        if self.informative {
            self.cov[0][0].max(0.0).sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// Values to store it: `1 + n + n(n+1)` numbers (flag, mean, upper triangles of the
    /// covariance and of the noise's share).
    pub fn values_len(n: usize) -> usize {
        1 + n + n * (n + 1)
    }

    /// Appends its [`Self::values_len`] values to `out`.
    pub fn to_values(&self, out: &mut Vec<f64>) {
        out.push(if self.informative { 1.0 } else { 0.0 });
        out.extend_from_slice(&self.mean[..self.n]);
        for i in 0..self.n {
            out.extend_from_slice(&self.cov[i][i..self.n]);
        }
        for i in 0..self.n {
            out.extend_from_slice(&self.noise[i][i..self.n]);
        }
    }

    /// The estimate of length `n` from [`Self::to_values`]' values (`None`: too few).
    pub fn from_values(n: usize, v: &[f64]) -> Option<Self> {
        if n > MAX_N || v.len() < Self::values_len(n) {
            return None;
        }
        let mut e = Self::none(n);
        e.informative = v[0] == 1.0;
        e.mean[..n].copy_from_slice(&v[1..1 + n]);
        let mut at = 1 + n;
        for m in [&mut e.cov, &mut e.noise] {
            for i in 0..n {
                for j in i..n {
                    m[i][j] = v[at];
                    m[j][i] = v[at];
                    at += 1;
                }
            }
        }
        Some(e)
    }

    /// The inverse of its covariance and the information vector, `None` without
    /// information or when the covariance is not positive definite.
    fn information(&self) -> Option<([[f64; MAX_N]; MAX_N], [f64; MAX_N])> {
        if !self.informative {
            return None;
        }
        let inv = inverse_spd(&self.cov, self.n)?;
        let mut v = [0.0; MAX_N];
        for (i, vi) in v.iter_mut().enumerate().take(self.n) {
            *vi = (0..self.n).map(|j| inv[i][j] * self.mean[j]).sum();
        }
        Some((inv, v))
    }

    /// The two-filter combination of two independent estimates of the same state
    /// (see the module), `None` when neither has information.
    pub fn combine(self, other: Self) -> Option<Self> {
        match (self.information(), other.information()) {
            (None, None) => None,
            (Some(_), None) => Some(self),
            (None, Some(_)) => Some(other),
            (Some((ia, va)), Some((ib, vb))) => {
                let n = self.n;
                let mut info = [[0.0; MAX_N]; MAX_N];
                for i in 0..n {
                    for j in 0..n {
                        info[i][j] = ia[i][j] + ib[i][j];
                    }
                }
                let cov = inverse_spd(&info, n)?;
                // The two sides see disjoint samples, so their noise is independent:
                // N = P (Iₐ Nₐ Iₐ + I_b N_b I_b) P.
                let (ta, tb) = (sandwich(&ia, &self.noise, n), sandwich(&ib, &other.noise, n));
                let mut t = [[0.0; MAX_N]; MAX_N];
                for i in 0..n {
                    for j in 0..n {
                        t[i][j] = ta[i][j] + tb[i][j];
                    }
                }
                let mut e = Self { n, mean: [0.0; MAX_N], cov, noise: sandwich(&cov, &t, n), informative: true };
                for i in 0..n {
                    e.mean[i] = (0..n).map(|j| cov[i][j] * (va[j] + vb[j])).sum();
                }
                Some(e)
            }
        }
    }
}

/// `A M A` for symmetric `A` and `M` (leading `n × n` blocks).
fn sandwich(a: &[[f64; MAX_N]; MAX_N], m: &[[f64; MAX_N]; MAX_N], n: usize) -> [[f64; MAX_N]; MAX_N] {
    let mut am = [[0.0; MAX_N]; MAX_N];
    for i in 0..n {
        for j in 0..n {
            am[i][j] = (0..n).map(|k| a[i][k] * m[k][j]).sum();
        }
    }
    let mut out = [[0.0; MAX_N]; MAX_N];
    for i in 0..n {
        for j in i..n {
            let v: f64 = (0..n).map(|k| am[i][k] * a[k][j]).sum();
            out[i][j] = v;
            out[j][i] = v;
        }
    }
    out
}

/// The level-and-rate torque with residual ripple orders, filtered in one direction
/// (see the module).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleTorqueTrack {
    q_nm2: f64,
    q_ripple_nm2: f64,
    r_nm2: f64,
    step_nis: f64,
    direction: f64,
    state: RippleTorqueEstimate,
}

impl RippleTorqueTrack {
    /// The forward filter with `orders` residual ripple orders (at most
    /// [`MAX_RIPPLE_ORDERS`]): torque rate noise `q_nm2`, ripple coefficient noise
    /// `q_ripple_nm2`, measurement noise variance `r_nm2` (N·m²), restart above `step_nis`.
    pub fn forward(orders: usize, q_nm2: f64, q_ripple_nm2: f64, r_nm2: f64, step_nis: f64) -> Self {
        let n = 2 + 2 * orders.min(MAX_RIPPLE_ORDERS);
        Self { q_nm2, q_ripple_nm2, r_nm2, step_nis, direction: 1.0, state: RippleTorqueEstimate::none(n) }
    }

    /// The backward filter (fed from the last sample to the first).
    pub fn backward(orders: usize, q_nm2: f64, q_ripple_nm2: f64, r_nm2: f64, step_nis: f64) -> Self {
        Self { direction: -1.0, ..Self::forward(orders, q_nm2, q_ripple_nm2, r_nm2, step_nis) }
    }

    /// The forward and backward filters for the measurement noise `noise_nm` (1σ, N·m, as
    /// the canceller's) at `sample_rate_hz`, with the torque's and the residual ripple's
    /// bandwidths ([`SMOOTHED_TORQUE_BANDWIDTH_HZ`], [`RESIDUAL_RIPPLE_BANDWIDTH_HZ`]).
    pub fn pair(orders: usize, noise_nm: f64, sample_rate_hz: f64) -> (Self, Self) {
        let r_nm2 = noise_nm * noise_nm;
        let w = |hz: f64| std::f64::consts::TAU * hz / sample_rate_hz;
        let q = r_nm2 * w(SMOOTHED_TORQUE_BANDWIDTH_HZ).powi(4);
        let qr = r_nm2 * w(RESIDUAL_RIPPLE_BANDWIDTH_HZ).powi(2);
        let nis = SMOOTHED_TORQUE_STEP_NIS;
        (Self::forward(orders, q, qr, r_nm2, nis), Self::backward(orders, q, qr, r_nm2, nis))
    }

    /// State length.
    pub fn state_len(&self) -> usize {
        self.state.n
    }

    /// The state predicted for the next sample, before it is seen.
    pub fn predicted(&self) -> RippleTorqueEstimate {
        let mut e = self.state;
        if !e.informative {
            return e;
        }
        let (n, d, q) = (e.n, self.direction, self.q_nm2);
        // F = I + d e₀e₁ᵀ: row 0 += d row 1, then column 0 += d column 1.
        e.mean[0] += d * e.mean[1];
        for j in 0..n {
            e.cov[0][j] += d * e.cov[1][j];
        }
        for i in 0..n {
            e.cov[i][0] += d * e.cov[i][1];
        }
        // The noise's share moves with the state and gains no process noise.
        for j in 0..n {
            e.noise[0][j] += d * e.noise[1][j];
        }
        for i in 0..n {
            e.noise[i][0] += d * e.noise[i][1];
        }
        e.cov[0][0] += q / 3.0;
        e.cov[0][1] += d * q / 2.0;
        e.cov[1][0] += d * q / 2.0;
        e.cov[1][1] += q;
        for i in 2..n {
            e.cov[i][i] += self.q_ripple_nm2;
        }
        e
    }

    /// The state filtered with the last sample.
    pub fn filtered(&self) -> RippleTorqueEstimate {
        self.state
    }

    /// Takes sample `y_nm` with the orders' phasors `(cos ψ_j, sin ψ_j)` (missing or
    /// non-finite ones count as 0); `cut`: a step is known to lie just before it. A non-finite `y_nm`
    /// is a time update only. Returns whether the filter restarted here.
    pub fn push(&mut self, y_nm: f64, phasors: &[[f64; 2]], cut: bool) -> bool {
        let n = self.state.n;
        if self.state.informative {
            self.state = self.predicted();
        }
        if !y_nm.is_finite() {
            return false;
        }
        let mut h = [0.0; MAX_N];
        h[0] = 1.0;
        // A phasor that is not finite (no angle at this sample) leaves its order unseen.
        for (j, p) in phasors.iter().take((n - 2) / 2).enumerate().filter(|(_, p)| p.iter().all(|v| v.is_finite())) {
            h[2 + 2 * j] = p[0];
            h[3 + 2 * j] = p[1];
        }
        let s = &mut self.state;
        let ph: Vec<f64> = (0..n).map(|i| (0..n).map(|j| s.cov[i][j] * h[j]).sum()).collect();
        let innovation_var = (0..n).map(|i| h[i] * ph[i]).sum::<f64>() + self.r_nm2;
        let e = y_nm - (0..n).map(|i| h[i] * s.mean[i]).sum::<f64>();
        let bad = !(innovation_var.is_finite() && innovation_var > 0.0);
        let restart = !s.informative || cut || bad || e * e / innovation_var > self.step_nis;
        if restart {
            let was = s.informative;
            if !was || bad {
                *s = RippleTorqueEstimate::none(n);
                for i in 2..n {
                    s.cov[i][i] = RIPPLE_PRIOR_NM2;
                }
            }
            // Level and rate start again; what is known of the ripple stays. The level
            // `y − h_r ẑ_r` carries this sample's noise and the ripple's noise share; the
            // rate's prior error is not noise.
            let ripple: f64 = (2..n).map(|i| h[i] * s.mean[i]).sum();
            let hn: Vec<f64> = (0..n).map(|j| (2..n).map(|i| h[i] * s.noise[i][j]).sum()).collect();
            let hnh: f64 = (2..n).map(|j| hn[j] * h[j]).sum();
            s.mean[0] = y_nm - ripple;
            s.mean[1] = 0.0;
            for i in 0..n {
                for j in 0..2 {
                    s.cov[i][j] = 0.0;
                    s.cov[j][i] = 0.0;
                    s.noise[i][j] = 0.0;
                    s.noise[j][i] = 0.0;
                }
            }
            s.cov[0][0] = self.r_nm2;
            s.cov[1][1] = RATE_PRIOR_NM2;
            s.noise[0][0] = self.r_nm2 + hnh;
            for j in 2..n {
                s.noise[0][j] = -hn[j];
                s.noise[j][0] = -hn[j];
            }
            s.informative = true;
            return was;
        }
        for i in 0..n {
            s.mean[i] += ph[i] * e / innovation_var;
        }
        for i in 0..n {
            for j in 0..n {
                s.cov[i][j] -= ph[i] * ph[j] / innovation_var;
            }
        }
        // The noise's share through the same gain `K = P hᵀ / S` (Joseph form):
        // N ← (I − K h) N (I − K h)ᵀ + K r Kᵀ.
        let k: Vec<f64> = ph.iter().map(|p| p / innovation_var).collect();
        let hn: Vec<f64> = (0..n).map(|j| (0..n).map(|i| h[i] * s.noise[i][j]).sum()).collect();
        let mut an = s.noise;
        for i in 0..n {
            for j in 0..n {
                an[i][j] -= k[i] * hn[j];
            }
        }
        let anh: Vec<f64> = (0..n).map(|i| (0..n).map(|j| an[i][j] * h[j]).sum()).collect();
        for i in 0..n {
            for j in i..n {
                // Symmetric up to rounding: kept exactly so.
                let v = 0.5 * (an[i][j] - anh[i] * k[j] + an[j][i] - anh[j] * k[i]) + self.r_nm2 * k[i] * k[j];
                s.noise[i][j] = v;
                s.noise[j][i] = v;
            }
        }
        false
    }
}

/// The multiples of the relative angle whose residual ripple the smoothed torque models:
/// the canceller's relative-angle orders (each multiple once, at most
/// [`MAX_RIPPLE_ORDERS`]) whose line, at the recording's mean relative speed
/// `mean_speed_rad_s`, lies above [`RESIDUAL_LINE_FRACTION`] of the torque's bandwidth.
/// A line well inside that band cannot be told from the torque within one recording:
/// modelling it would only widen the band.
/// None when the model is fed velocities (no phase to use).
pub fn residual_orders<const M: usize>(
    model: &strainwave_core::ripple::RippleModel<f64, M>,
    mean_speed_rad_s: f64,
) -> Vec<f64> {
    use strainwave_core::ripple::{PhaseSource, Reference};
    let mut out: Vec<f64> = Vec::new();
    if model.phase_source() != PhaseSource::Angle {
        return out;
    }
    for o in model.orders() {
        let n = o.multiple();
        let line_hz = n * mean_speed_rad_s.abs() / std::f64::consts::TAU;
        let above = line_hz > RESIDUAL_LINE_FRACTION * SMOOTHED_TORQUE_BANDWIDTH_HZ;
        if o.reference() == Reference::Relative && above && !out.contains(&n) && out.len() < MAX_RIPPLE_ORDERS {
            out.push(n);
        }
    }
    out
}

/// The mean of `|Δφ|` per second over a run of angles (wrapped or not), for
/// [`residual_orders`]; keeps only its sums, so it rides on a streaming pass.
#[derive(Debug, Clone, Copy, Default)]
pub struct MeanSpeed {
    last_rad: Option<f64>,
    sum_rad: f64,
    steps: u64,
}

impl MeanSpeed {
    /// Takes the next angle (non-finite ones are skipped).
    pub fn push(&mut self, angle_rad: f64) {
        if !angle_rad.is_finite() {
            return;
        }
        if let Some(last) = self.last_rad {
            let d = (angle_rad - last + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
            self.sum_rad += d.abs();
            self.steps += 1;
        }
        self.last_rad = Some(angle_rad);
    }

    /// The mean speed at `sample_rate_hz`, rad/s (0 before two angles).
    pub fn rad_per_s(&self, sample_rate_hz: f64) -> f64 {
        if self.steps == 0 {
            0.0
        } else {
            self.sum_rad / self.steps as f64 * sample_rate_hz
        }
    }
}

/// Smooths a whole series in memory with the (forward, backward) filters: per sample the
/// smoothed level and its standard deviation. `phasors[k]`: the orders' phasors at `k`;
/// `cuts[k]`: a known step just before sample `k`.
pub fn smooth_torque_with_ripple(
    y_nm: &[f64],
    phasors: &[Vec<[f64; 2]>],
    cuts: &[bool],
    (mut fwd, mut back): (RippleTorqueTrack, RippleTorqueTrack),
) -> Vec<(f64, f64)> {
    let n = y_nm.len();
    let cut = |k: usize| cuts.get(k).copied().unwrap_or(false);
    let ph = |k: usize| phasors.get(k).map_or(&[][..], |v| v.as_slice());
    let mut predicted = vec![RippleTorqueEstimate::none(fwd.state_len()); n];
    for k in (0..n).rev() {
        let p = back.predicted();
        if !back.push(y_nm[k], ph(k), cut(k + 1)) {
            predicted[k] = p;
        }
    }
    (0..n)
        .map(|k| {
            fwd.push(y_nm[k], ph(k), cut(k));
            fwd.filtered().combine(predicted[k]).map_or((y_nm[k], f64::NAN), |e| (e.level_nm(), e.level_sd_nm()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::torque::tests::{gaussians, rms};
    use super::super::torque::{smooth_torque, TorqueTrack};
    use super::*;

    /// A load with steps and a slow sine, white noise, and a residual 4× ripple of
    /// 0.03 N·m at 100 Hz whose amplitude drifts.
    fn series(n: usize) -> (Vec<f64>, Vec<f64>, Vec<Vec<[f64; 2]>>) {
        let mut g = gaussians(21);
        let (mut y, mut truth, mut ph) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..n {
            let t = k as f64 / 1000.0;
            let tau = 3.0 * (std::f64::consts::TAU * 0.7 * t).sin() + if k >= n / 2 { 1.0 } else { 0.0 };
            let phi = std::f64::consts::TAU * 25.0 * t;
            let amp = 0.03 * (1.0 + 0.3 * (0.5 * t).sin());
            truth.push(tau);
            y.push(tau + amp * (4.0 * phi + 0.4).cos() + 0.0162 * g());
            ph.push(vec![[(2.0 * phi).cos(), (2.0 * phi).sin()], [(4.0 * phi).cos(), (4.0 * phi).sin()]]);
        }
        (y, truth, ph)
    }

    #[test]
    fn without_orders_it_is_the_level_and_rate_smoother() {
        let (y, _, _) = series(3000);
        let noise = 0.0162;
        let a = smooth_torque(&y, &[], TorqueTrack::pair(noise, 1000.0));
        let b = smooth_torque_with_ripple(&y, &[], &[], RippleTorqueTrack::pair(0, noise, 1000.0));
        for (p, q) in a.iter().zip(&b) {
            // The same up to rounding (the information form inverts a 2 × 2 of condition 10¹⁰);
            // the band is the noise's share of the model's σ.
            assert!((p.0 - q.0).abs() < 1e-7 && q.1 <= p.1 + 1e-9, "{p:?} vs {q:?}");
        }
    }

    /// The band is the spread the noise alone gives the smoothed level: fed white noise
    /// only (a zero torque), the level's spread over many draws matches it.
    #[test]
    fn the_band_is_the_noise_share() {
        let (n, draws, sigma) = (1500, 200, 0.0162);
        let (_, _, ph) = series(n);
        let mut g = gaussians(5);
        let mut sum2 = vec![0.0; n];
        let mut band = Vec::new();
        for _ in 0..draws {
            let y: Vec<f64> = (0..n).map(|_| sigma * g()).collect();
            let out = smooth_torque_with_ripple(&y, &ph, &[], RippleTorqueTrack::pair(2, sigma, 1000.0));
            for (s2, o) in sum2.iter_mut().zip(&out) {
                *s2 += o.0 * o.0 / draws as f64;
            }
            band = out.iter().map(|o| o.1).collect();
        }
        // Per sample within 40 % in variance (200 draws: 10 % sampling error at 1σ, the
        // worst of 900 samples) away from the ends; averaged over the middle within 3 %.
        let mid = 300..n - 300;
        for k in mid.clone() {
            assert!((sum2[k] / band[k].powi(2) - 1.0).abs() < 0.4, "sample {k}: {} vs {}", sum2[k].sqrt(), band[k]);
        }
        let ratio = mid.clone().map(|k| sum2[k] / band[k].powi(2)).sum::<f64>() / mid.len() as f64;
        assert!((ratio - 1.0).abs() < 0.03, "{ratio}");
    }

    /// The residual ripple is removed, the band stays honest, the step stays sharp.
    #[test]
    fn residual_ripple_is_removed_and_counted() {
        let (y, truth, ph) = series(8000);
        let noise = 0.0162;
        let plain = smooth_torque(&y, &[], TorqueTrack::pair(noise, 1000.0));
        let with = smooth_torque_with_ripple(&y, &ph, &[], RippleTorqueTrack::pair(2, noise, 1000.0));
        let plain_band = smooth_torque_with_ripple(&y, &[], &[], RippleTorqueTrack::pair(0, noise, 1000.0));
        let err = |o: &[(f64, f64)]| rms((1000..8000).map(|k| o[k].0 - truth[k]));
        let cover =
            |o: &[(f64, f64)]| (1000..8000).filter(|&k| (o[k].0 - truth[k]).abs() <= o[k].1).count() as f64 / 7000.0;
        let (e0, e1) = (err(&plain), err(&with));
        assert!(e1 < 0.5 * 0.0162 && e1 < 0.8 * e0, "with orders {e1} vs without {e0}");
        // Without the orders the ripple it does not count makes the band too narrow.
        let (c0, c1) = (cover(&plain_band), cover(&with));
        assert!((0.63..=0.73).contains(&c1) && c1 > c0 + 0.05, "coverage with orders {c1}, without {c0}");
        for k in 3990..4000 {
            assert!((with[k].0 - truth[k]).abs() < 0.05, "sample {k}: {:?} vs {}", with[k], truth[k]);
        }
        for k in 4000..4010 {
            assert!((with[k].0 - truth[k]).abs() < 0.05, "sample {k}: {:?} vs {}", with[k], truth[k]);
        }
    }

    #[test]
    fn only_lines_above_the_torque_band_are_modelled() {
        let model = strainwave_core::ripple::RippleModel::<f64, 5>::full(1000.0, 0.0162).unwrap();
        let mut speed = MeanSpeed::default();
        for k in 0..1000 {
            speed.push((0.157 * k as f64).rem_euclid(std::f64::consts::TAU));
        }
        let w = speed.rad_per_s(1000.0);
        assert!((w - 157.0).abs() < 1e-6, "{w}");
        // 157 rad/s: 2× at 50 Hz, 4× at 100 Hz, both above 30 Hz; at 60 rad/s the 2× line
        // is at 19 Hz, inside the band, and the 4× at 38 Hz.
        assert_eq!(residual_orders(&model, w), vec![2.0, 4.0]);
        assert_eq!(residual_orders(&model, 60.0), vec![4.0]);
        assert_eq!(residual_orders(&model, 40.0), Vec::<f64>::new());
    }

    #[test]
    fn estimates_round_trip_through_values_and_bad_ones_are_refused() {
        let (y, _, ph) = series(500);
        let mut t = RippleTorqueTrack::pair(2, 1e-2, 1000.0).0;
        for (v, p) in y.iter().zip(&ph) {
            t.push(*v, p, false);
        }
        let e = t.predicted();
        let mut v = Vec::new();
        e.to_values(&mut v);
        assert_eq!(v.len(), RippleTorqueEstimate::values_len(6));
        assert_eq!(RippleTorqueEstimate::from_values(6, &v), Some(e));
        assert_eq!(RippleTorqueEstimate::from_values(6, &v[..5]), None);
        let none = RippleTorqueEstimate::none(6);
        assert_eq!(none.combine(none), None);
        assert_eq!(e.combine(none), Some(e));
    }
}
