//! One joint's filter update in a bank, from the time update to the outputs, written
//! so that a loop over the joints vectorizes: the kernel's arithmetic in the same order
//! of operations, selects instead of branches, and the model's numbers copied into
//! locals (so the loop needs no run-time overlap checks against the bank). Used by the
//! `fast` and `fused` paths.

// Several arrays share the joint index, and `!(x <= limit)` is deliberate: NaN must
// count as out of range.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::io::StepFlags;
use super::kernel::Lanes2;
use super::model::RippleModel;
use crate::Real;

/// After the joints' loop (rare cases, so not in it): the load-step limit for the
/// joints with a load step (models with the bias state; given their gains `g`, their
/// update row being the phasor), then the reset of joints whose covariance went bad.
#[inline(always)]
pub(super) fn settle<T: Real, const M: usize, const J: usize, const BIAS: bool>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    load_step: &[bool; J],
    g: &Lanes2<T, M, J>,
    bad: &mut [bool; J],
    out: &mut BankOutput<T, J>,
) {
    if BIAS && load_step.iter().any(|&s| s) {
        let h = bank.phasor;
        load_steps(model.r_nm2, bank, &h, g, load_step, &out.innovation_nm);
        for l in 0..J {
            if load_step[l] {
                out.flags[l].insert(StepFlags::LOAD_STEP);
                out.torque_state_nm[l] = input.expected_torque_nm[l] + bank.b[l];
                bad[l] = !healthy(true, bank, l, out.innovation_variance_nm2[l]);
            }
        }
    }
    if bad.iter().any(|&b| b) {
        for l in 0..J {
            if bad[l] {
                bank.reset_lane(model, l);
                out.flags[l].insert(StepFlags::COVARIANCE_RESET);
                if model.bias_q_nm2.is_some() {
                    out.torque_state_nm[l] = input.expected_torque_nm[l] + bank.b[l];
                }
            }
        }
    }
}

