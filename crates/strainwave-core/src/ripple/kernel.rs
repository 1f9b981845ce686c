//! The one step of the canceller, written once for `J` joints that share a model (one
//! joint is `J = 1`). Each oscillator is kept in its rotating frame `x_i = Φ(ψ_i) z_i`
//! (`docs/physics.md`, section 4): with the update row `h = [cos ψ_1, sin ψ_1, …, 1]`,
//! `P(k|k−1) = P + Q`, `g = P hᵀ`, `S = R + h g`, `ẑ += g e / S`, `P −= g gᵀ / S`, and
//! `Φ` never multiplies `P`. Every per-joint decision (skip, first sample, gap, jump,
//! order held or off, load step) is a select, so a bank's passes over its joints can
//! vectorize. The CPU-specific build is chosen in one place, `run`: on x86-64 with AVX2
//! and FMA (std builds) the same step compiled with its multiply–adds fused.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::filter::{RotatingGaussian, StepTrace};
use super::io::{OrderStatus, StepFlags};
use super::model::{Limits, Order, PhaseSource, RippleModel};
use super::trig::{phasor_power_with, sin_cos_with, wrap_angle as wrap, Doubling};
use crate::Real;

/// Weight of the newest increment in the running mean that decides holding (1/16).
const HOLD_AVERAGE: f64 = 1.0 / 16.0;

/// What the kernel precomputes from a model (refreshed whenever a builder changes it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Plan<T: Real, const M: usize> {
    /// Nominal sample interval, s.
    pub(crate) dt_s: T,
    /// A sample interval above this is a time gap, s.
    pub(crate) max_gap_s: T,
    /// An order whose phase increment `|a|` passes this is switched off, rad per sample.
    pub(crate) off_above_rad: T,
    /// An order off comes back below this, rad per sample.
    pub(crate) on_below_rad: T,
    /// An order whose mean increment is below this is held, rad per sample.
    pub(crate) hold_below_rad: T,
    /// Whether some order uses each reference.
    pub(crate) uses: [bool; 3],
    /// The reference index of each order.
    pub(crate) reference: [usize; M],
    /// Whole multiple `n ≤ 16` of each order, or 0 (fractional or larger: own phase).
    pub(crate) power: [u8; M],
    /// Initial (and reset) variance of each order: its prior's, or the model's.
    pub(crate) p0_nm2: [T; M],
}

impl<T: Real, const M: usize> Plan<T, M> {
    /// The plan of a model with these orders, sample rate, limits and initial variance.
    pub(crate) fn new(orders: &[Order<T>; M], sample_rate_hz: T, lim: &Limits<T>, p0_oscillator_nm2: T) -> Self {
        let off_above_rad = lim.nyquist_fraction * T::TAU;
        let mut plan = Self {
            dt_s: T::ONE / sample_rate_hz,
            max_gap_s: lim.max_gap_periods / sample_rate_hz,
            off_above_rad,
            on_below_rad: off_above_rad * T::from_f64(0.9),
            hold_below_rad: lim.hold_below_hz * T::TAU / sample_rate_hz,
            uses: [false; 3],
            reference: [0; M],
            power: [0; M],
            p0_nm2: [p0_oscillator_nm2; M],
        };
        for (i, o) in orders.iter().enumerate() {
            let r = o.reference.index();
            plan.uses[r] = true;
            plan.reference[i] = r;
            let n = o.multiple.to_f64();
            plan.power[i] = if n == libm::round(n) && (1.0..=16.0).contains(&n) { n as u8 } else { 0 };
            plan.p0_nm2[i] = o.prior_variance_nm2.unwrap_or(p0_oscillator_nm2);
        }
        plan
    }
}

