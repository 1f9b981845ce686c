//! Ready-made models: the classic 4th- and 6th-order filters of Taghirad and Bélanger, "Intelligent built-in torque sensor for harmonic drive systems" (1999),
//! and the product defaults.

use super::model::{Limits, Order, Reference, RippleModel};
use crate::error::{positive, Error};
use crate::tuning::{oscillator_q, per_radian, random_walk_q, slow_line_q};
use crate::Real;

/// The classic noise: `Q = 10⁻³ I` per sample, `R = 1` (N·m², at 1 kHz).
const CLASSIC_Q_NM2: f64 = 1e-3;

/// Product tuning, documented in [`RippleModel::product`].
const RIPPLE_BANDWIDTH_HZ: f64 = 1.0;
const RIPPLE_AT_LINE_HZ: f64 = 20.0;
const MISALIGNMENT_REVOLUTIONS: f64 = 5.0;
const BIAS_BANDWIDTH_HZ: f64 = 25.0;
const OSCILLATOR_P0_NM2: f64 = 1.0;
const BIAS_P0_NM2: f64 = 1e4;

fn classic_order<T: Real>(reference: Reference, multiple: f64) -> Result<Order<T>, Error> {
    Order::new(reference, T::from_f64(multiple))?.with_noise(T::from_f64(CLASSIC_Q_NM2), T::ZERO)
}

fn classic_limits<T: Real>() -> Limits<T> {
    Limits { hold_below_hz: T::ZERO, ..Limits::default() }
}

impl<T: Real> RippleModel<T, 2> {
    /// The classic 4th-order model (Taghirad and Bélanger, 1999): 2× and 4× of the
    /// reference angle, `Q = 10⁻³ I` per sample, `R = 1` (noise 1 N·m), no bias state, no hold (as
    /// published). The paper fed the motor angle; here it is the relative angle
    /// `φ = θ_wg − θ_fs` (wave generator minus flexspline) as `relative`.
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
    /// assert_eq!((m.state_len(), m.noise_nm()), (4, 1.0));
    /// ```
    pub fn taghirad_4th_order(sample_rate_hz: T) -> Result<Self, Error> {
        let orders = [classic_order(Reference::Relative, 2.0)?, classic_order(Reference::Relative, 4.0)?];
        RippleModel::new(orders, T::ONE, sample_rate_hz)?.with_limits(classic_limits())
    }
}

impl<T: Real> RippleModel<T, 3> {
    /// The classic 6th-order model: the 4th-order one plus misalignment at 1× the output
    /// angle, same noise.
    ///
    /// ```
    /// use strainwave_core::ripple::{Reference, RippleModel};
    /// let m = RippleModel::<f32, 3>::taghirad_6th_order(1000.0).unwrap();
    /// assert_eq!(m.orders()[2].reference(), Reference::Output);
    /// ```
    pub fn taghirad_6th_order(sample_rate_hz: T) -> Result<Self, Error> {
        let orders = [
            classic_order(Reference::Relative, 2.0)?,
            classic_order(Reference::Relative, 4.0)?,
            classic_order(Reference::Output, 1.0)?,
        ];
        RippleModel::new(orders, T::ONE, sample_rate_hz)?.with_limits(classic_limits())
    }

    /// The product configuration: 2× and 4× relative-angle ripple, 1× output
    /// misalignment and a torque/bias random walk, measurement noise `noise_nm` (1σ).
    ///
    /// - bias: random walk with a 25 Hz first-order bandwidth. It is the sink for load
    ///   (steps, friction, slow sinusoids); with the load-step detector of [`Limits`]
    ///   steps go to it in one sample. Its estimate is the filtered torque output.
    /// - ripple orders: noise per radian of phase, 1 Hz −3 dB half-width when the line
    ///   is at 20 Hz (`1 Hz · √(f_line / 20 Hz)` at other speeds, none at standstill),
    ///   fast enough to follow ripple amplitude that grows with load;
    /// - misalignment: per-sample noise from [`tuning::slow_line_q`](crate::tuning::slow_line_q)
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
        RippleModel::new(orders, noise_nm, fs)?
            .with_bias_state(bias_q)?
            .with_initial_variance(c(OSCILLATOR_P0_NM2), c(BIAS_P0_NM2))
    }
}

/// Tuning of the full configuration, documented in [`RippleModel::full`].
const FULL_RIPPLE_BANDWIDTH_HZ: f64 = 0.2;
const FULL_LOAD_RIPPLE_BANDWIDTH_HZ: f64 = 0.01;
const FULL_MISALIGNMENT_BANDWIDTH_HZ: f64 = 0.01;
const FULL_MISALIGNMENT_AT_LINE_HZ: f64 = 0.25;
const FULL_BIAS_BANDWIDTH_HZ: f64 = 100.0;
const COMMISSIONING_BIAS_BANDWIDTH_HZ: f64 = 0.1;
/// Prior 1σ of the misalignment, N·m: learned over revolutions, never seized from the
/// first load transient.
const MISALIGNMENT_PRIOR_NM: f64 = 0.1;
/// Prior 1σ of the load-proportional ripple, N·m per N·m (5 % of the load).
const LOAD_RIPPLE_PRIOR_NM_PER_NM: f64 = 0.05;

