//! The C functions called from Rust: bad input gives error codes (never a crash), and a
//! model passed through `sw_model` runs exactly as the same core model called directly,
//! in f64 and in f32, bare and under the do-no-harm guard.

// The test calls the C entry points as C does, through raw pointers.
#![allow(unsafe_code)]

use std::ffi::CStr;
use std::ptr::{null, null_mut};

use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::guard::{Guard, GuardSettings};
use strainwave_core::ripple::{step, ReferenceValues, RippleInput, RippleModel, RippleState};
use strainwave_ffi::*;

macro_rules! from_core {
    ($name:ident, $t:ty, $model:ident, $order:ident, $limits:ident, $cal:ident, $guard:ident) => {
        /// The `sw_model` of a core model (angle phase, both angle channels, gain 2.5),
        /// guard off (the bare canceller).
        fn $name<const M: usize>(core: &RippleModel<$t, M>) -> $model {
            let mut orders = [$order {
                reference: 0,
                load_scaled: 0,
                multiple: 1.0,
                q_per_sample_nm2: 0.0,
                q_per_rad_nm2: 0.0,
                prior_nm: [0.0; 2],
                prior_variance_nm2: 0.0,
            }; SW_MAX_ORDERS];
            for (c, o) in orders.iter_mut().zip(core.orders()) {
                let (prior_nm, variance) = o.prior();
                *c = $order {
                    reference: o.reference().index() as u32,
                    load_scaled: u32::from(o.is_load_scaled()),
                    multiple: o.multiple(),
                    q_per_sample_nm2: o.q_per_sample_nm2(),
                    q_per_rad_nm2: o.q_per_rad_nm2(),
                    prior_nm,
                    prior_variance_nm2: variance.unwrap_or(0.0),
                };
            }
            let l = core.limits();
            let mut alpha = [0.0; SW_MAX_CALIBRATION_POINTS];
            alpha[0] = 2.5;
            $model {
                version: SW_MODEL_VERSION,
                order_count: M as u32,
                gear_fixed: SW_GEAR_CIRCULAR_SPLINE_FIXED,
                phase_source: SW_PHASE_ANGLE,
                channels: SW_CHANNEL_MOTOR_ANGLE | SW_CHANNEL_OUTPUT_ANGLE,
                has_bias_state: u32::from(core.bias_q_nm2().is_some()),
                gear_ratio: 100.0,
                sample_rate_hz: core.sample_rate_hz(),
                noise_nm: core.noise_nm(),
                bias_q_nm2: core.bias_q_nm2().unwrap_or(0.0),
                initial_oscillator_variance_nm2: core.initial_variance_nm2().0,
                initial_bias_variance_nm2: core.initial_variance_nm2().1,
                limits: $limits {
                    max_angle_step_rad: l.max_angle_step_rad,
                    max_step_change_rad: l.max_step_change_rad,
                    max_gap_periods: l.max_gap_periods,
                    nyquist_fraction: l.nyquist_fraction,
                    hold_below_hz: l.hold_below_hz,
                    covariance_inflation: l.covariance_inflation,
                    load_step_nis: l.load_step_nis,
                },
                orders,
                calibration: $cal {
                    kind: SW_CALIBRATION_GAIN,
                    extrapolation: SW_EXTRAPOLATION_CLAMP,
                    len: 1,
                    speed_min_rad_s: 0.0,
                    speed_max_rad_s: 0.0,
                    speed_rad_s: [0.0; SW_MAX_CALIBRATION_POINTS],
                    alpha,
                    beta_nm: [0.0; SW_MAX_CALIBRATION_POINTS],
                },
                guard: $guard {
                    off: 1,
                    learned_prior: 0,
                    apply_chi2: 0.0,
                    release_chi2: 0.0,
                    apply_wander: 0.0,
                    release_wander: 0.0,
                    min_cycles: 0.0,
                    min_cycles_output: 0.0,
                    window_s: 0.0,
                    nis_pass_through: 0.0,
                    nis_recover: 0.0,
                    contradiction_margin: 0.0,
                    nis_clip: 0.0,
                    partial_min_line_hz: 0.0,
                    complete_max_nis: 0.0,
                    standstill_max_nis: 0.0,
                    standstill_window_s: 0.0,
                },
            }
        }
    };
}
from_core!(from_core64, f64, sw_model, sw_order, sw_limits, sw_calibration, sw_guard);
from_core!(from_core32, f32, sw32_model, sw32_order, sw32_limits, sw32_calibration, sw32_guard);

