//! The one step of the canceller, written once for `J` joints that share a model (one
//! joint is `J = 1`): the decisions, the time update, the prediction that is output and
//! the measurement update.
//!
//! Each oscillator is kept in its rotating frame `x_i = Φ(ψ_i) z_i`; with the update
//! row `h(k) = [cos ψ_1, sin ψ_1, …, 1]` and `Q = diag(q_i I₂, q_b)` (rotation invariant)
//! the filter of the [module documentation](super) becomes
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
//! Every quantity of the step is a [`Lanes`] value, one entry per joint, and every
//! operation on it is a loop over the joints that the compiler turns into SIMD
//! instructions across joints (for one joint, plain scalar code). Every per-joint
//! decision (skipped sample, first sample, gap, jump, order active, held or off, load
//! step) is a select, so the joints never branch apart.
//!
//! The CPU-specific build is chosen in one place, `run`: on x86-64 CPUs with AVX2 and
//! FMA (std builds) the same generic step is compiled with its multiply–adds fused,
//! else the portable build runs. The decisions are the same in both; the numbers agree
//! to rounding.

use core::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

use super::bank::{BankInput, BankOutput, RippleBank};
use super::filter::{RotatingGaussian, StepTrace};
use super::io::{OrderStatus, StepFlags};
use super::model::{Limits, Order, PhaseSource, RippleModel};
use super::trig::{phasor_power_with, sin_cos_with, wrap_angle as wrap, Doubling};
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

/// One value per joint. Each operation is a loop over the joints, small enough for the
/// compiler to unroll and turn into SIMD instructions; masks are `Lanes<bool, J>`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Lanes<T, const J: usize>(pub(super) [T; J]);

impl<T: Copy, const J: usize> Lanes<T, J> {
    /// `x` in every lane.
    #[inline(always)]
    pub(super) fn splat(x: T) -> Self {
        Self([x; J])
    }
    /// `f` of each lane.
    #[inline(always)]
    pub(super) fn map<U: Copy + Default>(self, f: impl Fn(T) -> U) -> Lanes<U, J> {
        let mut out = [U::default(); J];
        for l in 0..J {
            out[l] = f(self.0[l]);
        }
        Lanes(out)
    }
    /// `f` of each pair of lanes.
    #[inline(always)]
    pub(super) fn zip<U: Copy, R: Copy + Default>(self, o: Lanes<U, J>, f: impl Fn(T, U) -> R) -> Lanes<R, J> {
        let mut out = [R::default(); J];
        for l in 0..J {
            out[l] = f(self.0[l], o.0[l]);
        }
        Lanes(out)
    }
}

impl<const J: usize> Lanes<bool, J> {
    /// Lane-wise `if self { a } else { b }`.
    #[inline(always)]
    pub(super) fn sel<T: Copy>(self, a: Lanes<T, J>, b: Lanes<T, J>) -> Lanes<T, J> {
        let mut out = b;
        for l in 0..J {
            out.0[l] = if self.0[l] { a.0[l] } else { b.0[l] };
        }
        out
    }
    /// Whether every lane is set.
    #[inline(always)]
    pub(super) fn all(self) -> bool {
        self.0.iter().fold(true, |a, &b| a & b)
    }
    /// Whether some lane is set.
    #[inline(always)]
    pub(super) fn any(self) -> bool {
        self.0.iter().fold(false, |a, &b| a | b)
    }
}