/// Steps `J` joints sharing `model` by one sample, writing their results into `out`
/// (a buffer the caller keeps: nothing is copied per sample). A joint whose covariance
/// went bad is reset and flagged [`StepFlags::COVARIANCE_RESET`]; the others are
/// unaffected. Each joint gets exactly what [`step`](super::step) would give it alone.
///
/// ```
/// use strainwave_core::ripple::{step_many, BankInput, BankOutput, ReferenceValues, RippleBank, RippleModel};
/// let model = RippleModel::<f32, 2>::seed_4th_order(1000.0).unwrap();
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

/// Every joint's step in passes over the joints, each a loop without a branch of its
/// own so that a bank's loops can vectorize: decisions and time update, the orders' phasors
/// (order by order), prediction and update; then the reset of joints gone bad.
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

/// What the first pass decided (`[order][joint]`, `[joint]`): order kept (else reset),
/// increment (rad), process noise (N·m²); measurement used, gap, samples of noise.
#[derive(Clone, Copy)]
struct Decided<T, const M: usize, const J: usize> {
    keep: [[bool; J]; M],
    inc: [[T; J]; M],
    q: [[T; J]; M],
    meas_ok: [bool; J],
    gap: [bool; J],
    n_noise: [T; J],
}

/// The passes of [`advance`] for a model with (`BIAS`) or without the bias state.
#[inline(always)]
fn passes<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    mut trace: Option<&mut StepTrace<T, M>>,
) {
    let (no, zero) = ([[false; J]; M], [[T::ZERO; J]; M]);
    let mut d = Decided { keep: no, inc: zero, q: zero, meas_ok: no[0], gap: no[0], n_noise: zero[0] };
    bank.steps = bank.steps.map(|s| s.wrapping_add(1));
    for l in 0..J {
        decide::<T, M, J, F, BIAS>(model, bank, input, l, &mut d, out);
    }
    if J > 1 {
        phasors::<T, M, J, F>(model, bank, input, &d.inc);
    }
    let mut bad = [false; J];
    for l in 0..J {
        let tr = if TRACE && l == 0 { trace.as_deref_mut() } else { None };
        bad[l] = update::<T, M, J, F, BIAS, TRACE>(model, bank, input, l, &d, out, tr);
    }
    for l in (0..J).filter(|&l| bad[l]) {
        bank.reset_lane(model, l);
        out.flags[l].insert(StepFlags::COVARIANCE_RESET);
        if BIAS {
            out.torque_state_nm[l] = input.expected_torque_nm[l] + bank.b[l];
        }
    }
}

