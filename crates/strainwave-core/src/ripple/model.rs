//! The immutable error model of the canceller: orders, noise, limits; and the plan the
//! step precomputes from them (private, refreshed by every builder).
//!
//! ```text
//! x_i(k+1) = Φ_i(k) x_i(k) + w_i(k),   Φ_i(k) = [[cos a_i, sin a_i], [−sin a_i, cos a_i]]
//! a_i(k)   = n_i Δθ_r(k)               phase increment of order i on reference r, rad
//! b(k+1)   = b(k) + w_b(k)             optional torque/bias random walk
//! y(k)     = T_meas(k) − T_exp(k) = Σ_i [1 0] x_i(k) + b(k) + v(k)
//! E w_i w_iᵀ = (q_s,i + q_rad,i |a_i(k)|) I₂,   E w_b² = q_b,   E v² = R
//! ```
//!
//! Units: torques N·m, variances N·m², `q_rad` N·m² per radian of the order's phase.

use core::cmp::Ordering;

use crate::error::{finite, non_negative, positive, Error};
use crate::Real;

/// The measured angle an order is periodic in. The caller supplies each per sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Reference {
    /// Relative angle `φ = θ_wg − θ_fs` of wave generator and flexspline: gear meshing and elliptical
    /// interference ripple, 2× and 4×.
    #[default]
    Relative,
    /// Output (link) angle: misalignment of shaft and load, 1×.
    Output,
    /// Motor (WG) angle, e.g. `p·θ_m` harmonics of the electrical angle.
    Motor,
}

impl Reference {
    /// Index into [`ReferenceValues`](super::ReferenceValues) order: relative, output, motor.
    pub fn index(self) -> usize {
        match self {
            Reference::Relative => 0,
            Reference::Output => 1,
            Reference::Motor => 2,
        }
    }

    /// Whether an order on this reference counts as ripple (else as misalignment).
    pub fn is_ripple(self) -> bool {
        !matches!(self, Reference::Output)
    }
}

/// How the caller measures the reference angles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PhaseSource {
    /// Reference values are angles (rad, wrapped or unwrapped):
    /// `Δθ(k) = wrap_π(θ(k) − θ(k−1))`.
    #[default]
    Angle,
    /// Reference values are velocities (rad/s, tachometer): trapezoidal
    /// `Δθ(k) = (ω(k−1) + ω(k)) / 2 · dt`.
    Velocity,
}

/// One order: an oscillator at `multiple ×` a reference angle with its process noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Order<T: Real> {
    pub(crate) reference: Reference,
    pub(crate) multiple: T,
    pub(crate) q_per_sample_nm2: T,
    pub(crate) q_per_rad_nm2: T,
    pub(crate) prior_nm: [T; 2],
    pub(crate) prior_variance_nm2: Option<T>,
    pub(crate) load_scaled: bool,
}

impl<T: Real> Order<T> {
    /// An order `multiple > 0` on `reference`, without process noise yet.
    ///
    /// ```
    /// use strainwave_core::ripple::{Order, Reference};
    /// let o = Order::new(Reference::Relative, 2.0_f64).unwrap().with_noise(0.0, 1e-4).unwrap();
    /// assert_eq!(o.multiple(), 2.0);
    /// assert!(Order::new(Reference::Output, 0.0_f32).is_err());
    /// ```
    pub fn new(reference: Reference, multiple: T) -> Result<Self, Error> {
        positive(multiple, "multiple")?;
        Ok(Self {
            reference,
            multiple,
            q_per_sample_nm2: T::ZERO,
            q_per_rad_nm2: T::ZERO,
            prior_nm: [T::ZERO; 2],
            prior_variance_nm2: None,
            load_scaled: false,
        })
    }