/// The load-step limit for the joints `steps`, after their (void, gain 0) update: the
/// bias takes the innovation `e` and forgets its cross-covariance, and
/// `Var(b) = R + h P_zz hᵀ`, `Cov(z, b) = −P_zz hᵀ` (see `kernel::innovation`).
/// Inlined although rare: a call in the one-joint step costs registers saved and
/// spilled on every sample (6-state f64, 34.0 → 32.6 ns in a plain timing loop).
#[inline(always)]
pub(super) fn load_steps<T: Real, const M: usize, const J: usize>(
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
/// `s_var`: one sum catches any NaN/∞, one minimum any negative variance. Every path
/// checks with this one function, so their decisions agree.
#[inline(always)]
pub(super) fn healthy<T: Real, const M: usize, const J: usize>(
    bias: bool,
    bank: &RippleBank<T, M, J>,
    l: usize,
    s_var: T,
) -> bool {
    // The two entries of each pair apart, then together: two independent chains, which
    // a one-joint step keeps in one vector register (fewer shuffles, a shorter chain).
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

/// The model's numbers that one joint's update reads.
#[derive(Clone, Copy)]
pub(super) struct Params<T: Real, const M: usize> {
    q_per_sample: [T; M],
    q_per_rad: [T; M],
    is_ripple: [bool; M],
    r: T,
    inflation: T,
    q_bias: T,
    load_step_nis: T,
}

impl<T: Real, const M: usize> Params<T, M> {
    /// Whether order `i` is ripple (else misalignment).
    #[inline(always)]
    pub(super) fn is_ripple(&self, i: usize) -> bool {
        self.is_ripple[i]
    }

    #[inline(always)]
    pub(super) fn new(model: &RippleModel<T, M>) -> Self {
        Self {
            q_per_sample: array(T::ZERO, |i| model.orders[i].q_per_sample_nm2),
            q_per_rad: array(T::ZERO, |i| model.orders[i].q_per_rad_nm2),
            is_ripple: array(false, |i| model.orders[i].reference.is_ripple()),
            r: model.r_nm2,
            inflation: model.limits.covariance_inflation,
            q_bias: model.bias_q_nm2.unwrap_or(T::ZERO),
            load_step_nis: model.limits.load_step_nis,
        }
    }
}

/// Joint `l` from the time update to the outputs, given whether each order is ripple
/// (else misalignment), its update row `h` (the phasors) and phase increments `abs_a`:
/// the kernel's arithmetic in the same order of operations, with selects instead of
/// branches (so the caller's loop over the joints vectorizes). Keeps the gains in
/// `gains` (bias models). Returns (load step, covariance bad); the caller completes
/// load steps and resets bad joints (`settle`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn joint<T: Real, const M: usize, const J: usize, const BIAS: bool, const F: bool>(
    par: &Params<T, M>,
    is_ripple: impl Fn(usize) -> bool,
    bank: &mut RippleBank<T, M, J>,
    torque_nm: &[T; J],
    expected_nm: &[T; J],
    h: [[T; 2]; M],
    abs_a: [T; M],
    l: usize,
    gains: &mut Lanes2<T, M, J>,
    out: &mut BankOutput<T, J>,
) -> (bool, bool) {
    let infl = par.inflation;

    // Time update: inflation and process noise on the diagonal blocks, and the bias.
    for i in 0..M {
        let q = madd::<T, F>(par.q_per_sample[i], par.q_per_rad[i], abs_a[i]);
        let d = &mut bank.p[i][i];
        let trace = d[0][0][l] + d[1][1][l];
        // `d + grow + q` with `grow = ρ/2 · trace`.
        d[0][0][l] = madd::<T, F>(d[0][0][l], infl * T::HALF, trace) + q;
        d[1][1][l] = madd::<T, F>(d[1][1][l], infl * T::HALF, trace) + q;
    }
    if BIAS {
        let v = bank.pbb[l];
        bank.pbb[l] = madd::<T, F>(v, v, infl) + par.q_bias;
    }

    // Gains g = P hᵀ from the upper blocks of the symmetric P.
    let mut g = [[T::ZERO; 2]; M];
    for i in 0..M {
        let (mut g0, mut g1) = (T::ZERO, T::ZERO);
        if BIAS {
            g0 = bank.pb[i][0][l] * T::ONE;
            g1 = bank.pb[i][1][l] * T::ONE;
        }
        for j in 0..M {
            let [hj0, hj1] = h[j];
            let (t0, t1) = block_times::<T, M, J, F>(bank, i, j, l, [hj0, hj1]);
            let first = !BIAS && j == 0;
            g0 = sum_from(first, g0, t0);
            g1 = sum_from(first, g1, t1);
        }
        g[i] = [g0, g1];
    }
    let mut gb = T::ZERO;
    if BIAS {
        gb = bank.pbb[l] * T::ONE;
        for j in 0..M {
            gb += madd::<T, F>(bank.pb[j][0][l] * h[j][0], bank.pb[j][1][l], h[j][1]);
        }
    }

    // Prediction; the update row is the phasor itself.
    let (mut ripple, mut mis) = (T::ZERO, T::ZERO);
    let (mut any_ripple, mut any_mis) = (false, false);
    for i in 0..M {
        let v = madd::<T, F>(h[i][0] * bank.z[i][0][l], h[i][1], bank.z[i][1][l]);
        if is_ripple(i) {
            ripple = sum_from(!any_ripple, ripple, v);
            any_ripple = true;
        } else {
            mis = sum_from(!any_mis, mis, v);
            any_mis = true;
        }
    }

    // Innovation and the load-step decision.
    let mut s = if BIAS { gb * T::ONE } else { T::ZERO };
    for i in 0..M {
        s = sum_from(!BIAS && i == 0, s, madd::<T, F>(h[i][0] * g[i][0], h[i][1], g[i][1]));
    }
    let s_var = par.r + s;
    let mut inv = T::ONE / s_var;
    let y = torque_nm[l] - expected_nm[l];
    let e = y - (ripple + mis + bank.b[l]);
    let load_step = BIAS & (par.load_step_nis > T::ZERO) & (e * e > par.load_step_nis * s_var);
    inv = if load_step { T::ZERO } else { inv };

    // Measurement update, `P −= (g_i g_j)·(1/S)`: the products wait for no division.
    // A load step (gain 0 here) is completed after the loop (`settle`), from the gains
    // kept in `gains`.
    let floor = par.r * inv;
    for i in 0..M {
        let [k0, k1] = [g[i][0] * inv, g[i][1] * inv];
        bank.z[i][0][l] = madd::<T, F>(bank.z[i][0][l], k0, e);
        bank.z[i][1][l] = madd::<T, F>(bank.z[i][1][l], k1, e);
        let d = &mut bank.p[i][i];
        let (v0, v1) = (d[0][0][l], d[1][1][l]);
        d[0][0][l] = madd::<T, F>(v0, -(g[i][0] * g[i][0]), inv).max(v0 * floor);
        d[1][1][l] = madd::<T, F>(v1, -(g[i][1] * g[i][1]), inv).max(v1 * floor);
        let off = madd::<T, F>(d[0][1][l], -(g[i][0] * g[i][1]), inv);
        d[0][1][l] = off;
        d[1][0][l] = off;
        for j in i + 1..M {
            let [gj0, gj1] = g[j];
            let b = &mut bank.p[i][j];
            let [gi0, gi1] = g[i];
            b[0][0][l] = madd::<T, F>(b[0][0][l], -(gi0 * gj0), inv);
            b[0][1][l] = madd::<T, F>(b[0][1][l], -(gi0 * gj1), inv);
            b[1][0][l] = madd::<T, F>(b[1][0][l], -(gi1 * gj0), inv);
            b[1][1][l] = madd::<T, F>(b[1][1][l], -(gi1 * gj1), inv);
        }
        if BIAS {
            bank.pb[i][0][l] = madd::<T, F>(bank.pb[i][0][l], -k0, gb);
            bank.pb[i][1][l] = madd::<T, F>(bank.pb[i][1][l], -k1, gb);
            gains[i][0][l] = g[i][0];
            gains[i][1][l] = g[i][1];
        }
    }
    if BIAS {
        let kb = gb * inv;
        bank.b[l] = madd::<T, F>(bank.b[l], kb, e);
        let v = bank.pbb[l];
        bank.pbb[l] = madd::<T, F>(v, -kb, gb).max(v * par.r * inv);
    }

    // Health check and outputs.
    let bad = !healthy(BIAS, bank, l, s_var);
    let torque = torque_nm[l] - ripple - mis;
    out.torque_nm[l] = torque;
    out.ripple_nm[l] = ripple;
    out.misalignment_nm[l] = mis;
    out.torque_state_nm[l] = if BIAS { expected_nm[l] + bank.b[l] } else { torque };
    out.innovation_nm[l] = e;
    out.innovation_variance_nm2[l] = s_var;
    out.nis[l] = e * e / s_var;
    (load_step, bad)
}

/// `P_ij h_j` for joint `l` (two entries of `g_i`), from the upper blocks of the
/// symmetric P.
#[inline(always)]
pub(super) fn block_times<T: Real, const M: usize, const J: usize, const F: bool>(
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

/// `[f(0), …, f(N − 1)]` as a plain loop: `core::array::from_fn` is not always
/// inlined, and a call in the joints' loop would stop it from vectorizing.
#[inline(always)]
pub(super) fn array<T: Copy, const N: usize>(fill: T, f: impl Fn(usize) -> T) -> [T; N] {
    let mut a = [fill; N];
    for (i, v) in a.iter_mut().enumerate() {
        *v = f(i);
    }
    a
}

/// `c + a b`: rounded once (fused) in the build `F = true` (compiled for FMA, chosen at
/// run time for one joint), else rounded twice exactly as written. `c − a b` is
/// `madd(c, −a, b)`, bit for bit.
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
pub(super) fn sum_from<T: Real>(first: bool, acc: T, t: T) -> T {
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
pub(super) fn finite<T: Real>(x: T) -> bool {
    x - x == T::ZERO
}

/// The sample interval (`dt_s` or the nominal one) if the common paths may take it:
/// finite, positive and within the gap limit. One interval serves every joint.
#[inline(always)]
pub(super) fn common_interval<T: Real, const M: usize>(model: &RippleModel<T, M>, dt_s: Option<T>) -> Option<T> {
    let dt = dt_s.unwrap_or(model.dt_s);
    (finite(dt) && dt > T::ZERO && dt <= model.max_gap_s).then_some(dt)
}

#[cfg(test)]
mod tests {
    use super::super::bank::RippleBank;
    use super::super::model::RippleModel;
    use super::healthy;

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
        // The innovation variance: positive and finite.
        for s_var in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(!healthy(true, &fresh, 0, s_var), "S = {s_var}");
        }
        // Without the bias state its entries are not read.
        let mut bank = fresh;
        bank.pbb[0] = -1.0;
        assert!(healthy(false, &bank, 0, 1.0));
    }
}