/// The paper's 6th-order model with a 2.5 N·m/V gain, as a C program would write it.
fn taghirad6() -> sw_model {
    from_core64(&RippleModel::<f64, 3>::taghirad_6th_order(1000.0).unwrap())
}

/// Makes one field of a model invalid.
type Spoil = fn(&mut sw_model);

fn new_state() -> Box<sw_state> {
    Box::new(sw_state { magic: 0, storage: [0; SW_STATE_WORDS] })
}

fn text(code: i32) -> String {
    unsafe { CStr::from_ptr(sw_error_text(code)) }.to_str().unwrap().to_string()
}

/// A joint turning at 30 rad/s (motor) with ripple on a steady load, sample `k`.
fn sample(k: usize) -> (f64, f64, f64, f64) {
    let t = k as f64 * 1e-3;
    let motor = 30.0 * t;
    let output = motor / 100.0;
    let relative = motor - output;
    let torque_nm = 10.0 + 0.3 * (2.0 * relative).sin() + 0.1 * (4.0 * relative + 0.5).cos() + 0.2 * output.cos();
    (t, torque_nm / 2.5, motor, output)
}

#[test]
fn bad_input_gives_error_codes() {
    let model = taghirad6();
    let mut state = new_state();
    let s = sw_sample {
        time: 0.0,
        torque: 1.0,
        motor_angle: 0.0,
        output_angle: 0.0,
        motor_velocity: f64::NAN,
        expected_torque: f64::NAN,
    };
    let mut out = sw_output::default();
    unsafe {
        assert_eq!(sw_init(null_mut(), &model), SW_ERROR_NULL);
        assert_eq!(sw_init(&mut *state, null()), SW_ERROR_NULL);
        // Never initialised (zeroed, or garbage without the magic word).
        assert_eq!(sw_step(&mut *state, &s, &mut out), SW_ERROR_NOT_INITIALIZED);
        state.magic = 0x0123_4567_89ab_cdef;
        state.storage.fill(u64::MAX);
        assert_eq!(sw_step(&mut *state, &s, &mut out), SW_ERROR_NOT_INITIALIZED);
        assert_eq!(sw_reset(&mut *state), SW_ERROR_NOT_INITIALIZED);
        assert_eq!(sw_step(null_mut(), &s, &mut out), SW_ERROR_NULL);

        assert_eq!(sw_init(&mut *state, &model), SW_OK);
        assert_eq!(sw_step(&mut *state, null(), &mut out), SW_ERROR_NULL);
        assert_eq!(sw_step(&mut *state, &s, null_mut()), SW_ERROR_NULL);
        assert_eq!(sw_step(&mut *state, &s, &mut out), SW_OK);
        assert!(out.torque.is_finite());

        // Each invalid field: its code, and the state is no longer initialised.
        let cases: Vec<(i32, Spoil)> = vec![
            (SW_ERROR_VERSION, |m| m.version = 0),
            (SW_ERROR_ORDER_COUNT, |m| m.order_count = 0),
            (SW_ERROR_ORDER_COUNT, |m| m.order_count = 9),
            (SW_ERROR_ORDER_COUNT, |m| m.order_count = u32::MAX),
            (SW_ERROR_ORDER, |m| m.orders[0].reference = 3),
            (SW_ERROR_ORDER, |m| m.orders[1].multiple = 0.0),
            (SW_ERROR_ORDER, |m| m.orders[1].multiple = f64::NAN),
            (SW_ERROR_ORDER, |m| m.orders[2].q_per_sample_nm2 = -1.0),
            (SW_ERROR_ORDER, |m| m.orders[2].q_per_rad_nm2 = f64::INFINITY),
            (SW_ERROR_ORDER, |m| m.orders[0].prior_nm = [0.1, 0.0]),
            (SW_ERROR_ORDER, |m| m.orders[0].prior_variance_nm2 = -1.0),
            (SW_ERROR_ORDER, |m| m.orders[0].load_scaled = 2),
            (SW_ERROR_MODEL, |m| m.sample_rate_hz = 0.0),
            (SW_ERROR_MODEL, |m| m.noise_nm = f64::NAN),
            // Its square is finite, but every step's sums overflow (before: accepted, and
            // every `sw_step` then returned SW_ERROR_COVARIANCE).
            (SW_ERROR_MODEL, |m| m.noise_nm = 1e154),
            (SW_ERROR_MODEL, |m| m.phase_source = 7),
            (SW_ERROR_MODEL, |m| m.has_bias_state = 2),
            (SW_ERROR_MODEL, |m| {
                m.has_bias_state = 1;
                m.bias_q_nm2 = -1.0
            }),
            (SW_ERROR_MODEL, |m| m.initial_oscillator_variance_nm2 = 0.0),
            (SW_ERROR_MODEL, |m| m.limits.nyquist_fraction = 0.7),
            (SW_ERROR_MODEL, |m| m.limits.max_angle_step_rad = 4.0),
            (SW_ERROR_GEAR, |m| m.gear_ratio = -100.0),
            (SW_ERROR_GEAR, |m| m.gear_fixed = 2),
            (SW_ERROR_CALIBRATION, |m| m.calibration.alpha[0] = 0.0),
            (SW_ERROR_CALIBRATION, |m| m.calibration.kind = 4),
            (SW_ERROR_CALIBRATION, |m| m.calibration.len = 0),
            (SW_ERROR_CALIBRATION, |m| m.calibration.len = 65),
            (SW_ERROR_CALIBRATION, |m| m.calibration.extrapolation = 3),
            (SW_ERROR_CALIBRATION, |m| {
                m.calibration.kind = SW_CALIBRATION_SPEED_TABLE;
                m.calibration.len = 2; // breakpoints 0, 0: not increasing
            }),
            (SW_ERROR_CHANNELS, |m| m.channels = SW_CHANNEL_MOTOR_ANGLE),
            (SW_ERROR_CHANNELS, |m| m.channels |= 1 << 9),
            (SW_ERROR_CHANNELS, |m| m.phase_source = SW_PHASE_VELOCITY),
            (SW_ERROR_GUARD, |m| m.guard.off = 2),
            (SW_ERROR_GUARD, |m| {
                m.guard.off = 0;
                m.guard.learned_prior = 7
            }),
            (SW_ERROR_GUARD, |m| {
                m.guard.off = 0;
                m.guard.apply_chi2 = f64::NAN
            }),
            (SW_ERROR_GUARD, |m| {
                m.guard.off = 0;
                m.guard.window_s = -0.25
            }),
            (SW_ERROR_GUARD, |m| {
                m.guard.off = 0;
                m.guard.nis_clip = f64::INFINITY
            }),
        ];
        for (i, (code, spoil)) in cases.into_iter().enumerate() {
            let mut bad = model;
            spoil(&mut bad);
            assert_eq!(sw_init(&mut *state, &bad), code, "case {i}");
            assert_eq!(sw_step(&mut *state, &s, &mut out), SW_ERROR_NOT_INITIALIZED, "case {i}");
            assert!(!text(code).is_empty() && text(code) != text(-1), "case {i}");
        }
    }
    assert_eq!(text(SW_OK), "ok");
    assert_eq!(text(12345), "unknown strainwave error code");
    assert_eq!(text(i32::MIN), "unknown strainwave error code");
}

