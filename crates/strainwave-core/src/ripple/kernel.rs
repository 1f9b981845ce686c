//! The one step of the canceller, written once over lanes (one number per joint, see
//! `lanes.rs`) for `J` joints that share a model (one joint is `J = 1`).
//! Each oscillator is kept in its rotating frame `x_i = Φ(ψ_i) z_i` (`docs/physics.md`,
//! section 4): with the update row `h = [cos ψ_1, sin ψ_1, …, 1]`, `P(k|k−1) = P + Q`,
//! `g = P hᵀ`, `S = R + h g`, `ẑ += g e / S`, `P −= g gᵀ / S`; `Φ` never multiplies `P`.
//! Per-joint decisions are masks and selects, the common sample a branch. The build
//! for the CPU is chosen in one place, `run`.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::io::{OrderStatus, StepFlags};
use super::model::{PhaseSource, RippleModel};
use super::trace::{RotatingGaussian, StepTrace};
use super::trig::{phasor_power_with, sin_cos_with, wrap_angle as wrap, Doubling};
use crate::lanes::{Lanes as L, Mask};
use crate::Real;

/// Weight of the newest increment in the running mean that decides holding (1/16).
const HOLD_AVERAGE: f64 = 1.0 / 16.0;

/// Steps `J` joints sharing `model` by one sample, writing their results into `out`
/// (a buffer the caller keeps: nothing is copied per sample). A joint whose covariance
/// went bad is reset and flagged [`StepFlags::COVARIANCE_RESET`]; the others are
/// unaffected. Each joint gets exactly what [`step`](super::step) would give it alone.
///
/// ```
/// use strainwave_core::ripple::{step_many, BankInput, BankOutput, ReferenceValues, RippleBank, RippleModel};
/// let model = RippleModel::<f32, 2>::taghirad_4th_order(1000.0).unwrap();
/// let mut bank = RippleBank::<f32, 2, 4>::new(&model);
/// let mut out = BankOutput::default();
/// for k in 0..100 {
///     let phi = [0.05 * k as f32; 4];
///     let input = BankInput::new([1.0; 4], ReferenceValues::new(phi, [0.0; 4], [0.0; 4]));
///     step_many(&model, &mut bank, &input, &mut out);
///     assert!(out.torque_nm.iter().all(|t| t.is_finite()));
/// }
/// ```
#[inline]
pub fn step_many<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) {
    run::<T, M, J, false>(model, bank, input, out, None);
}

/// The step in the build for this CPU: the one place that chooses it. `TRACE`: record
/// joint 0's intermediate quantities in `trace`.
#[inline]
pub(crate) fn run<T: Real, const M: usize, const J: usize, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // The one `unsafe` of the core crate. A function compiled for CPU features may
        // only be called where the CPU has them; the check above makes sure it does.
        // Why have it at all: a multiply–add is one instruction instead of two on the
        // step's dependency chain, and x86-64 builds do not assume FMA by default.
        #[allow(unsafe_code)]
        // SAFETY: the CPU executes AVX2 and FMA instructions (checked just above).
        unsafe {
            run_fma::<T, M, J, TRACE>(model, bank, input, out, trace)
        };
        return;
    }
    run_portable::<T, M, J, TRACE>(model, bank, input, out, trace);
}

/// `advance` in the portable build (out of line: callers save no registers for it).
#[inline(never)]
fn run_portable<T: Real, const M: usize, const J: usize, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    advance::<T, M, J, false, TRACE>(model, bank, input, out, trace);
}

/// `advance` compiled for AVX2 and FMA, its multiply–adds fused.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx2,fma")]
fn run_fma<T: Real, const M: usize, const J: usize, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    advance::<T, M, J, true, TRACE>(model, bank, input, out, trace);
}

/// Every joint's step: the decisions, the orders' phasors, the time update, the
/// prediction and the measurement update; then the reset of joints gone bad.
#[inline(always)]
fn advance<T: Real, const M: usize, const J: usize, const F: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    if model.bias_q_nm2.is_some() {
        passes::<T, M, J, F, true, TRACE>(model, bank, input, out, trace);
    } else {
        passes::<T, M, J, F, false, TRACE>(model, bank, input, out, trace);
    }
}

/// What every sample's decisions give the rest of the step: per order and joint, the
/// increment (rad, 0 when the order restarts) and process noise (N·m²); the sample's
/// decisions.
#[derive(Clone, Copy)]
struct Noted<T: Real, const M: usize, const J: usize> {
    inc: [L<T, J>; M],
    q: [L<T, J>; M],
    sample: Sample<T, J>,
}

/// The decisions of a sample that is not common: per order and joint, kept (else
/// reset), coupled (else its covariances are dropped), off, active; the flags so far
/// ([`StepFlags`] bits).
#[derive(Clone, Copy)]
struct Decided<T: Real, const M: usize, const J: usize> {
    keep: [Mask<T, J>; M],
    couple: [Mask<T, J>; M],
    off: [Mask<T, J>; M],
    active: [Mask<T, J>; M],
    flags: Mask<T, J>,
}

/// The step of [`advance`] for a model with (`BIAS`) or without the bias state. The
/// common sample takes the rest of the step with its decisions as constants: a branch,
/// same numbers.
#[inline(always)]
fn passes<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    bank.steps = bank.steps.map(|s| s.wrapping_add(1));
    let dt = input.dt_s.unwrap_or(model.plan.dt_s);
    let dt_ok = L([dt]).finite().lane(0) & (dt > T::ZERO);
    let r = &input.references;
    let refs = [L(r.relative), L(r.output), L(r.motor)];
    let y = L(input.torque_nm) - L(input.expected_torque_nm);
    if let Some(steps) = is_common::<T, M, J, F>(model, bank, refs, y, dt, dt_ok) {
        #[cfg(test)]
        tests::count_common();
        let (noted, _) = decide::<T, M, J, F, true>(model, bank, refs, y, dt, dt_ok, steps);
        rest::<T, M, J, F, BIAS, TRACE, true>(model, bank, input, noted, None, out, trace);
    } else {
        let (noted, d) = decide::<T, M, J, F, false>(model, bank, refs, y, dt, dt_ok, [None; 3]);
        rest::<T, M, J, F, BIAS, TRACE, false>(model, bank, input, noted, Some(&d), out, trace);
    }
}

/// The phasors, the time update, the prediction and the measurement update; then the
/// reset of joints gone bad. `COMMON`: the decisions are those of the common sample
/// (`d` is `None`); else `d` holds them.
#[inline(always)]
fn rest<
    T: Real,
    const M: usize,
    const J: usize,
    const F: bool,
    const BIAS: bool,
    const TRACE: bool,
    const COMMON: bool,
