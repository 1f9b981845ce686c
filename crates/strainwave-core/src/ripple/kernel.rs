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
//! The per-joint decisions (skips, resets, statuses) are made first by
//! the `plan` module; the arithmetic below applies them as 0/1 masks with the joint
//! index innermost and no branch, so it vectorizes across joints.

// Lane loops index several arrays by the same joint index (structure of arrays), and
// `!(x <= limit)` is deliberate: NaN must count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::filter::StepTrace;
use super::io::StepFlags;
use super::model::RippleModel;
use super::plan::{plan, Plan};
use super::trig::{phasor_power, sin_cos_small};
use crate::Real;

/// Steps `J` joints sharing `model` by one sample. A joint whose covariance went bad is
/// reset and flagged [`StepFlags::COVARIANCE_RESET`]; the others are unaffected.
///
/// ```
/// use strainwave_core::ripple::{step_many, BankInput, ReferenceValues, RippleBank, RippleModel};
/// let model = RippleModel::<f32, 2>::seed_4th_order(1000.0).unwrap();
/// let mut bank = RippleBank::<f32, 2, 4>::new(&model);
/// for k in 0..100 {
///     let phi = [0.05 * k as f32; 4];
///     let input = BankInput::new([1.0; 4], ReferenceValues::new(phi, [0.0; 4], [0.0; 4]));
///     let out = step_many(&model, &mut bank, &input);
///     assert!(out.torque_nm.iter().all(|t| t.is_finite()));
/// }
/// ```
pub fn step_many<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> BankOutput<T, J> {
    run(model, bank, input, None)
}

/// The whole step; `trace` (for `J = 1`) records joint 0's intermediate quantities.
pub(crate) fn run<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    trace: Option<&mut StepTrace<T, M>>,
) -> BankOutput<T, J> {
    let mut pl = Plan::new();
    plan(model, bank, input, &mut pl);
    let has_bias = model.bias_q_nm2.is_some();

    // Phasors: one sine/cosine per reference, whole multiples by complex squaring.
    let mut base = [[[T::ONE; J]; 2]; 3];
    for r in 0..3 {
        if model.uses[r] {
            for l in 0..J {
                let (s, c) = sin_cos_small(bank.psi[r][l]);
                base[r][0][l] = c;
                base[r][1][l] = s;
            }
        }
    }
    for i in 0..M {
        let (n, r) = (model.power[i], model.orders[i].reference.index());
        for l in 0..J {
            let (c, s) = if n > 0 {
                phasor_power(base[r][0][l], base[r][1][l], n)
            } else {
                let (s, c) = sin_cos_small(bank.order_psi[i][l]);
                (c, s)
            };
            bank.phasor[i][0][l] = c;
            bank.phasor[i][1][l] = s;
        }
    }
    if model.any_load_scaled {
        // Load regressor |T_exp + b̂(k|k−1)| (the bias is not changed by the time update).
        let mut load = [T::ZERO; J];
        for l in 0..J {
            load[l] = (input.expected_torque_nm[l] + bank.b[l]).abs();
            load[l] = if load[l].is_finite() { load[l] } else { T::ZERO };
        }
        for i in 0..M {
            if model.orders[i].load_scaled {
                for l in 0..J {
                    bank.phasor[i][0][l] *= load[l];
                    bank.phasor[i][1][l] *= load[l];
                }
            }
        }
    }

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
    let mut h = [[[T::ZERO; J]; 2]; M];
    for i in 0..M {
        let is_ripple = model.orders[i].reference.is_ripple();
        for l in 0..J {
            let (c, s) = (bank.phasor[i][0][l], bank.phasor[i][1][l]);
            let v = pl.pred[i][l] * (c * bank.z[i][0][l] + s * bank.z[i][1][l]);
            if is_ripple {
                ripple[l] += v;
            } else {
                mis[l] += v;
            }
            h[i][0][l] = pl.upd[i][l] * c;
            h[i][1][l] = pl.upd[i][l] * s;
        }
    }

    // g = P hᵀ (symmetric P from its upper blocks), S = R + h g. Explicit 2×2 blocks
    // keep the loops shallow enough to unroll; the joint index stays innermost.
    let mut g = [[[T::ZERO; J]; 2]; M];
    let mut gb = [T::ZERO; J];
    for i in 0..M {
        let (mut g0, mut g1) = ([T::ZERO; J], [T::ZERO; J]);
        if has_bias {
            for l in 0..J {
                g0[l] = bank.pb[i][0][l] * pl.upd_b[l];
                g1[l] = bank.pb[i][1][l] * pl.upd_b[l];
            }
        }
        for j in 0..M {
            let (hj0, hj1) = (&h[j][0], &h[j][1]);
            if j >= i {
                let b = &bank.p[i][j];
                for l in 0..J {
                    g0[l] += b[0][0][l] * hj0[l] + b[0][1][l] * hj1[l];
                    g1[l] += b[1][0][l] * hj0[l] + b[1][1][l] * hj1[l];
                }
            } else {
                let b = &bank.p[j][i];
                for l in 0..J {
                    g0[l] += b[0][0][l] * hj0[l] + b[1][0][l] * hj1[l];
                    g1[l] += b[0][1][l] * hj0[l] + b[1][1][l] * hj1[l];
                }
            }
        }
        g[i] = [g0, g1];
    }
    if has_bias {
        for l in 0..J {
            gb[l] = bank.pbb[l] * pl.upd_b[l];
        }
        for j in 0..M {
            for l in 0..J {
                gb[l] += bank.pb[j][0][l] * h[j][0][l] + bank.pb[j][1][l] * h[j][1][l];
            }
        }
    }
    let mut s_var = [model.r_nm2; J];
    let mut e = [T::ZERO; J];
    let mut e_used = [T::ZERO; J];
    let mut inv = [T::ZERO; J];
    for l in 0..J {
        let mut s = gb[l] * pl.upd_b[l];
        for i in 0..M {
            s += h[i][0][l] * g[i][0][l] + h[i][1][l] * g[i][1][l];
        }
        s_var[l] += s;
        inv[l] = T::ONE / s_var[l];
        let yhat = ripple[l] + mis[l] + bank.b[l];
        e[l] = pl.y[l] - yhat;
        e_used[l] = if pl.meas_ok[l] { e[l] } else { T::ZERO };
    }
    let s_out = s_var;
    // Load step: an innovation beyond the NIS limit is a jump of the bias, not of the
    // oscillators. The update is then the exact limit Var(b) → ∞: the bias takes the
    // whole innovation, the oscillators are not updated, and
    // Var(b) = R + h P_zz hᵀ, Cov(z, b) = −P_zz hᵀ (no cancellation, PSD by construction).
    let mut load_step = [false; J];
    if has_bias && model.limits.load_step_nis > T::ZERO {
        for l in 0..J {
            if e_used[l] * e_used[l] > model.limits.load_step_nis * s_var[l] {
                load_step[l] = true;
                inv[l] = T::ZERO;
                pl.flags[l].insert(StepFlags::LOAD_STEP);
            }
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
                lane0(&s_var),
                lane0(&e_used),
                lane0(&pl.y),
                pl.reinflate.first().copied().unwrap_or(false),
                load_step.first().copied().unwrap_or(false),
            ),
        );
    }

    // Measurement update: ẑ += g e / S, P −= g gᵀ / S (upper blocks).
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
            let (k0, k1) = (k[i][0][l], k[i][1][l]);
            let floor = model.r_nm2 * inv[l];
            let d = &mut bank.p[i][i];
            let (v0, v1) = (d[0][0][l], d[1][1][l]);
            d[0][0][l] = (v0 - k0 * g[i][0][l]).max(v0 * floor);
            d[1][1][l] = (v1 - k1 * g[i][1][l]).max(v1 * floor);
            let off = d[0][1][l] - k0 * g[i][1][l];
            d[0][1][l] = off;
            d[1][0][l] = off;
        }
        for j in i + 1..M {
            let b = &mut bank.p[i][j];
            for l in 0..J {
                let (k0, k1, gj0, gj1) = (k[i][0][l], k[i][1][l], g[j][0][l], g[j][1][l]);
                b[0][0][l] -= k0 * gj0;
                b[0][1][l] -= k0 * gj1;
                b[1][0][l] -= k1 * gj0;
                b[1][1][l] -= k1 * gj1;
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
        for l in 0..J {
            if load_step[l] {
                // P_zz hᵀ = g − Cov(z, b) since the bias entry of h is 1.
                let mut s_z = T::ZERO;
                for i in 0..M {
                    for r in 0..2 {
                        let pzh = g[i][r][l] - bank.pb[i][r][l];
                        s_z += h[i][r][l] * pzh;
                        bank.pb[i][r][l] = -pzh;
                    }
                }
                bank.pbb[l] = model.r_nm2 + s_z;
                bank.b[l] += e_used[l];
            }
        }
    }

    finish(model, bank, input, pl, ripple, mis, e, s_out)
}