impl<T: Real, const J: usize> Lanes<T, J> {
    /// `self + a b`, see [`madd`].
    #[inline(always)]
    fn madd<const F: bool>(self, a: Self, b: Self) -> Self {
        let mut out = self;
        for l in 0..J {
            out.0[l] = madd::<T, F>(self.0[l], a.0[l], b.0[l]);
        }
        out
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.map(T::abs)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        self.zip(o, T::max)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        self.zip(o, T::min)
    }
    #[inline(always)]
    fn finite(self) -> Lanes<bool, J> {
        self.map(finite)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Lanes<bool, J> {
        self.zip(o, |a, b| a < b)
    }
    #[inline(always)]
    fn le(self, o: Self) -> Lanes<bool, J> {
        self.zip(o, |a, b| a <= b)
    }
}

/// `unroll!(n, |i| body)`: `for i in 0..n body` written out for `n ≤ 8`, so that every index is a constant
/// and each per-order value stays in a register (a loop beyond 8).
macro_rules! unroll {
    ($n:expr, |$i:ident| $body:block) => {{
        unroll!(@ $i $n $body 0 1 2 3 4 5 6 7);
        for $i in 8..$n $body
    }};
    (@ $i:ident $n:tt $body:block $($k:literal)*) => {$(
        if $k < $n {
            let $i: usize = $k;
            $body
        }
    )*};
}

/// Lane-wise binary operators.
macro_rules! lanewise {
    ($($tr:ident $f:ident $op:tt),*) => {$(
        impl<T: Copy + Default + $tr<Output = T>, const J: usize> $tr for Lanes<T, J> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                self.zip(o, |a, b| a $op b)
            }
        }
    )*};
}
lanewise!(Add add +, Sub sub -, Mul mul *, Div div /, BitAnd bitand &, BitOr bitor |);

impl<T: Copy + Default + Neg<Output = T>, const J: usize> Neg for Lanes<T, J> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}

impl<const J: usize> Not for Lanes<bool, J> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        self.map(|a| !a)
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
        // step's dependency chain, the lanes of a bank fill 256-bit registers, and
        // x86-64 builds assume neither by default.
        #[allow(unsafe_code)]
        // SAFETY: the CPU executes AVX2 and FMA instructions (checked just above).
        unsafe {
            run_fma::<T, M, J, TRACE>(model, bank, input, out, trace)
        };
        return;
    }
    run_portable::<T, M, J, TRACE>(model, bank, input, out, trace);
}

/// `advance` in the portable build. Out of line, so that a caller of [`run`] saves no
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

/// Every joint's step, then the reset of joints whose covariance went bad.
#[inline(always)]
fn advance<T: Real, const M: usize, const J: usize, const F: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) {
    let has_bias = model.bias_q_nm2.is_some();
    let bad = if has_bias {
        lanes::<T, M, J, F, true, TRACE>(model, bank, input, out, trace)
    } else {
        lanes::<T, M, J, F, false, TRACE>(model, bank, input, out, trace)
    };
    if bad.any() {
        for l in 0..J {
            if bad.0[l] {
                bank.reset_lane(model, l);
                out.flags[l].insert(StepFlags::COVARIANCE_RESET);
                if has_bias {
                    out.torque_state_nm[l] = input.expected_torque_nm[l] + bank.b[l];
                }
            }
        }
    }
}