/// Joint `l`'s decisions (valid input, increments `Δθ = wrap_π(θ(k) − θ(k−1))` or
/// `(ω(k−1) + ω(k))/2 · dt`, jumps, gaps, order status), phases and time update.
#[allow(clippy::too_many_lines)]
#[inline(always)]
fn decide<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    l: usize,
    dec: &mut Decided<T, M, J>,
    out: &mut BankOutput<T, J>,
) {
    let (plan, lim, orders) = (&model.plan, &model.limits, &model.orders);
    let angle_input = model.phase_source == PhaseSource::Angle;
    let dt = input.dt_s.unwrap_or(plan.dt_s);
    let dt_ok = finite(dt) & (dt > T::ZERO);
    let q_bias = model.bias_q_nm2.unwrap_or(T::ZERO);
    let refs = [input.references.relative[l], input.references.output[l], input.references.motor[l]];
    let y = input.torque_nm[l] - input.expected_torque_nm[l];

    // The sample: skipped (a used reference or `dt` not finite: the state stays as it
    // was, the next increment spans the gap), first, or after a time gap.
    let skip = !(0..3).fold(dt_ok, |ok, r| ok & (!plan.uses[r] | finite(refs[r])));
    let pending = bank.pending_samples[l];
    let n_samples = pending + T::ONE;
    let total_dt = bank.pending_dt[l] + dt;
    let first = !bank.has_last[l];
    let gap = !skip & !first & !(total_dt <= plan.max_gap_s);
    let meas_ok = !skip & finite(y);
    // The initial state is the prior of the first sample: no noise before it.
    let counted = !skip & !first;
    let n_noise = if counted { n_samples } else { T::ZERO };
    let infl = if counted { lim.covariance_inflation } else { T::ZERO };
    (dec.meas_ok[l], dec.gap[l], dec.n_noise[l]) = (meas_ok, gap, n_noise);

    // Each reference: its increment, whether it jumped, its phase. A bank works out
    // the unused ones too (a branch would stop its loop vectorizing) and keeps nothing
    // of them.
    let (mut delta, mut jump, mut mean) = ([T::ZERO; 3], [false; 3], [T::ZERO; 3]);
    for r in 0..3 {
        let used = plan.uses[r];
        if J == 1 && !used {
            continue;
        }
        let (v, last) = (refs[r], bank.last[r][l]);
        let d = if angle_input { wrap(v - last) } else { (v + last) * T::HALF * total_dt };
        // A glitch: an increment too large, or too different from the last one.
        let expected_d = bank.last_delta[r][l] * n_samples;
        let changed = bank.delta_known[l] & !((d - expected_d).abs() <= lim.max_step_change_rad);
        let jumped = used & counted & (!(d.abs() <= lim.max_angle_step_rad) | changed);
        let accept = used & counted & !jumped;
        let per_sample = if pending == T::ZERO { d } else { d / n_samples };
        // Mean increment over ~16 samples: encoder jitter at standstill averages out of
        // it, so it alone decides whether an order is held.
        let m = bank.mean_delta[r][l];
        mean[r] = if accept { madd::<T, F>(m, per_sample - m, T::from_f64(HOLD_AVERAGE)) } else { m };
        bank.mean_delta[r][l] = mean[r];
        bank.last_delta[r][l] = if accept { per_sample } else { bank.last_delta[r][l] };
        jump[r] = jumped;
        delta[r] = if counted { d } else { T::ZERO };
        // The phase: the angle itself, or the accumulated increments.
        let psi = bank.psi[r][l];
        let next = wrap(if angle_input { v } else { psi + delta[r] });
        let keep_psi = !used | skip | (!angle_input & jumped);
        bank.psi[r][l] = if keep_psi { psi } else { next };
        bank.last[r][l] = if skip | !used { last } else { v };
    }
    let any_jump = jump[0] | jump[1] | jump[2];
    bank.has_last[l] |= !skip;
    // After a jump or a gap the next increment sets a new baseline.
    bank.delta_known[l] = if skip { bank.delta_known[l] } else { !first & !gap & !any_jump };
    bank.pending_samples[l] = if skip { n_samples } else { T::ZERO };
    let pending_dt = bank.pending_dt[l] + if dt_ok { dt } else { plan.dt_s };
    bank.pending_dt[l] = if skip { pending_dt } else { T::ZERO };
    let mut flags = StepFlags::empty();
    flags.set(StepFlags::ANGLE_SKIPPED, skip);
    flags.set(StepFlags::MEASUREMENT_SKIPPED, !skip & !meas_ok);
    flags.set(StepFlags::GAP_RESET, gap);
    flags.set(StepFlags::JUMP_RESET, !gap & any_jump);

    // Each order: its status (active, held or off), what the time update does with it
    // (keep its state or restart from its prior, keep its covariances with the others)
    // and its process noise `q_i = q_s + q_rad |a_i|`.
    let mut couple = [true; M];
    for i in 0..M {
        // The order's reference by selects, not by index: the per-reference values
        // then stay in registers.
        let r = plan.reference[i];
        let reset = gap | pick(&jump, r);
        let a = if reset { T::ZERO } else { orders[i].multiple * pick(&delta, r) };
        let abs_a = a.abs();
        let mean_a = (orders[i].multiple * pick(&mean, r)).abs();
        let prev = bank.status[i][l];
        let was_off = prev == OrderStatus::Off;
        let off = !reset & ((was_off & !(abs_a < plan.on_below_rad)) | (!was_off & (abs_a > plan.off_above_rad)));
        let held = reset | (!off & (mean_a < plan.hold_below_rad));
        let status = if skip {
            prev
        } else if off {
            OrderStatus::Off
        } else if held {
            OrderStatus::Held
        } else {
            OrderStatus::Active
        };
        bank.status[i][l] = status;
        let (off, active) = (status == OrderStatus::Off, status == OrderStatus::Active);
        let zeroed = !skip & (reset | off);
        dec.keep[i][l] = !zeroed;
        couple[i] = skip | active;
        dec.inc[i][l] = if zeroed { T::ZERO } else { a };
        let q_i = madd::<T, F>(orders[i].q_per_sample_nm2 * n_noise, orders[i].q_per_rad_nm2, abs_a);
        dec.q[i][l] = if off | skip { T::ZERO } else { q_i };
        flags.set(StepFlags::ORDER_OFF, off);
        flags.set(StepFlags::ORDER_HELD, status == OrderStatus::Held);
    }
    out.flags[l] = flags;
    if J == 1 {
        // One joint: its phasors now, so that their chain starts before the time update.
        phasors::<T, M, J, F>(model, bank, input, &dec.inc);
    }

    // Time update: inflation `ρ (P_00 + P_11)/2 · I₂` (rotation invariant, like Q) and
    // process noise on the diagonal blocks; a reset order restarts from its prior and
    // forgets its covariances, an order not active is decoupled from the others.
    let grow = infl * T::HALF;
    for i in 0..M {
        let (keep, q) = (dec.keep[i][l], dec.q[i][l]);
        let d = &mut bank.p[i][i];
        let (v0, v1) = (d[0][0][l], d[1][1][l]);
        let trace = v0 + v1;
        let fresh = plan.p0_nm2[i] + q;
        d[0][0][l] = if keep { madd::<T, F>(v0, grow, trace) + q } else { fresh };
        d[1][1][l] = if keep { madd::<T, F>(v1, grow, trace) + q } else { fresh };
        let off = if keep { d[0][1][l] } else { T::ZERO };
        d[0][1][l] = off;
        d[1][0][l] = off;
        for r in 0..2 {
            bank.z[i][r][l] = if keep { bank.z[i][r][l] } else { orders[i].prior_nm[r] };
            if BIAS {
                bank.pb[i][r][l] = if couple[i] { bank.pb[i][r][l] } else { T::ZERO };
            }
        }
        for j in 0..M {
            // Constant bounds (no filter): every index is known, no bounds check is left.
            let both = couple[i] & couple[j];
            for r in 0..2 {
                for c in 0..2 {
                    let v = bank.p[i][j][r][c][l];
                    bank.p[i][j][r][c][l] = if (j <= i) | both { v } else { T::ZERO };
                }
            }
        }
    }
    if BIAS {
        // A time gap brings the bias variance back up to its initial value.
        let v = bank.pbb[l];
        let v = if gap & (v < model.p0_bias_nm2) { model.p0_bias_nm2 } else { v };
        bank.pbb[l] = madd::<T, F>(v, v, infl) + q_bias * n_noise;
    }
}