impl<T: Real> RippleModel<T, 5> {
    /// The full configuration in operation: 2× and 4× relative-angle ripple, the same
    /// two lines scaled by the load (ripple `A₀ + A₁ |τ|`, see
    /// [`Order::scaled_by_load`]), 1× output misalignment and a torque/bias random walk;
    /// measurement noise `noise_nm` (1σ). Orders 0–4 in that order.
    ///
    /// It is meant to start from coefficients learned on a commissioning run
    /// ([`Self::full_commissioning`], then [`Self::with_priors`]): the misalignment line
    /// (0.25 Hz at 1.5 rad/s of output) sits among the load's own frequencies, and only
    /// several output revolutions tell it from load, which one run of operation cannot
    /// promise. In operation the coefficients adapt slowly and the bias takes the rest:
    ///
    /// - bias: 100 Hz first-order random walk, the sink for every load the model does
    ///   not know (steps, friction, sinusoids), so little of it reaches the oscillators;
    /// - ripple orders: noise per radian of phase, 0.2 Hz half-width at a 20 Hz line
    ///   (none at standstill); load-scaled orders 0.01 Hz, prior 1σ 0.05 N·m per N·m;
    /// - misalignment: per radian of output travel, 0.01 Hz half-width at 0.25 Hz, prior
    ///   1σ 0.1 N·m (so a first load transient is not taken for it);
    /// - default [`Limits`]: held below 0.05 Hz, off above 0.45 fs, load steps beyond NIS 25.
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f32, 5>::full(1000.0, 0.0162).unwrap();
    /// assert_eq!(m.state_len(), 11);
    /// assert!(m.orders()[2].is_load_scaled());
    /// ```
    pub fn full(sample_rate_hz: T, noise_nm: T) -> Result<Self, Error> {
        full_with_bias(sample_rate_hz, noise_nm, FULL_BIAS_BANDWIDTH_HZ)
    }

    /// The full configuration for learning on a commissioning run: the same orders and
    /// noise as [`Self::full`] but a 0.1 Hz bias, so the oscillators, not the bias, explain
    /// what repeats with the angles. The bias must stay well below the misalignment line
    /// (0.19 Hz for a 50:1 gear at 60 rad/s): a 1 Hz bias took part of that line and
    /// left the learned misalignment 6 % off. The run should turn the output several times at a
    /// steady speed through two or more load levels (steps go to the bias through the
    /// load-step detector); then pass [`RippleState::learned_all`](super::RippleState::learned_all)
    /// to [`Self::with_priors`] of the operating model.
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f64, 5>::full_commissioning(1000.0, 0.0162).unwrap();
    /// assert!(m.bias_q_nm2().unwrap() < RippleModel::<f64, 5>::full(1000.0, 0.0162).unwrap().bias_q_nm2().unwrap());
    /// ```
    pub fn full_commissioning(sample_rate_hz: T, noise_nm: T) -> Result<Self, Error> {
        full_with_bias(sample_rate_hz, noise_nm, COMMISSIONING_BIAS_BANDWIDTH_HZ)
    }
}

fn full_with_bias<T: Real>(sample_rate_hz: T, noise_nm: T, bias_hz: f64) -> Result<RippleModel<T, 5>, Error> {
    let fs = positive(sample_rate_hz, "sample_rate_hz")?;
    let r = positive(noise_nm, "noise_nm")? * noise_nm;
    let c = T::from_f64;
    let line = c(RIPPLE_AT_LINE_HZ);
    let ripple_q = per_radian(oscillator_q(c(FULL_RIPPLE_BANDWIDTH_HZ), fs, r)?, line, fs)?;
    let load_q = per_radian(oscillator_q(c(FULL_LOAD_RIPPLE_BANDWIDTH_HZ), fs, r)?, line, fs)?;
    let mis_q =
        per_radian(oscillator_q(c(FULL_MISALIGNMENT_BANDWIDTH_HZ), fs, r)?, c(FULL_MISALIGNMENT_AT_LINE_HZ), fs)?;
    let load_p0 = c(LOAD_RIPPLE_PRIOR_NM_PER_NM * LOAD_RIPPLE_PRIOR_NM_PER_NM);
    let ripple = |n: f64, q: T| Order::new(Reference::Relative, c(n))?.with_noise(T::ZERO, q);
    let orders = [
        ripple(2.0, ripple_q)?,
        ripple(4.0, ripple_q)?,
        ripple(2.0, load_q)?.scaled_by_load().with_prior([T::ZERO; 2], load_p0)?,
        ripple(4.0, load_q)?.scaled_by_load().with_prior([T::ZERO; 2], load_p0)?,
        Order::new(Reference::Output, T::ONE)?
            .with_noise(T::ZERO, mis_q)?
            .with_prior([T::ZERO; 2], c(MISALIGNMENT_PRIOR_NM * MISALIGNMENT_PRIOR_NM))?,
    ];
    RippleModel::new(orders, noise_nm, fs)?
        .with_bias_state(random_walk_q(c(bias_hz), fs, r)?)?
        .with_initial_variance(c(OSCILLATOR_P0_NM2), c(BIAS_P0_NM2))
}
