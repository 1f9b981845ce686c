//! From a tracking bandwidth in Hz to process noise, and back: the canceller's oscillators
//! and random walks (`ripple::tuning` is this module too).
//!
//! An oscillator's steady-state prediction filter is a resonator with unit gain at its
//! line; its −3 dB half-width `B` sets `δ = 2π B / fs`, `p = 2 R δ / (1 − 2δ)` and
//! `q = p² / (2 (R + p))` (≈ 2 R δ²), `q_rad = q / |a|`. A random walk's `q = R K² / (1 − K)`
//! for the gain `K` of its −3 dB point. The derivation is in `docs/physics.md` (section
//! 4, "Tuning by bandwidth"); [`oscillator_q_calibrated`] solves the exact steady state.
//!
//! All computations run in f64 whatever `T`.

use crate::error::{positive, Error};
use crate::Real;

fn omega(bandwidth_hz: f64, sample_rate_hz: f64) -> Result<f64, Error> {
    if bandwidth_hz >= 0.5 * sample_rate_hz {
        return Err(Error::OutOfRange("bandwidth_hz"));
    }
    Ok(core::f64::consts::TAU * bandwidth_hz / sample_rate_hz)
}

fn pos<T: Real>(x: T, name: &'static str) -> Result<f64, Error> {
    Ok(positive(x, name)?.to_f64())
}

fn check3<T: Real>(a: T, an: &'static str, fs: T, r: T) -> Result<(f64, f64, f64), Error> {
    Ok((pos(a, an)?, pos(fs, "sample_rate_hz")?, pos(r, "r_nm2")?))
}

/// Per-sample oscillator noise for a −3 dB half-width `B` of the resonator, N·m²
/// (`q = p² / (2 (R + p))`, `p = 2 R δ / (1 − 2δ)`, `δ = 2π B / fs`; ≈ `2 R δ²`).
///
/// ```
/// use strainwave_core::tuning::{oscillator_bandwidth_hz, oscillator_q};
/// let q = oscillator_q(3.48_f64, 1000.0, 1.0).unwrap(); // ≈ the classic 1e-3 at R = 1
/// assert!((q - 1e-3).abs() < 1e-5);
/// assert!((oscillator_bandwidth_hz(q, 1000.0, 1.0).unwrap() - 3.48).abs() < 1e-9);
/// ```
pub fn oscillator_q<T: Real>(bandwidth_hz: T, sample_rate_hz: T, r_nm2: T) -> Result<T, Error> {
    let (b, fs, r) = check3(bandwidth_hz, "bandwidth_hz", sample_rate_hz, r_nm2)?;
    let d = omega(b, fs)?;
    if d >= 0.25 {
        return Err(Error::OutOfRange("bandwidth_hz"));
    }
    let p = 2.0 * r * d / (1.0 - 2.0 * d);
    Ok(T::from_f64(p * p / (2.0 * (r + p))))
}

/// Inverse of [`oscillator_q`]: `B = fs / 2π · p / (2 (R + p))`, `p = q + √(q² + 2qR)`, Hz.
pub fn oscillator_bandwidth_hz<T: Real>(q_nm2: T, sample_rate_hz: T, r_nm2: T) -> Result<T, Error> {
    let (q, fs, r) = check3(q_nm2, "q_nm2", sample_rate_hz, r_nm2)?;
    let p = q + libm::sqrt(q * q + 2.0 * q * r);
    Ok(T::from_f64(fs / core::f64::consts::TAU * p / (2.0 * (r + p))))
}

