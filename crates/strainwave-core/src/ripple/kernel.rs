//! One step of the canceller for a bank of joints: the time update (phase advance,
//! resets, process noise), the prediction that is output, and the measurement update.
//!
//! In the rotating frame `x_i = Φ(ψ_i) z_i` the seed recursion (SPEC §4)
//!
//! ```text
//! K(k)   = Φ P Cᵀ / (R + C P Cᵀ)
//! x̂(k+1) = Φ x̂ + K (y − C x̂)
//! P(k+1) = Q + (Φ − K C) P Φᵀ
//! ```
//!
//! becomes, with `h(k) = [cos ψ_1, sin ψ_1, …, 1]` and `Q = diag(q_i I₂, q_b)`
//! (rotation invariant):
//!
//! ```text
//! time update     ψ_i += a_i,  ẑ(k|k−1) = ẑ(k−1|k−1),  P(k|k−1) = P(k−1|k−1) + Q(k)
//! prediction      ŷ(k) = h ẑ(k|k−1)                      (output before y(k) is used)
//! update          g = P hᵀ,  S = R + h g,  ẑ += g e / S,  P −= g gᵀ / S
//! ```
//!
//! which is the same filter: identical `ŷ`, `x̂ = Φ(ψ) ẑ`, `P_x = Φ(ψ) P_z Φ(ψ)ᵀ`.
//! `Φ` never multiplies `P`; the cost is one symmetric mat-vec and one rank-1 update.
//!
//! Phase: for a whole multiple `n` of an angle input, `ψ_i = n θ(k)` (θ wrapped), which
//! equals `Σ n Δθ` modulo 2π, from one sine/cosine per reference and complex squaring;
//! fractional multiples (and velocity input) accumulate `ψ += a` instead. Both are
//! exactly the seed's Φ sequence with `ω_i T` replaced by the measured `n_i Δθ(k)`.
//!
//! Three paths, the same arithmetic bit for bit in the portable build (tested sample
//! for sample):
//! - `fused`: the common sample (every joint valid, caught up, no reset, every order
//!   active) of the common models (relative and output orders of multiple 1, 2, 4):
//!   one loop over the joints that vectorizes as a whole;
//! - `fast`: the common sample of any model, phase bookkeeping per quantity, then the
//!   same per-joint update (the `joint` module);
//! - otherwise the per-joint decisions (skips, resets, statuses) are made first by the
//!   `plan` module and the arithmetic below applies them as 0/1 masks, joint index
//!   innermost, no branch.
//!
//! On x86-64 CPUs with AVX2 and FMA, banks (`step_many`) and one joint (`step`) run a
//! build for both (`avx2`), chosen at run time, whose `fused` path rounds its
//! multiply–adds once (`madd`): the same decisions, the numbers equal to rounding. The
//! step's time is bound by the FP ports, so fusing is what pays. A single joint takes
//! `fused` first, then the scalar `lean` path.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::filter::StepTrace;
use super::io::StepFlags;
use super::joint::{healthy, load_steps, sum_from};
use super::model::RippleModel;
use super::plan::{plan, Plan};
use super::trig::phasors;
use super::{fast, fused};
use crate::Real;

/// Per-order, per-component, per-joint values `[i][r][joint]`.
pub(crate) type Lanes2<T, const M: usize, const J: usize> = [[[T; J]; 2]; M];

/// Steps `J` joints sharing `model` by one sample, writing their results into `out`
/// (a buffer the caller keeps: nothing is copied per sample). A joint whose covariance
/// went bad is reset and flagged [`StepFlags::COVARIANCE_RESET`]; the others are
/// unaffected.
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
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if J > 1 && super::avx2::available() {
        return super::avx2::step(model, bank, input, out);
    }
    fill::<T, M, J, false>(model, bank, input, None, out);
}

/// The whole step; `trace` (for `J = 1`) records joint 0's intermediate quantities.
#[inline(always)]
pub(crate) fn run<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) -> BankOutput<T, J> {
    let mut out = BankOutput::default();
    fill::<T, M, J, false>(model, bank, input, trace, &mut out);
    out
}

/// [`run`] into `out`: the one-loop step writes it in place, so the common sample
/// costs no copy of the output. `F`: the one-loop step's multiply–adds fused (the
/// build for FMA).
#[inline(always)]
pub(crate) fn fill<T: Real, const M: usize, const J: usize, const F: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
    out: &mut BankOutput<T, J>,
) {
    let common = trace.is_none();
    if !(common && fused::step::<T, M, J, F>(model, bank, input, out)) {
        *out = match common.then(|| fast::step(model, bank, input)).flatten() {
            Some(o) => o,
            None => general(model, bank, input, trace),
        };
    }
}