/// Every joint's whole step but the reset of a bad covariance: the decisions (input
/// validity, reference increments `Δθ = wrap_π(θ(k) − θ(k−1))` or `(ω(k−1) + ω(k))/2 · dt`,
/// encoder jumps and time gaps, each order's status), the phase bookkeeping and
/// phasors, the time update, the prediction that is output and the measurement
/// update, every decision applied as a select. Returns which covariances went bad.
#[allow(clippy::too_many_lines)]
#[inline(always)]
fn lanes<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) -> Lanes<bool, J> {
    let (plan, lim, orders) = (&model.plan, &model.limits, &model.orders);
    let k = Lanes::<T, J>::splat;
    let (zero, one, no) = (k(T::ZERO), k(T::ONE), Lanes::splat(false));
    let angle_input = model.phase_source == PhaseSource::Angle;
    let dt = input.dt_s.unwrap_or(plan.dt_s);
    let dt_ok = finite(dt) & (dt > T::ZERO);
    let rv = &input.references;
    let refs = [Lanes(rv.relative), Lanes(rv.output), Lanes(rv.motor)];
    let (torque, expected) = (Lanes(input.torque_nm), Lanes(input.expected_torque_nm));
    let y = torque - expected;

    // The sample: skipped (a used reference or `dt` not finite: the state stays as it
    // was, the next increment spans the gap), first, or after a time gap.
    let mut refs_ok = Lanes::splat(dt_ok);
    for r in 0..3 {
        if plan.uses[r] {
            refs_ok = refs_ok & refs[r].finite();
        }
    }
    let skip = !refs_ok;
    let pending = Lanes(bank.pending_samples);
    let n_samples = pending + one;
    let total_dt = Lanes(bank.pending_dt) + k(dt);
    let first = !Lanes(bank.has_last);
    // `!(x <= limit)`: NaN counts as out of range.
    let gap = !skip & !first & !total_dt.le(k(plan.max_gap_s));
    let meas_ok = !skip & y.finite();
    // The initial state is the prior of the first sample: no noise before it.
    let counted = !skip & !first;
    let n_noise = counted.sel(n_samples, zero);
    let infl = counted.sel(k(lim.covariance_inflation), zero);

    // Each reference: its increment, whether it jumped, its phase and phasor.
    let (mut delta, mut jump, mut mean) = ([zero; 3], [no; 3], [zero; 3]);
    let mut base = [Lanes::splat(Doubling::new(T::ONE, T::ZERO)); 3];
    unroll!(3, |r| {
        if plan.uses[r] {
            let (v, last) = (refs[r], Lanes(bank.last[r]));
            let d = if angle_input { (v - last).map(wrap) } else { (v + last) * k(T::HALF) * total_dt };
            // A glitch: an increment too large, or too different from the last one.
            let expected_d = Lanes(bank.last_delta[r]) * n_samples;
            let changed = Lanes(bank.delta_known) & !(d - expected_d).abs().le(k(lim.max_step_change_rad));
            let jumped = counted & (!d.abs().le(k(lim.max_angle_step_rad)) | changed);
            let accept = counted & !jumped;
            let per_sample = pending.zip(zero, |a, b| a == b).sel(d, d / n_samples);
            // Mean increment over ~16 samples: encoder jitter at standstill averages out of
            // it, so it alone decides whether an order is held.
            let m = Lanes(bank.mean_delta[r]);
            mean[r] = accept.sel(m.madd::<F>(per_sample - m, k(T::from_f64(HOLD_AVERAGE))), m);
            bank.mean_delta[r] = mean[r].0;
            bank.last_delta[r] = accept.sel(per_sample, Lanes(bank.last_delta[r])).0;
            jump[r] = jumped;
            delta[r] = counted.sel(d, zero);
            // The phase: the angle itself, or the accumulated increments.
            let psi = Lanes(bank.psi[r]);
            let next = if angle_input { v } else { psi + delta[r] }.map(wrap);
            let psi = (if angle_input { skip } else { skip | jumped }).sel(psi, next);
            bank.psi[r] = psi.0;
            bank.last[r] = skip.sel(last, v).0;
            base[r] = psi.map(sin_cos_with::<T, F>);
        }
    });
    let any_jump = jump[0] | jump[1] | jump[2];
    for s in &mut bank.steps {
        *s = s.wrapping_add(1);
    }
    bank.has_last = (!first | !skip).0;
    // After a jump or a gap the next increment sets a new baseline.
    bank.delta_known = skip.sel(Lanes(bank.delta_known), !first & !gap & !any_jump).0;
    bank.pending_samples = skip.sel(n_samples, zero).0;
    let pending_dt = Lanes(bank.pending_dt) + k(if dt_ok { dt } else { plan.dt_s });
    bank.pending_dt = skip.sel(pending_dt, zero).0;
    let mut flags = [StepFlags::empty(); J];
    let mut flag = |f: StepFlags, on: Lanes<bool, J>| {
        for l in 0..J {
            flags[l].set(f, on.0[l]);
        }
    };
    flag(StepFlags::ANGLE_SKIPPED, skip);
    flag(StepFlags::MEASUREMENT_SKIPPED, !skip & !meas_ok);
    flag(StepFlags::GAP_RESET, gap);
    flag(StepFlags::JUMP_RESET, !gap & any_jump);

    // Each order: its status (active, held or off), what the time update does with it
    // (keep its state or restart from its prior, keep its covariances with the others),
    // its process noise `q_i = q_s + q_rad |a_i|` and its phasor (times the load
    // `|T_exp + b̂(k|k−1)|` for a load-scaled order).
    let load = (expected + Lanes(bank.b)).abs();
    let load = load.finite().sel(load, zero);
    let (mut keep, mut couple, mut pred, mut upd) = ([no; M], [no; M], [no; M], [no; M]);
    let (mut inc, mut q, mut all_active) = ([zero; M], [zero; M], Lanes::splat(true));
    let (k_off, k_held, k_active) =
        (Lanes::splat(OrderStatus::Off), Lanes::splat(OrderStatus::Held), Lanes::splat(OrderStatus::Active));
    unroll!(M, |i| {
        // The order's reference by selects, not by index: the per-reference values
        // then stay in registers.
        let (o, r) = (&orders[i], plan.reference[i]);
        let reset = gap | pick(&jump, r);
        let a = reset.sel(zero, k(o.multiple) * pick(&delta, r));
        let abs_a = a.abs();
        let mean_a = (k(o.multiple) * pick(&mean, r)).abs();
        let prev = Lanes(bank.status[i]);
        let was_off = prev.map(|s| s == OrderStatus::Off);
        let stays_off = was_off & !abs_a.lt(k(plan.on_below_rad));
        let off = !reset & (stays_off | (!was_off & k(plan.off_above_rad).lt(abs_a)));
        let held = reset | (!off & mean_a.lt(k(plan.hold_below_rad)));
        let status = skip.sel(prev, off.sel(k_off, held.sel(k_held, k_active)));
        bank.status[i] = status.0;
        let off = status.map(|s| s == OrderStatus::Off);
        let active = status.map(|s| s == OrderStatus::Active);
        let zeroed = !skip & (reset | off);
        (keep[i], couple[i], pred[i], upd[i]) = (!zeroed, skip | active, !off, meas_ok & active);
        inc[i] = zeroed.sel(zero, a);
        all_active = all_active & active;
        let q_i = (k(o.q_per_sample_nm2) * n_noise).madd::<F>(k(o.q_per_rad_nm2), abs_a);
        q[i] = (off | skip).sel(zero, q_i);
        flag(StepFlags::ORDER_OFF, off);
        flag(StepFlags::ORDER_HELD, status.map(|s| s == OrderStatus::Held));
        let b = pick(&base, r);
        let ph = match plan.power[i] {
            1 => b,
            2 => b.map(|b| b.doubled::<F>()),
            4 => b.map(|b| b.doubled::<F>().doubled::<F>()),
            0 => {
                // A fractional multiple: its own accumulated phase.
                let psi = (Lanes(bank.order_psi[i]) + inc[i]).map(wrap);
                bank.order_psi[i] = psi.0;
                psi.map(sin_cos_with::<T, F>)
            }
            n => b.map(|b| {
                let (c, s) = phasor_power_with::<T, F>(b.c, b.s, n);
                Doubling::new(c, s)
            }),
        };
        let scale = if o.load_scaled { load } else { one };
        bank.phasor[i] = [(ph.map(|p| p.c) * scale).0, (ph.map(|p| p.s) * scale).0];
    });

    let pending_none = pending.zip(zero, |a, b| a == b);
    let common = (counted & meas_ok & !gap & !any_jump & pending_none & all_active).all();
    let d = Decisions { keep, couple, pred, upd, inc, q, meas_ok, gap, n_noise, infl, flags };
    if common {
        // The common sample: every decision is known, so the update has no select left.
        let yes = Lanes::splat(true);
        let (keep, couple, pred, upd) = ([yes; M], [yes; M], [yes; M], [yes; M]);
        let n_noise = one;
        let infl = k(lim.covariance_inflation);
        let flags = [StepFlags::empty(); J];
        let d = Decisions { keep, couple, pred, upd, meas_ok: yes, gap: no, n_noise, infl, flags, ..d };
        update::<T, M, J, F, BIAS, TRACE>(model, bank, input, d, out, trace)
    } else {
        update::<T, M, J, F, BIAS, TRACE>(model, bank, input, d, out, trace)
    }
}