>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    noted: Noted<T, M, J>,
    d: Option<&Decided<T, M, J>>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    order_phases(model, bank, &noted.inc);
    let phasor = phasors::<T, M, J, F>(model, bank, input);
    let prior = time_update::<T, M, J, F, BIAS, COMMON>(model, bank, noted.q, &noted.sample, d);
    let bad = update::<T, M, J, F, BIAS, TRACE, COMMON>(model, bank, input, (&noted, d), (&phasor, &prior), out, trace);
    if bad.any() {
        for l in (0..J).filter(|&l| bad.lane(l)) {
            bank.reset_lane(model, l);
            out.flags[l].insert(StepFlags::COVARIANCE_RESET);
            if BIAS {
                out.torque_state_nm[l] = input.expected_torque_nm[l] + bank.b[l];
            }
        }
    }
}

/// Per joint: the sample skipped; counted (neither skipped nor the first); after a
/// time gap; its measurement used; samples pending before it (skipped), their number
/// with this one and of process noise; time since the last one; covariance inflation.
#[derive(Clone, Copy)]
struct Sample<T: Real, const J: usize> {
    skip: Mask<T, J>,
    counted: Mask<T, J>,
    gap: Mask<T, J>,
    meas_ok: Mask<T, J>,
    pending: L<T, J>,
    n_samples: L<T, J>,
    n_noise: L<T, J>,
    total_dt: L<T, J>,
    inflation: L<T, J>,
}

/// The decisions of a sample for every joint: valid input, gaps, jumps, each order's
/// increment, process noise and status, and what the time update does with it; the
/// references' phases and last values. `COMMON`: the sample is common (see
/// [`is_common`]), so that its decisions are constants; `steps` then holds each used
/// reference's increment and running mean, as the test found them.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn decide<T: Real, const M: usize, const J: usize, const F: bool, const COMMON: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    refs: [L<T, J>; 3],
    y: L<T, J>,
    dt: T,
    dt_ok: bool,
    steps: [Option<Step<T, J>>; 3],
) -> (Noted<T, M, J>, Decided<T, M, J>) {
    let (plan, lim, orders) = (&model.plan, &model.limits, &model.orders);
    // The sample: skipped (a used reference or `dt` not finite: the state stays as it
    // was, the next increment spans the gap), first, or after a time gap.
    // (`x · 0` is 0 exactly for finite `x`: one test for every used reference.)
    let mut probe = L::splat(T::ZERO);
    for r in 0..3 {
        if plan.uses[r] {
            probe = probe + refs[r] * T::ZERO;
        }
    }
    let (none, zero) = (Mask::splat(false), L::splat(T::ZERO));
    let skip = if COMMON { none } else { !probe.equals(T::ZERO) | Mask::splat(!dt_ok) };
    let pending = if COMMON { zero } else { L(bank.pending_samples) };
    let total_dt = if COMMON { L::splat(dt) } else { L(bank.pending_dt) + dt };
    let first = if COMMON { none } else { !Mask::of(|l| bank.has_last[l]) };
    let gap = if COMMON { none } else { !skip & !first & !total_dt.at_most(plan.max_gap_s) };
    let meas_ok = if COMMON { !none } else { !skip & usable(y) };
    // The initial state is the prior of the first sample: no noise before it.
    let counted = !skip & !first;
    let n_samples = pending + T::ONE;
    let n_noise = counted.select(n_samples, zero);
    let inflation = counted.select(L::splat(lim.covariance_inflation), zero);
    let sample = Sample { skip, counted, gap, meas_ok, pending, n_samples, n_noise, total_dt, inflation };

    // Each reference some order uses.
    let mut per_ref = [(zero, Mask::splat(false), zero); 3];
    for r in 0..3 {
        if plan.uses[r] {
            per_ref[r] = reference::<T, M, J, F, COMMON>(model, bank, r, refs[r], &sample, steps[r]);
        }
    }
    let (delta, jump, mean) = (per_ref.map(|p| p.0), per_ref.map(|p| p.1), per_ref.map(|p| p.2));
    let any_jump = jump[0] | jump[1] | jump[2];
    // After a jump or a gap the next increment sets a new baseline.
    let baseline = !first & !gap & !any_jump;
    for l in 0..J {
        bank.has_last[l] |= !skip.lane(l);
        bank.delta_known[l] = if skip.lane(l) { bank.delta_known[l] } else { baseline.lane(l) };
    }
    bank.pending_samples = skip.select(sample.n_samples, zero).0;
    let pending_dt = L(bank.pending_dt) + if dt_ok { dt } else { plan.dt_s };
    bank.pending_dt = skip.select(pending_dt, zero).0;

    // Each order: its increment `a_i = n_i Δθ` (0 after a reset), process noise
    // `q_i = q_s + q_rad |a_i|` and status.
    let mut noted = Noted { inc: [zero; M], q: [zero; M], sample };
    let mut dec = Decided { keep: [none; M], couple: [none; M], off: [none; M], active: [none; M], flags: none };
    let (mut any_off, mut any_held) = (none, none);
    for i in 0..M {
        let r = plan.reference[i];
        let reset = gap | pick(&jump, r);
        let a = reset.select(zero, pick(&delta, r) * orders[i].multiple);
        let q = (n_noise * orders[i].q_per_sample_nm2).madd::<F>(orders[i].q_per_rad_nm2, a.abs());
        (noted.inc[i], noted.q[i]) = (a, q);
        if COMMON {
            continue;
        }
        let abs_a = a.abs();
        let prev = bank.status[i];
        let was_off = Mask::of(|l| prev[l] == OrderStatus::Off);
        let was_held = Mask::of(|l| prev[l] == OrderStatus::Held);
        let off_now = !reset
            & ((was_off & !abs_a.less(plan.on_below_rad)) | (!was_off & L::splat(plan.off_above_rad).less(abs_a)));
        let mean_a = (pick(&mean, r) * orders[i].multiple).abs();
        let held_now = !off_now & (reset | mean_a.less(plan.hold_below_rad));
        let off = skip.select_mask(was_off, off_now);
        let held = skip.select_mask(was_held, held_now);
        for l in 0..J {
            let held = if held.lane(l) { OrderStatus::Held } else { OrderStatus::Active };
            bank.status[i][l] = if off.lane(l) { OrderStatus::Off } else { held };
        }
        // The time update keeps the order's state (else restarts it from its prior)
        // and its covariances with the others (if active, or skipped).
        let zeroed = !skip & (reset | off);
        dec.keep[i] = !zeroed;
        dec.off[i] = off;
        dec.active[i] = !off & !held;
        dec.couple[i] = skip | dec.active[i];
        noted.inc[i] = zeroed.select(zero, a);
        noted.q[i] = (off | skip).select(zero, q);
        (any_off, any_held) = (any_off | off, any_held | held);
    }
    dec.flags = skip.bits(StepFlags::ANGLE_SKIPPED.bits())
        | (!skip & !meas_ok).bits(StepFlags::MEASUREMENT_SKIPPED.bits())
        | gap.bits(StepFlags::GAP_RESET.bits())
        | (!gap & any_jump).bits(StepFlags::JUMP_RESET.bits())
        | any_off.bits(StepFlags::ORDER_OFF.bits())
        | any_held.bits(StepFlags::ORDER_HELD.bits());
    (noted, dec)
}