    /// Makes the order's amplitude proportional to the load: its contribution is
    /// `|T̂| (z₀ cos ψ + z₁ sin ψ)` with `T̂ = T_exp + b̂(k|k−1)`, the expected torque plus
    /// the bias prior (just `T_exp` without the bias state); `z` is then in N·m per N·m.
    /// Beside an unscaled order on the same line it models ripple `A₀ + A₁ |τ|`, as
    /// meshing ripple grows with load in strain wave gears.
    ///
    /// ```
    /// use strainwave_core::ripple::{Order, Reference};
    /// let o = Order::new(Reference::Relative, 2.0_f32).unwrap().scaled_by_load();
    /// assert!(o.is_load_scaled());
    /// ```
    pub fn scaled_by_load(mut self) -> Self {
        self.load_scaled = true;
        self
    }

    /// A learned prior: the order's contribution starts (and restarts after a reset) as
    /// `mean[0] cos(nθ) + mean[1] sin(nθ)` with variance `variance_nm2` per component,
    /// instead of 0 with the model's initial variance. With angle input and a whole
    /// multiple the phase is `n θ` of the absolute reference angle, so coefficients
    /// learned on one run (see [`RippleState::learned`](super::RippleState::learned))
    /// carry over to the next; with velocity input or a fractional multiple the phase
    /// starts at 0 with each run and a learned mean does not carry over.
    ///
    /// ```
    /// use strainwave_core::ripple::{Order, Reference};
    /// let o = Order::new(Reference::Output, 1.0_f64)?.with_prior([0.5, -0.2], 1e-4)?;
    /// assert_eq!(o.prior(), ([0.5, -0.2], Some(1e-4)));
    /// assert!(o.with_prior([f64::NAN, 0.0], 1.0).is_err());
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn with_prior(mut self, mean_nm: [T; 2], variance_nm2: T) -> Result<Self, Error> {
        for v in mean_nm {
            finite(v, "prior mean_nm")?;
        }
        self.prior_variance_nm2 = Some(variance(variance_nm2, false, "prior variance_nm2")?);
        self.prior_nm = mean_nm;
        Ok(self)
    }

    /// The prior mean and its variance (`None`: the model's initial variance).
    pub fn prior(&self) -> ([T; 2], Option<T>) {
        (self.prior_nm, self.prior_variance_nm2)
    }

    /// Whether the amplitude scales with the load (see [`Self::scaled_by_load`]).
    pub fn is_load_scaled(&self) -> bool {
        self.load_scaled
    }

    /// Sets the process noise `Q_i = (q_per_sample + q_per_rad |n Δθ|) I₂`, N·m².
    /// The per-radian part stops at standstill, so the oscillator cannot drift there.
    pub fn with_noise(mut self, q_per_sample_nm2: T, q_per_rad_nm2: T) -> Result<Self, Error> {
        self.q_per_sample_nm2 = variance(q_per_sample_nm2, true, "q_per_sample_nm2")?;
        self.q_per_rad_nm2 = variance(q_per_rad_nm2, true, "q_per_rad_nm2")?;
        Ok(self)
    }

    /// The reference angle.
    pub fn reference(&self) -> Reference {
        self.reference
    }
    /// The multiple `n` of the reference angle.
    pub fn multiple(&self) -> T {
        self.multiple
    }
    /// Process noise per sample, N·m².
    pub fn q_per_sample_nm2(&self) -> T {
        self.q_per_sample_nm2
    }
    /// Process noise per radian of the order's phase `n θ`, N·m².
    pub fn q_per_rad_nm2(&self) -> T {
        self.q_per_rad_nm2
    }
}

