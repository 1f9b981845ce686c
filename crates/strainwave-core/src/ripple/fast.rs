//! The common sample, decided cheaply and computed without masks: every joint has a
//! finite torque and finite references, is caught up (no skipped samples pending), not
//! at its first sample, within the gap limit, without a jump, and every order stays
//! active. Then the decisions of `plan` are all trivial (keep = couple = pred = upd = 1,
//! no flags) and the step is the general one with the masks left out, bit for bit.
//!
//! The check runs before any state is written; if a joint fails it, nothing has changed
//! and the caller takes the general path.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::io::{OrderStatus, StepFlags};
use super::model::{PhaseSource, RippleModel};
use super::trig::{phasors, wrap_angle};
use crate::Real;

/// Weight of the newest increment in the running mean that decides holding (as in `plan`).
const HOLD_AVERAGE: f64 = 1.0 / 16.0;

/// `wrap_angle` for `|x| ≤ 3π` as selects (vectorizes); larger `|x|` are fixed up after.
#[inline(always)]
pub(super) fn wrap_near<T: Real>(x: T) -> T {
    let up = if x < -T::PI { x + T::TAU } else { x };
    if x > T::PI {
        x - T::TAU
    } else {
        up
    }
}

/// One step if every joint is in the common case, else `None` with nothing changed.
#[inline(always)]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> Option<BankOutput<T, J>> {
    let dt = input.dt_s.unwrap_or(model.dt_s);
    // One interval for all joints: valid and no gap (`pending = 0`, so it is the total).
    if !(dt.is_finite() && dt > T::ZERO && dt <= model.max_gap_s) {
        return None;
    }
    let refs = [&input.references.relative, &input.references.output, &input.references.motor];
    let angle_input = model.phase_source == PhaseSource::Angle;
    let lim = &model.limits;
    let three_pi = T::from_f64(3.0) * T::PI;

    // Decide: increments, means and every condition, into temporaries. The conditions
    // are accumulated without branches so the lane loops vectorize.
    let mut ok = [true; J];
    let mut y = [T::ZERO; J];
    for l in 0..J {
        y[l] = input.torque_nm[l] - input.expected_torque_nm[l];
        ok[l] = finite(y[l]) & bank.has_last[l] & (bank.pending_samples[l] == T::ZERO);
    }
    let mut delta = [[T::ZERO; J]; 3];
    let mut mean = [[T::ZERO; J]; 3];
    // A constant reference index per iteration (not a list of the used ones) makes
    // every access below a fixed offset.
    for r in 0..3 {
        if !model.uses[r] {
            continue;
        }
        let mut far = false;
        for l in 0..J {
            ok[l] &= finite(refs[r][l]);
        }
        if angle_input {
            for l in 0..J {
                let d = refs[r][l] - bank.last[r][l];
                far |= !(d.abs() <= three_pi);
                delta[r][l] = wrap_near(d);
            }
        } else {
            for l in 0..J {
                delta[r][l] = (refs[r][l] + bank.last[r][l]) * T::HALF * dt;
            }
        }
        if far {
            // Unwrapped input: exact wrapping where the near form does not apply.
            for l in 0..J {
                delta[r][l] = wrap_angle(refs[r][l] - bank.last[r][l]);
            }
        }
        for l in 0..J {
            let d = delta[r][l];
            let changed = bank.delta_known[l] & !((d - bank.last_delta[r][l]).abs() <= lim.max_step_change_rad);
            ok[l] &= (d.abs() <= lim.max_angle_step_rad) & !changed;
            let m = bank.mean_delta[r][l];
            mean[r][l] = m + (d - m) * T::from_f64(HOLD_AVERAGE);
        }
    }
    let mut abs_a = [[T::ZERO; J]; M];
    for i in 0..M {
        let o = &model.orders[i];
        let r = o.reference.index();
        for l in 0..J {
            let a = (o.multiple * delta[r][l]).abs();
            let mean_a = (o.multiple * mean[r][l]).abs();
            let active = bank.status[i][l] == OrderStatus::Active;
            ok[l] &= active & (a <= model.off_above_rad) & !(mean_a < model.hold_below_rad);
            abs_a[i][l] = a;
        }
    }
    if !ok.iter().all(|&k| k) {
        return None;
    }

    // Commit the phase-side state, as `plan` does for this case.
    for l in 0..J {
        bank.steps[l] = bank.steps[l].saturating_add(1);
        bank.pending_dt[l] = T::ZERO;
        bank.delta_known[l] = true;
    }
    for r in 0..3 {
        if !model.uses[r] {
            continue;
        }
        bank.last_delta[r] = delta[r];
        bank.mean_delta[r] = mean[r];
        // New phase: the angle itself, or the accumulated increments. One loop per
        // source and the range test as a lane-wise OR keep the loops branch-free.
        let mut x = *refs[r];
        if !angle_input {
            for l in 0..J {
                x[l] = bank.psi[r][l] + delta[r][l];
            }
        }
        bank.last[r] = *refs[r];
        let mut far = false;
        for l in 0..J {
            far |= !(x[l].abs() <= three_pi);
            bank.psi[r][l] = wrap_near(x[l]);
        }
        if far {
            for l in 0..J {
                bank.psi[r][l] = wrap_angle(x[l]);
            }
        }
    }
    for i in 0..M {
        if model.power[i] == 0 {
            let o = &model.orders[i];
            let r = o.reference.index();
            for l in 0..J {
                bank.order_psi[i][l] = wrap_angle(bank.order_psi[i][l] + o.multiple * delta[r][l]);
            }
        }
    }

    phasors(model, bank, input);

    // Everything after the phasors, one joint at a time: the temporaries stay in
    // registers and the loop vectorizes across joints as a whole.
    let mut out = empty_output();
    let mut load_step = [false; J];
    let mut bad = [false; J];
    // Local copies: the loop then reads and writes no memory the bank could share, so
    // it vectorizes without run-time overlap checks.
    let par = Params::new(model);
    let (torque, expected) = (input.torque_nm, input.expected_torque_nm);
    let abs_at = |l: usize| core::array::from_fn(|i| abs_a[i][l]);
    if model.bias_q_nm2.is_some() {
        for l in 0..J {
            let h = core::array::from_fn(|i| [bank.phasor[i][0][l], bank.phasor[i][1][l]]);
            (load_step[l], bad[l]) = joint::<T, M, J, true>(&par, bank, &torque, &expected, h, abs_at(l), l, &mut out);
        }
    } else {
        for l in 0..J {
            let h = core::array::from_fn(|i| [bank.phasor[i][0][l], bank.phasor[i][1][l]]);
            (load_step[l], bad[l]) = joint::<T, M, J, false>(&par, bank, &torque, &expected, h, abs_at(l), l, &mut out);
        }
    }
    settle(model, bank, input, &load_step, &bad, &mut out);
    Some(out)
}