/// A reference's increment over the sample and its running mean after it (rad).
type Step<T, const J: usize> = (L<T, J>, L<T, J>);

/// Whether the sample is common for every joint: the measurement and the references
/// are usable, it follows a sample taken (none pending) within the gap limit, no
/// reference jumps, and every order was active and stays so. Tested before anything is
/// written, with [`decide`]'s numbers; if common, each used reference's [`Step`].
#[inline(always)]
fn is_common<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &RippleBank<T, M, J>,
    refs: [L<T, J>; 3],
    y: L<T, J>,
    dt: T,
    dt_ok: bool,
) -> Option<[Option<Step<T, J>>; 3]> {
    #[cfg(test)]
    if tests::general_only() {
        return None;
    }
    if !(dt_ok && dt <= model.plan.max_gap_s) {
        return None;
    }
    // A non-finite reference gives a NaN increment, which fails the step limit.
    let mut ok = usable(y) & L(bank.pending_samples).equals(T::ZERO) & Mask::of(|l| bank.has_last[l]);
    let mut steps = [None; 3];
    for r in 0..3 {
        if model.plan.uses[r] {
            let (fine, step) = settled::<T, M, J, F>(model, bank, r, refs[r], dt);
            (ok, steps[r]) = (ok & fine, Some(step));
        }
    }
    for i in 0..M {
        ok = ok & Mask::of(|l| bank.status[i][l] == OrderStatus::Active);
    }
    ok.all().then_some(steps)
}

/// Where the common sample's reference `r` at `v` (increment over `dt`) is settled: it
/// does not jump, and each order's line `|n Δθ|` is within the limits (the widest's below
/// the switch-off, the narrowest's mean above the hold); its [`Step`].
#[inline(always)]
fn settled<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &RippleBank<T, M, J>,
    r: usize,
    v: L<T, J>,
    dt: T,
) -> (Mask<T, J>, Step<T, J>) {
    let (plan, lim) = (&model.plan, &model.limits);
    let d = increment(model, v, L(bank.last[r]), L::splat(dt));
    let m = mean_increment::<T, J, F>(L(bank.mean_delta[r]), d);
    let steady =
        !Mask::of(|l| bank.delta_known[l]) | (d - L(bank.last_delta[r])).abs().at_most(lim.max_step_change_rad);
    let fine = d.abs().at_most(lim.max_angle_step_rad)
        & steady
        & (d.abs() * plan.widest[r]).at_most(plan.off_above_rad)
        & !(m.abs() * plan.narrowest[r]).less(plan.hold_below_rad);
    (fine, (d, m))
}

/// A reference's increment from `last` to `v`: `wrap_π(θ(k) − θ(k−1))` of angles, or
/// `(ω(k−1) + ω(k))/2 · dt` of rates over `dt`.
#[inline(always)]
fn increment<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    v: L<T, J>,
    last: L<T, J>,
    dt: L<T, J>,
) -> L<T, J> {
    if model.phase_source == PhaseSource::Angle {
        wrap(v - last)
    } else {
        (v + last) * T::HALF * dt
    }
}

/// The running mean `m` of the increment per sample after increment `d`: over ~16
/// samples, so that encoder jitter at standstill averages out of it and it alone
/// decides whether an order is held.
#[inline(always)]
fn mean_increment<T: Real, const J: usize, const F: bool>(m: L<T, J>, d: L<T, J>) -> L<T, J> {
    m.madd::<F>(d - m, T::from_f64(HOLD_AVERAGE))
}

/// Reference `r` at `v`: its increment `Δθ = wrap_π(θ(k) − θ(k−1))` or `(ω(k−1) + ω(k))/2
/// · dt`, jump, and running mean of the increment per sample; its phase and last values.
/// `known`: the increment and mean, found already (the common sample).
#[inline(always)]
fn reference<T: Real, const M: usize, const J: usize, const F: bool, const COMMON: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    r: usize,
    v: L<T, J>,
    sample: &Sample<T, J>,
    known: Option<Step<T, J>>,
) -> (L<T, J>, Mask<T, J>, L<T, J>) {
    let lim = &model.limits;
    let Sample { skip, counted, pending, n_samples, total_dt, .. } = *sample;
    let angle_input = model.phase_source == PhaseSource::Angle;
    let last = L(bank.last[r]);
    let d = match known {
        Some((d, _)) => d,
        None => increment(model, v, last, total_dt),
    };
    // A glitch: an increment too large, or too different from the last one.
    let last_delta = L(bank.last_delta[r]);
    let changed = !(d - last_delta * n_samples).abs().at_most(lim.max_step_change_rad);
    let jump = counted & (!d.abs().at_most(lim.max_angle_step_rad) | (Mask::of(|l| bank.delta_known[l]) & changed));
    let jump = if COMMON { Mask::splat(false) } else { jump };
    let accept = counted & !jump;
    let per_sample = if pending.equals(T::ZERO).all() { d } else { pending.equals(T::ZERO).select(d, d / n_samples) };
    // State written where the mask holds (in the common sample it always does).
    let write = |mask: Mask<T, J>, old: L<T, J>, new: L<T, J>| if COMMON { new.0 } else { mask.update(old, new).0 };
    let m = L(bank.mean_delta[r]);
    let mean = match known {
        Some((_, mean)) => mean,
        None => mean_increment::<T, J, F>(m, per_sample),
    };
    bank.mean_delta[r] = write(accept, m, mean);
    bank.last_delta[r] = write(accept, last_delta, per_sample);
    let delta = counted.select(d, L::splat(T::ZERO));
    // The phase: the angle itself, or the accumulated increments.
    let psi = L(bank.psi[r]);
    let (next, keep_psi) = if angle_input { (v, skip) } else { (psi + delta, skip | jump) };
    bank.psi[r] = write(!keep_psi, psi, wrap(next));
    bank.last[r] = write(!skip, last, v);
    (delta, jump, L(bank.mean_delta[r]))
}

