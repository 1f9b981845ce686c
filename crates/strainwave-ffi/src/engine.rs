//! The canceller behind the C ABI, in either precision: a plain model checked and
//! converted into the core's `RippleModel`, its `RippleState`, the gear and the
//! calibration, and one sample's path from the raw channels to the core's `step`.
//!
//! The per-sample path is the one `strainwave filter` takes for each row of a recording
//! (calibration at the motor speed, references from the gear, the time step from the
//! time channel), so an exported model gives the command line's numbers.

use core::mem::MaybeUninit;

use strainwave_core::calibration::{Calibration, Extrapolation};
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::guard::{Guard, GuardSettings};
use strainwave_core::ripple::{
    step, Limits, Order, PhaseSource, Reference, ReferenceValues, RippleInput, RippleModel, RippleOutput, RippleState,
};
use strainwave_core::Real;

use crate::errors::*;
use crate::types::*;

/// A model in either precision, field by field as [`sw_model`].
#[derive(Clone, Copy)]
pub(crate) struct Plain<T: Real> {
    pub version: u32,
    pub order_count: u32,
    pub gear_fixed: u32,
    pub phase_source: u32,
    pub channels: u32,
    pub has_bias_state: u32,
    pub gear_ratio: T,
    pub sample_rate_hz: T,
    pub noise_nm: T,
    pub bias_q_nm2: T,
    pub p0_oscillator_nm2: T,
    pub p0_bias_nm2: T,
    pub limits: Limits<T>,
    pub orders: [PlainOrder<T>; SW_MAX_ORDERS],
    pub calibration: PlainCalibration<T>,
    pub guard: PlainGuard<T>,
}

/// The guard, as [`sw_guard`]: the thresholds in the struct's order.
#[derive(Clone, Copy)]
pub(crate) struct PlainGuard<T> {
    pub off: u32,
    pub learned_prior: u32,
    pub thresholds: [T; 15],
}

/// One order, as [`sw_order`].
#[derive(Clone, Copy)]
pub(crate) struct PlainOrder<T> {
    pub reference: u32,
    pub load_scaled: u32,
    pub multiple: T,
    pub q_per_sample_nm2: T,
    pub q_per_rad_nm2: T,
    pub prior_nm: [T; 2],
    pub prior_variance_nm2: T,
}

/// The calibration, as [`sw_calibration`].
#[derive(Clone, Copy)]
pub(crate) struct PlainCalibration<T> {
    pub kind: u32,
    pub extrapolation: u32,
    pub len: u32,
    pub speed_min_rad_s: T,
    pub speed_max_rad_s: T,
    pub speed_rad_s: [T; SW_MAX_CALIBRATION_POINTS],
    pub alpha: [T; SW_MAX_CALIBRATION_POINTS],
    pub beta_nm: [T; SW_MAX_CALIBRATION_POINTS],
}

/// One sample, as [`sw_sample`].
#[derive(Clone, Copy)]
pub(crate) struct Sample<T> {
    pub time: T,
    pub torque: T,
    pub motor_angle: T,
    pub output_angle: T,
    pub motor_velocity: T,
    pub expected_torque: T,
}

/// One result, as [`sw_output`].
#[derive(Clone, Copy)]
pub(crate) struct Output<T> {
    pub torque: T,
    pub ripple: T,
    pub misalignment: T,
    pub innovation: T,
    pub nis: T,
    pub flags: u32,
    pub guard_flags: u32,
    pub withheld_orders: u32,
}

/// The canceller of one order count: bare, or under the do-no-harm guard (which holds
/// the canceller's state).
#[derive(Clone)]
pub(crate) enum Canceller<T: Real, const M: usize> {
    Bare(RippleState<T, M>),
    Guarded(Guard<T, M>),
}