/// What the first half of a step decided for each joint.
#[derive(Clone, Copy)]
struct Decisions<T, const M: usize, const J: usize> {
    /// Per order: state kept (else restarted from its prior), coupled with the others,
    /// predicted, updated.
    keep: [Lanes<bool, J>; M],
    couple: [Lanes<bool, J>; M],
    pred: [Lanes<bool, J>; M],
    upd: [Lanes<bool, J>; M],
    /// Per order: the applied phase increment, rad, and the process noise, N·m².
    inc: [Lanes<T, J>; M],
    q: [Lanes<T, J>; M],
    /// Measurement used; time gap.
    meas_ok: Lanes<bool, J>,
    gap: Lanes<bool, J>,
    /// Samples of bias noise since the last counted sample; covariance inflation.
    n_noise: Lanes<T, J>,
    infl: Lanes<T, J>,
    flags: [StepFlags; J],
}

/// The second half of a step: the time update, the prediction that is output and the
/// measurement update, as `d` decided. Returns which covariances went bad.
#[allow(clippy::too_many_lines)]
#[inline(always)]
fn update<T: Real, const M: usize, const J: usize, const F: bool, const BIAS: bool, const TRACE: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    d: Decisions<T, M, J>,
    out: &mut BankOutput<T, J>,
    mut trace: Option<&mut StepTrace<T, M>>,
) -> Lanes<bool, J> {
    let (plan, lim, orders) = (&model.plan, &model.limits, &model.orders);
    let k = Lanes::<T, J>::splat;
    let (zero, one, no) = (k(T::ZERO), k(T::ONE), Lanes::splat(false));
    let q_bias = model.bias_q_nm2.unwrap_or(T::ZERO);
    let (torque, expected) = (Lanes(input.torque_nm), Lanes(input.expected_torque_nm));
    let y = torque - expected;
    let Decisions { keep, couple, pred, upd, inc, q, meas_ok, gap, n_noise, infl, mut flags } = d;

    // Time update: inflation `ρ (P_00 + P_11)/2 · I₂` (rotation invariant, like Q) and
    // process noise on the diagonal blocks; a reset order restarts from its prior and
    // forgets its covariances, an order not active is decoupled from the others.
    let grow = infl * k(T::HALF);
    unroll!(M, |i| {
        let d = &mut bank.p[i][i];
        let (v0, v1) = (Lanes(d[0][0]), Lanes(d[1][1]));
        let trace = v0 + v1;
        let fresh = k(plan.p0_nm2[i]) + q[i];
        d[0][0] = keep[i].sel(v0.madd::<F>(grow, trace) + q[i], fresh).0;
        d[1][1] = keep[i].sel(v1.madd::<F>(grow, trace) + q[i], fresh).0;
        let off = keep[i].sel(Lanes(d[0][1]), zero).0;
        (d[0][1], d[1][0]) = (off, off);
        for r in 0..2 {
            bank.z[i][r] = keep[i].sel(Lanes(bank.z[i][r]), k(orders[i].prior_nm[r])).0;
            if BIAS {
                bank.pb[i][r] = couple[i].sel(Lanes(bank.pb[i][r]), zero).0;
            }
        }
        unroll!(M, |j| {
            if j > i {
                let both = couple[i] & couple[j];
                for v in bank.p[i][j].iter_mut().flatten() {
                    *v = both.sel(Lanes(*v), zero).0;
                }
            }
        });
    });
    if BIAS {
        // A time gap brings the bias variance back up to its initial value.
        let (v, p0) = (Lanes(bank.pbb), k(model.p0_bias_nm2));
        let v = (gap & v.lt(p0)).sel(p0, v);
        bank.pbb = (v.madd::<F>(v, infl) + k(q_bias) * n_noise).0;
    }

    // Prediction ŷ(k) = h ẑ(k|k−1) (every order not off) and the update row h (the
    // orders updated; the bias entry is 1 when the measurement is used).
    let (mut ripple, mut mis) = (zero, zero);
    let (mut any_ripple, mut any_mis) = (false, false);
    let mut h = [[zero; 2]; M];
    unroll!(M, |i| {
        let (c, s) = (Lanes(bank.phasor[i][0]), Lanes(bank.phasor[i][1]));
        let v = pred[i].sel((c * Lanes(bank.z[i][0])).madd::<F>(s, Lanes(bank.z[i][1])), zero);
        if orders[i].reference.is_ripple() {
            ripple = sum_from(!any_ripple, ripple, v);
            any_ripple = true;
        } else {
            mis = sum_from(!any_mis, mis, v);
            any_mis = true;
        }
        h[i] = [upd[i].sel(c, zero), upd[i].sel(s, zero)];
    });

    // Gains g = P hᵀ from the upper blocks of the symmetric P, and the bias entry.
    let mut g = [[zero; 2]; M];
    unroll!(M, |i| {
        if BIAS {
            g[i] = [meas_ok.sel(Lanes(bank.pb[i][0]), zero), meas_ok.sel(Lanes(bank.pb[i][1]), zero)];
        }
        unroll!(M, |j| {
            let (t0, t1) = block_times::<T, M, J, F>(bank, i, j, h[j]);
            let first = !BIAS && j == 0;
            g[i] = [sum_from(first, g[i][0], t0), sum_from(first, g[i][1], t1)];
        });
    });
    let mut gb = zero;
    if BIAS {
        gb = meas_ok.sel(Lanes(bank.pbb), zero);
        for j in 0..M {
            gb = gb + (Lanes(bank.pb[j][0]) * h[j][0]).madd::<F>(Lanes(bank.pb[j][1]), h[j][1]);
        }
    }

    // Innovation `e = y − ŷ`, its variance `S = R + h g`, and the load-step decision:
    // an innovation beyond the NIS limit is a jump of the bias, not of the oscillators.
    // The update is then the exact limit Var(b) → ∞ (gain 0 here, completed below).
    let mut s = if BIAS { gb } else { zero };
    unroll!(M, |i| {
        s = sum_from(!BIAS && i == 0, s, (h[i][0] * g[i][0]).madd::<F>(h[i][1], g[i][1]));
    });
    let s_var = k(model.r_nm2) + s;
    let e = y - (ripple + mis + Lanes(bank.b));
    let e_used = meas_ok.sel(e, zero);
    let load_step =
        if BIAS && lim.load_step_nis > T::ZERO { (k(lim.load_step_nis) * s_var).lt(e_used * e_used) } else { no };
    let inv = load_step.sel(zero, one / s_var);
    for l in 0..J {
        flags[l].set(StepFlags::LOAD_STEP, load_step.0[l]);
    }
    if let Some(tr) = trace.as_deref_mut().filter(|_| TRACE) {
        let row_b = if BIAS { meas_ok.sel(one, zero) } else { zero };
        let lane0 = [q_bias * n_noise.0[0], row_b.0[0], gb.0[0], s_var.0[0], e_used.0[0], y.0[0]];
        record(tr, bank, (inc, q, [keep, pred], h, g), lane0, gap.0[0] & BIAS, load_step.0[0]);
    }

    // Measurement update `ẑ += g e / S`, `P −= g gᵀ / S` (upper blocks; each product
    // `g_i g_j` times `1/S`, so that it waits on the division for one multiply–add).
    // Variances never fall below their exact lower bound `P_ii R / S`.
    let floor = k(model.r_nm2) * inv;
    let (mut diag, mut z) = ([[zero; 2]; M], [[zero; 2]; M]);
    unroll!(M, |i| {
        let [g0, g1] = g[i];
        let (k0, k1) = (g0 * inv, g1 * inv);
        z[i] = [Lanes(bank.z[i][0]).madd::<F>(k0, e_used), Lanes(bank.z[i][1]).madd::<F>(k1, e_used)];
        bank.z[i] = [z[i][0].0, z[i][1].0];
        let d = &mut bank.p[i][i];
        let (v0, v1) = (Lanes(d[0][0]), Lanes(d[1][1]));
        diag[i] = [v0.madd::<F>(-(g0 * g0), inv).max(v0 * floor), v1.madd::<F>(-(g1 * g1), inv).max(v1 * floor)];
        (d[0][0], d[1][1]) = (diag[i][0].0, diag[i][1].0);
        let off = Lanes(d[0][1]).madd::<F>(-(g0 * g1), inv).0;
        (d[0][1], d[1][0]) = (off, off);
        unroll!(M, |j| {
            if j > i {
                let b = &mut bank.p[i][j];
                for (r, gr) in [g0, g1].into_iter().enumerate() {
                    for c in 0..2 {
                        b[r][c] = Lanes(b[r][c]).madd::<F>(-(gr * g[j][c]), inv).0;
                    }
                }
            }
        });
        if BIAS {
            bank.pb[i][0] = Lanes(bank.pb[i][0]).madd::<F>(-k0, gb).0;
            bank.pb[i][1] = Lanes(bank.pb[i][1]).madd::<F>(-k1, gb).0;
        }
    });
    if BIAS {
        let kb = gb * inv;
        bank.b = Lanes(bank.b).madd::<F>(kb, e_used).0;
        let v = Lanes(bank.pbb);
        bank.pbb = v.madd::<F>(-kb, gb).max(v * k(model.r_nm2) * inv).0;
        // The load-step limit: the bias takes the whole innovation, the oscillators
        // learn nothing, and `Var(b) = R + h P_zz hᵀ`, `Cov(z, b) = −P_zz hᵀ` (no
        // cancellation, PSD by construction); `P_zz hᵀ = g − Cov(z, b)` as h's bias
        // entry is 1.
        let mut s_z = zero;
        for i in 0..M {
            for r in 0..2 {
                let pzh = g[i][r] - Lanes(bank.pb[i][r]);
                s_z = s_z + h[i][r] * pzh;
                bank.pb[i][r] = load_step.sel(-pzh, Lanes(bank.pb[i][r])).0;
            }
        }
        bank.pbb = load_step.sel(k(model.r_nm2) + s_z, Lanes(bank.pbb)).0;
        bank.b = load_step.sel(Lanes(bank.b) + e_used, Lanes(bank.b)).0;
    }
    if let Some(tr) = trace.filter(|_| TRACE) {
        tr.posterior = gaussian(bank, 0);
    }

    // Outputs, and whether the covariance went bad.
    let clean = torque - ripple - mis;
    (out.torque_nm, out.ripple_nm, out.misalignment_nm) = (clean.0, ripple.0, mis.0);
    out.torque_state_nm = if BIAS { (expected + Lanes(bank.b)).0 } else { clean.0 };
    (out.innovation_nm, out.innovation_variance_nm2) = (e.0, s_var.0);
    out.nis = (e * e / s_var).0;
    out.flags = flags;
    let bias = if BIAS { Some(Lanes(bank.pbb)) } else { None };
    !healthy(diag, z, Lanes(bank.b), bias, s_var)
}