/// Any sample: decisions as masks, then the same arithmetic as the fast path.
#[inline(never)]
pub(crate) fn general<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) -> BankOutput<T, J> {
    let mut pl = Plan::new();
    plan(model, bank, input, &mut pl);
    let has_bias = model.bias_q_nm2.is_some();
    phasors(model, bank, input);

    // Time update: resets and decoupling, process noise.
    for i in 0..M {
        if pl.plain {
            // keep = 1: the general formulas below reduce to these, bit for bit.
            for l in 0..J {
                let d = &mut bank.p[i][i];
                let grow = pl.infl[l] * T::HALF * (d[0][0][l] + d[1][1][l]);
                d[0][0][l] = d[0][0][l] + grow + pl.q[i][l];
                d[1][1][l] = d[1][1][l] + grow + pl.q[i][l];
            }
            continue;
        }
        let (p0, mu) = (model.p0_order[i], model.orders[i].prior_nm);
        for l in 0..J {
            let k = pl.keep[i][l];
            // A reset restarts the order from its prior (0 or learned coefficients).
            bank.z[i][0][l] = k * bank.z[i][0][l] + (T::ONE - k) * mu[0];
            bank.z[i][1][l] = k * bank.z[i][1][l] + (T::ONE - k) * mu[1];
            let fresh = (T::ONE - k) * p0 + pl.q[i][l];
            let d = &mut bank.p[i][i];
            // Isotropic inflation ρ (P_00 + P_11)/2 I₂: rotation invariant, like Q.
            let grow = pl.infl[l] * T::HALF * (d[0][0][l] + d[1][1][l]);
            d[0][0][l] = k * (d[0][0][l] + grow) + fresh;
            d[1][1][l] = k * (d[1][1][l] + grow) + fresh;
            let off = k * d[0][1][l];
            d[0][1][l] = off;
            d[1][0][l] = off;
        }
        for j in i + 1..M {
            for l in 0..J {
                let w = pl.couple[i][l] * pl.couple[j][l];
                for r in 0..2 {
                    for c in 0..2 {
                        bank.p[i][j][r][c][l] *= w;
                    }
                }
            }
        }
        if has_bias {
            for r in 0..2 {
                for l in 0..J {
                    bank.pb[i][r][l] *= pl.couple[i][l];
                }
            }
        }
    }
    if has_bias {
        for l in 0..J {
            let v = bank.pbb[l];
            let v = if pl.reinflate[l] && v < model.p0_bias_nm2 { model.p0_bias_nm2 } else { v };
            bank.pbb[l] = v + v * pl.infl[l] + pl.q_b[l];
        }
    }

    // Prediction ŷ(k) = h ẑ(k|k−1) and the update row.
    let mut ripple = [T::ZERO; J];
    let mut mis = [T::ZERO; J];
    let (mut any_ripple, mut any_mis) = (false, false);
    let mut h = [[[T::ZERO; J]; 2]; M];
    for i in 0..M {
        let is_ripple = model.orders[i].reference.is_ripple();
        let first = if is_ripple { !any_ripple } else { !any_mis };
        for l in 0..J {
            let (c, s) = (bank.phasor[i][0][l], bank.phasor[i][1][l]);
            let v = pl.pred[i][l] * (c * bank.z[i][0][l] + s * bank.z[i][1][l]);
            if is_ripple {
                ripple[l] = sum_from(first, ripple[l], v);
            } else {
                mis[l] = sum_from(first, mis[l], v);
            }
            h[i][0][l] = pl.upd[i][l] * c;
            h[i][1][l] = pl.upd[i][l] * s;
        }
        any_ripple |= is_ripple;
        any_mis |= !is_ripple;
    }

    let (g, gb) = gains(model, bank, &h, &pl.upd_b);
    let mut inn = innovation(model, bank, &h, &g, gb, &pl.upd_b, &pl.y, &pl.meas_ok, [&ripple, &mis]);
    for l in 0..J {
        if inn.load_step[l] {
            pl.flags[l].insert(StepFlags::LOAD_STEP);
        }
    }
    if let Some(tr) = trace {
        tr.record(
            bank,
            &pl.inc,
            &pl.q,
            &pl.keep,
            &pl.pred,
            &h,
            &g,
            (
                lane0(&pl.q_b),
                lane0(&pl.upd_b),
                lane0(&gb),
                lane0(&inn.s_var),
                lane0(&inn.e_used),
                lane0(&pl.y),
                pl.reinflate.first().copied().unwrap_or(false),
                inn.load_step.first().copied().unwrap_or(false),
            ),
        );
    }
    update(model, bank, &h, &g, &gb, &mut inn);
    finish(model, bank, input, pl.flags, ripple, mis, &inn)
}

