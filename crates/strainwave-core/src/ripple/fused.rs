//! The common sample of the common models as one loop over the joints: orders on the
//! relative angle (and the output angle) with whole multiples 1, 2 or 4, angle input,
//! every joint caught up, within ±3π of its last angle, without a jump and with every
//! order active. The phase bookkeeping, the phasors and the filter update of a joint
//! then run together, so its temporaries stay in registers and the loop vectorizes
//! across joints as a whole.
//!
//! Same decisions and same arithmetic as the `fast` module (and so the general path),
//! bit for bit when `F` is false; with `F` (the build for FMA) its multiply–adds are
//! fused, so the numbers agree to rounding. The check runs first and writes nothing
//! (the references' phasors are computed before it, as the start of the step's
//! longest dependency chain); if any joint fails it, the caller takes the `fast` path,
//! which handles the wider case.
//!
//! The presets' layouts are compiled with their orders as constants (see `layout`), so
//! nothing is selected per order in the loop; other layouts read the model. A single
//! joint (`J = 1`) takes this step first too.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::io::{OrderStatus, StepFlags};
use super::joint::{array, common_interval, finite, joint, madd, settle, Params};
use super::kernel::Lanes2;
use super::layout::{self, FULL, PRODUCT, RUNTIME, SEED_4TH, SEED_6TH};
use super::model::{PhaseSource, Reference, RippleModel};
use super::plan::HOLD_AVERAGE;
use super::trig::{phasor_of_wrapped, wrap_near, Doubling};
use crate::Real;

/// One step into `out` if the model and every joint qualify (true), else false with
/// nothing changed.
///
/// The presets' layouts are compiled with their orders known ([`layout`]); any other
/// layout of the same kind reads them from the model.
#[inline(always)]
pub(crate) fn step<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) -> bool {
    if !(model.single_pass && model.phase_source == PhaseSource::Angle) {
        return false;
    }
    match (model.layout, model.bias_q_nm2.is_some(), model.uses[1]) {
        (SEED_4TH, _, _) => step_with::<T, M, J, SEED_4TH, false, false, F>(model, bank, input, out),
        (SEED_6TH, _, _) => step_with::<T, M, J, SEED_6TH, false, true, F>(model, bank, input, out),
        (PRODUCT, _, _) => step_with::<T, M, J, PRODUCT, true, true, F>(model, bank, input, out),
        (FULL, _, _) => step_with::<T, M, J, FULL, true, true, F>(model, bank, input, out),
        (_, false, false) => step_with::<T, M, J, RUNTIME, false, false, F>(model, bank, input, out),
        (_, false, true) => step_with::<T, M, J, RUNTIME, false, true, F>(model, bank, input, out),
        (_, true, false) => step_with::<T, M, J, RUNTIME, true, false, F>(model, bank, input, out),
        (_, true, true) => step_with::<T, M, J, RUNTIME, true, true, F>(model, bank, input, out),
    }
}

/// The orders as the model has them, for [`RUNTIME`]; a layout `L` reads its constant
/// [`layout::Table`] instead (kept out of memory the loop writes, so it folds away).
#[derive(Clone, Copy)]
struct Orders<T: Real, const M: usize> {
    on_output: [bool; M],
    power: [u8; M],
    multiple: [T; M],
    load_scaled: [bool; M],
}

impl<T: Real, const M: usize> Orders<T, M> {
    #[inline(always)]
    fn of(model: &RippleModel<T, M>) -> Self {
        Self {
            on_output: array(false, |i| model.orders[i].reference == Reference::Output),
            power: array(1, |i| model.power[i]),
            multiple: array(T::ONE, |i| model.orders[i].multiple),
            load_scaled: array(false, |i| model.orders[i].load_scaled),
        }
    }

    #[inline(always)]
    fn on_output<const L: u32>(&self, i: usize) -> bool {
        if L == RUNTIME {
            self.on_output[i]
        } else {
            layout::table_of::<L>().on_output.get(i).copied().unwrap_or(false)
        }
    }

    #[inline(always)]
    fn power<const L: u32>(&self, i: usize) -> u8 {
        if L == RUNTIME {
            self.power[i]
        } else {
            layout::table_of::<L>().power.get(i).copied().unwrap_or(1)
        }
    }

    #[inline(always)]
    fn multiple<const L: u32>(&self, i: usize) -> T {
        if L == RUNTIME {
            self.multiple[i]
        } else {
            T::from_f64(f64::from(self.power::<L>(i)))
        }
    }

    #[inline(always)]
    fn load_scaled<const L: u32>(&self, i: usize) -> bool {
        if L == RUNTIME {
            self.load_scaled[i]
        } else {
            layout::table_of::<L>().load_scaled.get(i).copied().unwrap_or(false)
        }
    }
}