/// Each order with a fractional multiple keeps its own phase, advanced by its increment
/// `a_i` (rad): `ψ_i ← wrap_π(ψ_i + a_i)`.
#[inline(always)]
fn order_phases<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    inc: &[L<T, J>; M],
) {
    for i in 0..M {
        if model.plan.power[i] == 0 {
            bank.order_psi[i] = wrap(L(bank.order_psi[i]) + inc[i]).0;
        }
    }
}

/// Each order's phasor (times `|T_exp + b̂(k|k−1)|` if load-scaled): its reference's to
/// a whole power, or of its own phase for a fractional multiple; kept in the state.
#[inline(always)]
fn phasors<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> [[L<T, J>; 2]; M] {
    let plan = &model.plan;
    let mut phasor = [[L::splat(T::ZERO); 2]; M];
    let load = (L(input.expected_torque_nm) + L(bank.b)).abs();
    let load = load.finite().select(load, L::splat(T::ZERO));
    let mut base = [(L::splat(T::ONE), L::splat(T::ZERO)); 3];
    for r in 0..3 {
        if plan.uses[r] {
            base[r] = sin_cos_with::<T, F, J>(L(bank.psi[r])).pair();
        }
    }
    for i in 0..M {
        let (c, s) = pick(&base, plan.reference[i]);
        let (mut c, mut s) = match plan.power[i] {
            1 => (c, s),
            2 => Doubling::new(c, s).doubled::<F>().pair(),
            4 => Doubling::new(c, s).doubled::<F>().doubled::<F>().pair(),
            0 => sin_cos_with::<T, F, J>(L(bank.order_psi[i])).pair(),
            n => phasor_power_with::<T, F, J>(c, s, n).pair(),
        };
        if model.orders[i].load_scaled {
            (c, s) = (c * load, s * load);
        }
        (bank.phasor[i][0], bank.phasor[i][1]) = (c.0, s.0);
        phasor[i] = [c, s];
    }
    phasor
}

/// Where measurement `y` is used: within ±10¹² N·m (a DAQ's overrange code is skipped as NaN is).
fn usable<T: Real, const J: usize>(y: L<T, J>) -> Mask<T, J> {
    y.abs().at_most(T::from_f64(1e12))
}

/// Time update: inflation `ρ (P_00 + P_11)/2 · I₂` (rotation invariant, like Q) and
/// process noise on the diagonal blocks; a reset order restarts from its prior and
/// forgets its covariances, an order not active is decoupled from the others.
/// `COMMON`: every order of every joint is kept and coupled (nothing to select); the
/// predicted variances are then left for the update to write (their store and reload,
/// at other widths, would lengthen the step's dependency chain). Returns them.
#[inline(always)]
fn time_update<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool, const COMMON: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    q: [L<T, J>; M],
    sample: &Sample<T, J>,
    d: Option<&Decided<T, M, J>>,
) -> Predicted<T, M, J> {
    let (plan, orders) = (&model.plan, &model.orders);
    let mut prior = Predicted { diag: [[L::splat(T::ZERO); 2]; M], pbb: L(bank.pbb) };
    let grow = if COMMON { L::splat(model.limits.covariance_inflation * T::HALF) } else { sample.inflation * T::HALF };
    let zero = L::splat(T::ZERO);
    for i in 0..M {
        let q = q[i];
        let blk = &mut bank.p[i][i];
        let (v0, v1) = (L(blk[0][0]), L(blk[1][1]));
        let trace = v0 + v1;
        let (v0, v1) = (v0.madd::<F>(grow, trace) + q, v1.madd::<F>(grow, trace) + q);
        let Some(d) = d.filter(|_| !COMMON) else {
            prior.diag[i] = [v0, v1];
            continue;
        };
        let keep = d.keep[i];
        let fresh = q + plan.p0_nm2[i];
        // A held order (kept, not updated) forgets toward its prior, never past it (the
        // inflation alone would grow its variances without bound).
        let held = keep & !d.active[i];
        let p0 = L::splat(plan.p0_nm2[i]);
        let (v0, v1) = (held.select(v0.min(L(blk[0][0]).max(p0)), v0), held.select(v1.min(L(blk[1][1]).max(p0)), v1));
        prior.diag[i] = [keep.select(v0, fresh), keep.select(v1, fresh)];
        (blk[0][0], blk[1][1]) = (prior.diag[i][0].0, prior.diag[i][1].0);
        let off = (!keep).update(L(blk[0][1]), zero).0;
        (blk[0][1], blk[1][0]) = (off, off);
        for r in 0..2 {
            bank.z[i][r] = (!keep).update(L(bank.z[i][r]), L::splat(orders[i].prior_nm[r])).0;
            if BIAS {
                bank.pb[i][r] = (!d.couple[i]).update(L(bank.pb[i][r]), zero).0;
            }
        }
        for j in i + 1..M {
            let both = d.couple[i] & d.couple[j];
            for v in bank.p[i][j].iter_mut().flatten() {
                *v = (!both).update(L(*v), zero).0;
            }
        }
    }
    if BIAS {
        // A time gap brings the bias variance back up to its initial value.
        let v = L(bank.pbb);
        let v =
            if COMMON { v } else { (sample.gap & v.less(model.p0_bias_nm2)).select(L::splat(model.p0_bias_nm2), v) };
        let q_bias = model.bias_q_nm2.unwrap_or(T::ZERO);
        prior.pbb = v.madd::<F>(v, sample.inflation) + sample.n_noise * q_bias;
        if !COMMON {
            bank.pbb = prior.pbb.0;
        }
    }
    prior
}

/// The predicted variances of a step: each order's diagonal `[P_00, P_11]` and `Var(b)`.
#[derive(Clone, Copy)]
struct Predicted<T: Real, const M: usize, const J: usize> {
    diag: [[L<T, J>; 2]; M],
    pbb: L<T, J>,
}

/// The prediction (the output) and measurement update of every joint; where the state
/// went bad.
#[allow(clippy::too_many_lines)]
#[inline(always)]
fn update<
    T: Real,
    const M: usize,
    const J: usize,
    const F: bool,
    const BIAS: bool,
    const TRACE: bool,
    const COMMON: bool,