/// An output to fill in.
#[inline(always)]
pub(super) fn empty_output<T: Real, const J: usize>() -> BankOutput<T, J> {
    BankOutput {
        torque_nm: [T::ZERO; J],
        ripple_nm: [T::ZERO; J],
        misalignment_nm: [T::ZERO; J],
        torque_state_nm: [T::ZERO; J],
        innovation_nm: [T::ZERO; J],
        innovation_variance_nm2: [T::ZERO; J],
        nis: [T::ZERO; J],
        flags: [StepFlags::empty(); J],
    }
}

/// Flags for the joints with a load step, and the reset of joints whose covariance
/// went bad (rare, so after the loop).
#[inline(always)]
pub(super) fn settle<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    load_step: &[bool; J],
    bad: &[bool; J],
    out: &mut BankOutput<T, J>,
) {
    if load_step.iter().any(|&s| s) {
        for l in 0..J {
            if load_step[l] {
                out.flags[l].insert(StepFlags::LOAD_STEP);
            }
        }
    }
    if bad.iter().any(|&b| b) {
        for l in 0..J {
            if bad[l] {
                bank.reset_lane(model, l);
                out.flags[l].insert(StepFlags::COVARIANCE_RESET);
                if model.bias_q_nm2.is_some() {
                    out.torque_state_nm[l] = input.expected_torque_nm[l] + bank.b[l];
                }
            }
        }
    }
}

/// The model's numbers that one joint's update reads.
#[derive(Clone, Copy)]
pub(super) struct Params<T: Real, const M: usize> {
    q_per_sample: [T; M],
    q_per_rad: [T; M],
    is_ripple: [bool; M],
    r: T,
    inflation: T,
    q_bias: T,
    load_step_nis: T,
}

impl<T: Real, const M: usize> Params<T, M> {
    #[inline(always)]
    pub(super) fn new(model: &RippleModel<T, M>) -> Self {
        Self {
            q_per_sample: core::array::from_fn(|i| model.orders[i].q_per_sample_nm2),
            q_per_rad: core::array::from_fn(|i| model.orders[i].q_per_rad_nm2),
            is_ripple: core::array::from_fn(|i| model.orders[i].reference.is_ripple()),
            r: model.r_nm2,
            inflation: model.limits.covariance_inflation,
            q_bias: model.bias_q_nm2.unwrap_or(T::ZERO),
            load_step_nis: model.limits.load_step_nis,
        }
    }
}