/// Each order's phasor (times `|T_exp + b̂(k|k−1)|` if load-scaled): its reference's to
/// a whole power, or of its own phase (`inc`: increments) for a fractional multiple.
#[inline(always)]
fn phasors<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    inc: &[[T; J]; M],
) {
    let plan = &model.plan;
    let mut base = [[[T::ZERO; J]; 2]; 3];
    for r in 0..3 {
        if plan.uses[r] {
            for l in 0..J {
                let p = sin_cos_with::<T, F>(bank.psi[r][l]);
                (base[r][0][l], base[r][1][l]) = (p.c, p.s);
            }
        }
    }
    for i in 0..M {
        let [c, s] = base[plan.reference[i]];
        let ph = match plan.power[i] {
            1 => [c, s],
            2 => each_lane(&c, &s, |_, b| b.doubled::<F>()),
            4 => each_lane(&c, &s, |_, b| b.doubled::<F>().doubled::<F>()),
            0 => {
                // A fractional multiple: its own accumulated phase.
                for l in 0..J {
                    bank.order_psi[i][l] = wrap(bank.order_psi[i][l] + inc[i][l]);
                }
                let psi = bank.order_psi[i];
                each_lane(&c, &s, |l, _| sin_cos_with::<T, F>(psi[l]))
            }
            n => each_lane(&c, &s, |_, b| {
                let (c, s) = phasor_power_with::<T, F>(b.c, b.s, n);
                Doubling::new(c, s)
            }),
        };
        for l in 0..J {
            let load = (input.expected_torque_nm[l] + bank.b[l]).abs();
            let load = if finite(load) { load } else { T::ZERO };
            let scale = if model.orders[i].load_scaled { load } else { T::ONE };
            bank.phasor[i][0][l] = ph[0][l] * scale;
            bank.phasor[i][1][l] = ph[1][l] * scale;
        }
    }
}