/// Per-radian noise giving per-sample noise `q_per_sample` when the line is at
/// `line_frequency_hz`: `q_rad = q / (2π f_line / fs)`. With it the bandwidth scales as
/// `√(f_line)`, and an oscillator at standstill receives no noise.
///
/// ```
/// use strainwave_core::tuning::per_radian;
/// let q_rad = per_radian(1e-3_f64, 50.0, 1000.0).unwrap();
/// assert!((q_rad * (std::f64::consts::TAU * 50.0 / 1000.0) - 1e-3).abs() < 1e-15);
/// ```
pub fn per_radian<T: Real>(q_per_sample_nm2: T, line_frequency_hz: T, sample_rate_hz: T) -> Result<T, Error> {
    let q = crate::error::non_negative(q_per_sample_nm2, "q_per_sample_nm2")?.to_f64();
    let f = pos(line_frequency_hz, "line_frequency_hz")?;
    let fs = pos(sample_rate_hz, "sample_rate_hz")?;
    Ok(T::from_f64(q * fs / (core::f64::consts::TAU * f)))
}

/// Exact bias random-walk noise for a first-order −3 dB bandwidth `B`, N·m² per sample.
///
/// ```
/// use strainwave_core::tuning::{random_walk_bandwidth_hz, random_walk_q};
/// let q = random_walk_q(5.0_f64, 1000.0, 0.01).unwrap();
/// assert!((random_walk_bandwidth_hz(q, 1000.0, 0.01).unwrap() - 5.0).abs() < 1e-9);
/// ```
pub fn random_walk_q<T: Real>(bandwidth_hz: T, sample_rate_hz: T, r_nm2: T) -> Result<T, Error> {
    let (b, fs, r) = check3(bandwidth_hz, "bandwidth_hz", sample_rate_hz, r_nm2)?;
    let w = omega(b, fs)?;
    let m = 4.0 - 2.0 * libm::cos(w);
    let rho = 0.5 * (m - libm::sqrt(m * m - 4.0));
    let k = 1.0 - rho;
    Ok(T::from_f64(r * k * k / rho))
}

/// Inverse of [`random_walk_q`], Hz.
pub fn random_walk_bandwidth_hz<T: Real>(q_nm2: T, sample_rate_hz: T, r_nm2: T) -> Result<T, Error> {
    let (q, fs, r) = check3(q_nm2, "q_nm2", sample_rate_hz, r_nm2)?;
    let p = 0.5 * (q + libm::sqrt(q * q + 4.0 * q * r));
    let rho = 1.0 - p / (p + r);
    let cos_w = (-1.0 + 4.0 * rho - rho * rho) / (2.0 * rho);
    if !(-1.0..=1.0).contains(&cos_w) {
        return Err(Error::OutOfRange("q_nm2"));
    }
    Ok(T::from_f64(libm::acos(cos_w) * fs / core::f64::consts::TAU))
}

/// Per-sample noise of an oscillator whose line is well inside the bandwidth of the bias
/// random walk (`q_bias`), so that it settles in about `revolutions` turns of its own
/// phase whatever the speed: `q = 2 q_b / (2π n)²`.
///
/// Derivation: below the bias bandwidth the bias is the oscillator's dominant
/// "measurement noise", with spectral density `S_b(a) = q_b / a²` at the line
/// (`a` rad/sample). The oscillator formula above with `R → S_b` gives the envelope decay
/// `δ = √(q / 2 S_b) = a √(q / 2 q_b)` per sample, i.e. `√(q / 2 q_b)` per radian of
/// the line's phase; `δ = 1 / (2π n)` per radian is `n` revolutions per e-fold. The ratio
/// `q / q_b` also sets how much of a slow load the oscillator mistakes for itself (about
/// `√(q / q_b)` of the load's rate of change per line radian), so slower is cleaner.
///
/// ```
/// use strainwave_core::tuning::slow_line_q;
/// let q = slow_line_q(5.0_f64, 6e-5).unwrap();
/// assert!((q - 2.0 * 6e-5 / (std::f64::consts::TAU * 5.0).powi(2)).abs() < 1e-18);
/// ```
pub fn slow_line_q<T: Real>(revolutions: T, q_bias_nm2: T) -> Result<T, Error> {
    let n = pos(revolutions, "revolutions")?;
    let qb = pos(q_bias_nm2, "q_bias_nm2")?;
    let w = core::f64::consts::TAU * n;
    Ok(T::from_f64(2.0 * qb / (w * w)))
}