/// `sw_step` against the core's `step` on the same model, bit for bit, over a run with
/// a NaN torque now and then and a time step back.
fn same_as_core<const M: usize>(core: RippleModel<f64, M>) {
    let model = from_core64(&core);
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let mut core_state = RippleState::new(&core);
    let mut state = new_state();
    assert_eq!(unsafe { sw_init(&mut *state, &model) }, SW_OK);
    let mut out = sw_output::default();
    let mut last_t = None;
    for k in 0..3000 {
        let (t, volts, motor, output) = sample(k);
        let volts = if k % 997 == 5 { f64::NAN } else { volts };
        let t = if k == 1500 { t - 0.5 } else { t };
        let s = sw_sample {
            time: t,
            torque: volts,
            motor_angle: motor,
            output_angle: output,
            motor_velocity: 1.0,
            expected_torque: 5.0,
        };
        assert_eq!(unsafe { sw_step(&mut *state, &s, &mut out) }, SW_OK);
        let torque = if volts.is_finite() { 2.5 * volts } else { f64::NAN };
        let mut input = RippleInput::new(torque, ReferenceValues::from_gear(&gear, motor, output));
        if let Some(t0) = last_t.filter(|&t0| t > t0) {
            input = input.with_dt(t - t0);
        }
        last_t = Some(t);
        let o = step(&core, &mut core_state, &input).unwrap();
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        assert!(same(out.torque, o.torque_nm), "row {k}: {} vs {}", out.torque, o.torque_nm);
        assert!(same(out.ripple, o.ripple_nm) && same(out.misalignment, o.misalignment_nm), "row {k}");
        assert!(same(out.innovation, o.innovation_nm) && same(out.nis, o.nis), "row {k}");
        assert_eq!(out.flags, u32::from(o.flags.bits()), "row {k}");
    }
    assert!(out.torque.is_finite());

    // Reset: the same outputs as a fresh state.
    let mut fresh = new_state();
    let mut out2 = out;
    let (t, volts, motor, output) = sample(0);
    let s = sw_sample {
        time: t,
        torque: volts,
        motor_angle: motor,
        output_angle: output,
        motor_velocity: 0.0,
        expected_torque: 0.0,
    };
    unsafe {
        assert_eq!(sw_reset(&mut *state), SW_OK);
        assert_eq!(sw_init(&mut *fresh, &model), SW_OK);
        assert_eq!(sw_step(&mut *state, &s, &mut out), SW_OK);
        assert_eq!(sw_step(&mut *fresh, &s, &mut out2), SW_OK);
    }
    assert_eq!(out, out2);
}