/// Joint `l`'s prediction (the output) and measurement update; whether it went bad.
#[allow(clippy::too_many_lines)]
#[inline(always)]
fn update<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    l: usize,
    dec: &Decided<T, M, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) -> bool {
    let (lim, orders) = (&model.limits, &model.orders);
    let (torque, expected) = (input.torque_nm[l], input.expected_torque_nm[l]);
    let y = torque - expected;
    let meas_ok = dec.meas_ok[l];
    // Prediction ŷ(k) = h ẑ(k|k−1) (every order not off) and the update row h (the
    // orders updated; the bias entry is 1 when the measurement is used).
    let (mut ripple, mut mis) = (T::ZERO, T::ZERO);
    let (mut any_ripple, mut any_mis) = (false, false);
    let mut h = [[T::ZERO; 2]; M];
    for i in 0..M {
        let (c, s) = (bank.phasor[i][0][l], bank.phasor[i][1][l]);
        let v = madd::<T, F>(c * bank.z[i][0][l], s, bank.z[i][1][l]);
        let status = bank.status[i][l];
        let v = if status != OrderStatus::Off { v } else { T::ZERO };
        if orders[i].reference.is_ripple() {
            ripple = sum_from(!any_ripple, ripple, v);
            any_ripple = true;
        } else {
            mis = sum_from(!any_mis, mis, v);
            any_mis = true;
        }
        h[i] = if meas_ok & (status == OrderStatus::Active) { [c, s] } else { [T::ZERO; 2] };
    }

    // Gains g = P hᵀ from the upper blocks of the symmetric P, and the bias entry.
    let mut g = [[T::ZERO; 2]; M];
    for i in 0..M {
        if BIAS {
            g[i] = if meas_ok { [bank.pb[i][0][l], bank.pb[i][1][l]] } else { [T::ZERO; 2] };
        }
        for j in 0..M {
            let (t0, t1) = block_times::<T, M, J, F>(bank, i, j, l, h[j]);
            let first = !BIAS && j == 0;
            g[i] = [sum_from(first, g[i][0], t0), sum_from(first, g[i][1], t1)];
        }
    }
    let mut gb = T::ZERO;
    if BIAS {
        gb = if meas_ok { bank.pbb[l] } else { T::ZERO };
        for j in 0..M {
            gb += madd::<T, F>(bank.pb[j][0][l] * h[j][0], bank.pb[j][1][l], h[j][1]);
        }
    }

    // Innovation `e = y − ŷ`, its variance `S = R + h g`, and the load-step decision:
    // an innovation beyond the NIS limit is a jump of the bias, not of the oscillators.
    // The update is then the exact limit Var(b) → ∞ (gain 0 here, completed below).
    let mut s = if BIAS { gb } else { T::ZERO };
    for i in 0..M {
        s = sum_from(!BIAS && i == 0, s, madd::<T, F>(h[i][0] * g[i][0], h[i][1], g[i][1]));
    }
    let s_var = model.r_nm2 + s;
    let e = y - (ripple + mis + bank.b[l]);
    let e_used = if meas_ok { e } else { T::ZERO };
    let load_step = BIAS & (lim.load_step_nis > T::ZERO) & (e_used * e_used > lim.load_step_nis * s_var);
    let inv = if load_step { T::ZERO } else { T::ONE / s_var };
    out.flags[l].set(StepFlags::LOAD_STEP, load_step);
    let mut trace = trace;
    if let Some(tr) = trace.as_deref_mut().filter(|_| TRACE) {
        let row_b = if BIAS && meas_ok { T::ONE } else { T::ZERO };
        let q_b = model.bias_q_nm2.unwrap_or(T::ZERO) * dec.n_noise[l];
        record(tr, bank, l, dec, (h, g), [q_b, row_b, gb, s_var, e_used, y], [BIAS, load_step]);
    }

    // Measurement update `ẑ += g e / S`, `P −= g gᵀ / S` (upper blocks; each product
    // `g_i g_j` times `1/S`, so that it waits on the division for one multiply–add).
    // Variances never fall below their exact lower bound `P_ii R / S`.
    let floor = model.r_nm2 * inv;
    for i in 0..M {
        let [g0, g1] = g[i];
        let (k0, k1) = (g0 * inv, g1 * inv);
        bank.z[i][0][l] = madd::<T, F>(bank.z[i][0][l], k0, e_used);
        bank.z[i][1][l] = madd::<T, F>(bank.z[i][1][l], k1, e_used);
        let d = &mut bank.p[i][i];
        let (v0, v1) = (d[0][0][l], d[1][1][l]);
        d[0][0][l] = madd::<T, F>(v0, -(g0 * g0), inv).max(v0 * floor);
        d[1][1][l] = madd::<T, F>(v1, -(g1 * g1), inv).max(v1 * floor);
        let off = madd::<T, F>(d[0][1][l], -(g0 * g1), inv);
        d[0][1][l] = off;
        d[1][0][l] = off;
        for j in (0..M).filter(|&j| j > i) {
            let [gj0, gj1] = g[j];
            let b = &mut bank.p[i][j];
            b[0][0][l] = madd::<T, F>(b[0][0][l], -(g0 * gj0), inv);
            b[0][1][l] = madd::<T, F>(b[0][1][l], -(g0 * gj1), inv);
            b[1][0][l] = madd::<T, F>(b[1][0][l], -(g1 * gj0), inv);
            b[1][1][l] = madd::<T, F>(b[1][1][l], -(g1 * gj1), inv);
        }
        if BIAS {
            bank.pb[i][0][l] = madd::<T, F>(bank.pb[i][0][l], -k0, gb);
            bank.pb[i][1][l] = madd::<T, F>(bank.pb[i][1][l], -k1, gb);
        }
    }
    if BIAS {
        let kb = gb * inv;
        bank.b[l] = madd::<T, F>(bank.b[l], kb, e_used);
        let v = bank.pbb[l];
        bank.pbb[l] = madd::<T, F>(v, -kb, gb).max(v * model.r_nm2 * inv);
        // The load-step limit: the bias takes the whole innovation, the oscillators
        // learn nothing, and `Var(b) = R + h P_zz hᵀ`, `Cov(z, b) = −P_zz hᵀ` (no
        // cancellation, PSD by construction); `P_zz hᵀ = g − Cov(z, b)` as h's bias
        // entry is 1.
        let mut s_z = T::ZERO;
        for i in 0..M {
            for r in 0..2 {
                let pzh = g[i][r] - bank.pb[i][r][l];
                s_z += h[i][r] * pzh;
                bank.pb[i][r][l] = if load_step { -pzh } else { bank.pb[i][r][l] };
            }
        }
        bank.pbb[l] = if load_step { model.r_nm2 + s_z } else { bank.pbb[l] };
        bank.b[l] = if load_step { bank.b[l] + e_used } else { bank.b[l] };
    }
    if let Some(tr) = trace.filter(|_| TRACE) {
        tr.posterior = gaussian(bank, l);
    }

    // Outputs, and whether the covariance went bad.
    let clean = torque - ripple - mis;
    out.torque_nm[l] = clean;
    out.ripple_nm[l] = ripple;
    out.misalignment_nm[l] = mis;
    out.torque_state_nm[l] = if BIAS { expected + bank.b[l] } else { clean };
    out.innovation_nm[l] = e;
    out.innovation_variance_nm2[l] = s_var;
    out.nis[l] = e * e / s_var;
    !healthy(BIAS, bank, l, s_var)
}