/// Steady-state prediction gain `K = Φ P Cᵀ / (R + C P Cᵀ)` of one oscillator with
/// `Q = q I₂` whose line advances `a` rad per sample (Riccati iteration from the
/// approximate solution; bounded, `NoConvergence` if it does not settle).
fn steady_gain(q: f64, r: f64, a: f64) -> Result<[f64; 2], Error> {
    let (s, c) = (libm::sin(a), libm::cos(a));
    let p_guess = libm::sqrt(2.0 * q * r) + q;
    let mut p = [[p_guess, 0.0], [0.0, p_guess]];
    for _ in 0..2_000_000 {
        let den = r + p[0][0];
        // Φ P Φᵀ − (Φ P Cᵀ)(Φ P Cᵀ)ᵀ / den + Q with Φ = [[c, s], [−s, c]].
        let fp = [
            [c * p[0][0] + s * p[1][0], c * p[0][1] + s * p[1][1]],
            [-s * p[0][0] + c * p[1][0], -s * p[0][1] + c * p[1][1]],
        ];
        let fpf = [
            [fp[0][0] * c + fp[0][1] * s, -fp[0][0] * s + fp[0][1] * c],
            [fp[1][0] * c + fp[1][1] * s, -fp[1][0] * s + fp[1][1] * c],
        ];
        let k = [fp[0][0], fp[1][0]];
        let n00 = fpf[0][0] - k[0] * k[0] / den + q;
        let n01 = fpf[0][1] - k[0] * k[1] / den;
        let n11 = fpf[1][1] - k[1] * k[1] / den + q;
        let change = (n00 - p[0][0]).abs() + (n01 - p[0][1]).abs() + (n11 - p[1][1]).abs();
        p = [[n00, n01], [n01, n11]];
        if !(change.is_finite()) {
            return Err(Error::NoConvergence("oscillator riccati"));
        }
        if change <= 1e-13 * (n00 + n11) {
            let den = r + p[0][0];
            return Ok([(c * p[0][0] + s * p[1][0]) / den, (-s * p[0][0] + c * p[1][0]) / den]);
        }
    }
    Err(Error::NoConvergence("oscillator riccati"))
}

/// Steady-state closed-loop matrix `A = Φ − K C` of one oscillator.
fn closed_loop(q: f64, r: f64, a: f64) -> Result<[[f64; 2]; 2], Error> {
    let k = steady_gain(q, r, a)?;
    let (s, c) = (libm::sin(a), libm::cos(a));
    Ok([[c - k[0], s], [-s - k[1], c]])
}

/// Exact envelope decay `δ = 1 − |λ|` per sample of one oscillator's steady-state
/// filter (`λ` the closed-loop poles of `Φ − K C`, a complex pair), expressed as a
/// half-width in Hz: `B = δ fs / 2π`. `line_hz` is the line frequency.
///
/// ```
/// use strainwave_core::tuning::{oscillator_bandwidth_hz, oscillator_pole_bandwidth_hz};
/// let exact = oscillator_pole_bandwidth_hz(1e-3_f64, 1.0, 50.0, 1000.0).unwrap();
/// let approx = oscillator_bandwidth_hz(1e-3_f64, 1000.0, 1.0).unwrap();
/// assert!((exact / approx - 1.0).abs() < 0.02);
/// ```
pub fn oscillator_pole_bandwidth_hz<T: Real>(q_nm2: T, r_nm2: T, line_hz: T, sample_rate_hz: T) -> Result<T, Error> {
    let (q, r, fs) = (pos(q_nm2, "q_nm2")?, pos(r_nm2, "r_nm2")?, pos(sample_rate_hz, "sample_rate_hz")?);
    let a = omega(pos(line_hz, "line_hz")?, fs)?;
    let m = closed_loop(q, r, a)?;
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if det.is_nan() || det <= 0.0 {
        return Err(Error::OutOfRange("q_nm2"));
    }
    Ok(T::from_f64((1.0 - libm::sqrt(det)) * fs / core::f64::consts::TAU))
}

