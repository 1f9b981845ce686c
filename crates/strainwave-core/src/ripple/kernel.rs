//! The one step of the canceller, written once for `J` joints that share a model (one
//! joint is `J = 1`): the decisions, the time update, the prediction that is output and
//! the measurement update.
//!
//! Each oscillator is kept in its rotating frame `x_i = Φ(ψ_i) z_i`. The textbook
//! recursion
//!
//! ```text
//! K(k)   = Φ P Cᵀ / (R + C P Cᵀ)
//! x̂(k+1) = Φ x̂ + K (y − C x̂)
//! P(k+1) = Q + (Φ − K C) P Φᵀ
//! ```
//!
//! becomes, with `h(k) = [cos ψ_1, sin ψ_1, …, 1]` and `Q = diag(q_i I₂, q_b)` (rotation
//! invariant):
//!
//! ```text
//! time update     ψ_i += a_i,  ẑ(k|k−1) = ẑ(k−1|k−1),  P(k|k−1) = P(k−1|k−1) + Q(k)
//! prediction      ŷ(k) = h ẑ(k|k−1)                      (output before y(k) is used)
//! update          g = P hᵀ,  S = R + h g,  ẑ += g e / S,  P −= g gᵀ / S
//! ```
//!
//! which is the same filter: identical `ŷ`, `x̂ = Φ(ψ) ẑ`, `P_x = Φ(ψ) P_z Φ(ψ)ᵀ`.
//! `Φ` never multiplies `P`; a step costs one symmetric mat-vec and one rank-1 update.
//!
//! A step has two parts:
//! - [`decide`]: per joint, what the sample means (skipped, first, gap, jump, each
//!   order active, held or off) and the phase bookkeeping, as lane-wise selects;
//! - [`advance`]: the arithmetic, with the decisions applied as selects. The common
//!   sample (no order reset or decoupled in any joint) skips the reset block: that is
//!   the only branch on the data.
//!
//! Joints are the innermost index of every array (structure of arrays), so a bank's
//! loops vectorize across joints and one joint's step is straight-line code.
//!
//! The CPU-specific build is chosen in [`run`] alone: on x86-64 CPUs with AVX2 and FMA
//! (std builds) the same generic step is compiled with its multiply–adds fused
//! (`madd`), else the portable build runs. The decisions are the same in both; the
//! numbers agree to rounding.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::filter::{RotatingGaussian, StepTrace};
use super::io::{OrderStatus, StepFlags};
use super::model::{Order, PhaseSource, RippleModel};
use super::trig::{phasor_power_with, sin_cos_with, wrap_angle, wrap_near, Doubling};
use crate::Real;

/// Weight of the newest increment in the running mean that decides holding (1/16).
const HOLD_AVERAGE: f64 = 1.0 / 16.0;

/// What the kernel precomputes from a model (kept in the model, refreshed whenever a
/// builder changes it).
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
    /// Whole multiple `n ≤ 16` of each order (its phasor is the reference's to the
    /// `n`th power), or 0 for a fractional or larger multiple (own accumulated phase).
    pub(crate) power: [u8; M],
    /// Initial (and reset) variance of each order: its prior's, or the model's.
    pub(crate) p0_nm2: [T; M],
    /// Whether some order is scaled by the load.
    pub(crate) any_load_scaled: bool,
}