/// Whether joint `l`'s state is usable after an update with innovation variance
/// `s_var`: one sum catches any NaN/∞, one minimum any negative variance.
#[inline(always)]
pub(super) fn healthy<T: Real, const M: usize, const J: usize>(
    bias: bool,
    bank: &RippleBank<T, M, J>,
    l: usize,
    s_var: T,
) -> bool {
    // The two entries of each pair apart, then together: two independent chains.
    let mut sum = [T::ZERO; 2];
    let mut least = [s_var; 2];
    for i in 0..M {
        let d = &bank.p[i][i];
        for r in 0..2 {
            sum[r] = sum_from(i == 0, sum[r], d[r][r][l] + bank.z[i][r][l]);
            least[r] = least[r].min(d[r][r][l]);
        }
    }
    let mut total = (sum[0] + sum[1]) + (s_var + bank.b[l]);
    let mut low = least[0].min(least[1]);
    if bias {
        total += bank.pbb[l];
        low = low.min(bank.pbb[l]);
    }
    finite(total) & (low >= T::ZERO) & (s_var > T::ZERO)
}

/// `f(l, (cos, sin))` of each lane `l` of the phasors `(c, s)`, as `[cos, sin]` lanes.
#[inline(always)]
fn each_lane<T: Real, const J: usize>(
    c: &[T; J],
    s: &[T; J],
    f: impl Fn(usize, Doubling<T>) -> Doubling<T>,
) -> [[T; J]; 2] {
    let mut ph = [[T::ZERO; J]; 2];
    for l in 0..J {
        let p = f(l, Doubling::new(c[l], s[l]));
        (ph[0][l], ph[1][l]) = (p.c, p.s);
    }
    ph
}