impl<T: Real, const M: usize> Canceller<T, M> {
    fn new(model: &RippleModel<T, M>, guard: Option<GuardSettings<T>>) -> Self {
        match guard {
            Some(settings) => Canceller::Guarded(Guard::new(model, settings)),
            None => Canceller::Bare(RippleState::new(model)),
        }
    }

    /// Back to the initial state, in place. Out of line: a stack holds one order count's
    /// temporaries.
    #[inline(never)]
    fn reset(&mut self, model: &RippleModel<T, M>) {
        match self {
            Canceller::Guarded(g) => *g = Guard::new(model, *g.settings()),
            Canceller::Bare(s) => s.reset(model),
        }
    }

    /// One step: the output, the guard's flags and the withheld orders.
    fn step(
        &mut self,
        model: &RippleModel<T, M>,
        input: &RippleInput<T>,
    ) -> Result<(RippleOutput<T>, u32, u32), strainwave_core::Error> {
        match self {
            Canceller::Bare(s) => step(model, s, input).map(|o| (o, 0, 0)),
            Canceller::Guarded(g) => {
                g.step(model, input).map(|o| (o.output, u32::from(o.flags.bits()), u32::from(o.withheld_mask())))
            }
        }
    }
}

/// The model and canceller for each order count (the core sizes them at compile time).
#[derive(Clone)]
pub(crate) enum Engine<T: Real> {
    O1(RippleModel<T, 1>, Canceller<T, 1>),
    O2(RippleModel<T, 2>, Canceller<T, 2>),
    O3(RippleModel<T, 3>, Canceller<T, 3>),
    O4(RippleModel<T, 4>, Canceller<T, 4>),
    O5(RippleModel<T, 5>, Canceller<T, 5>),
    O6(RippleModel<T, 6>, Canceller<T, 6>),
    O7(RippleModel<T, 7>, Canceller<T, 7>),
    O8(RippleModel<T, 8>, Canceller<T, 8>),
}

/// Everything one joint needs between steps; lives inside `sw_state` / `sw32_state`.
#[derive(Clone)]
pub(crate) struct Instance<T: Real> {
    engine: Engine<T>,
    gear: Gear<T>,
    calibration: Calibration<T, SW_MAX_CALIBRATION_POINTS>,
    channels: u32,
    velocity: bool,
    last_time_s: Option<T>,
}

/// Calls `$body` with `$m`, `$s` bound to the model and state of whichever size `$e` is.
macro_rules! with_engine {
    ($e:expr, $m:ident, $s:ident => $body:expr) => {
        match $e {
            Engine::O1($m, $s) => $body,
            Engine::O2($m, $s) => $body,
            Engine::O3($m, $s) => $body,
            Engine::O4($m, $s) => $body,
            Engine::O5($m, $s) => $body,
            Engine::O6($m, $s) => $body,
            Engine::O7($m, $s) => $body,
            Engine::O8($m, $s) => $body,
        }
    };
}

fn order<T: Real>(p: &PlainOrder<T>) -> Result<Order<T>, i32> {
    let reference = match p.reference {
        SW_REFERENCE_RELATIVE => Reference::Relative,
        SW_REFERENCE_OUTPUT => Reference::Output,
        SW_REFERENCE_MOTOR => Reference::Motor,
        _ => return Err(SW_ERROR_ORDER),
    };
    let bad = |_| SW_ERROR_ORDER;
    let mut o = Order::new(reference, p.multiple).and_then(|o| o.with_noise(p.q_per_sample_nm2, p.q_per_rad_nm2));
    if p.prior_variance_nm2 != T::ZERO {
        o = o.and_then(|o| o.with_prior(p.prior_nm, p.prior_variance_nm2));
    } else if p.prior_nm != [T::ZERO; 2] {
        return Err(SW_ERROR_ORDER);
    }
    let o = o.map_err(bad)?;
    match p.load_scaled {
        0 => Ok(o),
        1 => Ok(o.scaled_by_load()),
        _ => Err(SW_ERROR_ORDER),
    }
}

