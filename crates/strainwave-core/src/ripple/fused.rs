//! The common sample of the common models as one loop over the joints: orders on the
//! relative angle (and the output angle) with whole multiples 1, 2 or 4, angle input,
//! every joint caught up, within ±3π of its last angle, without a jump and with every
//! order active. The phase bookkeeping, the phasors and the filter update of a joint
//! then run together, so its temporaries stay in registers and the loop vectorizes
//! across joints as a whole.
//!
//! Same decisions and same arithmetic as the `fast` module (and so the general path),
//! bit for bit. The check runs first and writes nothing; if any joint fails it, the
//! caller takes the `fast` path, which handles the wider case.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::io::OrderStatus;
use super::joint::{common_interval, empty_output, finite, joint, settle, Params};
use super::model::{PhaseSource, RippleModel};
use super::plan::HOLD_AVERAGE;
use super::trig::{phasor_power, sin_cos_small, wrap_near};
use crate::Real;

/// One step if the model and every joint qualify, else `None` with nothing changed.
#[inline(always)]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> Option<BankOutput<T, J>> {
    if !(model.single_pass && model.phase_source == PhaseSource::Angle) {
        return None;
    }
    match (model.bias_q_nm2.is_some(), model.uses[1]) {
        (false, false) => step_with::<T, M, J, false, false>(model, bank, input),
        (false, true) => step_with::<T, M, J, false, true>(model, bank, input),
        (true, false) => step_with::<T, M, J, true, false>(model, bank, input),
        (true, true) => step_with::<T, M, J, true, true>(model, bank, input),
    }
}

/// Increment, its running mean and whether both are acceptable, for reference `r`.
#[inline(always)]
fn increment<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &RippleBank<T, M, J>,
    v: T,
    r: usize,
    l: usize,
) -> (T, T, bool) {
    let lim = &model.limits;
    let three_pi = T::from_f64(3.0) * T::PI;
    let d = v - bank.last[r][l];
    let near = (d.abs() <= three_pi) & (v.abs() <= three_pi);
    let d = wrap_near(d);
    let changed = bank.delta_known[l] & !((d - bank.last_delta[r][l]).abs() <= lim.max_step_change_rad);
    let m = bank.mean_delta[r][l];
    let mean = m + (d - m) * T::from_f64(HOLD_AVERAGE);
    (d, mean, finite(v) & near & (d.abs() <= lim.max_angle_step_rad) & !changed)
}

#[inline(always)]
fn step_with<T: Real, const M: usize, const J: usize, const BIAS: bool, const OUT: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> Option<BankOutput<T, J>> {
    common_interval(model, input.dt_s)?;
    let (rel, out_angle) = (&input.references.relative, &input.references.output);
    let reference: [usize; M] = core::array::from_fn(|i| model.orders[i].reference.index());
    let multiple: [T; M] = core::array::from_fn(|i| model.orders[i].multiple);

    // Decide, writing nothing.
    let mut ok = [true; J];
    for l in 0..J {
        let y = input.torque_nm[l] - input.expected_torque_nm[l];
        let mut k = finite(y) & bank.has_last[l] & (bank.pending_samples[l] == T::ZERO);
        let (d0, m0, ok0) = increment(model, bank, rel[l], 0, l);
        let (mut d1, mut m1) = (T::ZERO, T::ZERO);
        k &= ok0;
        if OUT {
            let ok1;
            (d1, m1, ok1) = increment(model, bank, out_angle[l], 1, l);
            k &= ok1;
        }
        for i in 0..M {
            let (d, m) = if reference[i] == 0 { (d0, m0) } else { (d1, m1) };
            let a = (multiple[i] * d).abs();
            let mean_a = (multiple[i] * m).abs();
            let active = bank.status[i][l] == OrderStatus::Active;
            k &= active & (a <= model.off_above_rad) & !(mean_a < model.hold_below_rad);
        }
        ok[l] = k;
    }
    if !ok.iter().all(|&k| k) {
        return None;
    }

    // Commit, phasors and update, one joint at a time.
    let mut out = empty_output();
    let mut load_step = [false; J];
    let mut bad = [false; J];
    let sh = Shared {
        par: Params::new(model),
        torque: input.torque_nm,
        expected: input.expected_torque_nm,
        rel: *rel,
        out_angle: *out_angle,
        reference,
        multiple,
        power: model.power,
        load_scaled: core::array::from_fn(|i| model.orders[i].load_scaled),
    };
    // Counters and flags first: other element widths in the main loop would narrow
    // its vectors.
    for l in 0..J {
        bank.steps[l] = bank.steps[l].saturating_add(1);
        bank.pending_dt[l] = T::ZERO;
        bank.delta_known[l] = true;
    }
    for l in 0..J {
        (load_step[l], bad[l]) = joint_step::<T, M, J, BIAS, OUT>(model, &sh, bank, l, &mut out);
    }
    settle(model, bank, input, &load_step, &bad, &mut out);
    Some(out)
}