/// Robustness limits. All fields are public; [`RippleModel::with_limits`] validates them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits<T: Real> {
    /// A reference increment `|Δθ|` above this (rad per sample) is an encoder jump: the
    /// orders on that reference are reset. Must be in `(0, π)` for wrapped angles.
    /// Default π/2.
    pub max_angle_step_rad: T,
    /// An increment differing from the previous one (per sample) by more than this, rad,
    /// is also a jump: it catches encoder glitches smaller than `max_angle_step_rad`.
    /// Default π/4 (785 rad/s of speed change within one sample at 1 kHz); ∞ disables.
    pub max_step_change_rad: T,
    /// A sample interval `dt_s` above this many nominal periods is a time gap: every
    /// oscillator is reset and the bias variance reinflated. Default 5 (∞ disables).
    pub max_gap_periods: T,
    /// An order whose line passes `nyquist_fraction · fs` (`|a| > nyquist_fraction·2π`)
    /// is switched off; it comes back below 90 % of that. Default 0.45, range (0, 0.5].
    pub nyquist_fraction: T,
    /// An order whose line frequency is below this is held: still predicted and
    /// subtracted, never updated, so standstill load cannot leak into it. The line
    /// frequency is taken from the running mean (≈ 16 samples) of the signed increment,
    /// so ±1-count encoder jitter at standstill does not count as motion.
    /// Default 0.05 Hz; 0 disables (as the classic filter).
    pub hold_below_hz: T,
    /// Each sample the covariance is inflated by this fraction `ρ`: every oscillator block
    /// gains `ρ (P_i,00 + P_i,11)/2 · I₂` (rotation invariant, so it is part of `Q`) and
    /// the bias `ρ P_bb`. It dominates the rounding of the update so `P` stays positive
    /// in f32 over 10⁸ samples. Default `ρ = 16 ε` (f32: 1.9e-6, a forgetting time of 5·10⁵ samples;
    /// f64: 3.6e-15, invisible). The update also never lets a variance fall below its
    /// exact lower bound `P_ii R / S`, and a held order's variances (no measurement
    /// updates them) never grow past the order's initial variance (or where they were,
    /// if above it).
    pub covariance_inflation: T,
    /// With the bias state, an innovation whose NIS `e²/S` exceeds this is taken as a
    /// load step: the update is the limit `Var(b) → ∞`, so the bias takes the whole
    /// innovation and the oscillators learn nothing from that sample. Default 25 (5σ);
    /// 0 disables.
    pub load_step_nis: T,
}

impl<T: Real> Default for Limits<T> {
    fn default() -> Self {
        Self {
            max_angle_step_rad: T::PI * T::HALF,
            max_step_change_rad: T::PI * T::from_f64(0.25),
            max_gap_periods: T::from_f64(5.0),
            nyquist_fraction: T::from_f64(0.45),
            hold_below_hz: T::from_f64(0.05),
            covariance_inflation: T::from_f64(16.0) * T::EPSILON,
            load_step_nis: T::from_f64(25.0),
        }
    }
}

/// The configuration of an oscillator bank of `M` orders (plus an optional bias
/// state): everything but the state. One model serves any number of joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleModel<T: Real, const M: usize> {
    pub(crate) orders: [Order<T>; M],
    /// Measurement noise, 1σ, N·m (what the caller gave).
    pub(crate) noise_nm: T,
    /// Its variance `R = noise_nm²`, N·m² (what the filter uses).
    pub(crate) r_nm2: T,
    pub(crate) sample_rate_hz: T,
    pub(crate) bias_q_nm2: Option<T>,
    pub(crate) p0_oscillator_nm2: T,
    pub(crate) p0_bias_nm2: T,
    pub(crate) phase_source: PhaseSource,
    pub(crate) limits: Limits<T>,
    /// What the kernel precomputes from the fields above, refreshed by `derive`.
    pub(crate) plan: Plan<T, M>,
}