fn ripple_model<T: Real, const M: usize>(p: &Plain<T>) -> Result<RippleModel<T, M>, i32> {
    let mut orders = [Order::new(Reference::Relative, T::ONE).map_err(|_| SW_ERROR_ORDER)?; M];
    for (o, plain) in orders.iter_mut().zip(&p.orders) {
        *o = order(plain)?;
    }
    let phase = match p.phase_source {
        SW_PHASE_ANGLE => PhaseSource::Angle,
        SW_PHASE_VELOCITY => PhaseSource::Velocity,
        _ => return Err(SW_ERROR_MODEL),
    };
    let bad = |_| SW_ERROR_MODEL;
    let mut m = RippleModel::new(orders, p.noise_nm, p.sample_rate_hz)
        .map_err(bad)?
        .with_phase_source(phase)
        .with_initial_variance(p.p0_oscillator_nm2, p.p0_bias_nm2)
        .and_then(|m| m.with_limits(p.limits))
        .map_err(bad)?;
    match p.has_bias_state {
        0 => {}
        1 => m = m.with_bias_state(p.bias_q_nm2).map_err(bad)?,
        _ => return Err(SW_ERROR_MODEL),
    }
    Ok(m)
}

/// The guard's settings (`None`: off); a threshold of 0 takes its default.
fn guard_settings<T: Real>(g: &PlainGuard<T>) -> Result<Option<GuardSettings<T>>, i32> {
    let learned_prior = match (g.off, g.learned_prior) {
        (1, _) => return Ok(None),
        (0, 0) => false,
        (0, 1) => true,
        _ => return Err(SW_ERROR_GUARD),
    };
    if g.thresholds.iter().any(|x| !x.is_finite() || *x < T::ZERO) {
        return Err(SW_ERROR_GUARD);
    }
    let d = GuardSettings::<T>::default();
    let [a, b, c, e, f, h, i, j, k, l, m, n, o, q, r] = g.thresholds.map(|x| if x == T::ZERO { None } else { Some(x) });
    Ok(Some(GuardSettings {
        apply_chi2: a.unwrap_or(d.apply_chi2),
        release_chi2: b.unwrap_or(d.release_chi2),
        apply_wander: c.unwrap_or(d.apply_wander),
        release_wander: e.unwrap_or(d.release_wander),
        min_cycles: f.unwrap_or(d.min_cycles),
        min_cycles_output: h.unwrap_or(d.min_cycles_output),
        learned_prior,
        window_s: i.unwrap_or(d.window_s),
        nis_pass_through: j.unwrap_or(d.nis_pass_through),
        nis_recover: k.unwrap_or(d.nis_recover),
        contradiction_margin: l.unwrap_or(d.contradiction_margin),
        nis_clip: m.unwrap_or(d.nis_clip),
        partial_min_line_hz: n.unwrap_or(d.partial_min_line_hz),
        complete_max_nis: o.unwrap_or(d.complete_max_nis),
        standstill_max_nis: q.unwrap_or(d.standstill_max_nis),
        standstill_window_s: r.unwrap_or(d.standstill_window_s),
    }))
}

/// What the model gives besides the canceller: checked before the canceller is built.
struct Parts<T: Real> {
    gear: Gear<T>,
    calibration: Calibration<T, SW_MAX_CALIBRATION_POINTS>,
    channels: u32,
    velocity: bool,
}

/// Builds the instance of `M` orders in `dest`. Out of line, so that a stack holds the
/// temporaries of one order count at a time, not of all eight.
#[inline(never)]
fn build_sized<T: Real, const M: usize>(
    p: &Plain<T>,
    guard: Option<GuardSettings<T>>,
    parts: Parts<T>,
    variant: fn(RippleModel<T, M>, Canceller<T, M>) -> Engine<T>,
    dest: &mut MaybeUninit<Instance<T>>,
) -> Result<(), i32> {
    let m = ripple_model::<T, M>(p)?;
    let c = Canceller::new(&m, guard);
    let Parts { gear, calibration, channels, velocity } = parts;
    dest.write(Instance { engine: variant(m, c), gear, calibration, channels, velocity, last_time_s: None });
    Ok(())
}