/// Which joints' states are usable after an update: the new variances `diag` (the
/// diagonal of each oscillator block), means `z`, bias `b`, its variance (with the
/// bias state) and the innovation variance `s_var`. One sum catches any NaN/∞, one
/// minimum any negative variance; the values come in registers, not from the state.
#[inline(always)]
pub(super) fn healthy<T: Real, const M: usize, const J: usize>(
    diag: [[Lanes<T, J>; 2]; M],
    z: [[Lanes<T, J>; 2]; M],
    b: Lanes<T, J>,
    pbb: Option<Lanes<T, J>>,
    s_var: Lanes<T, J>,
) -> Lanes<bool, J> {
    // The two entries of each pair apart, then together: two independent chains.
    let zero = Lanes::splat(T::ZERO);
    let (mut sum, mut least) = ([zero; 2], [s_var; 2]);
    unroll!(M, |i| {
        for r in 0..2 {
            sum[r] = sum_from(i == 0, sum[r], diag[i][r] + z[i][r]);
            least[r] = least[r].min(diag[i][r]);
        }
    });
    let mut total = (sum[0] + sum[1]) + (s_var + b);
    let mut low = least[0].min(least[1]);
    if let Some(v) = pbb {
        total = total + v;
        low = low.min(v);
    }
    total.finite() & zero.le(low) & zero.lt(s_var)
}

