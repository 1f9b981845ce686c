//! Phase A of a step: the per-joint decisions before any arithmetic on the state —
//! input validity, reference increments `Δθ = wrap_π(θ(k) − θ(k−1))` (or `ω dt`),
//! encoder jumps and time gaps, each order's status (active, held, off), its phase
//! increment `a_i = n_i Δθ` and process noise `q_i = q_s + q_rad |a_i|`.
//!
//! The results are masks (1 or 0 per order and joint) that the arithmetic of
//! [`kernel`](super::kernel) applies without branching.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, RippleBank};
use super::io::{OrderStatus, StepFlags};
use super::model::{PhaseSource, RippleModel};
use super::trig::wrap_angle;
use crate::Real;

/// Per-order, per-joint decisions of the time update.
pub(crate) struct Plan<T: Real, const M: usize, const J: usize> {
    pub(crate) inc: [[T; J]; M],
    pub(crate) q: [[T; J]; M],
    pub(crate) keep: [[T; J]; M],
    pub(crate) couple: [[T; J]; M],
    pub(crate) infl: [T; J],
    pub(crate) pred: [[T; J]; M],
    pub(crate) upd: [[T; J]; M],
    pub(crate) q_b: [T; J],
    pub(crate) upd_b: [T; J],
    pub(crate) reinflate: [bool; J],
    pub(crate) y: [T; J],
    pub(crate) meas_ok: [bool; J],
    pub(crate) flags: [StepFlags; J],
    /// Every joint is in the common case: a good sample, not the first, no reset, every
    /// order active. The masks are then all 1 and their loops can be skipped (the
    /// arithmetic is otherwise identical, bit for bit).
    pub(crate) plain: bool,
}

/// Weight of the newest increment in the running mean that decides holding (1/16).
pub(super) const HOLD_AVERAGE: f64 = 1.0 / 16.0;

fn classify<T: Real, const M: usize>(model: &RippleModel<T, M>, abs_a: T) -> OrderStatus {
    if abs_a < model.hold_below_rad {
        OrderStatus::Held
    } else {
        OrderStatus::Active
    }
}

impl<T: Real, const M: usize, const J: usize> Plan<T, M, J> {
    pub(crate) fn new() -> Self {
        Self {
            inc: [[T::ZERO; J]; M],
            q: [[T::ZERO; J]; M],
            keep: [[T::ONE; J]; M],
            couple: [[T::ONE; J]; M],
            infl: [T::ZERO; J],
            pred: [[T::ONE; J]; M],
            upd: [[T::ZERO; J]; M],
            q_b: [T::ZERO; J],
            upd_b: [T::ZERO; J],
            reinflate: [false; J],
            y: [T::ZERO; J],
            meas_ok: [false; J],
            flags: [StepFlags::empty(); J],
            plain: true,
        }
    }
}