fn calibration<T: Real>(c: &PlainCalibration<T>) -> Result<Calibration<T, SW_MAX_CALIBRATION_POINTS>, i32> {
    let bad = |_| SW_ERROR_CALIBRATION;
    let n = usize::try_from(c.len).map_err(|_| SW_ERROR_CALIBRATION)?;
    if !(1..=SW_MAX_CALIBRATION_POINTS).contains(&n) {
        return Err(SW_ERROR_CALIBRATION);
    }
    let extrapolation = match c.extrapolation {
        SW_EXTRAPOLATION_CLAMP => Extrapolation::Clamp,
        SW_EXTRAPOLATION_LINEAR => Extrapolation::Linear,
        SW_EXTRAPOLATION_REJECT => Extrapolation::Reject,
        _ => return Err(SW_ERROR_CALIBRATION),
    };
    // `n` is within the arrays: checked above.
    let (speed, alpha, beta) = (&c.speed_rad_s[..n], &c.alpha[..n], &c.beta_nm[..n]);
    match c.kind {
        SW_CALIBRATION_GAIN => Calibration::gain(c.alpha[0]),
        SW_CALIBRATION_AFFINE => Calibration::affine(c.alpha[0], c.beta_nm[0]),
        SW_CALIBRATION_SPEED_TABLE => Calibration::speed_table(speed, alpha, beta, extrapolation),
        SW_CALIBRATION_SPEED_POLYNOMIAL => {
            Calibration::speed_polynomial(alpha, beta, c.speed_min_rad_s, c.speed_max_rad_s, extrapolation)
        }
        _ => return Err(SW_ERROR_CALIBRATION),
    }
    .map_err(bad)
}

/// Every channel bit the model may carry.
const ALL_CHANNELS: u32 =
    SW_CHANNEL_MOTOR_ANGLE | SW_CHANNEL_OUTPUT_ANGLE | SW_CHANNEL_MOTOR_VELOCITY | SW_CHANNEL_EXPECTED_TORQUE;

impl<T: Real> Instance<T> {
    /// Checks a plain model and builds the canceller in `dest` (in place: a firmware's
    /// stack need not hold a second instance); the error is an `SW_ERROR_*` code, and
    /// `dest` is then left as it was.
    pub(crate) fn build(p: &Plain<T>, dest: &mut MaybeUninit<Self>) -> Result<(), i32> {
        if p.version != SW_MODEL_VERSION {
            return Err(SW_ERROR_VERSION);
        }
        let fixed = match p.gear_fixed {
            SW_GEAR_CIRCULAR_SPLINE_FIXED => FixedElement::CircularSpline,
            SW_GEAR_FLEXSPLINE_FIXED => FixedElement::Flexspline,
            _ => return Err(SW_ERROR_GEAR),
        };
        let gear = Gear::new(p.gear_ratio, fixed).map_err(|_| SW_ERROR_GEAR)?;
        let guard = guard_settings(&p.guard)?;
        if !(1..=SW_MAX_ORDERS as u32).contains(&p.order_count) {
            return Err(SW_ERROR_ORDER_COUNT);
        }
        let calibration = calibration(&p.calibration)?;
        let velocity = p.phase_source == SW_PHASE_VELOCITY;
        let needed =
            if velocity { SW_CHANNEL_MOTOR_VELOCITY } else { SW_CHANNEL_MOTOR_ANGLE | SW_CHANNEL_OUTPUT_ANGLE };
        if p.channels & !ALL_CHANNELS != 0 || p.channels & needed != needed {
            return Err(SW_ERROR_CHANNELS);
        }
        let parts = Parts { gear, calibration, channels: p.channels, velocity };
        match p.order_count {
            1 => build_sized(p, guard, parts, Engine::O1, dest),
            2 => build_sized(p, guard, parts, Engine::O2, dest),
            3 => build_sized(p, guard, parts, Engine::O3, dest),
            4 => build_sized(p, guard, parts, Engine::O4, dest),
            5 => build_sized(p, guard, parts, Engine::O5, dest),
            6 => build_sized(p, guard, parts, Engine::O6, dest),
            7 => build_sized(p, guard, parts, Engine::O7, dest),
            _ => build_sized(p, guard, parts, Engine::O8, dest),
        }
    }