/// Joint `l` from the time update to the outputs, given its update row `h` (the
/// phasors) and phase increments `abs_a`: the kernel's arithmetic in the same order of
/// operations, with selects instead of branches (so the caller's loop over the joints
/// vectorizes). Returns (load step, covariance bad); the caller resets bad joints.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn joint<T: Real, const M: usize, const J: usize, const BIAS: bool>(
    par: &Params<T, M>,
    bank: &mut RippleBank<T, M, J>,
    torque_nm: &[T; J],
    expected_nm: &[T; J],
    h: [[T; 2]; M],
    abs_a: [T; M],
    l: usize,
    out: &mut BankOutput<T, J>,
) -> (bool, bool) {
    let infl = par.inflation;

    // Time update: inflation and process noise on the diagonal blocks, and the bias.
    for i in 0..M {
        let q = par.q_per_sample[i] + par.q_per_rad[i] * abs_a[i];
        let d = &mut bank.p[i][i];
        let grow = infl * T::HALF * (d[0][0][l] + d[1][1][l]);
        d[0][0][l] = d[0][0][l] + grow + q;
        d[1][1][l] = d[1][1][l] + grow + q;
    }
    if BIAS {
        let v = bank.pbb[l];
        bank.pbb[l] = v + v * infl + par.q_bias;
    }

    // Prediction; the update row is the phasor itself.
    let (mut ripple, mut mis) = (T::ZERO, T::ZERO);
    for i in 0..M {
        let v = h[i][0] * bank.z[i][0][l] + h[i][1] * bank.z[i][1][l];
        if par.is_ripple[i] {
            ripple += v;
        } else {
            mis += v;
        }
    }

    // Gains g = P hᵀ from the upper blocks of the symmetric P.
    let mut g = [[T::ZERO; 2]; M];
    for i in 0..M {
        let (mut g0, mut g1) = (T::ZERO, T::ZERO);
        if BIAS {
            g0 = bank.pb[i][0][l] * T::ONE;
            g1 = bank.pb[i][1][l] * T::ONE;
        }
        for j in 0..M {
            let [hj0, hj1] = h[j];
            if j >= i {
                let b = &bank.p[i][j];
                g0 += b[0][0][l] * hj0 + b[0][1][l] * hj1;
                g1 += b[1][0][l] * hj0 + b[1][1][l] * hj1;
            } else {
                let b = &bank.p[j][i];
                g0 += b[0][0][l] * hj0 + b[1][0][l] * hj1;
                g1 += b[0][1][l] * hj0 + b[1][1][l] * hj1;
            }
        }
        g[i] = [g0, g1];
    }
    let mut gb = T::ZERO;
    if BIAS {
        gb = bank.pbb[l] * T::ONE;
        for j in 0..M {
            gb += bank.pb[j][0][l] * h[j][0] + bank.pb[j][1][l] * h[j][1];
        }
    }

    // Innovation and the load-step decision.
    let mut s = if BIAS { gb * T::ONE } else { T::ZERO };
    for i in 0..M {
        s += h[i][0] * g[i][0] + h[i][1] * g[i][1];
    }
    let s_var = par.r + s;
    let mut inv = T::ONE / s_var;
    let y = torque_nm[l] - expected_nm[l];
    let e = y - (ripple + mis + bank.b[l]);
    let load_step = BIAS & (par.load_step_nis > T::ZERO) & (e * e > par.load_step_nis * s_var);
    inv = if load_step { T::ZERO } else { inv };

    // Measurement update.
    let floor = par.r * inv;
    for i in 0..M {
        let [k0, k1] = [g[i][0] * inv, g[i][1] * inv];
        bank.z[i][0][l] += k0 * e;
        bank.z[i][1][l] += k1 * e;
        let d = &mut bank.p[i][i];
        let (v0, v1) = (d[0][0][l], d[1][1][l]);
        d[0][0][l] = (v0 - k0 * g[i][0]).max(v0 * floor);
        d[1][1][l] = (v1 - k1 * g[i][1]).max(v1 * floor);
        let off = d[0][1][l] - k0 * g[i][1];
        d[0][1][l] = off;
        d[1][0][l] = off;
        for j in i + 1..M {
            let [gj0, gj1] = g[j];
            let b = &mut bank.p[i][j];
            b[0][0][l] -= k0 * gj0;
            b[0][1][l] -= k0 * gj1;
            b[1][0][l] -= k1 * gj0;
            b[1][1][l] -= k1 * gj1;
        }
        if BIAS {
            bank.pb[i][0][l] -= k0 * gb;
            bank.pb[i][1][l] -= k1 * gb;
        }
    }
    if BIAS {
        let kb = gb * inv;
        bank.b[l] += kb * e;
        let v = bank.pbb[l];
        bank.pbb[l] = (v - kb * gb).max(v * par.r * inv);
        // Load step: the update above was void (gain 0); the bias takes the innovation
        // and forgets its cross-covariance (`kernel::load_step`), as selects.
        let mut s_z = T::ZERO;
        for i in 0..M {
            for r in 0..2 {
                let pzh = g[i][r] - bank.pb[i][r][l];
                s_z += h[i][r] * pzh;
                bank.pb[i][r][l] = if load_step { -pzh } else { bank.pb[i][r][l] };
            }
        }
        bank.pbb[l] = if load_step { par.r + s_z } else { bank.pbb[l] };
        bank.b[l] = if load_step { bank.b[l] + e } else { bank.b[l] };
    }

    // Health check and outputs.
    let mut sum = s_var + bank.b[l];
    let mut least = s_var;
    if BIAS {
        sum += bank.pbb[l];
        least = least.min(bank.pbb[l]);
    }
    for i in 0..M {
        let d = &bank.p[i][i];
        sum += d[0][0][l] + d[1][1][l] + bank.z[i][0][l] + bank.z[i][1][l];
        least = least.min(d[0][0][l]).min(d[1][1][l]);
    }
    let bad = !(finite(sum) & (least >= T::ZERO) & (s_var > T::ZERO));
    let torque = torque_nm[l] - ripple - mis;
    out.torque_nm[l] = torque;
    out.ripple_nm[l] = ripple;
    out.misalignment_nm[l] = mis;
    out.torque_state_nm[l] = if BIAS { expected_nm[l] + bank.b[l] } else { torque };
    out.innovation_nm[l] = e;
    out.innovation_variance_nm2[l] = s_var;
    out.nis[l] = e * e / s_var;
    (load_step, bad)
}