impl<T: Real, const M: usize> RippleModel<T, M> {
    /// A bank of `orders`, the measurement noise `noise_nm > 0` (1σ, N·m; the filter's
    /// `R` is its square) and the sample rate. No bias state, initial variance 1 N·m² per
    /// oscillator, default limits.
    ///
    /// ```
    /// use strainwave_core::ripple::{Order, Reference, RippleModel};
    /// let orders = [
    ///     Order::new(Reference::Relative, 2.0_f64)?.with_noise(1e-3, 0.0)?,
    ///     Order::new(Reference::Relative, 4.0)?.with_noise(1e-3, 0.0)?,
    /// ];
    /// let model = RippleModel::new(orders, 1.0, 1000.0)?;
    /// assert_eq!(model.state_len(), 4);
    /// assert!(RippleModel::new(orders, 0.0, 1000.0).is_err());
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn new(orders: [Order<T>; M], noise_nm: T, sample_rate_hz: T) -> Result<Self, Error> {
        for o in &orders {
            positive(o.multiple, "multiple")?;
            variance(o.q_per_sample_nm2, true, "q_per_sample_nm2")?;
            variance(o.q_per_rad_nm2, true, "q_per_rad_nm2")?;
            finite(o.prior_nm[0], "prior mean_nm")?;
            finite(o.prior_nm[1], "prior mean_nm")?;
            if let Some(v) = o.prior_variance_nm2 {
                variance(v, false, "prior variance_nm2")?;
            }
        }
        let noise_nm = positive(noise_nm, "noise_nm")?;
        let mut m = Self {
            orders,
            noise_nm,
            // A σ whose square underflows, or passes the largest variance, is refused too.
            r_nm2: variance(noise_nm * noise_nm, false, "noise_nm")?,
            sample_rate_hz: sample_rate(sample_rate_hz)?,
            bias_q_nm2: None,
            p0_oscillator_nm2: T::ONE,
            p0_bias_nm2: T::from_f64(1e4),
            phase_source: PhaseSource::Angle,
            limits: Limits::default(),
            plan: Plan::new(&orders, T::ONE, &Limits::default(), T::ONE),
        };
        m.derive();
        Ok(m)
    }

    /// Adds the torque/bias random-walk state `b(k+1) = b(k) + w_b`, `E w_b² = q_b` (N·m²
    /// per sample; see [`tuning::random_walk_q`](crate::tuning::random_walk_q)).
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f32, 2>::taghirad_4th_order(1000.0)?.with_bias_state(1e-2)?;
    /// assert_eq!(m.state_len(), 5);
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn with_bias_state(mut self, q_bias_nm2: T) -> Result<Self, Error> {
        self.bias_q_nm2 = Some(variance(q_bias_nm2, true, "q_bias_nm2")?);
        self.derive();
        Ok(self)
    }

    /// Initial (and reset) variances of each oscillator component and of the bias, N·m².
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f64, 3>::taghirad_6th_order(1000.0)?.with_initial_variance(4.0, 100.0)?;
    /// assert_eq!(m.initial_variance_nm2(), (4.0, 100.0));
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn with_initial_variance(mut self, oscillator_nm2: T, bias_nm2: T) -> Result<Self, Error> {
        self.p0_oscillator_nm2 = variance(oscillator_nm2, false, "oscillator_nm2")?;
        self.p0_bias_nm2 = variance(bias_nm2, false, "bias_nm2")?;
        self.derive();
        Ok(self)
    }

    /// Sets every order's prior (mean coefficients, variance per component), e.g. what a
    /// commissioning run learned ([`RippleState::learned_all`](super::RippleState::learned_all)).
    ///
    /// ```
    /// use strainwave_core::ripple::RippleModel;
    /// let m = RippleModel::<f64, 2>::taghirad_4th_order(1000.0)?;
    /// let m = m.with_priors([([0.3, 0.1], 1e-4), ([0.0, -0.05], 1e-4)])?;
    /// assert_eq!(m.orders()[0].prior(), ([0.3, 0.1], Some(1e-4)));
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn with_priors(mut self, priors: [([T; 2], T); M]) -> Result<Self, Error> {
        for (o, (mean, var)) in self.orders.iter_mut().zip(priors) {
            *o = o.with_prior(mean, var)?;
        }
        self.derive();
        Ok(self)
    }

    /// Whether the reference values fed to `step` are angles or velocities.
    ///
    /// ```
    /// use strainwave_core::ripple::{PhaseSource, RippleModel};
    /// let m = RippleModel::<f64, 2>::taghirad_4th_order(1000.0)?.with_phase_source(PhaseSource::Velocity);
    /// assert_eq!(m.phase_source(), PhaseSource::Velocity);
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn with_phase_source(mut self, source: PhaseSource) -> Self {
        self.phase_source = source;
        self
    }