    /// Back to the state right after `build`.
    pub(crate) fn reset(&mut self) {
        self.last_time_s = None;
        with_engine!(&mut self.engine, m, c => c.reset(m));
    }

    fn has(&self, channel: u32) -> bool {
        self.channels & channel != 0
    }

    /// One sample; on a core error (covariance reset) the output is the calibrated torque
    /// with nothing removed, and the error code.
    pub(crate) fn step(&mut self, s: &Sample<T>) -> (Output<T>, i32) {
        let nan = T::from_f64(f64::NAN);
        let channel = |bit, v: T| if self.has(bit) { v } else { nan };
        // Speed for the calibration: 0 without a tachometer, as the command line does.
        let speed = if self.has(SW_CHANNEL_MOTOR_VELOCITY) { s.motor_velocity } else { T::ZERO };
        let mut flags = 0;
        let torque = match self.calibration.apply_flagged(s.torque, speed) {
            Ok(a) => {
                if a.extrapolated {
                    flags |= SW_FLAG_CALIBRATION_EXTRAPOLATED;
                }
                a.torque_nm
            }
            // A non-finite sample or a speed the policy rejects: the filter skips it.
            Err(_) => nan,
        };
        let refs = if self.velocity {
            let w = s.motor_velocity;
            ReferenceValues::new(w * self.gear.relative_rate_rigid(T::ONE), self.gear.output_angle(w), w)
        } else {
            let motor = channel(SW_CHANNEL_MOTOR_ANGLE, s.motor_angle);
            let output = channel(SW_CHANNEL_OUTPUT_ANGLE, s.output_angle);
            ReferenceValues::from_gear(&self.gear, motor, output)
        };
        let mut input = RippleInput::new(torque, refs);
        if self.has(SW_CHANNEL_EXPECTED_TORQUE) {
            input = input.with_expected_torque(s.expected_torque);
        }
        let t = s.time;
        if let Some(t0) = self.last_time_s.filter(|t0| t.is_finite() && t > *t0) {
            input = input.with_dt(t - t0);
        }
        if t.is_finite() {
            self.last_time_s = Some(t);
        }
        let result = with_engine!(&mut self.engine, m, c => c.step(m, &input));
        // On a reset no order is applied: every order's bit (at most 8).
        let every_order = with_engine!(&mut self.engine, m, _c => (1u32 << m.orders().len()) - 1);
        match result {
            Ok((o, guard_flags, withheld_orders)) => (
                Output {
                    torque: o.torque_nm,
                    ripple: o.ripple_nm,
                    misalignment: o.misalignment_nm,
                    innovation: o.innovation_nm,
                    nis: o.nis,
                    flags: flags | u32::from(o.flags.bits()),
                    guard_flags,
                    withheld_orders,
                },
                SW_OK,
            ),
            Err(_) => (
                Output {
                    torque,
                    ripple: T::ZERO,
                    misalignment: T::ZERO,
                    innovation: nan,
                    nis: nan,
                    flags: flags | SW_FLAG_COVARIANCE_RESET,
                    guard_flags: 0,
                    withheld_orders: every_order,
                },
                SW_ERROR_COVARIANCE,
            ),
        }
    }
}