/// Increment and its running mean of reference `r` (relative 0, output 1) for joint
/// `l`, and whether they qualify: within ±3π of the last angle (so finite), no jump in
/// speed, and within the model's `fused_bounds` (a step below the limit, every order's
/// line below the off limit and above the hold limit).
#[inline(always)]
fn increment<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &RippleBank<T, M, J>,
    v: T,
    r: usize,
    l: usize,
) -> (T, T, bool) {
    let three_pi = T::from_f64(3.0) * T::PI;
    let [step, mean_low] = model.fused_bounds[r];
    let d = v - bank.last[r][l];
    let near = (d.abs() <= three_pi) & (v.abs() <= three_pi);
    let d = wrap_near(d);
    let steady = (d - bank.last_delta[r][l]).abs() <= model.limits.max_step_change_rad;
    let m = bank.mean_delta[r][l];
    let mean = madd::<T, F>(m, d - m, T::from_f64(HOLD_AVERAGE));
    (d, mean, near & (d.abs() <= step) & steady & !(mean.abs() < mean_low))
}

#[inline(always)]
fn step_with<
    T: Real,
    const M: usize,
    const J: usize,
    const L: u32,
    const BIAS: bool,
    const OUT: bool,
    const F: bool,
>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) -> bool {
    if L != RUNTIME && const { layout::orders(L) } != M || common_interval(model, input.dt_s).is_none() {
        return false;
    }
    let orders = Orders::of(model);

    // The references' phasors first, before the checks: they depend on the angles
    // alone and start the step's longest dependency chain, so it runs beside the
    // checks instead of after them. The decision reads them (finite, as they are for
    // any angle), so that the compiler keeps them before it. Used only if every joint
    // qualifies: then each angle is within ±3π, so its wrapped phase within ±π and no
    // clamp is needed (see `trig`'s tests).
    let (rel, out_angle) = (&input.references.relative, &input.references.output);
    let references = if OUT { 2 } else { 1 };
    // `base[r][part][joint]`: parts of each reference's phasor (see `Doubling`).
    let mut base = [[[T::ZERO; J]; 4]; 2];
    for (r, angle) in [rel, out_angle].into_iter().enumerate().take(references) {
        for l in 0..J {
            let parts = phasor_of_wrapped::<T, F>(wrap_near(angle[l])).parts();
            for p in 0..4 {
                base[r][p][l] = parts[p];
            }
        }
    }

    // The flags, as bytes: every joint caught up (a last angle and increment) and
    // every order active.
    let mut caught_up = true;
    for l in 0..J {
        let mut c = bank.has_last[l] & bank.delta_known[l];
        for i in 0..M {
            c &= bank.status[i][l] == OrderStatus::Active;
        }
        caught_up &= c;
    }
    // Then the numbers, as one mask. `inc`: increment and mean of each reference.
    let mut ok = caught_up;
    let mut inc = [[[T::ZERO; J]; 2]; 2];
    for l in 0..J {
        let y = input.torque_nm[l] - input.expected_torque_nm[l];
        let mut k = finite(y) & (bank.pending_samples[l] == T::ZERO);
        for r in 0..references {
            k &= finite(base[r][0][l] + base[r][1][l]);
        }
        let (d, m, fine) = increment::<T, M, J, F>(model, bank, rel[l], 0, l);
        (inc[0][0][l], inc[0][1][l]) = (d, m);
        k &= fine;
        if OUT {
            let (d, m, fine) = increment::<T, M, J, F>(model, bank, out_angle[l], 1, l);
            (inc[1][0][l], inc[1][1][l]) = (d, m);
            k &= fine;
        }
        ok &= k;
    }

    if !ok {
        return false;
    }

    // Commit: bookkeeping, phasors and the update, one joint at a time.
    out.flags = [StepFlags::empty(); J];
    let mut load_step = [false; J];
    let mut bad = [false; J];
    let mut gains = [[[T::ZERO; J]; 2]; M];
    let par = Params::new(model);
    let sh =
        Shared { torque: &input.torque_nm, expected: &input.expected_torque_nm, angle: [rel, out_angle], inc, base };
    // Counters and flags first: other element widths in the main loop would narrow
    // its vectors.
    for l in 0..J {
        bank.steps[l] = bank.steps[l].wrapping_add(1);
        bank.pending_dt[l] = T::ZERO;
    }
    for l in 0..J {
        (load_step[l], bad[l]) = joint_step::<T, M, J, L, BIAS, OUT, F>(&par, orders, &sh, bank, l, &mut gains, out);
    }
    settle::<T, M, J, BIAS>(model, bank, input, &load_step, &gains, &mut bad, out);
    true
}