/// `|H(e^{iω})|` of the steady-state resonator `ŷ/y` of one oscillator with noise `q`
/// (per sample) and line `line_hz`, at frequency `f_hz`. At the line it is 1; its −3 dB
/// points sit about `B` either side (slightly asymmetric: the prediction form leads).
///
/// ```
/// use strainwave_core::tuning::{oscillator_q, oscillator_response};
/// let q = oscillator_q(2.0_f64, 1000.0, 1.0).unwrap();
/// let at_line = oscillator_response(q, 1.0, 100.0, 100.0, 1000.0).unwrap();
/// assert!((at_line - 1.0).abs() < 1e-6);
/// let at_edge = oscillator_response(q, 1.0, 100.0, 102.0, 1000.0).unwrap();
/// assert!((at_edge - 0.5f64.sqrt()).abs() < 0.05);
/// ```
pub fn oscillator_response<T: Real>(q_nm2: T, r_nm2: T, line_hz: T, f_hz: T, sample_rate_hz: T) -> Result<T, Error> {
    let (q, r, fs) = (pos(q_nm2, "q_nm2")?, pos(r_nm2, "r_nm2")?, pos(sample_rate_hz, "sample_rate_hz")?);
    let a = omega(pos(line_hz, "line_hz")?, fs)?;
    let f = crate::error::finite(f_hz, "f_hz")?.to_f64();
    let k = steady_gain(q, r, a)?;
    let m = closed_loop(q, r, a)?;
    // H(z) = C (zI − A)⁻¹ K = [(z − a11) k0 + a01 k1] / [(z − a00)(z − a11) − a01 a10].
    let w = core::f64::consts::TAU * f / fs;
    let z = (libm::cos(w), libm::sin(w));
    let num = ((z.0 - m[1][1]) * k[0] + m[0][1] * k[1], z.1 * k[0]);
    let d1 = (z.0 - m[0][0], z.1);
    let d2 = (z.0 - m[1][1], z.1);
    let den = (d1.0 * d2.0 - d1.1 * d2.1 - m[0][1] * m[1][0], d1.0 * d2.1 + d1.1 * d2.0);
    let mag = libm::sqrt((num.0 * num.0 + num.1 * num.1) / (den.0 * den.0 + den.1 * den.1));
    Ok(T::from_f64(mag))
}