#[test]
fn sw_step_equals_the_core_step() {
    same_as_core(RippleModel::<f64, 3>::taghirad_6th_order(1000.0).unwrap());
    same_as_core(RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap().with_bias_state(1e-4).unwrap());
    same_as_core(RippleModel::<f64, 3>::product(1000.0, 0.02).unwrap());
    let full = RippleModel::<f64, 5>::full(1000.0, 0.02).unwrap();
    let priors = [([0.3, 0.1], 1e-4), ([0.1, 0.0], 1e-4), ([0.01, 0.0], 1e-6), ([0.0, 0.01], 1e-6), ([0.2, 0.0], 1e-4)];
    same_as_core(full.with_priors(priors).unwrap());
}

#[test]
fn single_precision_matches_the_f32_core() {
    let core = RippleModel::<f32, 5>::full(1000.0, 0.02).unwrap();
    let model = from_core32(&core);
    let gear = Gear::new(100.0f32, FixedElement::CircularSpline).unwrap();
    let mut core_state = RippleState::new(&core);
    let mut state = Box::new(sw32_state { magic: 0, storage: [0; SW32_STATE_WORDS] });
    unsafe {
        assert_eq!(sw32_init(&mut *state, null()), SW_ERROR_NULL);
        assert_eq!(sw32_init(&mut *state, &model), SW_OK);
    }
    let mut out = sw32_output::default();
    let mut last_t: Option<f32> = None;
    for k in 0..3000 {
        let (t, volts, motor, output) = sample(k);
        // Wrapped angles and time, as f32 firmware would pass them.
        let wrap = |x: f64| (x % std::f64::consts::TAU) as f32;
        let s = sw32_sample {
            time: (t % 1.0) as f32,
            torque: volts as f32,
            motor_angle: wrap(motor),
            output_angle: wrap(output),
            motor_velocity: f32::NAN,
            expected_torque: f32::NAN,
        };
        assert_eq!(unsafe { sw32_step(&mut *state, &s, &mut out) }, SW_OK);
        let refs = ReferenceValues::from_gear(&gear, s.motor_angle, s.output_angle);
        let mut input = RippleInput::new(2.5f32 * s.torque, refs);
        if let Some(t0) = last_t.filter(|&t0| s.time > t0) {
            input = input.with_dt(s.time - t0);
        }
        last_t = Some(s.time);
        let o = step(&core, &mut core_state, &input).unwrap();
        assert_eq!(out.torque.to_bits(), o.torque_nm.to_bits(), "row {k}");
        assert_eq!(out.flags, u32::from(o.flags.bits()), "row {k}");
    }
    assert!(out.torque.is_finite());
}

