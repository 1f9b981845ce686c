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
use super::layout::{self, FULL, PRODUCT, RUNTIME, SEED_4TH, SEED_6TH};
use super::model::{PhaseSource, Reference, RippleModel};
use super::plan::HOLD_AVERAGE;
use super::trig::{phasor_power, sin_cos_small, wrap_near};
use crate::Real;

/// One step if the model and every joint qualify, else `None` with nothing changed.
///
/// The presets' layouts are compiled with their orders known ([`layout`]); any other
/// layout of the same kind reads them from the model.
#[inline(always)]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> Option<BankOutput<T, J>> {
    if !(model.single_pass && model.phase_source == PhaseSource::Angle) {
        return None;
    }
    match (model.layout, model.bias_q_nm2.is_some(), model.uses[1]) {
        (SEED_4TH, _, _) => step_with::<T, M, J, SEED_4TH, false, false>(model, bank, input),
        (SEED_6TH, _, _) => step_with::<T, M, J, SEED_6TH, false, true>(model, bank, input),
        (PRODUCT, _, _) => step_with::<T, M, J, PRODUCT, true, true>(model, bank, input),
        (FULL, _, _) => step_with::<T, M, J, FULL, true, true>(model, bank, input),
        (_, false, false) => step_with::<T, M, J, RUNTIME, false, false>(model, bank, input),
        (_, false, true) => step_with::<T, M, J, RUNTIME, false, true>(model, bank, input),
        (_, true, false) => step_with::<T, M, J, RUNTIME, true, false>(model, bank, input),
        (_, true, true) => step_with::<T, M, J, RUNTIME, true, true>(model, bank, input),
    }
}

/// What the joints' loop needs of the orders: constants for a layout `L`, the model's
/// values for [`RUNTIME`].
struct Orders<T: Real, const M: usize> {
    on_output: [bool; M],
    power: [u8; M],
    multiple: [T; M],
    load_scaled: [bool; M],
    /// Smallest and largest multiple on the relative and the output angle.
    span: [[T; 2]; 2],
}

impl<T: Real, const M: usize> Orders<T, M> {
    #[inline(always)]
    fn of<const L: u32>(model: &RippleModel<T, M>) -> Self {
        let run_time = L == RUNTIME;
        let span = |output: bool| {
            let s = layout::multiple_span(L, output);
            [T::from_f64(f64::from(s[0])), T::from_f64(f64::from(s[1]))]
        };
        Self {
            on_output: core::array::from_fn(|i| {
                if run_time {
                    model.orders[i].reference == Reference::Output
                } else {
                    layout::on_output(L, i)
                }
            }),
            power: core::array::from_fn(|i| if run_time { model.power[i] } else { layout::power(L, i) }),
            multiple: core::array::from_fn(|i| {
                if run_time {
                    model.orders[i].multiple
                } else {
                    T::from_f64(f64::from(layout::power(L, i)))
                }
            }),
            load_scaled: core::array::from_fn(|i| {
                if run_time {
                    model.orders[i].load_scaled
                } else {
                    layout::load_scaled(L, i)
                }
            }),
            span: if run_time { [model.multiple_span[0], model.multiple_span[1]] } else { [span(false), span(true)] },
        }
    }
}

/// Increment and its running mean of reference `r` (relative 0, output 1) for joint
/// `l`, and whether they qualify: within ±3π of the last angle (so finite), a step
/// below the limit, no jump in speed, every order's line below the off limit and above
/// the hold limit. `fl(n |Δ|)` grows with `n`, so testing the largest and smallest
/// multiple (`span`) is testing every order.
#[inline(always)]
fn increment<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &RippleBank<T, M, J>,
    v: T,
    r: usize,
    l: usize,
    span: [T; 2],
) -> (T, T, bool) {
    let lim = &model.limits;
    let three_pi = T::from_f64(3.0) * T::PI;
    let d = v - bank.last[r][l];
    let near = (d.abs() <= three_pi) & (v.abs() <= three_pi);
    let d = wrap_near(d);
    let steady = (d - bank.last_delta[r][l]).abs() <= lim.max_step_change_rad;
    let m = bank.mean_delta[r][l];
    let mean = m + (d - m) * T::from_f64(HOLD_AVERAGE);
    let lines = (span[1] * d.abs() <= model.off_above_rad) & !(span[0] * mean.abs() < model.hold_below_rad);
    (d, mean, near & (d.abs() <= lim.max_angle_step_rad) & steady & lines)
}

