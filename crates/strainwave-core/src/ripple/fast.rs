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
use super::io::OrderStatus;
use super::joint::{array, common_interval, finite, joint, settle, Params};
use super::model::{PhaseSource, RippleModel};
use super::plan::HOLD_AVERAGE;
use super::trig::{phasors, wrap_angle, wrap_near};
use crate::Real;

/// One step if every joint is in the common case, else `None` with nothing changed.
#[inline(always)]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> Option<BankOutput<T, J>> {
    // No gap (`pending = 0`), so this interval is the total.
    let dt = common_interval(model, input.dt_s)?;
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
        bank.steps[l] = bank.steps[l].wrapping_add(1);
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

    let mut out = BankOutput::default();
    if model.bias_q_nm2.is_some() {
        update::<T, M, J, true>(model, bank, input, &abs_a, &mut out);
    } else {
        update::<T, M, J, false>(model, bank, input, &abs_a, &mut out);
    }
    Some(out)
}

/// Everything after the phasors, one joint at a time: the temporaries stay in
/// registers and the loop vectorizes across joints as a whole.
#[inline(always)]
fn update<T: Real, const M: usize, const J: usize, const BIAS: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    abs_a: &[[T; J]; M],
    out: &mut BankOutput<T, J>,
) {
    let mut load_step = [false; J];
    let mut bad = [false; J];
    let mut gains = [[[T::ZERO; J]; 2]; M];
    // Local copies: the loop then reads and writes no memory the bank could share, so
    // it vectorizes without run-time overlap checks.
    let par = Params::new(model);
    let (torque, expected) = (input.torque_nm, input.expected_torque_nm);
    for l in 0..J {
        let h = array([T::ZERO; 2], |i| [bank.phasor[i][0][l], bank.phasor[i][1][l]]);
        let abs = array(T::ZERO, |i| abs_a[i][l]);
        (load_step[l], bad[l]) = joint::<T, M, J, BIAS, false>(
            &par,
            |i| par.is_ripple(i),
            bank,
            &torque,
            &expected,
            h,
            abs,
            l,
            &mut gains,
            out,
        );
    }
    settle::<T, M, J, BIAS>(model, bank, input, &load_step, &gains, &mut bad, out);
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