/// The model's numbers and the sample's inputs the joints' loop reads, as locals.
struct Shared<T: Real, const M: usize, const J: usize> {
    par: Params<T, M>,
    torque: [T; J],
    expected: [T; J],
    rel: [T; J],
    out_angle: [T; J],
    reference: [usize; M],
    multiple: [T; M],
    power: [u8; M],
    load_scaled: [bool; M],
}

/// Joint `l`: phase bookkeeping, phasors and the filter update.
#[inline(always)]
fn joint_step<T: Real, const M: usize, const J: usize, const BIAS: bool, const OUT: bool>(
    model: &RippleModel<T, M>,
    sh: &Shared<T, M, J>,
    bank: &mut RippleBank<T, M, J>,
    l: usize,
    out: &mut BankOutput<T, J>,
) -> (bool, bool) {
    let (d0, m0, _) = increment(model, bank, sh.rel[l], 0, l);
    bank.last_delta[0][l] = d0;
    bank.mean_delta[0][l] = m0;
    bank.last[0][l] = sh.rel[l];
    let psi0 = wrap_near(sh.rel[l]);
    bank.psi[0][l] = psi0;
    let (s, c) = sin_cos_small(psi0);
    let mut base = [(c, s); 2];
    let mut d1 = T::ZERO;
    if OUT {
        let m1;
        (d1, m1, _) = increment(model, bank, sh.out_angle[l], 1, l);
        bank.last_delta[1][l] = d1;
        bank.mean_delta[1][l] = m1;
        bank.last[1][l] = sh.out_angle[l];
        let psi1 = wrap_near(sh.out_angle[l]);
        bank.psi[1][l] = psi1;
        let (s, c) = sin_cos_small(psi1);
        base[1] = (c, s);
    }
    let load = (sh.expected[l] + bank.b[l]).abs();
    let load = if finite(load) { load } else { T::ZERO };
    let mut h = [[T::ZERO; 2]; M];
    let mut abs_a = [T::ZERO; M];
    for i in 0..M {
        let ((c, s), d) = if sh.reference[i] == 0 { (base[0], d0) } else { (base[1], d1) };
        // Both squarings, then selects: no branch in the loop.
        let c2 = phasor_power(c, s, 2);
        let c4 = phasor_power(c2.0, c2.1, 2);
        let (c, s) = if sh.power[i] == 4 {
            c4
        } else if sh.power[i] == 2 {
            c2
        } else {
            (c, s)
        };
        let (c, s) = if sh.load_scaled[i] { (c * load, s * load) } else { (c, s) };
        bank.phasor[i][0][l] = c;
        bank.phasor[i][1][l] = s;
        h[i] = [c, s];
        abs_a[i] = (sh.multiple[i] * d).abs();
    }
    joint::<T, M, J, BIAS>(&sh.par, bank, &sh.torque, &sh.expected, h, abs_a, l, out)
}

#[cfg(test)]
mod tests {
    use super::super::path_check::against_general;
    use super::super::{Order, Reference, RippleModel};
    use crate::Real;

    fn took<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>, unwrapped_after: usize) -> usize {
        against_general::<T, M, J>(&model, unwrapped_after, super::step)
    }

    #[test]
    fn one_loop_step_is_the_general_path() {
        assert!(took::<f64, 2, 3>(RippleModel::seed_4th_order(1000.0).unwrap(), usize::MAX) > 4000);
        assert!(took::<f32, 3, 8>(RippleModel::seed_6th_order(1000.0).unwrap(), usize::MAX) > 4000);
        assert!(took::<f32, 3, 2>(RippleModel::product(1000.0, 0.05).unwrap(), usize::MAX) > 4000);
        assert!(took::<f64, 5, 4>(RippleModel::full(1000.0, 0.05).unwrap(), usize::MAX) > 4000);
        // Unwrapped angles: taken only while within ±3π (the first ~118 samples at
        // 0.08 rad/sample), then declined and the `fast` path takes them.
        assert!(took::<f64, 3, 2>(RippleModel::seed_6th_order(1000.0).unwrap(), 0) < 150);
        // Motor-angle orders are not its case.
        let motor = [Order::new(Reference::Motor, 1.0).unwrap()];
        assert_eq!(took::<f64, 1, 2>(RippleModel::new(motor, 1.0, 1000.0).unwrap(), usize::MAX), 0);
    }
}