/// `P_ij h_j` for joint `l` (two entries of `g_i`), from the upper blocks of the
/// symmetric P.
#[inline(always)]
fn block_times<T: Real, const M: usize, const J: usize, const F: bool>(
    bank: &RippleBank<T, M, J>,
    i: usize,
    j: usize,
    l: usize,
    [h0, h1]: [T; 2],
) -> (T, T) {
    if j >= i {
        let b = &bank.p[i][j];
        (madd::<T, F>(b[0][0][l] * h0, b[0][1][l], h1), madd::<T, F>(b[1][0][l] * h0, b[1][1][l], h1))
    } else {
        let b = &bank.p[j][i];
        (madd::<T, F>(b[0][0][l] * h0, b[1][0][l], h1), madd::<T, F>(b[0][1][l] * h0, b[1][1][l], h1))
    }
}

/// `c + a b`: rounded once (fused) in the build `F = true` (compiled for FMA), else
/// rounded twice exactly as written. `c − a b` is `madd(c, −a, b)`, bit for bit.
#[inline(always)]
pub(super) fn madd<T: Real, const F: bool>(c: T, a: T, b: T) -> T {
    if F {
        c.fused_mul_add(a, b)
    } else {
        c + a * b
    }
}

/// `acc + t`, or `t` itself for a sum's first term: sums start from their first term,
/// not from 0 (one addition fewer, and `0 + (−0)` would turn −0 into +0).
#[inline(always)]
fn sum_from<T: Real>(first: bool, acc: T, t: T) -> T {
    if first {
        t
    } else {
        acc + t
    }
}