    /// Replaces the robustness limits after checking them.
    ///
    /// ```
    /// use strainwave_core::ripple::{Limits, RippleModel};
    /// let limits = Limits { hold_below_hz: 0.0, ..Limits::default() };
    /// let m = RippleModel::<f64, 2>::taghirad_4th_order(1000.0)?.with_limits(limits)?;
    /// assert_eq!(m.limits().hold_below_hz, 0.0);
    /// let bad = Limits { nyquist_fraction: 0.7, ..Limits::default() };
    /// assert!(RippleModel::<f64, 2>::taghirad_4th_order(1000.0)?.with_limits(bad).is_err());
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn with_limits(mut self, limits: Limits<T>) -> Result<Self, Error> {
        positive(limits.max_angle_step_rad, "max_angle_step_rad")?;
        if limits.max_angle_step_rad >= T::PI && self.phase_source == PhaseSource::Angle {
            return Err(Error::OutOfRange("max_angle_step_rad"));
        }
        if limits.max_step_change_rad.partial_cmp(&T::ZERO) != Some(Ordering::Greater) {
            return Err(Error::NonPositive("max_step_change_rad"));
        }
        // ∞ is allowed (no gap detection); NaN and ≤ 0 are not.
        if limits.max_gap_periods.partial_cmp(&T::ZERO) != Some(Ordering::Greater) {
            return Err(Error::NonPositive("max_gap_periods"));
        }
        positive(limits.nyquist_fraction, "nyquist_fraction")?;
        if limits.nyquist_fraction > T::HALF {
            return Err(Error::OutOfRange("nyquist_fraction"));
        }
        non_negative(limits.hold_below_hz, "hold_below_hz")?;
        if non_negative(limits.covariance_inflation, "covariance_inflation")? > T::from_f64(MAX_COVARIANCE_INFLATION) {
            return Err(Error::OutOfRange("covariance_inflation"));
        }
        non_negative(limits.load_step_nis, "load_step_nis")?;
        self.limits = limits;
        self.derive();
        Ok(self)
    }

    fn derive(&mut self) {
        self.plan = Plan::new(&self.orders, self.sample_rate_hz, &self.limits, self.p0_oscillator_nm2);
    }

    /// The orders.
    pub fn orders(&self) -> &[Order<T>; M] {
        &self.orders
    }
    /// Measurement noise, 1σ, N·m (the filter's `R` is its square).
    pub fn noise_nm(&self) -> T {
        self.noise_nm
    }
    /// Sample rate, Hz.
    pub fn sample_rate_hz(&self) -> T {
        self.sample_rate_hz
    }
    /// Bias random-walk variance per sample, if the model has the bias state.
    pub fn bias_q_nm2(&self) -> Option<T> {
        self.bias_q_nm2
    }
    /// Initial variances (oscillator component, bias), N·m².
    pub fn initial_variance_nm2(&self) -> (T, T) {
        (self.p0_oscillator_nm2, self.p0_bias_nm2)
    }
    /// Angle or velocity input.
    pub fn phase_source(&self) -> PhaseSource {
        self.phase_source
    }
    /// The robustness limits.
    pub fn limits(&self) -> &Limits<T> {
        &self.limits
    }
    /// Whether an order uses `reference` (the others' values are ignored, even NaN).
    pub fn uses(&self, reference: Reference) -> bool {
        self.plan.uses[reference.index()]
    }
    /// State dimension: `2M`, plus 1 with the bias state.
    pub fn state_len(&self) -> usize {
        2 * M + usize::from(self.bias_q_nm2.is_some())
    }
}

/// Largest variance (measurement, initial, prior or process noise per sample) a model
/// accepts, N·m²: a 1σ of 10⁶ N·m, beyond any joint. Larger ones overflow the filter.
pub const MAX_VARIANCE_NM2: f64 = 1e12;
/// Largest covariance inflation per sample (1 %; the default is 16 ε).
pub const MAX_COVARIANCE_INFLATION: f64 = 1e-2;
/// Sample rates a model accepts, Hz (outside: a unit slip, not a joint).
pub const SAMPLE_RATE_RANGE_HZ: (f64, f64) = (1e-3, 1e9);