/// Per-sample oscillator noise whose exact steady-state filter at `line_hz` has the
/// envelope half-width `bandwidth_hz` of [`oscillator_pole_bandwidth_hz`] (bisection on
/// `log q`, 80 steps). Use near 0 Hz or `fs/2`, or for wide bandwidths, where the
/// closed form of [`oscillator_q`] drifts.
///
/// ```
/// use strainwave_core::tuning::{oscillator_pole_bandwidth_hz, oscillator_q_calibrated};
/// let q = oscillator_q_calibrated(2.0_f64, 20.0, 1000.0, 1.0).unwrap();
/// let b = oscillator_pole_bandwidth_hz(q, 1.0, 20.0, 1000.0).unwrap();
/// assert!((b - 2.0).abs() < 1e-6);
/// ```
pub fn oscillator_q_calibrated<T: Real>(bandwidth_hz: T, line_hz: T, sample_rate_hz: T, r_nm2: T) -> Result<T, Error> {
    let (b, fs, r) = check3(bandwidth_hz, "bandwidth_hz", sample_rate_hz, r_nm2)?;
    let line = pos(line_hz, "line_hz")?;
    let guess = oscillator_q(b, fs, r)?;
    let (mut lo, mut hi) = (libm::log(guess) - 6.0, libm::log(guess) + 6.0);
    let bw = |lq: f64| oscillator_pole_bandwidth_hz(libm::exp(lq), r, line, fs);
    if bw(lo)? > b || bw(hi)? < b {
        return Err(Error::OutOfRange("bandwidth_hz"));
    }
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if bw(mid)? < b {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(T::from_f64(libm::exp(0.5 * (lo + hi))))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQRT_HALF: f64 = core::f64::consts::FRAC_1_SQRT_2;
    /// The closed form's bandwidth is within this relative error of the exact pole's.
    const POLE_TOL: f64 = 0.03;
    /// The mean of the two −3 dB offsets is within this relative error of `B`.
    const MINUS_3DB_TOL: f64 = 0.06;

    /// Offset from the line where `|H|` first drops below 1/√2, scanning in `dir`.
    fn edge(q: f64, r: f64, line: f64, b: f64, dir: f64) -> f64 {
        let n = 4000;
        for k in 1..=n {
            let off = 4.0 * b * k as f64 / n as f64;
            if oscillator_response(q, r, line, line + dir * off, 1000.0).unwrap() < SQRT_HALF {
                return off;
            }
        }
        f64::INFINITY
    }

    #[test]
    fn closed_form_matches_exact_pole_and_minus_3db() {
        let fs = 1000.0;
        for &(line, b) in &[(20.0, 0.5), (50.0, 2.0), (100.0, 5.0), (250.0, 1.0), (400.0, 3.0)] {
            let r = 0.01;
            let q = oscillator_q(b, fs, r).unwrap();
            let pole = oscillator_pole_bandwidth_hz(q, r, line, fs).unwrap();
            assert!((pole / b - 1.0).abs() < POLE_TOL, "line {line} B {b}: pole {pole}");
            let half = 0.5 * (edge(q, r, line, b, 1.0) + edge(q, r, line, b, -1.0));
            assert!((half / b - 1.0).abs() < MINUS_3DB_TOL, "line {line} B {b}: {half}");
            let far = oscillator_response(q, r, line, line + 10.0 * b, fs).unwrap();
            assert!(far < 0.15, "line {line} B {b}: {far}");
        }
    }

    #[test]
    fn classic_noise_is_about_3_5_hz_at_1_khz() {
        let b = oscillator_bandwidth_hz(1e-3, 1000.0, 1.0).unwrap();
        assert!((b - 3.480).abs() < 1e-3, "{b}");
        // 156 rad/s motor speed (the classic test bench), 2× line at 312 rad/s.
        let line = 312.0 / core::f64::consts::TAU;
        let q = oscillator_q_calibrated(b, line, 1000.0, 1.0).unwrap();
        assert!((q / 1e-3 - 1.0).abs() < 0.03, "{q}");
    }

    #[test]
    fn random_walk_round_trip() {
        for &b in &[0.1, 5.0, 50.0, 200.0] {
            let q = random_walk_q(b, 1000.0, 0.5).unwrap();
            let back = random_walk_bandwidth_hz(q, 1000.0, 0.5).unwrap();
            assert!((back - b).abs() < 1e-9 * b.max(1.0), "{b} → {back}");
        }
    }

    #[test]
    fn rejects_bad_arguments() {
        assert_eq!(oscillator_q(600.0, 1000.0, 1.0), Err(Error::OutOfRange("bandwidth_hz")));
        assert_eq!(oscillator_q(1.0, 0.0, 1.0), Err(Error::NonPositive("sample_rate_hz")));
        assert_eq!(random_walk_q(1.0, 1000.0, f64::NAN), Err(Error::NonPositive("r_nm2")));
        assert!(oscillator_response(1e-3, 1.0, 100.0, f64::INFINITY, 1000.0).is_err());
    }

    #[test]
    fn f32_goes_through_f64() {
        let q = oscillator_q(2.0_f32, 1000.0, 1.0).unwrap();
        assert!((q as f64 - oscillator_q(2.0_f64, 1000.0, 1.0).unwrap()).abs() < 1e-9);
    }
}