impl<T: Real, const M: usize> Plan<T, M> {
    /// The plan of a model with these orders, rates and limits.
    pub(crate) fn new(
        orders: &[Order<T>; M],
        sample_rate_hz: T,
        max_gap_periods: T,
        nyquist_fraction: T,
        hold_below_hz: T,
        p0_oscillator_nm2: T,
    ) -> Self {
        let off_above_rad = nyquist_fraction * T::TAU;
        let mut plan = Self {
            dt_s: T::ONE / sample_rate_hz,
            max_gap_s: max_gap_periods / sample_rate_hz,
            off_above_rad,
            on_below_rad: off_above_rad * T::from_f64(0.9),
            hold_below_rad: hold_below_hz * T::TAU / sample_rate_hz,
            uses: [false; 3],
            reference: [0; M],
            power: [0; M],
            p0_nm2: [p0_oscillator_nm2; M],
            any_load_scaled: orders.iter().any(|o| o.load_scaled),
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

/// [`advance`] in the portable build. Out of line, so that a caller of [`run`] saves no
/// registers for the build it does not take.
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

/// [`advance`] compiled for AVX2 and FMA, its multiply–adds fused.
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

/// Per-order, per-component, per-joint values `[i][r][joint]`.
type Lanes2<T, const M: usize, const J: usize> = [[[T; J]; 2]; M];

/// What a sample means for each joint and order; the state's phase bookkeeping is
/// already done when these exist.
struct Decisions<T: Real, const M: usize, const J: usize> {
    /// `y = T_meas − T_exp`.
    y: [T; J],
    /// The measurement update runs (angles accepted and `y` finite).
    meas_ok: [bool; J],
    /// Covariance inflation `ρ` (0 at the first sample and for skipped samples).
    infl: [T; J],
    /// Process noise of the bias.
    q_b: [T; J],
    /// Time gap: the bias variance goes back up to its initial value.
    reinflate: [bool; J],
    /// Phase increment `a_i` of each order (0 when reset or off).
    inc: [[T; J]; M],
    /// Process noise of each order.
    q: [[T; J]; M],
    /// The order keeps its state (else it restarts from its prior).
    keep: [[bool; J]; M],
    /// The order keeps its covariance with the others (else decoupled).
    couple: [[bool; J]; M],
    /// The order enters the prediction.
    pred: [[bool; J]; M],
    /// The order is updated.
    upd: [[bool; J]; M],
    flags: [StepFlags; J],
    /// Every order of every joint keeps its state and coupling, and no bias variance
    /// is reinflated: the time update needs no resets.
    plain: bool,
}

/// Wraps each value into `[−π, π]`: as selects when all are within `±3π` (wrapped
/// encoder angles and their differences), exactly otherwise.
#[inline(always)]
fn wrap_lanes<T: Real, const J: usize>(x: &mut [T; J]) {
    let three_pi = T::from_f64(3.0) * T::PI;
    let raw = *x;
    let mut far = false;
    for l in 0..J {
        far |= !(raw[l].abs() <= three_pi);
        x[l] = wrap_near(raw[l]);
    }
    if far {
        for l in 0..J {
            x[l] = wrap_angle(raw[l]);
        }
    }
}

/// The decisions of one sample, and the phase bookkeeping they imply: input validity,
/// reference increments `Δθ = wrap_π(θ(k) − θ(k−1))` (or `(ω(k−1) + ω(k))/2 · dt`),
/// encoder jumps and time gaps, each order's status, its phase increment `a_i = n_i Δθ`
/// and process noise `q_i = q_s + q_rad |a_i|`.
#[inline(always)]
fn decide<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> Decisions<T, M, J> {
    let plan = &model.plan;
    let lim = &model.limits;
    let refs = input.references.as_array();
    let angle_input = model.phase_source == PhaseSource::Angle;
    let dt = input.dt_s.unwrap_or(plan.dt_s);
    let dt_ok = finite(dt) & (dt > T::ZERO);
    let q_bias = model.bias_q_nm2.unwrap_or(T::ZERO);
    let mut d = Decisions {
        y: [T::ZERO; J],
        meas_ok: [false; J],
        infl: [T::ZERO; J],
        q_b: [T::ZERO; J],
        reinflate: [false; J],
        inc: [[T::ZERO; J]; M],
        q: [[T::ZERO; J]; M],
        keep: [[true; J]; M],
        couple: [[true; J]; M],
        pred: [[true; J]; M],
        upd: [[false; J]; M],
        flags: [StepFlags::empty(); J],
        plain: true,
    };

    // Per joint: whether the sample is skipped (a used reference or `dt` not finite:
    // the state stays as it was, the next increment spans the gap), how many samples
    // it spans, whether it is the first or follows a time gap.
    let (mut skip, mut first, mut gap) = ([false; J], [false; J], [false; J]);
    let (mut n_samples, mut n_noise, mut total_dt) = ([T::ONE; J], [T::ZERO; J], [dt; J]);
    for l in 0..J {
        let mut refs_ok = dt_ok;
        for r in 0..3 {
            refs_ok &= !plan.uses[r] | finite(refs[r][l]);
        }
        skip[l] = !refs_ok;
        n_samples[l] = bank.pending_samples[l] + T::ONE;
        total_dt[l] = bank.pending_dt[l] + dt;
        first[l] = !bank.has_last[l];
        gap[l] = !skip[l] & !first[l] & !(total_dt[l] <= plan.max_gap_s);
        let y = input.torque_nm[l] - input.expected_torque_nm[l];
        d.y[l] = y;
        d.meas_ok[l] = !skip[l] & finite(y);
        // The initial state is the prior of the first sample: no noise before it.
        let counted = !skip[l] & !first[l];
        n_noise[l] = if counted { n_samples[l] } else { T::ZERO };
        d.infl[l] = if counted { lim.covariance_inflation } else { T::ZERO };
        d.q_b[l] = q_bias * n_noise[l];
        d.reinflate[l] = model.bias_q_nm2.is_some() & gap[l];
    }

    // Per reference: the increment, whether it jumped, the new phase.
    let mut delta = [[T::ZERO; J]; 3];
    let mut jump = [[false; J]; 3];
    for r in 0..3 {
        if !plan.uses[r] {
            continue;
        }
        let v = &refs[r];
        let mut dr = [T::ZERO; J];
        if angle_input {
            for l in 0..J {
                dr[l] = v[l] - bank.last[r][l];
            }
            wrap_lanes(&mut dr);
        } else {
            for l in 0..J {
                dr[l] = (v[l] + bank.last[r][l]) * T::HALF * total_dt[l];
            }
        }
        for l in 0..J {
            let moving = !skip[l] & !first[l];
            // A glitch: an increment too large, or too different from the last one.
            let expected = bank.last_delta[r][l] * n_samples[l];
            let changed = bank.delta_known[l] & !((dr[l] - expected).abs() <= lim.max_step_change_rad);
            let jumped = moving & (!(dr[l].abs() <= lim.max_angle_step_rad) | changed);
            let accept = moving & !jumped;
            let caught_up = bank.pending_samples[l] == T::ZERO;
            let per_sample = if caught_up { dr[l] } else { dr[l] / n_samples[l] };
            // Mean increment over ~16 samples: encoder jitter at standstill averages
            // out of it, so it alone decides whether an order is held.
            let m = bank.mean_delta[r][l];
            let mean = madd::<T, F>(m, per_sample - m, T::from_f64(HOLD_AVERAGE));
            bank.mean_delta[r][l] = if accept { mean } else { m };
            bank.last_delta[r][l] = if accept { per_sample } else { bank.last_delta[r][l] };
            jump[r][l] = jumped;
            delta[r][l] = if moving { dr[l] } else { T::ZERO };
        }
        // The phase: the angle itself, or the accumulated increments.
        let mut psi = [T::ZERO; J];
        for l in 0..J {
            psi[l] = if angle_input { v[l] } else { bank.psi[r][l] + delta[r][l] };
        }
        wrap_lanes(&mut psi);
        for l in 0..J {
            let hold_phase = skip[l] | (!angle_input & jump[r][l]);
            bank.psi[r][l] = if hold_phase { bank.psi[r][l] } else { psi[l] };
            bank.last[r][l] = if skip[l] { bank.last[r][l] } else { v[l] };
        }
    }

    // Per joint: counters, flags.
    for l in 0..J {
        let any_jump = jump[0][l] | jump[1][l] | jump[2][l];
        let s = skip[l];
        bank.steps[l] = bank.steps[l].wrapping_add(1);
        bank.has_last[l] |= !s;
        // After a jump or a gap the next increment sets a new baseline.
        bank.delta_known[l] = if s { bank.delta_known[l] } else { !first[l] & !gap[l] & !any_jump };
        bank.pending_samples[l] = if s { bank.pending_samples[l] + T::ONE } else { T::ZERO };
        let pending_dt = bank.pending_dt[l] + if dt_ok { dt } else { plan.dt_s };
        bank.pending_dt[l] = if s { pending_dt } else { T::ZERO };
        let mut f = StepFlags::empty();
        f.set(StepFlags::ANGLE_SKIPPED, s);
        f.set(StepFlags::MEASUREMENT_SKIPPED, !s & !d.meas_ok[l]);
        f.set(StepFlags::GAP_RESET, gap[l]);
        f.set(StepFlags::JUMP_RESET, !gap[l] & any_jump);
        d.flags[l] = f;
    }

    // Per order: status (active, held, off) and the masks of the time update.
    for i in 0..M {
        let o = &model.orders[i];
        let r = plan.reference[i];
        for l in 0..J {
            let reset = gap[l] | jump[r][l];
            let a = if reset { T::ZERO } else { o.multiple * delta[r][l] };
            let abs_a = a.abs();
            let mean_a = (o.multiple * bank.mean_delta[r][l]).abs();
            let prev = bank.status[i][l];
            let was_off = prev == OrderStatus::Off;
            let off = !reset & ((was_off & !(abs_a < plan.on_below_rad)) | (!was_off & (abs_a > plan.off_above_rad)));
            let held = reset | (!off & (mean_a < plan.hold_below_rad));
            let status = if off {
                OrderStatus::Off
            } else if held {
                OrderStatus::Held
            } else {
                OrderStatus::Active
            };
            let status = if skip[l] { prev } else { status };
            bank.status[i][l] = status;
            let (off, active) = (status == OrderStatus::Off, status == OrderStatus::Active);
            let zeroed = !skip[l] & (reset | off);
            d.keep[i][l] = !zeroed;
            d.couple[i][l] = skip[l] | active;
            d.pred[i][l] = !off;
            d.upd[i][l] = d.meas_ok[l] & active;
            d.inc[i][l] = if zeroed { T::ZERO } else { a };
            let q = madd::<T, F>(o.q_per_sample_nm2 * n_noise[l], o.q_per_rad_nm2, abs_a);
            d.q[i][l] = if off | skip[l] { T::ZERO } else { q };
            d.flags[l].set(StepFlags::ORDER_OFF, off);
            d.flags[l].set(StepFlags::ORDER_HELD, status == OrderStatus::Held);
            d.plain &= d.keep[i][l] & d.couple[i][l] & !d.reinflate[l];
        }
        if plan.power[i] == 0 {
            for l in 0..J {
                bank.order_psi[i][l] = wrap_angle(bank.order_psi[i][l] + d.inc[i][l]);
            }
        }
    }
    d
}

/// `(cos ψ_i, sin ψ_i)` of every order into `bank.phasor` (times the load for
/// load-scaled orders): one sine/cosine per reference, whole multiples by doubling
/// the reference's phasor, the others from their own phase.
#[inline(always)]
fn phasors<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) {
    let plan = &model.plan;
    let mut base = [[Doubling::new(T::ONE, T::ZERO); J]; 3];
    for r in 0..3 {
        if plan.uses[r] {
            for l in 0..J {
                base[r][l] = sin_cos_with::<T, F>(bank.psi[r][l]);
            }
        }
    }
    // The load regressor `|T_exp + b̂(k|k−1)|` (the time update leaves the bias as is).
    let mut load = [T::ONE; J];
    if plan.any_load_scaled {
        for l in 0..J {
            let v = (input.expected_torque_nm[l] + bank.b[l]).abs();
            load[l] = if finite(v) { v } else { T::ZERO };
        }
    }
    for i in 0..M {
        let b = &base[plan.reference[i]];
        let scaled = model.orders[i].load_scaled;
        let n = plan.power[i];
        for l in 0..J {
            let p = match n {
                0 => sin_cos_with::<T, F>(bank.order_psi[i][l]),
                1 => b[l],
                2 => b[l].doubled::<F>(),
                4 => b[l].doubled::<F>().doubled::<F>(),
                _ => {
                    let (c, s) = phasor_power_with::<T, F>(b[l].c, b[l].s, n);
                    Doubling::new(c, s)
                }
            };
            let (c, s) = if scaled { (p.c * load[l], p.s * load[l]) } else { (p.c, p.s) };
            bank.phasor[i][0][l] = c;
            bank.phasor[i][1][l] = s;
        }
    }
}

/// One step of every joint into `out`: [`decide`], the phasors, then the filter.
#[inline(always)]
fn advance<T: Real, const M: usize, const J: usize, const F: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    let mut d = decide::<T, M, J, F>(model, bank, input);
    phasors::<T, M, J, F>(model, bank, input);
    let has_bias = model.bias_q_nm2.is_some();
    let r_nm2 = model.r_nm2;

    // Time update: inflation `ρ (P_00 + P_11)/2 · I₂` (rotation invariant, like Q) and
    // process noise on the diagonal blocks; resets and decoupling where decided.
    for i in 0..M {
        let p = &mut bank.p[i][i];
        for l in 0..J {
            let (trace, q, grow) = (p[0][0][l] + p[1][1][l], d.q[i][l], d.infl[l] * T::HALF);
            p[0][0][l] = madd::<T, F>(p[0][0][l], grow, trace) + q;
            p[1][1][l] = madd::<T, F>(p[1][1][l], grow, trace) + q;
        }
    }
    if !d.plain {
        reset_orders(model, bank, &d);
    }
    if has_bias {
        for l in 0..J {
            let v = bank.pbb[l];
            let v = if d.reinflate[l] && v < model.p0_bias_nm2 { model.p0_bias_nm2 } else { v };
            bank.pbb[l] = madd::<T, F>(v, v, d.infl[l]) + d.q_b[l];
        }
    }

    // Prediction ŷ(k) = h ẑ(k|k−1) (every order not off) and the update row h (the
    // orders updated; the bias entry is 1 when the measurement is used).
    let (mut ripple, mut mis) = ([T::ZERO; J], [T::ZERO; J]);
    let (mut any_ripple, mut any_mis) = (false, false);
    let mut h = [[[T::ZERO; J]; 2]; M];
    for i in 0..M {
        let is_ripple = model.orders[i].reference.is_ripple();
        let first = if is_ripple { !any_ripple } else { !any_mis };
        let sum = if is_ripple { &mut ripple } else { &mut mis };
        for l in 0..J {
            let (c, s) = (bank.phasor[i][0][l], bank.phasor[i][1][l]);
            let v = madd::<T, F>(c * bank.z[i][0][l], s, bank.z[i][1][l]);
            sum[l] = sum_from(first, sum[l], if d.pred[i][l] { v } else { T::ZERO });
            let u = d.upd[i][l];
            h[i][0][l] = if u { c } else { T::ZERO };
            h[i][1][l] = if u { s } else { T::ZERO };
        }
        any_ripple |= is_ripple;
        any_mis |= !is_ripple;
    }

    // Gains g = P hᵀ from the upper blocks of the symmetric P, and the bias entry.
    let mut g = [[[T::ZERO; J]; 2]; M];
    let mut gb = [T::ZERO; J];
    for i in 0..M {
        if has_bias {
            for l in 0..J {
                let u = d.meas_ok[l];
                g[i][0][l] = if u { bank.pb[i][0][l] } else { T::ZERO };
                g[i][1][l] = if u { bank.pb[i][1][l] } else { T::ZERO };
            }
        }
        for j in 0..M {
            let first = !has_bias && j == 0;
            for l in 0..J {
                let (t0, t1) = block_times::<T, M, J, F>(bank, i, j, l, [h[j][0][l], h[j][1][l]]);
                g[i][0][l] = sum_from(first, g[i][0][l], t0);
                g[i][1][l] = sum_from(first, g[i][1][l], t1);
            }
        }
    }
    if has_bias {
        for l in 0..J {
            gb[l] = if d.meas_ok[l] { bank.pbb[l] } else { T::ZERO };
            for j in 0..M {
                gb[l] += madd::<T, F>(bank.pb[j][0][l] * h[j][0][l], bank.pb[j][1][l], h[j][1][l]);
            }
        }
    }

    // Innovation `e = y − ŷ`, its variance `S = R + h g`, and the load-step decision:
    // an innovation beyond the NIS limit is a jump of the bias, not of the oscillators.
    // The update is then the exact limit Var(b) → ∞ (gain 0 here, completed below).
    let (mut s_var, mut inv, mut e, mut e_used) = ([T::ZERO; J], [T::ZERO; J], [T::ZERO; J], [T::ZERO; J]);
    let mut load_step = [false; J];
    let nis_limit = model.limits.load_step_nis;
    for l in 0..J {
        let mut s = if has_bias && d.meas_ok[l] { gb[l] } else { T::ZERO };
        for i in 0..M {
            s = sum_from(!has_bias && i == 0, s, madd::<T, F>(h[i][0][l] * g[i][0][l], h[i][1][l], g[i][1][l]));
        }
        s_var[l] = r_nm2 + s;
        e[l] = d.y[l] - (ripple[l] + mis[l] + bank.b[l]);
        e_used[l] = if d.meas_ok[l] { e[l] } else { T::ZERO };
        load_step[l] = has_bias & (nis_limit > T::ZERO) & (e_used[l] * e_used[l] > nis_limit * s_var[l]);
        inv[l] = if load_step[l] { T::ZERO } else { T::ONE / s_var[l] };
        d.flags[l].set(StepFlags::LOAD_STEP, load_step[l]);
    }
    let mut trace = trace;
    if let Some(tr) = trace.as_deref_mut().filter(|_| TRACE) {
        record(tr, bank, &d, &h, &g, [gb, s_var, e_used, d.y], load_step, has_bias);
    }

    // Measurement update `ẑ += g e / S`, `P −= g gᵀ / S` (upper blocks; each product
    // `g_i g_j` times `1/S`, so that it waits on the division for one multiply–add).
    // Variances never fall below their exact lower bound `P_ii R / S`.
    for i in 0..M {
        for l in 0..J {
            let [g0, g1] = [g[i][0][l], g[i][1][l]];
            let (k0, k1) = (g0 * inv[l], g1 * inv[l]);
            bank.z[i][0][l] = madd::<T, F>(bank.z[i][0][l], k0, e_used[l]);
            bank.z[i][1][l] = madd::<T, F>(bank.z[i][1][l], k1, e_used[l]);
            let floor = r_nm2 * inv[l];
            let p = &mut bank.p[i][i];
            let (v0, v1) = (p[0][0][l], p[1][1][l]);
            p[0][0][l] = madd::<T, F>(v0, -(g0 * g0), inv[l]).max(v0 * floor);
            p[1][1][l] = madd::<T, F>(v1, -(g1 * g1), inv[l]).max(v1 * floor);
            let off = madd::<T, F>(p[0][1][l], -(g0 * g1), inv[l]);
            p[0][1][l] = off;
            p[1][0][l] = off;
            for j in i + 1..M {
                let [gj0, gj1] = [g[j][0][l], g[j][1][l]];
                let b = &mut bank.p[i][j];
                b[0][0][l] = madd::<T, F>(b[0][0][l], -(g0 * gj0), inv[l]);
                b[0][1][l] = madd::<T, F>(b[0][1][l], -(g0 * gj1), inv[l]);
                b[1][0][l] = madd::<T, F>(b[1][0][l], -(g1 * gj0), inv[l]);
                b[1][1][l] = madd::<T, F>(b[1][1][l], -(g1 * gj1), inv[l]);
            }
            if has_bias {
                bank.pb[i][0][l] = madd::<T, F>(bank.pb[i][0][l], -k0, gb[l]);
                bank.pb[i][1][l] = madd::<T, F>(bank.pb[i][1][l], -k1, gb[l]);
            }
        }
    }
    if has_bias {
        for l in 0..J {
            let kb = gb[l] * inv[l];
            bank.b[l] = madd::<T, F>(bank.b[l], kb, e_used[l]);
            let v = bank.pbb[l];
            bank.pbb[l] = madd::<T, F>(v, -kb, gb[l]).max(v * r_nm2 * inv[l]);
        }
        if load_step.iter().any(|&s| s) {
            complete_load_steps(r_nm2, bank, &h, &g, &load_step, &e_used);
        }
    }
    if let Some(tr) = trace.filter(|_| TRACE) {
        tr.posterior = gaussian(bank);
    }

    // Health check (a joint whose covariance went bad restarts) and the outputs.
    let mut any_bad = false;
    for l in 0..J {
        let bad = !healthy(has_bias, bank, l, s_var[l]);
        d.flags[l].set(StepFlags::COVARIANCE_RESET, bad);
        any_bad |= bad;
    }
    if any_bad {
        for l in 0..J {
            if d.flags[l].contains(StepFlags::COVARIANCE_RESET) {
                bank.reset_lane(model, l);
            }
        }
    }
    for l in 0..J {
        let torque = input.torque_nm[l] - ripple[l] - mis[l];
        out.torque_nm[l] = torque;
        out.ripple_nm[l] = ripple[l];
        out.misalignment_nm[l] = mis[l];
        out.torque_state_nm[l] = if has_bias { input.expected_torque_nm[l] + bank.b[l] } else { torque };
        out.innovation_nm[l] = e[l];
        out.innovation_variance_nm2[l] = s_var[l];
        out.nis[l] = e[l] * e[l] / s_var[l];
        out.flags[l] = d.flags[l];
    }
}

/// The resets and decoupling of the time update, for the joints and orders where
/// [`decide`] asked for them: a reset order restarts from its prior (0 or learned
/// coefficients) and forgets its covariances; an order not active is decoupled from
/// the others.
#[inline(never)]
fn reset_orders<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    d: &Decisions<T, M, J>,
) {
    for i in 0..M {
        let (p0, mu) = (model.plan.p0_nm2[i], model.orders[i].prior_nm);
        for l in 0..J {
            if !d.keep[i][l] {
                bank.z[i][0][l] = mu[0];
                bank.z[i][1][l] = mu[1];
                let p = &mut bank.p[i][i];
                p[0][0][l] = p0 + d.q[i][l];
                p[1][1][l] = p0 + d.q[i][l];
                p[0][1][l] = T::ZERO;
                p[1][0][l] = T::ZERO;
            }
        }
        for j in i + 1..M {
            for l in 0..J {
                if !(d.couple[i][l] & d.couple[j][l]) {
                    bank.p[i][j] = zero_lane(bank.p[i][j], l);
                }
            }
        }
        for l in 0..J {
            if !d.couple[i][l] {
                bank.pb[i][0][l] = T::ZERO;
                bank.pb[i][1][l] = T::ZERO;
            }
        }
    }
}