/// Phase A: scalar decisions per joint (validity, increments, jumps, gaps, statuses).
pub(crate) fn plan<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    pl: &mut Plan<T, M, J>,
) {
    let refs = [&input.references.relative, &input.references.output, &input.references.motor];
    let has_bias = model.bias_q_nm2.is_some();
    let q_bias = model.bias_q_nm2.unwrap_or(T::ZERO);
    let angle_input = model.phase_source == PhaseSource::Angle;
    let used = &model.used_refs[..usize::from(model.n_used).min(3)];
    let lim = &model.limits;
    for l in 0..J {
        bank.steps[l] = bank.steps[l].wrapping_add(1);
        let y = input.torque_nm[l] - input.expected_torque_nm[l];
        pl.y[l] = y;
        let dt = input.dt_s.unwrap_or(model.dt_s);
        let dt_ok = dt.is_finite() && dt > T::ZERO;
        let refs_ok = used.iter().all(|&r| refs[usize::from(r)][l].is_finite());
        let mut flags = StepFlags::empty();
        if !(refs_ok && dt_ok) {
            // State untouched: identity rotation, no noise, no update.
            pl.plain = false;
            flags.insert(StepFlags::ANGLE_SKIPPED);
            bank.pending_samples[l] += T::ONE;
            bank.pending_dt[l] += if dt_ok { dt } else { model.dt_s };
            for i in 0..M {
                let st = bank.status[i][l];
                pl.pred[i][l] = if st == OrderStatus::Off { T::ZERO } else { T::ONE };
                status_flags(&mut flags, st);
            }
            pl.flags[l] = flags;
            continue;
        }
        let meas_ok = y.is_finite();
        pl.meas_ok[l] = meas_ok;
        let caught_up = bank.pending_samples[l] == T::ZERO;
        let (n_samples, total_dt) =
            if caught_up { (T::ONE, dt) } else { (bank.pending_samples[l] + T::ONE, bank.pending_dt[l] + dt) };
        bank.pending_samples[l] = T::ZERO;
        bank.pending_dt[l] = T::ZERO;
        let first = !bank.has_last[l];
        let gap = !first && !(total_dt <= model.max_gap_s);
        // The initial state is the prior of the first sample: no noise before it.
        let n_noise = if first { T::ZERO } else { n_samples };
        pl.infl[l] = if first { T::ZERO } else { lim.covariance_inflation };
        let mut delta = [T::ZERO; 3];
        let mut jump = [false; 3];
        for &r in used {
            let r = usize::from(r);
            let v = refs[r][l];
            if !first {
                let last = bank.last[r][l];
                let d = if angle_input { wrap_angle(v - last) } else { (v + last) * T::HALF * total_dt };
                // A glitch: an increment too large, or too different from the last one.
                let expected = bank.last_delta[r][l] * n_samples;
                let changed = bank.delta_known[l] && !((d - expected).abs() <= lim.max_step_change_rad);
                let jumped = !(d.abs() <= lim.max_angle_step_rad) || changed;
                if !jumped {
                    let per_sample = if caught_up { d } else { d / n_samples };
                    bank.last_delta[r][l] = per_sample;
                    // Mean increment over ~16 samples: encoder jitter at standstill
                    // averages out of it, so it alone decides whether an order is held.
                    let m = bank.mean_delta[r][l];
                    bank.mean_delta[r][l] = m + (per_sample - m) * T::from_f64(HOLD_AVERAGE);
                }
                jump[r] = jumped;
                delta[r] = d;
            }
            bank.last[r][l] = v;
            bank.psi[r][l] = if angle_input {
                wrap_angle(v)
            } else if !jump[r] {
                wrap_angle(bank.psi[r][l] + delta[r])
            } else {
                bank.psi[r][l]
            };
        }
        bank.has_last[l] = true;
        let any_jump = jump[0] || jump[1] || jump[2];
        // After a jump or a gap the next increment sets a new baseline.
        bank.delta_known[l] = !first && !gap && !any_jump;
        let mut lane_plain = meas_ok && !first && !gap;
        if !meas_ok {
            flags.insert(StepFlags::MEASUREMENT_SKIPPED);
        }
        if gap {
            flags.insert(StepFlags::GAP_RESET);
        } else if any_jump {
            flags.insert(StepFlags::JUMP_RESET);
        }
        let upd = if meas_ok { T::ONE } else { T::ZERO };
        for i in 0..M {
            let o = &model.orders[i];
            let r = o.reference.index();
            let reset = gap || jump[r];
            let a = if reset { T::ZERO } else { o.multiple * delta[r] };
            let abs_a = a.abs();
            let mean_a = (o.multiple * bank.mean_delta[r][l]).abs();
            let q_moving = o.q_per_sample_nm2 * n_noise + o.q_per_rad_nm2 * abs_a;
            let prev = bank.status[i][l];
            if !reset && prev == OrderStatus::Active && abs_a <= model.off_above_rad && !(mean_a < model.hold_below_rad)
            {
                // The common case: stays active (keep, couple and pred are already 1).
                pl.upd[i][l] = upd;
                pl.inc[i][l] = a;
                pl.q[i][l] = q_moving;
            } else {
                let new = if reset {
                    OrderStatus::Held
                } else {
                    match prev {
                        OrderStatus::Off if !(abs_a < model.on_below_rad) => OrderStatus::Off,
                        OrderStatus::Active | OrderStatus::Held if abs_a > model.off_above_rad => OrderStatus::Off,
                        _ => classify(model, mean_a),
                    }
                };
                bank.status[i][l] = new;
                status_flags(&mut flags, new);
                let off = new == OrderStatus::Off;
                let zeroed = reset || off;
                let active = new == OrderStatus::Active;
                lane_plain &= active;
                pl.keep[i][l] = if zeroed { T::ZERO } else { T::ONE };
                pl.couple[i][l] = if active { T::ONE } else { T::ZERO };
                pl.pred[i][l] = if off { T::ZERO } else { T::ONE };
                pl.upd[i][l] = if active { upd } else { T::ZERO };
                pl.inc[i][l] = if zeroed { T::ZERO } else { a };
                pl.q[i][l] = if off { T::ZERO } else { q_moving };
            }
            if model.power[i] == 0 {
                bank.order_psi[i][l] = wrap_angle(bank.order_psi[i][l] + pl.inc[i][l]);
            }
        }
        if has_bias {
            pl.q_b[l] = q_bias * n_noise;
            pl.upd_b[l] = upd;
            pl.reinflate[l] = gap;
        }
        pl.flags[l] = flags;
        pl.plain &= lane_plain;
    }
}

fn status_flags(flags: &mut StepFlags, st: OrderStatus) {
    match st {
        OrderStatus::Off => flags.insert(StepFlags::ORDER_OFF),
        OrderStatus::Held => flags.insert(StepFlags::ORDER_HELD),
        OrderStatus::Active => {}
    }
}