/// The guard on (all thresholds 0: the defaults): `sw_step` gives the core guard's output
/// bit for bit, its flags in `guard_flags` and the orders it did not apply in
/// `withheld_orders`; the model starts cold, so some order is withheld at first and later
/// applied.
#[test]
fn guarded_sw_step_equals_the_core_guard() {
    let core = RippleModel::<f64, 5>::full(1000.0, 0.02).unwrap();
    let mut model = from_core64(&core);
    model.guard.off = 0;
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let mut guard = Guard::new(&core, GuardSettings::default());
    let mut state = new_state();
    assert_eq!(unsafe { sw_init(&mut *state, &model) }, SW_OK);
    let mut out = sw_output::default();
    let (mut withheld, mut applied) = (false, false);
    for k in 0..6000 {
        let (t, volts, motor, output) = sample(k);
        let s = sw_sample {
            time: t,
            torque: volts,
            motor_angle: motor,
            output_angle: output,
            motor_velocity: f64::NAN,
            expected_torque: f64::NAN,
        };
        assert_eq!(unsafe { sw_step(&mut *state, &s, &mut out) }, SW_OK);
        let mut input = RippleInput::new(2.5 * volts, ReferenceValues::from_gear(&gear, motor, output));
        if k > 0 {
            input = input.with_dt(1e-3);
        }
        let o = guard.step(&core, &input).unwrap();
        assert_eq!(out.torque.to_bits(), o.output.torque_nm.to_bits(), "row {k}");
        assert_eq!(out.ripple.to_bits(), o.output.ripple_nm.to_bits(), "row {k}");
        assert_eq!(out.flags, u32::from(o.output.flags.bits()), "row {k}");
        assert_eq!(out.guard_flags, u32::from(o.flags.bits()), "row {k}");
        assert_eq!(out.withheld_orders, u32::from(o.withheld_mask()), "row {k}");
        withheld |= out.guard_flags & SW_GUARD_WITHHELD != 0;
        // The 4x line (19 Hz here) is applied once shown; the misalignment never is.
        applied |= out.withheld_orders & 0b10 == 0;
    }
    assert!(withheld && applied, "the guard withheld the orders at first, then applied the 4x line");
}

/// A finite glitch that breaks the covariance (an expected torque of 2.5·10¹⁶⁰ N·m,
/// matched by the torque, overflows the load-scaled orders' innovation variance):
/// `SW_ERROR_COVARIANCE`, the calibrated torque passed through, nothing applied, and every
/// order's bit in `withheld_orders`; the next sample steps again.
#[test]
fn a_covariance_reset_marks_every_order_withheld() {
    let mut model = from_core64(&RippleModel::<f64, 5>::full(1000.0, 0.02).unwrap());
    model.guard.off = 0;
    model.channels |= SW_CHANNEL_EXPECTED_TORQUE;
    let mut state = new_state();
    assert_eq!(unsafe { sw_init(&mut *state, &model) }, SW_OK);
    let mut out = sw_output::default();
    let mut resets = 0;
    for k in 0..3010 {
        let (t, volts, motor, output) = sample(k);
        let torque = if k == 3000 { 1e160 } else { volts };
        let s = sw_sample {
            time: t,
            torque,
            motor_angle: motor,
            output_angle: output,
            motor_velocity: f64::NAN,
            expected_torque: if k == 3000 { 2.5 * torque } else { 0.0 },
        };
        let code = unsafe { sw_step(&mut *state, &s, &mut out) };
        if code == SW_ERROR_COVARIANCE && k == 3000 {
            resets += 1;
            assert_eq!((out.ripple, out.misalignment, out.withheld_orders), (0.0, 0.0, 0b11111), "row {k}");
            assert_eq!(out.torque, 2.5 * torque, "row {k}");
        } else {
            assert_eq!(code, SW_OK, "row {k}");
        }
    }
    assert_eq!(resets, 1);
}
