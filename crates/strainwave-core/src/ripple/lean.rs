//! The common sample of a single joint, as scalar code, for the models the one-loop
//! step (`fused`) does not take: motor-angle orders, fractional multiples, velocity
//! input. The same decisions and the same arithmetic as the `fast` module for `J = 1`,
//! in the same order of operations (so bit for bit the general path), without lane
//! arrays, masks or intermediate structs.
//!
//! The check runs before any state is written; if it fails, nothing has changed and the
//! caller takes the general path.

// Several arrays share the order index, and `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::RippleBank;
use super::io::{OrderStatus, RippleInput, RippleOutput, StepFlags};
use super::joint::{array, block_times, common_interval, finite, healthy, load_steps, sum_from};
use super::model::{PhaseSource, RippleModel};
use super::plan::HOLD_AVERAGE;
use super::trig::{phasor_power, sin_cos_small, wrap_angle};
use crate::Real;

/// One step of joint 0 if the sample is the common case, else `None` with nothing changed.
#[inline(always)]
pub(crate) fn step<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, 1>,
    input: &RippleInput<T>,
) -> Option<RippleOutput<T>> {
    let dt = common_interval(model, input.dt_s)?;
    let y = input.torque_nm - input.expected_torque_nm;
    if !(finite(y) & bank.has_last[0] & (bank.pending_samples[0] == T::ZERO)) {
        return None;
    }
    let refs = [input.references.relative, input.references.output, input.references.motor];
    let angle_input = model.phase_source == PhaseSource::Angle;
    let lim = &model.limits;

    // Decide: increments and running means of the used references.
    let mut delta = [T::ZERO; 3];
    let mut mean = [T::ZERO; 3];
    for r in 0..3 {
        if !model.uses[r] {
            continue;
        }
        let v = refs[r];
        let last = bank.last[r][0];
        // `wrap_angle` equals the fast path's near form wherever that applies.
        let d = if angle_input { wrap_angle(v - last) } else { (v + last) * T::HALF * dt };
        let changed = bank.delta_known[0] & !((d - bank.last_delta[r][0]).abs() <= lim.max_step_change_rad);
        if !(finite(v) & (d.abs() <= lim.max_angle_step_rad) & !changed) {
            return None;
        }
        let m = bank.mean_delta[r][0];
        delta[r] = d;
        mean[r] = m + (d - m) * T::from_f64(HOLD_AVERAGE);
    }
    let mut abs_a = [T::ZERO; M];
    for i in 0..M {
        let o = &model.orders[i];
        let r = o.reference.index();
        let a = (o.multiple * delta[r]).abs();
        let mean_a = (o.multiple * mean[r]).abs();
        let active = bank.status[i][0] == OrderStatus::Active;
        if !(active & (a <= model.off_above_rad) & !(mean_a < model.hold_below_rad)) {
            return None;
        }
        abs_a[i] = a;
    }

    // Commit the phase-side state and form the phasors.
    bank.steps[0] = bank.steps[0].wrapping_add(1);
    bank.pending_dt[0] = T::ZERO;
    bank.delta_known[0] = true;
    let mut base = [(T::ONE, T::ZERO); 3];
    for r in 0..3 {
        if !model.uses[r] {
            continue;
        }
        bank.last_delta[r][0] = delta[r];
        bank.mean_delta[r][0] = mean[r];
        let x = if angle_input { refs[r] } else { bank.psi[r][0] + delta[r] };
        bank.last[r][0] = refs[r];
        let psi = wrap_angle(x);
        bank.psi[r][0] = psi;
        let (s, c) = sin_cos_small(psi);
        base[r] = (c, s);
    }
    let load = if model.any_load_scaled {
        let v = (input.expected_torque_nm + bank.b[0]).abs();
        if finite(v) {
            v
        } else {
            T::ZERO
        }
    } else {
        T::ONE
    };
    let mut h = [[T::ZERO; 2]; M];
    for i in 0..M {
        let o = &model.orders[i];
        let (c, s) = base[o.reference.index()];
        let (mut c, mut s) = match model.power[i] {
            0 => {
                let psi = wrap_angle(bank.order_psi[i][0] + o.multiple * delta[o.reference.index()]);
                bank.order_psi[i][0] = psi;
                let (s, c) = sin_cos_small(psi);
                (c, s)
            }
            1 => (c, s),
            n => phasor_power(c, s, n),
        };
        if o.load_scaled {
            c *= load;
            s *= load;
        }
        bank.phasor[i][0][0] = c;
        bank.phasor[i][1][0] = s;
        h[i] = [c, s];
    }

    // Time update: inflation and process noise on the diagonal blocks, and the bias.
    let infl = lim.covariance_inflation;
    for i in 0..M {
        let o = &model.orders[i];
        let q = o.q_per_sample_nm2 + o.q_per_rad_nm2 * abs_a[i];
        let d = &mut bank.p[i][i];
        let grow = infl * T::HALF * (d[0][0][0] + d[1][1][0]);
        d[0][0][0] = d[0][0][0] + grow + q;
        d[1][1][0] = d[1][1][0] + grow + q;
    }
    let has_bias = model.bias_q_nm2.is_some();
    if has_bias {
        let q_b = model.bias_q_nm2.unwrap_or(T::ZERO);
        let v = bank.pbb[0];
        bank.pbb[0] = v + v * infl + q_b;
    }

    // Prediction and gains g = P hᵀ (upper blocks of the symmetric P).
    let (mut ripple, mut mis) = (T::ZERO, T::ZERO);
    let (mut any_ripple, mut any_mis) = (false, false);
    for i in 0..M {
        let v = h[i][0] * bank.z[i][0][0] + h[i][1] * bank.z[i][1][0];
        if model.orders[i].reference.is_ripple() {
            ripple = sum_from(!any_ripple, ripple, v);
            any_ripple = true;
        } else {
            mis = sum_from(!any_mis, mis, v);
            any_mis = true;
        }
    }
    let upd_b = if has_bias { T::ONE } else { T::ZERO };
    let mut g = [[T::ZERO; 2]; M];
    for i in 0..M {
        let (mut g0, mut g1) = (T::ZERO, T::ZERO);
        if has_bias {
            g0 = bank.pb[i][0][0] * upd_b;
            g1 = bank.pb[i][1][0] * upd_b;
        }
        for j in 0..M {
            let [hj0, hj1] = h[j];
            let (t0, t1) = block_times::<T, M, 1, false>(bank, i, j, 0, [hj0, hj1]);
            let first = !has_bias && j == 0;
            g0 = sum_from(first, g0, t0);
            g1 = sum_from(first, g1, t1);
        }
        g[i] = [g0, g1];
    }
    let mut gb = T::ZERO;
    if has_bias {
        gb = bank.pbb[0] * upd_b;
        for j in 0..M {
            gb += bank.pb[j][0][0] * h[j][0] + bank.pb[j][1][0] * h[j][1];
        }
    }

    // Innovation and the load-step decision.
    let mut s = gb * upd_b;
    for i in 0..M {
        s = sum_from(!has_bias && i == 0, s, h[i][0] * g[i][0] + h[i][1] * g[i][1]);
    }
    let s_var = model.r_nm2 + s;
    let mut inv = T::ONE / s_var;
    let e = y - (ripple + mis + bank.b[0]);
    let mut load_step = false;
    if has_bias && model.limits.load_step_nis > T::ZERO {
        load_step = e * e > model.limits.load_step_nis * s_var;
        inv = if load_step { T::ZERO } else { inv };
    }

    // Measurement update.
    let mut k = [[T::ZERO; 2]; M];
    for i in 0..M {
        k[i] = [g[i][0] * inv, g[i][1] * inv];
        bank.z[i][0][0] += k[i][0] * e;
        bank.z[i][1][0] += k[i][1] * e;
    }
    let floor = model.r_nm2 * inv;
    for i in 0..M {
        let [k0, k1] = k[i];
        let [g0, g1] = g[i];
        let d = &mut bank.p[i][i];
        let (v0, v1) = (d[0][0][0], d[1][1][0]);
        d[0][0][0] = (v0 - g0 * g0 * inv).max(v0 * floor);
        d[1][1][0] = (v1 - g1 * g1 * inv).max(v1 * floor);
        let off = d[0][1][0] - g0 * g1 * inv;
        d[0][1][0] = off;
        d[1][0][0] = off;
        for j in i + 1..M {
            let [gj0, gj1] = g[j];
            let b = &mut bank.p[i][j];
            b[0][0][0] -= g0 * gj0 * inv;
            b[0][1][0] -= g0 * gj1 * inv;
            b[1][0][0] -= g1 * gj0 * inv;
            b[1][1][0] -= g1 * gj1 * inv;
        }
        if has_bias {
            bank.pb[i][0][0] -= k0 * gb;
            bank.pb[i][1][0] -= k1 * gb;
        }
    }
    let mut flags = StepFlags::empty();
    if has_bias {
        let kb = gb * inv;
        bank.b[0] += kb * e;
        let v = bank.pbb[0];
        bank.pbb[0] = (v - kb * gb).max(v * model.r_nm2 * inv);
        if load_step {
            flags.insert(StepFlags::LOAD_STEP);
            let lanes = |a: &[[T; 2]; M]| array([[T::ZERO; 1]; 2], |i| [[a[i][0]], [a[i][1]]]);
            load_steps(model.r_nm2, bank, &lanes(&h), &lanes(&g), &[true], &[e]);
        }
    }

    // Health check and outputs.
    if !healthy(has_bias, bank, 0, s_var) {
        bank.reset_lane(model, 0);
        flags.insert(StepFlags::COVARIANCE_RESET);
    }
    let torque = input.torque_nm - ripple - mis;
    Some(RippleOutput {
        torque_nm: torque,
        ripple_nm: ripple,
        misalignment_nm: mis,
        torque_state_nm: if has_bias { input.expected_torque_nm + bank.b[0] } else { torque },
        innovation_nm: e,
        innovation_variance_nm2: s_var,
        nis: e * e / s_var,
        flags,
    })
}