/// A variance (`zero_ok`: or a process noise, which may be 0), finite and at most
/// [`MAX_VARIANCE_NM2`]; else the error naming it.
fn variance<T: Real>(x: T, zero_ok: bool, name: &'static str) -> Result<T, Error> {
    let x = if zero_ok { non_negative(x, name)? } else { positive(x, name)? };
    (x <= T::from_f64(MAX_VARIANCE_NM2)).then_some(x).ok_or(Error::OutOfRange(name))
}

/// A sample rate within [`SAMPLE_RATE_RANGE_HZ`].
fn sample_rate<T: Real>(fs: T) -> Result<T, Error> {
    let (fs, (low, high)) = (positive(fs, "sample_rate_hz")?, SAMPLE_RATE_RANGE_HZ);
    let inside = fs >= T::from_f64(low) && fs <= T::from_f64(high);
    inside.then_some(fs).ok_or(Error::OutOfRange("sample_rate_hz"))
}

/// What the kernel precomputes from a model (refreshed whenever a builder changes it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Plan<T: Real, const M: usize> {
    /// Nominal sample interval, s.
    pub(crate) dt_s: T,
    /// A sample interval above this is a time gap, s.
    pub(crate) max_gap_s: T,
    /// An order whose phase increment `|a|` passes this is switched off, rad per sample.
    pub(crate) off_above_rad: T,
    /// An order off comes back below this, rad per sample.
    pub(crate) on_below_rad: T,
    /// An order whose mean increment is below this is held, rad per sample.
    pub(crate) hold_below_rad: T,
    /// Whether some order uses each reference.
    pub(crate) uses: [bool; 3],
    /// The largest and smallest multiple of the orders on each reference (1 if none):
    /// every order's line is within the limits when these two are.
    pub(crate) widest: [T; 3],
    pub(crate) narrowest: [T; 3],
    /// The reference index of each order.
    pub(crate) reference: [usize; M],
    /// Whole multiple `n ≤ 16` of each order, or 0 (fractional or larger: own phase).
    pub(crate) power: [u8; M],
    /// Initial (and reset) variance of each order: its prior's, or the model's.
    pub(crate) p0_nm2: [T; M],
}

impl<T: Real, const M: usize> Plan<T, M> {
    /// The plan of a model with these orders, sample rate, limits and initial variance.
    pub(crate) fn new(orders: &[Order<T>; M], sample_rate_hz: T, lim: &Limits<T>, p0_oscillator_nm2: T) -> Self {
        let off_above_rad = lim.nyquist_fraction * T::TAU;
        let mut plan = Self {
            dt_s: T::ONE / sample_rate_hz,
            max_gap_s: lim.max_gap_periods / sample_rate_hz,
            off_above_rad,
            on_below_rad: off_above_rad * T::from_f64(0.9),
            hold_below_rad: lim.hold_below_hz * T::TAU / sample_rate_hz,
            uses: [false; 3],
            widest: [T::ONE; 3],
            narrowest: [T::ONE; 3],
            reference: [0; M],
            power: [0; M],
            p0_nm2: [p0_oscillator_nm2; M],
        };
        for (i, o) in orders.iter().enumerate() {
            let r = o.reference.index();
            let first = !plan.uses[r];
            plan.widest[r] = if first { o.multiple } else { plan.widest[r].max(o.multiple) };
            plan.narrowest[r] = if first { o.multiple } else { plan.narrowest[r].min(o.multiple) };
            plan.uses[r] = true;
            plan.reference[i] = r;
            let n = o.multiple.to_f64();
            plan.power[i] = if n == libm::round(n) && (1.0..=16.0).contains(&n) { n as u8 } else { 0 };
            plan.p0_nm2[i] = o.prior_variance_nm2.unwrap_or(p0_oscillator_nm2);
        }
        plan
    }
}
