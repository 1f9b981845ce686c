//! Causal denoised torque: the canceller's clean torque filtered as a torque state, for
//! real-time users who trade a known delay for less white noise.
//!
//! The torque is taken as a random walk seen in white noise; the steady-state Kalman
//! filter of that model is a first-order low-pass whose gain `α` sets the bandwidth:
//!
//! ```text
//! T̃(k) = T̃(k−1) + α [T(k) − T̃(k−1)],     α = 1 − exp(−2π f_c / fs)
//! H(z) = α / (1 − (1 − α) z⁻¹),           group delay at DC  τ = (1 − α) / (α fs)
//! ```
//!
//! (`τ ≈ 1 / (2π f_c)` when `f_c ≪ fs`.) A load step the canceller detected restarts the
//! state at the sample, so steps pass without the low-pass's delay; a sample whose
//! measurement the canceller skipped, or a non-finite torque, leaves the state as it is.
//!
//! ```
//! use strainwave_core::denoise::TorqueDenoiser;
//! use strainwave_core::ripple::StepFlags;
//! let mut d = TorqueDenoiser::<f64>::new(10.0, 1000.0)?;
//! let out = d.step(2.0, StepFlags::empty());
//! assert_eq!(out, 2.0); // the first sample starts the state
//! assert!((d.group_delay_s() - 0.0154).abs() < 1e-3);
//! # Ok::<(), strainwave_core::Error>(())
//! ```

use crate::error::{positive, Error};
use crate::ripple::StepFlags;
use crate::Real;

/// First-order torque-state filter of a set bandwidth (see the module).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueDenoiser<T: Real> {
    alpha: T,
    sample_rate_hz: T,
    state_nm: Option<T>,
}

impl<T: Real> TorqueDenoiser<T> {
    /// A filter of bandwidth `bandwidth_hz` (−3 dB, positive, below `0.45 fs`, not so
    /// small that the gain rounds to 0) at `sample_rate_hz`.
    pub fn new(bandwidth_hz: T, sample_rate_hz: T) -> Result<Self, Error> {
        let fs = positive(sample_rate_hz, "sample_rate_hz")?;
        let fc = positive(bandwidth_hz, "torque_bandwidth_hz")?;
        if fc > T::from_f64(0.45) * fs {
            return Err(Error::OutOfRange("torque_bandwidth_hz"));
        }
        let alpha = T::ONE - (-(T::TAU * fc / fs)).exp();
        // So small a bandwidth that the gain rounds to 0 would never move.
        if alpha <= T::ZERO {
            return Err(Error::OutOfRange("torque_bandwidth_hz"));
        }
        Ok(Self { alpha, sample_rate_hz: fs, state_nm: None })
    }

    /// The gain `α` per sample.
    pub fn gain(&self) -> T {
        self.alpha
    }

    /// Group delay at DC, `(1 − α) / (α fs)`, s.
    pub fn group_delay_s(&self) -> T {
        (T::ONE - self.alpha) / (self.alpha * self.sample_rate_hz)
    }

    /// Filters one sample of clean torque `torque_nm` with the canceller's `flags`: a
    /// load step restarts the state there; a skipped measurement or a non-finite torque
    /// returns the state unchanged (NaN before the first finite sample).
    pub fn step(&mut self, torque_nm: T, flags: StepFlags) -> T {
        let load_step = flags.contains(StepFlags::LOAD_STEP);
        if !torque_nm.is_finite() || flags.contains(StepFlags::MEASUREMENT_SKIPPED) {
            return self.state_nm.unwrap_or(T::from_f64(f64::NAN));
        }
        let next = match self.state_nm {
            Some(s) if !load_step => s + self.alpha * (torque_nm - s),
            _ => torque_nm,
        };
        self.state_nm = Some(next);
        next
    }

    /// Forgets the state (the next sample starts it again).
    pub fn reset(&mut self) {
        self.state_nm = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_ramp_lags_by_the_stated_group_delay() {
        let fs = 1000.0;
        let mut d = TorqueDenoiser::<f64>::new(20.0, fs).unwrap();
        // A ramp of slope s is followed with a steady lag of s·τ.
        let slope_nm_per_s = 3.0;
        let mut out = 0.0;
        let n = 5000;
        for k in 0..n {
            out = d.step(slope_nm_per_s * k as f64 / fs, StepFlags::empty());
        }
        let truth = slope_nm_per_s * (n - 1) as f64 / fs;
        let lag_s = (truth - out) / slope_nm_per_s;
        assert!((lag_s - d.group_delay_s()).abs() < 1e-9, "lag {lag_s} vs τ {}", d.group_delay_s());
        assert!(
            (d.group_delay_s() - 1.0 / (std::f64::consts::TAU * 20.0)).abs() < 0.1 / (std::f64::consts::TAU * 20.0)
        );
    }

    #[test]
    fn white_noise_is_reduced_as_the_bandwidth_says_and_steps_restart() {
        let fs = 1000.0;
        let mut d = TorqueDenoiser::<f64>::new(10.0, fs).unwrap();
        let mut seed = 7u64;
        let mut noise = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
        };
        let (mut sum, n) = (0.0, 200_000);
        for k in 0..n {
            let y = d.step(5.0 + noise(), StepFlags::empty());
            if k > 1000 {
                sum += (y - 5.0) * (y - 5.0);
            }
        }
        // Variance ratio of a first-order low-pass to white noise: α / (2 − α).
        let a = d.gain();
        let ratio = (sum / (n - 1001) as f64).sqrt() / (a / (2.0 - a)).sqrt();
        assert!((ratio - 1.0).abs() < 0.05, "noise ratio {ratio}");
        // A flagged step is taken at once; a NaN keeps the state.
        assert_eq!(d.step(12.0, StepFlags::LOAD_STEP), 12.0);
        assert_eq!(d.step(f64::NAN, StepFlags::empty()), 12.0);
        // So does a measurement the canceller skipped (an overrange code passes through).
        assert_eq!(d.step(9.9e37, StepFlags::MEASUREMENT_SKIPPED), 12.0);
    }

    #[test]
    fn bad_bandwidths_are_refused() {
        assert_eq!(TorqueDenoiser::<f32>::new(0.0, 1000.0), Err(Error::NonPositive("torque_bandwidth_hz")));
        assert_eq!(TorqueDenoiser::<f32>::new(f32::NAN, 1000.0), Err(Error::NonPositive("torque_bandwidth_hz")));
        assert_eq!(TorqueDenoiser::<f32>::new(460.0, 1000.0), Err(Error::OutOfRange("torque_bandwidth_hz")));
        assert!(TorqueDenoiser::<f32>::new(10.0, 0.0).is_err());
        assert_eq!(TorqueDenoiser::<f32>::new(1e-30, 1000.0), Err(Error::OutOfRange("torque_bandwidth_hz")));
        let mut d = TorqueDenoiser::<f32>::new(10.0, 1000.0).unwrap();
        assert!(d.step(f32::NAN, StepFlags::empty()).is_nan());
        d.step(1.0, StepFlags::empty());
        d.reset();
        assert_eq!(d.step(3.0, StepFlags::empty()), 3.0);
    }
}