/// Health check (reset on a bad covariance) and the outputs.
#[allow(clippy::too_many_arguments)]
fn finish<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    mut pl: Plan<T, M, J>,
    ripple: [T; J],
    mis: [T; J],
    e: [T; J],
    s_var: [T; J],
) -> BankOutput<T, J> {
    let has_bias = model.bias_q_nm2.is_some();
    let mut out = BankOutput {
        torque_nm: [T::ZERO; J],
        ripple_nm: ripple,
        misalignment_nm: mis,
        torque_state_nm: [T::ZERO; J],
        innovation_nm: e,
        innovation_variance_nm2: s_var,
        nis: [T::ZERO; J],
        flags: pl.flags,
    };
    for l in 0..J {
        let s = s_var[l];
        // One sum catches any NaN/∞, one minimum any negative variance.
        let mut sum = s + bank.b[l];
        let mut least = s;
        if has_bias {
            sum += bank.pbb[l];
            least = least.min(bank.pbb[l]);
        }
        for i in 0..M {
            let d = &bank.p[i][i];
            sum += d[0][0][l] + d[1][1][l] + bank.z[i][0][l] + bank.z[i][1][l];
            least = least.min(d[0][0][l]).min(d[1][1][l]);
        }
        let ok = sum.is_finite() && least >= T::ZERO && s > T::ZERO;
        if !ok {
            bank.reset_lane(model, l);
            pl.flags[l].insert(StepFlags::COVARIANCE_RESET);
        }
        out.flags[l] = pl.flags[l];
        out.torque_nm[l] = input.torque_nm[l] - ripple[l] - mis[l];
        out.torque_state_nm[l] = if has_bias { input.expected_torque_nm[l] + bank.b[l] } else { out.torque_nm[l] };
        out.nis[l] = e[l] * e[l] / s;
    }
    out
}

fn lane0<T: Real, const J: usize>(a: &[T; J]) -> T {
    a.first().copied().unwrap_or(T::ZERO)
}