>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    (noted, d): (&Noted<T, M, J>, Option<&Decided<T, M, J>>),
    (phasor, prior): (&[[L<T, J>; 2]; M], &Predicted<T, M, J>),
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) -> Mask<T, J> {
    let sample = &noted.sample;
    let (lim, orders) = (&model.limits, &model.orders);
    let (torque, expected) = (L(input.torque_nm), L(input.expected_torque_nm));
    let y = torque - expected;
    let zero = L::splat(T::ZERO);
    // In the common sample every measurement is used and every order active.
    let d = d.filter(|_| !COMMON);
    let meas_ok = if d.is_some() { sample.meas_ok } else { Mask::splat(true) };
    // Prediction ŷ(k) = h ẑ(k|k−1) (every order not off) and the update row h (the
    // orders updated; the bias entry is 1 when the measurement is used).
    let (mut ripple, mut mis) = (zero, zero);
    let mut h = [[zero; 2]; M];
    for i in 0..M {
        let [c, s] = phasor[i];
        let v = (c * L(bank.z[i][0])).madd::<F>(s, L(bank.z[i][1]));
        let v = d.map_or(v, |d| d.off[i].select(zero, v));
        if orders[i].reference.is_ripple() {
            ripple = ripple + v;
        } else {
            mis = mis + v;
        }
        h[i] = d.map_or([c, s], |d| {
            let row = meas_ok & d.active[i];
            [row.select(c, zero), row.select(s, zero)]
        });
    }

    // Gains g = P hᵀ from the upper blocks of the symmetric P, and the bias entry.
    let mut g = [[zero; 2]; M];
    for i in 0..M {
        let mut acc = if BIAS { Some([0, 1].map(|r| meas_ok.select(L(bank.pb[i][r]), zero))) } else { None };
        for j in 0..M {
            let t = block_times::<T, M, J, F>(bank, prior, i, j, h[j]);
            acc = Some(acc.map_or(t, |a| [a[0] + t[0], a[1] + t[1]]));
        }
        g[i] = acc.unwrap_or([zero; 2]);
    }
    let mut gb = zero;
    if BIAS {
        gb = meas_ok.select(prior.pbb, zero);
        for j in 0..M {
            gb = gb + (L(bank.pb[j][0]) * h[j][0]).madd::<F>(L(bank.pb[j][1]), h[j][1]);
        }
    }

    // Innovation `e = y − ŷ`, its variance `S = R + h g`, and the load-step decision:
    // an innovation beyond the NIS limit is a jump of the bias, not of the oscillators.
    // The update is then the exact limit Var(b) → ∞ (gain 0 here, completed below).
    let mut s = if BIAS { Some(gb) } else { None };
    for i in 0..M {
        let t = (h[i][0] * g[i][0]).madd::<F>(h[i][1], g[i][1]);
        s = Some(s.map_or(t, |acc| acc + t));
    }
    let s_var = s.map_or(L::splat(model.r_nm2), |s| s + model.r_nm2);
    let e = y - (ripple + mis + L(bank.b));
    let e_used = meas_ok.select(e, zero);
    let load_step =
        Mask::splat(BIAS && lim.load_step_nis > T::ZERO) & (s_var * lim.load_step_nis).less(e_used * e_used);
    let inv = load_step.select(zero, s_var.map(|s| T::ONE / s));
    let flags = d.map_or(Mask::splat(false), |d| d.flags) | load_step.bits(StepFlags::LOAD_STEP.bits());
    out.flags = flags.low_bits().map(StepFlags::from_bits);
    let mut trace = trace.filter(|_| TRACE);
    if let Some(tr) = trace.as_deref_mut() {
        let row_b = if BIAS && meas_ok.lane(0) { T::ONE } else { T::ZERO };
        let q_b = model.bias_q_nm2.unwrap_or(T::ZERO) * sample.n_noise.0[0];
        let lane0 = |v: [[L<T, J>; 2]; M]| v.map(|p| p.map(|x| x.0[0]));
        let scalars = [q_b, row_b, gb.0[0], s_var.0[0], e_used.0[0], y.0[0]];
        // The trace shows the predicted state.
        for i in 0..M {
            (bank.p[i][i][0][0], bank.p[i][i][1][1]) = (prior.diag[i][0].0, prior.diag[i][1].0);
        }
        bank.pbb = prior.pbb.0;
        record(tr, bank, noted, d, (lane0(h), lane0(g)), scalars, [BIAS, load_step.lane(0)]);
    }
    update_state::<T, M, J, F, BIAS>(model, bank, prior, (&h, &g, gb), (e_used, inv, load_step));
    if let Some(tr) = trace {
        tr.posterior = gaussian(bank, 0);
    }

    // Outputs, and where the covariance went bad.
    let clean = torque - ripple - mis;
    let e = if COMMON { e } else { usable(y).select(e, L::splat(T::from_f64(f64::NAN))) };
    out.torque_nm = clean.0;
    out.ripple_nm = ripple.0;
    out.misalignment_nm = mis.0;
    out.torque_state_nm = if BIAS { (expected + L(bank.b)).0 } else { clean.0 };
    out.innovation_nm = e.0;
    out.innovation_variance_nm2 = s_var.0;
    out.nis = (e * e / s_var).0;
    !healthy(BIAS, bank, s_var)
}