/// Whether `x` is neither infinite nor NaN: `x − x` is 0 exactly then (two
/// instructions instead of a classification).
#[inline(always)]
#[allow(clippy::eq_op)]
fn finite<T: Real>(x: T) -> bool {
    x - x == T::ZERO
}

/// `a[r]` by selects (`r < 3`).
#[inline(always)]
fn pick<V: Copy>(a: &[V; 3], r: usize) -> V {
    if r == 0 {
        a[0]
    } else if r == 1 {
        a[1]
    } else {
        a[2]
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

/// Joint `l`'s quantities of this step into `tr`, before the measurement update: what
/// `dec` decided, the update row and gains `(h, g)`; `scalars`: bias noise, update row
/// and gain entries, `S`, the innovation used, `y`.
#[inline(never)]
fn record<T: Real, const M: usize, const J: usize>(
    tr: &mut StepTrace<T, M>,
    bank: &RippleBank<T, M, J>,
    l: usize,
    dec: &Decided<T, M, J>,
    (h, g): ([[T; 2]; M], [[T; 2]; M]),
    [q_b, row_b, g_b, s_var, e_used, y]: [T; 6],
    [bias, load_step]: [bool; 2],
) {
    for i in 0..M {
        (tr.increment_rad[i], tr.q_nm2[i], tr.kept[i], tr.predicted[i]) =
            (dec.inc[i][l], dec.q[i][l], dec.keep[i][l], bank.status[i][l] != OrderStatus::Off);
        tr.phasor[i] = [bank.phasor[i][0][l], bank.phasor[i][1][l]];
    }
    (tr.update_row, tr.gain_numerator) = (h, g);
    tr.prior = gaussian(bank, l);
    (tr.q_bias_nm2, tr.update_row_bias, tr.gain_numerator_bias) = (q_b, row_b, g_b);
    (tr.innovation_variance_nm2, tr.innovation_used_nm, tr.measurement_nm) = (s_var, e_used, y);
    tr.bias_reinflated = bias & dec.gap[l];
    tr.load_step = load_step;
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::{step, step_traced, Order, PhaseSource, Reference, ReferenceValues, RippleInput, RippleState};
    use super::*;

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
        let w = if k < 3000 { 0.08 } else { 0.3 };
        let theta = |j: usize| {
            let t = w * k as f64 + 0.3 * j as f64 + if k % 997 == 500 { 2.0 } else { 0.0 };
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
            RippleModel::seed_6th_order(1000.0).unwrap(),
            RippleModel::new(motor, 0.5, 1000.0).unwrap().with_bias_state(1e-3).unwrap(),
            RippleModel::full(1000.0, 0.05).unwrap(),
            RippleModel::seed_4th_order(1000.0).unwrap().with_phase_source(PhaseSource::Velocity),
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
        assert!(healthy(true, &fresh, 0, 1.0) && healthy(true, &fresh, 1, 1.0));
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
            assert!(!healthy(true, &bank, 0, 1.0), "corruption {k} passed");
            assert!(healthy(true, &bank, 1, 1.0), "corruption {k} reached joint 1");
        }
        for s_var in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(!healthy(true, &fresh, 0, s_var), "S = {s_var}");
        }
        // Without the bias state its entries are not read.
        let mut bank = fresh;
        bank.pbb[0] = -1.0;
        assert!(healthy(false, &bank, 0, 1.0));
    }
}