#[inline(always)]
fn step_with<T: Real, const M: usize, const J: usize, const L: u32, const BIAS: bool, const OUT: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> Option<BankOutput<T, J>> {
    if L != RUNTIME && layout::orders(L) != M {
        return None;
    }
    common_interval(model, input.dt_s)?;
    let orders = Orders::of::<L>(model);

    // Decide, writing nothing. The flags first, as bytes: every joint caught up (a
    // last angle and increment) and every order active.
    let mut caught_up = true;
    for l in 0..J {
        let mut c = bank.has_last[l] & bank.delta_known[l];
        for i in 0..M {
            c &= bank.status[i][l] == OrderStatus::Active;
        }
        caught_up &= c;
    }
    if !caught_up {
        return None;
    }
    // Then the numbers, as one mask. `inc`: increment and mean of each reference.
    let (rel, out_angle) = (&input.references.relative, &input.references.output);
    let mut ok = true;
    let mut inc = [[[T::ZERO; J]; 2]; 2];
    for l in 0..J {
        let y = input.torque_nm[l] - input.expected_torque_nm[l];
        let mut k = finite(y) & (bank.pending_samples[l] == T::ZERO);
        let (d, m, fine) = increment(model, bank, rel[l], 0, l, orders.span[0]);
        (inc[0][0][l], inc[0][1][l]) = (d, m);
        k &= fine;
        if OUT {
            let (d, m, fine) = increment(model, bank, out_angle[l], 1, l, orders.span[1]);
            (inc[1][0][l], inc[1][1][l]) = (d, m);
            k &= fine;
        }
        ok &= k;
    }
    if !ok {
        return None;
    }

    // Commit, phasors and update, one joint at a time.
    let mut out = empty_output();
    let mut load_step = [false; J];
    let mut bad = [false; J];
    let mut par = Params::new(model);
    par.is_ripple = core::array::from_fn(|i| !orders.on_output[i]);
    let sh = Shared {
        par,
        torque: input.torque_nm,
        expected: input.expected_torque_nm,
        angle: [*rel, *out_angle],
        inc,
        orders,
    };
    // Counters and flags first: other element widths in the main loop would narrow
    // its vectors.
    for l in 0..J {
        bank.steps[l] = bank.steps[l].saturating_add(1);
        bank.pending_dt[l] = T::ZERO;
    }
    for l in 0..J {
        (load_step[l], bad[l]) = joint_step::<T, M, J, L, BIAS, OUT>(&sh, bank, l, &mut out);
    }
    settle(model, bank, input, &load_step, &bad, &mut out);
    Some(out)
}

/// The model's numbers and the sample's inputs the joints' loop reads, as locals.
struct Shared<T: Real, const M: usize, const J: usize> {
    par: Params<T, M>,
    torque: [T; J],
    expected: [T; J],
    /// Relative and output angle.
    angle: [[T; J]; 2],
    /// Increment and mean of each reference.
    inc: [[[T; J]; 2]; 2],
    orders: Orders<T, M>,
}

/// Joint `l`: phase bookkeeping, phasors and the filter update.
#[inline(always)]
fn joint_step<T: Real, const M: usize, const J: usize, const L: u32, const BIAS: bool, const OUT: bool>(
    sh: &Shared<T, M, J>,
    bank: &mut RippleBank<T, M, J>,
    l: usize,
    out: &mut BankOutput<T, J>,
) -> (bool, bool) {
    let mut base = [(T::ONE, T::ZERO); 2];
    let references = if OUT { 2 } else { 1 };
    for r in 0..references {
        bank.last_delta[r][l] = sh.inc[r][0][l];
        bank.mean_delta[r][l] = sh.inc[r][1][l];
        bank.last[r][l] = sh.angle[r][l];
        let psi = wrap_near(sh.angle[r][l]);
        bank.psi[r][l] = psi;
        let (s, c) = sin_cos_small(psi);
        base[r] = (c, s);
    }
    let load = (sh.expected[l] + bank.b[l]).abs();
    let load = if finite(load) { load } else { T::ZERO };
    let o = &sh.orders;
    let mut h = [[T::ZERO; 2]; M];
    let mut abs_a = [T::ZERO; M];
    for i in 0..M {
        let r = usize::from(o.on_output[i]);
        let (c, s) = base[r];
        let (c, s) = if L == RUNTIME {
            // Both squarings, then selects: no branch in the loop.
            let c2 = phasor_power(c, s, 2);
            let c4 = phasor_power(c2.0, c2.1, 2);
            match o.power[i] {
                4 => c4,
                2 => c2,
                _ => (c, s),
            }
        } else {
            // A constant power: orders on the same angle share their squarings.
            phasor_power(c, s, o.power[i])
        };
        let (c, s) = if o.load_scaled[i] { (c * load, s * load) } else { (c, s) };
        bank.phasor[i][0][l] = c;
        bank.phasor[i][1][l] = s;
        h[i] = [c, s];
        abs_a[i] = (o.multiple[i] * sh.inc[r][0][l]).abs();
    }
    joint::<T, M, J, BIAS>(&sh.par, bank, &sh.torque, &sh.expected, h, abs_a, l, out)
}

#[cfg(test)]
mod tests {
    use super::super::path_check::against_general;
    use super::super::{Order, Reference, RippleModel};
    use super::{FULL, PRODUCT, SEED_4TH, SEED_6TH};
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
        // Layouts of no preset are read from the model at run time.
        let custom = [
            Order::new(Reference::Relative, 1.0).unwrap(),
            Order::new(Reference::Output, 2.0).unwrap(),
            Order::new(Reference::Relative, 4.0).unwrap().scaled_by_load(),
        ];
        let model = RippleModel::new(custom, 0.5, 1000.0).unwrap();
        assert!(![SEED_4TH, SEED_6TH, PRODUCT, FULL].contains(&model.layout));
        assert!(took::<f32, 3, 4>(model, usize::MAX) > 4000);
        assert!(took::<f32, 3, 3>(model.with_bias_state(1e-4).unwrap(), usize::MAX) > 4000);
        let relative_only = [custom[0], custom[2]];
        assert!(took::<f32, 2, 5>(RippleModel::new(relative_only, 0.5, 1000.0).unwrap(), usize::MAX) > 4000);
        // Motor-angle orders are not its case.
        let motor = [Order::new(Reference::Motor, 1.0).unwrap()];
        assert_eq!(took::<f64, 1, 2>(RippleModel::new(motor, 1.0, 1000.0).unwrap(), usize::MAX), 0);
    }
}