/// Measurement update `ẑ += k e`, `P −= k gᵀ` with the gain `k = g / S` (upper blocks), with
/// the update row `h`, gains `g` and `gb` (bias), the innovation used, `1/S` (0 on a
/// load step) and the load steps. Variances never fall below their exact lower bound
/// `P_ii R / S`.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn update_state<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    prior: &Predicted<T, M, J>,
    (h, g, gb): (&[[L<T, J>; 2]; M], &[[L<T, J>; 2]; M], L<T, J>),
    (e_used, inv, load_step): (L<T, J>, L<T, J>, Mask<T, J>),
) {
    let floor = inv * model.r_nm2;
    for i in 0..M {
        let [g0, g1] = g[i];
        let (k0, k1) = (g0 * inv, g1 * inv);
        bank.z[i][0] = L(bank.z[i][0]).madd::<F>(k0, e_used).0;
        bank.z[i][1] = L(bank.z[i][1]).madd::<F>(k1, e_used).0;
        let blk = &mut bank.p[i][i];
        let [v0, v1] = prior.diag[i];
        blk[0][0] = v0.madd::<F>(-k0, g0).max(v0 * floor).0;
        blk[1][1] = v1.madd::<F>(-k1, g1).max(v1 * floor).0;
        let off = L(blk[0][1]).madd::<F>(-k0, g1).0;
        (blk[0][1], blk[1][0]) = (off, off);
        for j in i + 1..M {
            let [gj0, gj1] = g[j];
            let b = &mut bank.p[i][j];
            for (r, kr) in [k0, k1].into_iter().enumerate() {
                b[r][0] = L(b[r][0]).madd::<F>(-kr, gj0).0;
                b[r][1] = L(b[r][1]).madd::<F>(-kr, gj1).0;
            }
        }
        if BIAS {
            bank.pb[i][0] = L(bank.pb[i][0]).madd::<F>(-k0, gb).0;
            bank.pb[i][1] = L(bank.pb[i][1]).madd::<F>(-k1, gb).0;
        }
    }
    if BIAS {
        let kb = gb * inv;
        let b = L(bank.b).madd::<F>(kb, e_used);
        let v = prior.pbb;
        let pbb = v.madd::<F>(-kb, gb).max(v * model.r_nm2 * inv);
        // The load-step limit: the bias takes the whole innovation, the oscillators
        // learn nothing, and `Var(b) = R + h P_zz hᵀ`, `Cov(z, b) = −P_zz hᵀ` (no
        // cancellation, PSD by construction); `P_zz hᵀ = g − Cov(z, b)` as h's bias
        // entry is 1.
        let mut s_z = L::splat(T::ZERO);
        for i in 0..M {
            for r in 0..2 {
                let pb = L(bank.pb[i][r]);
                let pzh = g[i][r] - pb;
                s_z = s_z + h[i][r] * pzh;
                bank.pb[i][r] = load_step.select(-pzh, pb).0;
            }
        }
        bank.pbb = load_step.select(s_z + model.r_nm2, pbb).0;
        bank.b = load_step.select(b + e_used, b).0;
    }
}

/// Where the joints' state is usable after an update with innovation variance `s_var`:
/// one sum catches any NaN/∞, one minimum any negative variance.
#[inline(always)]
pub(super) fn healthy<T: Real, const M: usize, const J: usize>(
    bias: bool,
    bank: &RippleBank<T, M, J>,
    s_var: L<T, J>,
) -> Mask<T, J> {
    // The two entries of each pair apart, then together: two independent chains.
    let (mut sum, mut least) = ([None; 2], [s_var; 2]);
    for i in 0..M {
        let d = &bank.p[i][i];
        for r in 0..2 {
            let t = L(d[r][r]) + L(bank.z[i][r]);
            sum[r] = Some(sum[r].map_or(t, |acc| acc + t));
            least[r] = least[r].min(L(d[r][r]));
        }
    }
    let zero = L::splat(T::ZERO);
    let total = (sum[0].unwrap_or(zero) + sum[1].unwrap_or(zero)) + (s_var + L(bank.b));
    let (total, low) = if bias {
        (total + L(bank.pbb), least[0].min(least[1]).min(L(bank.pbb)))
    } else {
        (total, least[0].min(least[1]))
    };
    total.finite() & zero.at_most(low) & zero.less(s_var)
}

/// `P_ij h_j` (two entries of `g_i`), from the upper blocks of the symmetric P, the
/// diagonal's variances from `prior`.
#[inline(always)]
fn block_times<T: Real, const M: usize, const J: usize, const F: bool>(
    bank: &RippleBank<T, M, J>,
    prior: &Predicted<T, M, J>,
    i: usize,
    j: usize,
    [h0, h1]: [L<T, J>; 2],
) -> [L<T, J>; 2] {
    let (b, t) = if j >= i { (&bank.p[i][j], false) } else { (&bank.p[j][i], true) };
    if i == j {
        // The variances come from `prior`, the covariance from one entry (a load of both
        // entries, stored apart, would wait for both stores to retire).
        let ([v0, v1], off) = (prior.diag[i], L(b[0][1]));
        return [(v0 * h0).madd::<F>(off, h1), (off * h0).madd::<F>(v1, h1)];
    }
    let at = |r: usize, c: usize| L(if t { b[c][r] } else { b[r][c] });
    [(at(0, 0) * h0).madd::<F>(at(0, 1), h1), (at(1, 0) * h0).madd::<F>(at(1, 1), h1)]
}

/// `a[r]` by selects (`r < 3`).
#[inline(always)]
fn pick<V: Copy>(a: &[V; 3], r: usize) -> V {
    match r {
        0 => a[0],
        1 => a[1],
        _ => a[2],
    }
}

/// Joint `l`'s rotating-frame mean and covariance.
fn gaussian<T: Real, const M: usize, const J: usize>(bank: &RippleBank<T, M, J>, l: usize) -> RotatingGaussian<T, M> {
    let mut g = RotatingGaussian::zeros();
    for i in 0..M {
        for r in 0..2 {
            g.z[i][r] = bank.z[i][r][l];
            g.pb[i][r] = bank.pb[i][r][l];
        }
        for j in 0..M {
            g.p[i][j] = bank.block(i, j, l).unwrap_or([[T::ZERO; 2]; 2]);
        }
    }
    g.bias = bank.b[l];
    g.pbb = bank.pbb[l];
    g
}