/// `g = P hᵀ` (symmetric P from its upper blocks) and its bias entry.
#[inline(always)]
pub(crate) fn gains<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &RippleBank<T, M, J>,
    h: &Lanes2<T, M, J>,
    upd_b: &[T; J],
) -> (Lanes2<T, M, J>, [T; J]) {
    let has_bias = model.bias_q_nm2.is_some();
    // Explicit 2×2 blocks keep the loops shallow enough to unroll.
    let mut g = [[[T::ZERO; J]; 2]; M];
    let mut gb = [T::ZERO; J];
    for i in 0..M {
        let (mut g0, mut g1) = ([T::ZERO; J], [T::ZERO; J]);
        if has_bias {
            for l in 0..J {
                g0[l] = bank.pb[i][0][l] * upd_b[l];
                g1[l] = bank.pb[i][1][l] * upd_b[l];
            }
        }
        for j in 0..M {
            let (hj0, hj1) = (&h[j][0], &h[j][1]);
            let first = !has_bias && j == 0;
            if j >= i {
                let b = &bank.p[i][j];
                for l in 0..J {
                    g0[l] = sum_from(first, g0[l], b[0][0][l] * hj0[l] + b[0][1][l] * hj1[l]);
                    g1[l] = sum_from(first, g1[l], b[1][0][l] * hj0[l] + b[1][1][l] * hj1[l]);
                }
            } else {
                let b = &bank.p[j][i];
                for l in 0..J {
                    g0[l] = sum_from(first, g0[l], b[0][0][l] * hj0[l] + b[1][0][l] * hj1[l]);
                    g1[l] = sum_from(first, g1[l], b[0][1][l] * hj0[l] + b[1][1][l] * hj1[l]);
                }
            }
        }
        g[i] = [g0, g1];
    }
    if has_bias {
        for l in 0..J {
            gb[l] = bank.pbb[l] * upd_b[l];
        }
        for j in 0..M {
            for l in 0..J {
                gb[l] += bank.pb[j][0][l] * h[j][0][l] + bank.pb[j][1][l] * h[j][1][l];
            }
        }
    }
    (g, gb)
}

/// Innovation and its variance of each joint.
pub(crate) struct Innovation<T, const J: usize> {
    pub(crate) s_var: [T; J],
    pub(crate) e: [T; J],
    pub(crate) e_used: [T; J],
    pub(crate) inv: [T; J],
    pub(crate) load_step: [bool; J],
}

/// `S = R + h g`, `e = y − ŷ` and the load-step decision.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn innovation<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &RippleBank<T, M, J>,
    h: &Lanes2<T, M, J>,
    g: &Lanes2<T, M, J>,
    gb: [T; J],
    upd_b: &[T; J],
    y: &[T; J],
    meas_ok: &[bool; J],
    [ripple, mis]: [&[T; J]; 2],
) -> Innovation<T, J> {
    let has_bias = model.bias_q_nm2.is_some();
    let mut n = Innovation {
        s_var: [model.r_nm2; J],
        e: [T::ZERO; J],
        e_used: [T::ZERO; J],
        inv: [T::ZERO; J],
        load_step: [false; J],
    };
    for l in 0..J {
        let mut s = gb[l] * upd_b[l];
        for i in 0..M {
            s = sum_from(!has_bias && i == 0, s, h[i][0][l] * g[i][0][l] + h[i][1][l] * g[i][1][l]);
        }
        n.s_var[l] += s;
        n.inv[l] = T::ONE / n.s_var[l];
        let yhat = ripple[l] + mis[l] + bank.b[l];
        n.e[l] = y[l] - yhat;
        n.e_used[l] = if meas_ok[l] { n.e[l] } else { T::ZERO };
    }
    // Load step: an innovation beyond the NIS limit is a jump of the bias, not of the
    // oscillators. The update is then the exact limit Var(b) → ∞: the bias takes the
    // whole innovation, the oscillators are not updated, and
    // Var(b) = R + h P_zz hᵀ, Cov(z, b) = −P_zz hᵀ (no cancellation, PSD by construction).
    if has_bias && model.limits.load_step_nis > T::ZERO {
        for l in 0..J {
            let step = n.e_used[l] * n.e_used[l] > model.limits.load_step_nis * n.s_var[l];
            n.load_step[l] = step;
            n.inv[l] = if step { T::ZERO } else { n.inv[l] };
        }
    }
    n
}