/// The sample's inputs the joints' loop reads, as locals.
struct Shared<'a, T: Real, const J: usize> {
    torque: &'a [T; J],
    expected: &'a [T; J],
    /// Relative and output angle.
    angle: [&'a [T; J]; 2],
    /// Increment and mean of each reference.
    inc: [[[T; J]; 2]; 2],
    /// Phasor of each reference, `[reference][part][joint]`.
    base: [[[T; J]; 4]; 2],
}

/// Joint `l`: phase bookkeeping, its orders' phasors (update row) and the filter
/// update.
#[inline(always)]
fn joint_step<
    T: Real,
    const M: usize,
    const J: usize,
    const L: u32,
    const BIAS: bool,
    const OUT: bool,
    const F: bool,
>(
    par: &Params<T, M>,
    o: Orders<T, M>,
    sh: &Shared<'_, T, J>,
    bank: &mut RippleBank<T, M, J>,
    l: usize,
    gains: &mut Lanes2<T, M, J>,
    out: &mut BankOutput<T, J>,
) -> (bool, bool) {
    let references = if OUT { 2 } else { 1 };
    for r in 0..references {
        bank.last_delta[r][l] = sh.inc[r][0][l];
        bank.mean_delta[r][l] = sh.inc[r][1][l];
        bank.last[r][l] = sh.angle[r][l];
        bank.psi[r][l] = wrap_near(sh.angle[r][l]);
    }
    let h = update_row::<T, M, J, L, F>(o, bank, sh.expected, &sh.base, l);
    let mut abs_a = [T::ZERO; M];
    for i in 0..M {
        let r = usize::from(o.on_output::<L>(i));
        bank.phasor[i][0][l] = h[i][0];
        bank.phasor[i][1][l] = h[i][1];
        abs_a[i] = (o.multiple::<L>(i) * sh.inc[r][0][l]).abs();
    }
    let is_ripple = |i: usize| !o.on_output::<L>(i);
    joint::<T, M, J, BIAS, F>(par, is_ripple, bank, sh.torque, sh.expected, h, abs_a, l, gains, out)
}

/// Joint `l`'s update row: each order's phasor from its reference's (times the load
/// for load-scaled orders).
#[inline(always)]
fn update_row<T: Real, const M: usize, const J: usize, const L: u32, const F: bool>(
    o: Orders<T, M>,
    bank: &RippleBank<T, M, J>,
    expected: &[T; J],
    base: &[[[T; J]; 4]; 2],
    l: usize,
) -> [[T; 2]; M] {
    let load = (expected[l] + bank.b[l]).abs();
    let load = if finite(load) { load } else { T::ZERO };
    let mut h = [[T::ZERO; 2]; M];
    for i in 0..M {
        let r = usize::from(o.on_output::<L>(i));
        // Both doublings, then selects: no branch in the loop (and for a layout's
        // constant power, no select either; orders on one angle share the doublings).
        let b = Doubling::from_parts(array(T::ZERO, |p| base[r][p][l]));
        let twice = b.doubled::<F>();
        let four = twice.doubled::<F>();
        let (c, s) = match o.power::<L>(i) {
            4 => (four.c, four.s),
            2 => (twice.c, twice.s),
            _ => (b.c, b.s),
        };
        h[i] = if o.load_scaled::<L>(i) { [c * load, s * load] } else { [c, s] };
    }
    h
}

#[cfg(test)]
mod tests {
    use super::super::path_check::against_general;
    use super::super::{Order, Reference, RippleModel};
    use super::{FULL, PRODUCT, SEED_4TH, SEED_6TH};
    use crate::Real;

    fn took<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>, unwrapped_after: usize) -> usize {
        against_general::<T, M, J>(&model, unwrapped_after, |m, b, i| {
            let mut out = super::super::BankOutput::default();
            super::step::<T, M, J, false>(m, b, i, &mut out).then_some(out)
        })
    }

    #[test]
    fn one_loop_step_is_the_general_path() {
        assert!(took::<f64, 2, 3>(RippleModel::seed_4th_order(1000.0).unwrap(), usize::MAX) > 4000);
        assert!(took::<f32, 3, 8>(RippleModel::seed_6th_order(1000.0).unwrap(), usize::MAX) > 4000);
        assert!(took::<f32, 3, 2>(RippleModel::product(1000.0, 0.05).unwrap(), usize::MAX) > 4000);
        assert!(took::<f64, 5, 4>(RippleModel::full(1000.0, 0.05).unwrap(), usize::MAX) > 4000);
        // One joint (the single-joint `step` takes this path first).
        assert!(took::<f64, 3, 1>(RippleModel::seed_6th_order(1000.0).unwrap(), usize::MAX) > 4000);
        assert!(took::<f32, 3, 1>(RippleModel::product(1000.0, 0.05).unwrap(), usize::MAX) > 4000);
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