/// `block` with joint `l`'s entries set to 0.
#[inline(always)]
fn zero_lane<T: Real, const J: usize>(mut block: [[[T; J]; 2]; 2], l: usize) -> [[[T; J]; 2]; 2] {
    for row in &mut block {
        for v in row {
            v[l] = T::ZERO;
        }
    }
    block
}

/// The load-step limit `Var(b) → ∞` for the joints `steps`, after their (gain 0)
/// update: the bias takes the whole innovation `e`, the oscillators learn nothing, and
/// `Var(b) = R + h P_zz hᵀ`, `Cov(z, b) = −P_zz hᵀ` (no cancellation, PSD by
/// construction).
#[inline(always)]
fn complete_load_steps<T: Real, const M: usize, const J: usize>(
    r_nm2: T,
    bank: &mut RippleBank<T, M, J>,
    h: &Lanes2<T, M, J>,
    g: &Lanes2<T, M, J>,
    steps: &[bool; J],
    e: &[T; J],
) {
    for l in 0..J {
        if steps[l] {
            // P_zz hᵀ = g − Cov(z, b) since the bias entry of h is 1.
            let mut s_z = T::ZERO;
            for i in 0..M {
                for r in 0..2 {
                    let pzh = g[i][r][l] - bank.pb[i][r][l];
                    s_z += h[i][r][l] * pzh;
                    bank.pb[i][r][l] = -pzh;
                }
            }
            bank.pbb[l] = r_nm2 + s_z;
            bank.b[l] += e[l];
        }
    }
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

/// Joint 0's rotating-frame mean and covariance.
fn gaussian<T: Real, const M: usize, const J: usize>(bank: &RippleBank<T, M, J>) -> RotatingGaussian<T, M> {
    let mut g = RotatingGaussian::zeros();
    if J == 0 {
        return g;
    }
    for i in 0..M {
        for r in 0..2 {
            g.z[i][r] = bank.z[i][r][0];
            g.pb[i][r] = bank.pb[i][r][0];
        }
        for j in 0..M {
            g.p[i][j] = bank.block(i, j, 0).unwrap_or([[T::ZERO; 2]; 2]);
        }
    }
    g.bias = bank.b[0];
    g.pbb = bank.pbb[0];
    g
}

/// Joint 0's quantities of this step into `tr` (before the measurement update):
/// `scalars` are `[g_b, S, e used, y]` per joint.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn record<T: Real, const M: usize, const J: usize>(
    tr: &mut StepTrace<T, M>,
    bank: &RippleBank<T, M, J>,
    d: &Decisions<T, M, J>,
    h: &Lanes2<T, M, J>,
    g: &Lanes2<T, M, J>,
    scalars: [[T; J]; 4],
    load_step: [bool; J],
    has_bias: bool,
) {
    if J == 0 {
        return;
    }
    for i in 0..M {
        tr.increment_rad[i] = d.inc[i][0];
        tr.q_nm2[i] = d.q[i][0];
        tr.kept[i] = d.keep[i][0];
        tr.predicted[i] = d.pred[i][0];
        for r in 0..2 {
            tr.phasor[i][r] = bank.phasor[i][r][0];
            tr.update_row[i][r] = h[i][r][0];
            tr.gain_numerator[i][r] = g[i][r][0];
        }
    }
    tr.prior = gaussian(bank);
    let [gb, s_var, e_used, y] = scalars;
    tr.q_bias_nm2 = d.q_b[0];
    tr.update_row_bias = if has_bias && d.meas_ok[0] { T::ONE } else { T::ZERO };
    tr.gain_numerator_bias = gb[0];
    tr.innovation_variance_nm2 = s_var[0];
    tr.innovation_used_nm = e_used[0];
    tr.measurement_nm = y[0];
    tr.bias_reinflated = d.reinflate[0];
    tr.load_step = load_step[0];
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