/// Measurement update: `ẑ += g e / S`, `P −= g gᵀ / S` (upper blocks; each product
/// `g_i g_j` times `1/S`, so that it waits on the division for one multiply–add).
#[inline(always)]
pub(crate) fn update<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    h: &Lanes2<T, M, J>,
    g: &Lanes2<T, M, J>,
    gb: &[T; J],
    n: &mut Innovation<T, J>,
) {
    let has_bias = model.bias_q_nm2.is_some();
    let (inv, e_used) = (&n.inv, &n.e_used);
    let mut k = [[[T::ZERO; J]; 2]; M];
    for i in 0..M {
        for l in 0..J {
            k[i][0][l] = g[i][0][l] * inv[l];
            k[i][1][l] = g[i][1][l] * inv[l];
            bank.z[i][0][l] += k[i][0][l] * e_used[l];
            bank.z[i][1][l] += k[i][1][l] * e_used[l];
        }
    }
    for i in 0..M {
        // Diagonal block: exactly symmetric, variances never below `P_ii R / S`.
        for l in 0..J {
            let (g0, g1) = (g[i][0][l], g[i][1][l]);
            let floor = model.r_nm2 * inv[l];
            let d = &mut bank.p[i][i];
            let (v0, v1) = (d[0][0][l], d[1][1][l]);
            d[0][0][l] = (v0 - g0 * g0 * inv[l]).max(v0 * floor);
            d[1][1][l] = (v1 - g1 * g1 * inv[l]).max(v1 * floor);
            let off = d[0][1][l] - g0 * g1 * inv[l];
            d[0][1][l] = off;
            d[1][0][l] = off;
        }
        for j in i + 1..M {
            let b = &mut bank.p[i][j];
            for l in 0..J {
                let (gi0, gi1, gj0, gj1) = (g[i][0][l], g[i][1][l], g[j][0][l], g[j][1][l]);
                b[0][0][l] -= gi0 * gj0 * inv[l];
                b[0][1][l] -= gi0 * gj1 * inv[l];
                b[1][0][l] -= gi1 * gj0 * inv[l];
                b[1][1][l] -= gi1 * gj1 * inv[l];
            }
        }
        if has_bias {
            for l in 0..J {
                bank.pb[i][0][l] -= k[i][0][l] * gb[l];
                bank.pb[i][1][l] -= k[i][1][l] * gb[l];
            }
        }
    }
    if has_bias {
        for l in 0..J {
            let k = gb[l] * inv[l];
            bank.b[l] += k * e_used[l];
            let v = bank.pbb[l];
            bank.pbb[l] = (v - k * gb[l]).max(v * model.r_nm2 * inv[l]);
        }
        if n.load_step.iter().any(|&s| s) {
            load_steps(model.r_nm2, bank, h, g, &n.load_step, &n.e_used);
        }
    }
}

/// Health check (reset on a bad covariance) and the outputs.
#[inline(always)]
pub(crate) fn finish<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    mut flags: [StepFlags; J],
    ripple: [T; J],
    mis: [T; J],
    n: &Innovation<T, J>,
) -> BankOutput<T, J> {
    let has_bias = model.bias_q_nm2.is_some();
    let (e, s_var) = (n.e, n.s_var);
    // Joint index outermost here: `healthy` inlines to selects, so the loop vectorizes.
    let mut bad = [false; J];
    let mut any_bad = false;
    for l in 0..J {
        bad[l] = !healthy(has_bias, bank, l, s_var[l]);
        any_bad |= bad[l];
    }
    if any_bad {
        for l in 0..J {
            if bad[l] {
                bank.reset_lane(model, l);
                flags[l].insert(StepFlags::COVARIANCE_RESET);
            }
        }
    }
    let mut out = BankOutput {
        torque_nm: [T::ZERO; J],
        ripple_nm: ripple,
        misalignment_nm: mis,
        torque_state_nm: [T::ZERO; J],
        innovation_nm: e,
        innovation_variance_nm2: s_var,
        nis: [T::ZERO; J],
        flags,
    };
    for l in 0..J {
        out.torque_nm[l] = input.torque_nm[l] - ripple[l] - mis[l];
        out.torque_state_nm[l] = if has_bias { input.expected_torque_nm[l] + bank.b[l] } else { out.torque_nm[l] };
        out.nis[l] = e[l] * e[l] / s_var[l];
    }
    out
}

fn lane0<T: Real, const J: usize>(a: &[T; J]) -> T {
    a.first().copied().unwrap_or(T::ZERO)
}