/// Whether `x` is neither infinite nor NaN: `x − x` is 0 exactly then (two
/// instructions instead of a classification).
#[inline(always)]
#[allow(clippy::eq_op)]
pub(super) fn finite<T: Real>(x: T) -> bool {
    x - x == T::ZERO
}

#[cfg(test)]
mod tests {
    use super::super::kernel::general;
    use super::super::path_check::{against_general, sample};
    use super::super::{BankInput, PhaseSource, ReferenceValues, RippleBank, RippleInput, RippleModel, RippleOutput};
    use crate::Real;

    /// The single-joint lean path against the general path, bit for bit; returns how
    /// many samples it took.
    fn lean_against_general<T: Real, const M: usize>(model: &RippleModel<T, M>, unwrapped_after: usize) -> usize {
        let mut a = RippleBank::<T, M, 1>::new(model);
        let mut b = a;
        let mut took = 0;
        for k in 0..6000 {
            let input: BankInput<T, 1> = sample(model, k, unwrapped_after);
            let r = &input.references;
            let mut one =
                RippleInput::new(input.torque_nm[0], ReferenceValues::new(r.relative[0], r.output[0], r.motor[0]));
            one.expected_torque_nm = input.expected_torque_nm[0];
            one.dt_s = input.dt_s;
            let before = a;
            let lean = super::super::lean::step(model, &mut a, &one);
            took += usize::from(lean.is_some());
            let want = RippleOutput::from(general(model, &mut b, &input, None));
            match lean {
                Some(got) => assert_eq!(format!("{got:?}"), format!("{want:?}"), "k {k} (lean)"),
                None => {
                    assert_eq!(format!("{a:?}"), format!("{before:?}"), "k {k}: the lean check changed the state");
                    let _ = general(model, &mut a, &input, None);
                }
            }
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "k {k} (lean)");
        }
        took
    }

    /// The fast path (two joints) and the lean one (one joint) against the general path.
    fn same<T: Real, const M: usize>(model: RippleModel<T, M>, unwrapped: bool) {
        let unwrapped_after = if unwrapped { 0 } else { usize::MAX };
        let fast = against_general::<T, M, 2>(&model, unwrapped_after, super::step);
        assert!(fast > 4000, "{fast}");
        let lean = lean_against_general(&model, unwrapped_after);
        assert!(lean > 4000, "{lean}");
    }

    #[test]
    fn fast_path_is_the_general_path() {
        same(RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap(), false);
        same(RippleModel::<f64, 3>::seed_6th_order(1000.0).unwrap(), true);
        same(RippleModel::<f32, 3>::product(1000.0, 0.05).unwrap(), false);
        same(RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap().with_phase_source(PhaseSource::Velocity), false);
        same(RippleModel::<f64, 5>::full(1000.0, 0.05).unwrap(), false);
        same(RippleModel::<f32, 5>::full(1000.0, 0.05).unwrap(), true);
    }
}