/// `P_ij h_j` (two entries of `g_i`), from the upper blocks of the symmetric P.
#[inline(always)]
fn block_times<T: Real, const M: usize, const J: usize, const F: bool>(
    bank: &RippleBank<T, M, J>,
    i: usize,
    j: usize,
    [h0, h1]: [Lanes<T, J>; 2],
) -> (Lanes<T, J>, Lanes<T, J>) {
    let (a, b, t) = if j >= i { (i, j, false) } else { (j, i, true) };
    let p = |r: usize, c: usize| Lanes(if t { bank.p[a][b][c][r] } else { bank.p[a][b][r][c] });
    ((p(0, 0) * h0).madd::<F>(p(0, 1), h1), (p(1, 0) * h0).madd::<F>(p(1, 1), h1))
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
fn sum_from<V: Add<Output = V>>(first: bool, acc: V, t: V) -> V {
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

/// Per order, lane-wise: increments, process noise, [kept, predicted], update row, gains.
type OrderLanes<T, const M: usize, const J: usize> =
    ([Lanes<T, J>; M], [Lanes<T, J>; M], [[Lanes<bool, J>; M]; 2], [[Lanes<T, J>; 2]; M], [[Lanes<T, J>; 2]; M]);

/// Joint 0's quantities of this step into `tr`, before the measurement update;
/// `scalars`: bias noise, update row and gain entries, `S`, the innovation used, `y`.
#[inline(never)]
fn record<T: Real, const M: usize, const J: usize>(
    tr: &mut StepTrace<T, M>,
    bank: &RippleBank<T, M, J>,
    (inc, q, [kept, predicted], h, g): OrderLanes<T, M, J>,
    [q_b, row_b, g_b, s_var, e_used, y]: [T; 6],
    reinflated: bool,
    load_step: bool,
) {
    for i in 0..M {
        (tr.increment_rad[i], tr.q_nm2[i]) = (inc[i].0[0], q[i].0[0]);
        (tr.kept[i], tr.predicted[i]) = (kept[i].0[0], predicted[i].0[0]);
        tr.update_row[i] = [h[i][0].0[0], h[i][1].0[0]];
        tr.gain_numerator[i] = [g[i][0].0[0], g[i][1].0[0]];
        tr.phasor[i] = [bank.phasor[i][0][0], bank.phasor[i][1][0]];
    }
    tr.prior = gaussian(bank, 0);
    (tr.q_bias_nm2, tr.update_row_bias, tr.gain_numerator_bias) = (q_b, row_b, g_b);
    (tr.innovation_variance_nm2, tr.innovation_used_nm, tr.measurement_nm) = (s_var, e_used, y);
    tr.bias_reinflated = reinflated;
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

    /// [`healthy`] of the state in `bank` after an update with innovation variance `s`.
    fn health_of(bias: bool, bank: &RippleBank<f64, 3, 2>, s: f64) -> [bool; 2] {
        let lanes = |v: [f64; 2]| Lanes(v);
        let diag = core::array::from_fn(|i| [lanes(bank.p[i][i][0][0]), lanes(bank.p[i][i][1][1])]);
        let z = core::array::from_fn(|i| [lanes(bank.z[i][0]), lanes(bank.z[i][1])]);
        healthy(diag, z, lanes(bank.b), bias.then_some(lanes(bank.pbb)), Lanes::splat(s)).0
    }

    /// Each corruption of joint 0 is caught, and joint 1 (untouched) stays healthy.
    #[test]
    fn health_check_catches_each_bad_entry() {
        let model = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let fresh = RippleBank::<f64, 3, 2>::new(&model);
        assert!(health_of(true, &fresh, 1.0)[0] && health_of(true, &fresh, 1.0)[1]);
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
            assert!(!health_of(true, &bank, 1.0)[0], "corruption {k} passed");
            assert!(health_of(true, &bank, 1.0)[1], "corruption {k} reached joint 1");
        }
        for s_var in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(!health_of(true, &fresh, s_var)[0], "S = {s_var}");
        }
        // Without the bias state its entries are not read.
        let mut bank = fresh;
        bank.pbb[0] = -1.0;
        assert!(health_of(false, &bank, 1.0)[0]);
    }
}
