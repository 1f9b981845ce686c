//! The C structs into the precision-generic forms of [`crate::engine`] and back.

use crate::engine::{Output, Plain, PlainCalibration, PlainGuard, PlainOrder, Sample};
use crate::types::*;
use strainwave_core::ripple::Limits;

macro_rules! convert {
    ($t:ty, $model:ty, $sample:ty, $output:ty) => {
        impl From<&$model> for Plain<$t> {
            fn from(m: &$model) -> Self {
                let l = &m.limits;
                let c = &m.calibration;
                let g = &m.guard;
                Self {
                    version: m.version,
                    order_count: m.order_count,
                    gear_fixed: m.gear_fixed,
                    phase_source: m.phase_source,
                    channels: m.channels,
                    has_bias_state: m.has_bias_state,
                    gear_ratio: m.gear_ratio,
                    sample_rate_hz: m.sample_rate_hz,
                    noise_nm: m.noise_nm,
                    bias_q_nm2: m.bias_q_nm2,
                    p0_oscillator_nm2: m.initial_oscillator_variance_nm2,
                    p0_bias_nm2: m.initial_bias_variance_nm2,
                    limits: Limits {
                        max_angle_step_rad: l.max_angle_step_rad,
                        max_step_change_rad: l.max_step_change_rad,
                        max_gap_periods: l.max_gap_periods,
                        nyquist_fraction: l.nyquist_fraction,
                        hold_below_hz: l.hold_below_hz,
                        covariance_inflation: l.covariance_inflation,
                        load_step_nis: l.load_step_nis,
                    },
                    orders: m.orders.map(|o| PlainOrder {
                        reference: o.reference,
                        load_scaled: o.load_scaled,
                        multiple: o.multiple,
                        q_per_sample_nm2: o.q_per_sample_nm2,
                        q_per_rad_nm2: o.q_per_rad_nm2,
                        prior_nm: o.prior_nm,
                        prior_variance_nm2: o.prior_variance_nm2,
                    }),
                    calibration: PlainCalibration {
                        kind: c.kind,
                        extrapolation: c.extrapolation,
                        len: c.len,
                        speed_min_rad_s: c.speed_min_rad_s,
                        speed_max_rad_s: c.speed_max_rad_s,
                        speed_rad_s: c.speed_rad_s,
                        alpha: c.alpha,
                        beta_nm: c.beta_nm,
                    },
                    guard: PlainGuard {
                        off: g.off,
                        learned_prior: g.learned_prior,
                        thresholds: [
                            g.apply_chi2,
                            g.release_chi2,
                            g.apply_wander,
                            g.release_wander,
                            g.min_cycles,
                            g.min_cycles_output,
                            g.window_s,
                            g.nis_pass_through,
                            g.nis_recover,
                            g.contradiction_margin,
                            g.nis_clip,
                            g.partial_min_line_hz,
                            g.complete_max_nis,
                            g.standstill_max_nis,
                            g.standstill_window_s,
                        ],
                    },
                }
            }
        }

        impl From<&$sample> for Sample<$t> {
            fn from(s: &$sample) -> Self {
                Self {
                    time: s.time,
                    torque: s.torque,
                    motor_angle: s.motor_angle,
                    output_angle: s.output_angle,
                    motor_velocity: s.motor_velocity,
                    expected_torque: s.expected_torque,
                }
            }
        }

        impl From<Output<$t>> for $output {
            fn from(o: Output<$t>) -> Self {
                Self {
                    torque: o.torque,
                    ripple: o.ripple,
                    misalignment: o.misalignment,
                    innovation: o.innovation,
                    nis: o.nis,
                    flags: o.flags,
                    guard_flags: o.guard_flags,
                    withheld_orders: o.withheld_orders,
                }
            }
        }
    };
}

convert!(f64, sw_model, sw_sample, sw_output);
convert!(f32, sw32_model, sw32_sample, sw32_output);