/// Joint 0's quantities of this step into `tr`, before the measurement update: what
/// `dec` decided, the update row and gains `(h, g)`; `scalars`: bias noise, update row
/// and gain entries, `S`, the innovation used, `y`.
#[inline(never)]
fn record<T: Real, const M: usize, const J: usize>(
    tr: &mut StepTrace<T, M>,
    bank: &RippleBank<T, M, J>,
    noted: &Noted<T, M, J>,
    dec: Option<&Decided<T, M, J>>,
    (h, g): ([[T; 2]; M], [[T; 2]; M]),
    [q_b, row_b, g_b, s_var, e_used, y]: [T; 6],
    [bias, load_step]: [bool; 2],
) {
    for i in 0..M {
        (tr.increment_rad[i], tr.q_nm2[i]) = (noted.inc[i].0[0], noted.q[i].0[0]);
        tr.kept[i] = dec.is_none_or(|d| d.keep[i].lane(0));
        tr.predicted[i] = dec.is_none_or(|d| !d.off[i].lane(0));
        tr.phasor[i] = [bank.phasor[i][0][0], bank.phasor[i][1][0]];
    }
    (tr.update_row, tr.gain_numerator) = (h, g);
    tr.prior = gaussian(bank, 0);
    (tr.q_bias_nm2, tr.update_row_bias, tr.gain_numerator_bias) = (q_b, row_b, g_b);
    (tr.innovation_variance_nm2, tr.innovation_used_nm, tr.measurement_nm) = (s_var, e_used, y);
    tr.bias_reinflated = bias & noted.sample.gap.lane(0);
    tr.load_step = load_step;
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::{step, step_traced, Order, PhaseSource, Reference, ReferenceValues, RippleInput, RippleState};
    use super::*;
    use std::cell::Cell;

    std::thread_local! {
        /// Whether this thread's steps skip the common sample's test (to compare with it).
        static GENERAL_ONLY: Cell<bool> = const { Cell::new(false) };
        /// How many common samples this thread's steps took.
        static COMMON_SAMPLES: Cell<usize> = const { Cell::new(0) };
    }

    pub(super) fn general_only() -> bool {
        GENERAL_ONLY.get()
    }

    pub(super) fn count_common() {
        COMMON_SAMPLES.set(COMMON_SAMPLES.get() + 1);
    }

    /// The common sample's shortcut gives what the general decisions give, bit for bit
    /// (outputs and the whole state), over the awkward sequence; both are exercised.
    fn shortcut_is_the_general_step<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>) -> usize {
        let (mut fast, mut general) = (RippleBank::<T, M, J>::new(&model), RippleBank::<T, M, J>::new(&model));
        let n = 6000;
        COMMON_SAMPLES.set(0);
        for k in 0..n {
            let input = sample::<T, M, J>(&model, k, 4000);
            let (mut a, mut b) = (BankOutput::default(), BankOutput::default());
            step_many(&model, &mut fast, &input, &mut a);
            GENERAL_ONLY.set(true);
            step_many(&model, &mut general, &input, &mut b);
            GENERAL_ONLY.set(false);
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "k {k}");
            assert_eq!(format!("{fast:?}"), format!("{general:?}"), "k {k}");
        }
        let common = COMMON_SAMPLES.get();
        assert!(common > n / 2 && common < n, "{common} common samples of {n}");
        common
    }

    #[test]
    fn common_sample_shortcut_is_the_general_step_bit_for_bit() {
        let (seed6, motor, full, velocity) = models_f64();
        shortcut_is_the_general_step::<f64, 3, 1>(seed6);
        shortcut_is_the_general_step::<f64, 3, 2>(motor);
        shortcut_is_the_general_step::<f64, 5, 4>(full);
        shortcut_is_the_general_step::<f64, 2, 3>(velocity);
        // Two lines of one reference held at different speeds (the default hold limit).
        let ripple = [Order::new(Reference::Relative, 2.0).unwrap(), Order::new(Reference::Relative, 4.0).unwrap()];
        shortcut_is_the_general_step::<f64, 2, 2>(RippleModel::new(ripple, 0.5, 1000.0).unwrap());
        shortcut_is_the_general_step::<f32, 3, 8>(RippleModel::product(1000.0, 0.05).unwrap());
        shortcut_is_the_general_step::<f32, 3, 1>(RippleModel::product(1000.0, 0.05).unwrap());
    }

    /// Sample `k` for `J` joints with the awkward cases: NaN torque, angle jumps, a gap,
    /// load steps, two speeds, angles unwrapped from sample `unwrapped_after` on.
    pub(crate) fn sample<T: Real, const M: usize, const J: usize>(
        model: &RippleModel<T, M>,
        k: usize,
        unwrapped_after: usize,
    ) -> BankInput<T, J> {
        let c = T::from_f64;
        let mut seed = 0x9E37_79B9_7F4A_7C15_u64 ^ (k as u64).wrapping_mul(0x2545_F491_4F6C_DD1D);
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let noise = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        // Relative angle per sample: slow, faster, 4× lines above the Nyquist guard (2×
        // not), then slowing down smoothly to near standstill (2× lines held, 4× not).
        let ramp = |from: f64, to: f64, i: usize, start: usize, len: usize| {
            from + (to - from) * (i - start) as f64 / len as f64
        };
        let speed = |i: usize| match i {
            0..3000 => 0.08,
            4600..4900 => 0.8,
            5000..5200 => ramp(0.3, 1.2e-4, i, 5000, 200),
            5200..5500 => 1.2e-4,
            5500..5600 => ramp(1.2e-4, 0.3, i, 5500, 100),
            3000.. => 0.3,
        };
        let (w, phase) = (speed(k), (0..k).map(speed).sum::<f64>());
        let theta = |j: usize| {
            let t = phase + 0.3 * j as f64 + if k % 997 == 500 { 2.0 } else { 0.0 };
            if model.phase_source() == PhaseSource::Velocity {
                w * 1000.0
            } else if k >= unwrapped_after {
                t
            } else {
                t.rem_euclid(core::f64::consts::TAU)
            }
        };
        let load_step = if k % 1500 == 700 { 40.0 } else { 0.0 };
        let mut input = BankInput::new(
            core::array::from_fn(|j| c(2.0 + (2.0 * theta(j)).cos() + 0.1 * noise + load_step)),
            ReferenceValues::new(
                core::array::from_fn(|j| c(theta(j))),
                core::array::from_fn(|j| c(-theta(j) / 50.0)),
                core::array::from_fn(|j| c(theta(j) + 0.1)),
            ),
        );
        input.expected_torque_nm = core::array::from_fn(|j| c(1.5 - j as f64));
        if k % 611 == 3 {
            input.torque_nm[J - 1] = c(f64::NAN);
        }
        if k % 1777 == 900 {
            input.dt_s = Some(c(if k.is_multiple_of(2) { 0.01 } else { 0.0011 }));
        }
        input
    }

    /// Joint `j` of a bank input.
    fn joint<T: Real, const J: usize>(b: &BankInput<T, J>, j: usize) -> RippleInput<T> {
        let r = &b.references;
        let mut input = RippleInput::new(b.torque_nm[j], ReferenceValues::new(r.relative[j], r.output[j], r.motor[j]));
        input.expected_torque_nm = b.expected_torque_nm[j];
        input.dt_s = b.dt_s;
        input
    }

    fn models_f64() -> (RippleModel<f64, 3>, RippleModel<f64, 3>, RippleModel<f64, 5>, RippleModel<f64, 2>) {
        let motor = [
            Order::new(Reference::Motor, 1.0).unwrap(),
            Order::new(Reference::Relative, 2.5).unwrap().with_noise(1e-4, 0.0).unwrap(),
            Order::new(Reference::Output, 3.0).unwrap().scaled_by_load(),
        ];
        (
            RippleModel::taghirad_6th_order(1000.0).unwrap(),
            RippleModel::new(motor, 0.5f64.sqrt(), 1000.0).unwrap().with_bias_state(1e-3).unwrap(),
            RippleModel::full(1000.0, 0.05).unwrap(),
            RippleModel::taghirad_4th_order(1000.0).unwrap().with_phase_source(PhaseSource::Velocity),
        )
    }

    /// A bank steps each joint exactly as that joint steps alone, whatever the others
    /// do (skips, resets and load steps fall on different joints at different times).
    fn bank_is_its_joints<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>) {
        let mut bank = RippleBank::<T, M, J>::new(&model);
        let mut singles = [RippleState::new(&model); J];
        let mut out = BankOutput::default();
        let mut flagged = 0;
        for k in 0..6000 {
            let input = sample::<T, M, J>(&model, k, 4000);
            step_many(&model, &mut bank, &input, &mut out);
            for j in 0..J {
                let one = step(&model, &mut singles[j], &joint(&input, j)).unwrap();
                let lane = |a: &[T; J]| a[j];
                assert_eq!(one.torque_nm.to_f64().to_bits(), lane(&out.torque_nm).to_f64().to_bits(), "k {k} j {j}");
                assert_eq!(one.nis.to_f64().to_bits(), lane(&out.nis).to_f64().to_bits(), "k {k} j {j}");
                assert_eq!(one.torque_state_nm.to_f64().to_bits(), lane(&out.torque_state_nm).to_f64().to_bits());
                assert_eq!(one.flags, out.flags[j], "k {k} j {j}");
                flagged += usize::from(!one.flags.is_empty());
            }
        }
        assert!(flagged > 10, "the run should exercise the uncommon samples: {flagged}");
    }

    #[test]
    fn bank_steps_each_joint_as_it_steps_alone() {
        let (seed6, motor, full, velocity) = models_f64();
        bank_is_its_joints::<f64, 3, 3>(seed6);
        bank_is_its_joints::<f64, 3, 2>(motor);
        bank_is_its_joints::<f64, 5, 4>(full);
        bank_is_its_joints::<f64, 2, 3>(velocity);
        bank_is_its_joints::<f32, 3, 8>(RippleModel::product(1000.0, 0.05).unwrap());
    }

    /// The traced step is the step, bit for bit, and its trace holds joint 0's update.
    #[test]
    fn traced_step_is_the_step() {
        let model = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let (mut a, mut b) = (RippleState::new(&model), RippleState::new(&model));
        let mut trace = StepTrace::new();
        let mut load_steps = 0;
        for k in 0..4000 {
            let input = joint(&sample::<f64, 3, 1>(&model, k, usize::MAX), 0);
            let x = step(&model, &mut a, &input);
            let y = step_traced(&model, &mut b, &input, &mut trace);
            assert_eq!(format!("{x:?}"), format!("{y:?}"), "k {k}");
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "k {k}");
            // The posterior in the trace is the state after the step.
            let z = |i: usize| if i < 6 { b.bank.z[i / 2][i % 2][0] } else { b.bank.b[0] };
            for i in 0..7 {
                assert_eq!(trace.posterior.mean(i), Some(z(i)), "k {k}");
            }
            assert_eq!(trace.posterior.cov(6, 6), Some(b.bank.pbb[0]), "k {k}");
            load_steps += usize::from(trace.load_step);
        }
        assert!(load_steps >= 2, "{load_steps}");
    }

    /// Agreement per step of the build for this CPU with the portable build, from the
    /// same state: the same decisions, numbers within `tol` of their magnitude (≥ 1).
    fn builds_agree<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>, tol: f64) -> usize {
        let mut a = RippleBank::<T, M, J>::new(&model);
        let mut differ = 0;
        for k in 0..6000 {
            let input = sample::<T, M, J>(&model, k, 5000);
            let mut b = a;
            let (mut oa, mut ob) = (BankOutput::default(), BankOutput::default());
            run::<T, M, J, false>(&model, &mut a, &input, &mut oa, None);
            run_portable::<T, M, J, false>(&model, &mut b, &input, &mut ob, None);
            assert_eq!(oa.flags, ob.flags, "k {k}");
            assert_eq!(a.status, b.status, "k {k}");
            let pairs = oa.torque_nm.iter().zip(&ob.torque_nm).chain(oa.nis.iter().zip(&ob.nis));
            for (x, y) in pairs.chain(a.z.iter().flatten().flatten().zip(b.z.iter().flatten().flatten())) {
                let (x, y) = (x.to_f64(), y.to_f64());
                let same = x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan());
                assert!(same || (x - y).abs() <= tol * x.abs().max(y.abs()).max(1.0), "k {k}: {x} against {y}");
                differ += usize::from(x.to_bits() != y.to_bits());
            }
        }
        differ
    }

    #[test]
    fn cpu_build_agrees_with_the_portable_build() {
        let (seed6, motor, full, _) = models_f64();
        let differ = builds_agree::<f64, 3, 1>(seed6, 1e-10)
            + builds_agree::<f64, 3, 2>(motor, 1e-10)
            + builds_agree::<f64, 5, 4>(full, 1e-10)
            + builds_agree::<f32, 3, 8>(RippleModel::product(1000.0, 0.05).unwrap(), 2e-4);
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // Else the test would compare the portable build with itself.
            assert!(differ > 1000, "{differ}");
        }
        eprintln!("numbers that differ in their last bits: {differ}");
    }

    /// Each corruption of joint 0 is caught, and joint 1 (untouched) stays healthy.
    #[test]
    fn health_check_catches_each_bad_entry() {
        let model = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let fresh = RippleBank::<f64, 3, 2>::new(&model);
        let one = L::splat(1.0);
        assert_eq!(healthy(true, &fresh, one), Mask::splat(true));
        let corruptions: [fn(&mut RippleBank<f64, 3, 2>); 8] = [
            |b| b.p[2][2][1][1][0] = f64::NAN,
            |b| b.p[1][1][0][0][0] = f64::INFINITY,
            |b| b.p[0][0][1][1][0] = -1e-9,
            |b| b.z[2][0][0] = f64::NAN,
            |b| b.z[0][1][0] = f64::NEG_INFINITY,
            |b| b.b[0] = f64::NAN,
            |b| b.pbb[0] = -1.0,
            |b| b.pbb[0] = f64::INFINITY,
        ];
        for (k, corrupt) in corruptions.iter().enumerate() {
            let mut bank = fresh;
            corrupt(&mut bank);
            assert_eq!(healthy(true, &bank, one), Mask::of(|l| l == 1), "corruption {k}");
        }
        for s_var in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(healthy(true, &fresh, L([s_var, 1.0])), Mask::of(|l| l == 1), "S = {s_var}");
        }
        // Without the bias state its entries are not read.
        let mut bank = fresh;
        bank.pbb[0] = -1.0;
        assert_eq!(healthy(false, &bank, one), Mask::splat(true));
    }
}
