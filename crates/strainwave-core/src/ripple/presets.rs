//! Ready-made models: the seed's 4th- and 6th-order filters and the product default.

use super::model::{Limits, Order, Reference, RippleModel};
use super::tuning::{oscillator_q, per_radian, random_walk_q, slow_line_q};
use crate::error::{positive, Error};
use crate::Real;

/// The seed's noise: `Q = 10⁻³ I` per sample, `R = 1` (N·m², seed 000 §V at 1 kHz).
const SEED_Q_NM2: f64 = 1e-3;

/// Product tuning, documented in [`RippleModel::product`].
const RIPPLE_BANDWIDTH_HZ: f64 = 1.0;
const RIPPLE_AT_LINE_HZ: f64 = 20.0;
const MISALIGNMENT_REVOLUTIONS: f64 = 5.0;
const BIAS_BANDWIDTH_HZ: f64 = 25.0;
const OSCILLATOR_P0_NM2: f64 = 1.0;
const BIAS_P0_NM2: f64 = 1e4;

fn seed_order<T: Real>(reference: Reference, multiple: f64) -> Result<Order<T>, Error> {
    Order::new(reference, T::from_f64(multiple))?.with_noise(T::from_f64(SEED_Q_NM2), T::ZERO)
}

fn seed_limits<T: Real>() -> Limits<T> {
    Limits { hold_below_hz: T::ZERO, ..Limits::default() }
}

impl<T: Real> RippleModel<T, 2> {
    /// Seed 000's 4th-order model: 2× and 4× of the reference angle, `Q = 10⁻³ I` per
    /// sample, `R = 1`, no bias state, no hold (the seed's behaviour). The seed fed the
    /// motor angle; the product feeds the relative angle `φ` (SPEC §1) as `relative`.
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap();
    /// assert_eq!((m.state_len(), m.r_nm2()), (4, 1.0));
    /// ```
    pub fn seed_4th_order(sample_rate_hz: T) -> Result<Self, Error> {
        let orders = [seed_order(Reference::Relative, 2.0)?, seed_order(Reference::Relative, 4.0)?];
        RippleModel::new(orders, T::ONE, sample_rate_hz)?.with_limits(seed_limits())
    }
}

impl<T: Real> RippleModel<T, 3> {
    /// Seed 000's 6th-order model: the 4th-order one plus misalignment at 1× the output
    /// angle, same noise.
    ///
    /// ```
    /// use strainwave_core::ripple::{Reference, RippleModel};
    /// let m = RippleModel::<f32, 3>::seed_6th_order(1000.0).unwrap();
    /// assert_eq!(m.orders()[2].reference(), Reference::Output);
    /// ```
    pub fn seed_6th_order(sample_rate_hz: T) -> Result<Self, Error> {
        let orders = [
            seed_order(Reference::Relative, 2.0)?,
            seed_order(Reference::Relative, 4.0)?,
            seed_order(Reference::Output, 1.0)?,
        ];
        RippleModel::new(orders, T::ONE, sample_rate_hz)?.with_limits(seed_limits())
    }

    /// The product configuration: 2× and 4× relative-angle ripple, 1× output
    /// misalignment and a torque/bias random walk, measurement noise `noise_nm` (1σ).
    ///
    /// - bias: random walk with a 25 Hz first-order bandwidth. It is the sink for load
    ///   (steps, friction, slow sinusoids); with the load-step detector of [`Limits`]
    ///   steps go to it in one sample. Its estimate is seed 001's torque output.
    /// - ripple orders: noise per radian of phase, 1 Hz −3 dB half-width when the line
    ///   is at 20 Hz (`1 Hz · √(f_line / 20 Hz)` at other speeds, none at standstill),
    ///   fast enough to follow ripple amplitude that grows with load;
    /// - misalignment: per-sample noise from [`tuning::slow_line_q`](super::tuning::slow_line_q)
    ///   for ≈ 5 output revolutions per e-fold at any speed: its line sits far inside
    ///   the bias bandwidth, where this keeps load from leaking into it;
    /// - initial variances 1 N·m² (oscillator components) and 10⁴ N·m² (bias);
    /// - default [`Limits`]: orders held below 0.05 Hz, off above 0.45 fs, load steps
    ///   beyond NIS 25.
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f32, 3>::product(1000.0, 0.05).unwrap();
    /// assert_eq!(m.state_len(), 7);
    /// assert!(RippleModel::<f32, 3>::product(1000.0, 0.0).is_err());
    /// ```
    pub fn product(sample_rate_hz: T, noise_nm: T) -> Result<Self, Error> {
        let fs = positive(sample_rate_hz, "sample_rate_hz")?;
        let r = positive(noise_nm, "noise_nm")? * noise_nm;
        let c = T::from_f64;
        let ripple_q = per_radian(oscillator_q(c(RIPPLE_BANDWIDTH_HZ), fs, r)?, c(RIPPLE_AT_LINE_HZ), fs)?;
        let bias_q = random_walk_q(c(BIAS_BANDWIDTH_HZ), fs, r)?;
        let mis_q = slow_line_q(c(MISALIGNMENT_REVOLUTIONS), bias_q)?;
        let orders = [
            Order::new(Reference::Relative, c(2.0))?.with_noise(T::ZERO, ripple_q)?,
            Order::new(Reference::Relative, c(4.0))?.with_noise(T::ZERO, ripple_q)?,
            Order::new(Reference::Output, T::ONE)?.with_noise(mis_q, T::ZERO)?,
        ];
        RippleModel::new(orders, r, fs)?
            .with_bias_state(bias_q)?
            .with_initial_variance(c(OSCILLATOR_P0_NM2), c(BIAS_P0_NM2))
    }
}
