//! The joint bank's step and one joint's step compiled for AVX2 and FMA, chosen at run
//! time on x86-64 CPUs that have both (std builds only; `no_std` builds use what the
//! target enables at compile time).
//!
//! The same source as [`step_many`](super::step_many) and [`step`](super::step), with
//! one difference: the common sample's multiply–adds (`madd` in the one-loop step) are
//! fused, rounded once instead of twice. The results therefore agree with the portable
//! build to rounding, not bit for bit; the decisions (skips, resets, load steps, order
//! status) are the same, and a bank and its joints stepped one by one agree to rounding
//! (bit for bit in the portable build: samples the fallback paths take are not fused).
//! Fusing pays because a multiply–add is one instruction on the step's dependency chain
//! instead of two: 6-state f64 38 ns against 44 in the portable build when it came in
//! (x86-64, plain timing loop; see the README for today's figures).

// The one place the project uses `unsafe`: calling a function compiled for a CPU
// feature, after checking that the CPU has it.
#![allow(unsafe_code)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::filter::RippleState;
use super::io::{RippleInput, RippleOutput};
use super::kernel::fill;
use super::model::RippleModel;
use crate::{Error, Real};

/// Whether this CPU runs this build (AVX2 and FMA; checked once, then cached by the
/// standard library).
#[inline]
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
}

/// [`fill`] for banks in this build. Call only when [`available`] is true.
#[inline]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) {
    debug_assert!(available());
    // SAFETY: callers check `available()`, so the CPU executes AVX2 and FMA instructions.
    unsafe { step_avx2(model, bank, input, out) }
}

/// One joint's step ([`step`](super::step)) in this build. Call only when [`available`]
/// is true.
#[inline]
pub(crate) fn single<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    state: &mut RippleState<T, M>,
    input: &RippleInput<T>,
) -> Result<RippleOutput<T>, Error> {
    debug_assert!(available());
    // SAFETY: callers check `available()`, so the CPU executes AVX2 and FMA instructions.
    unsafe { single_avx2(model, state, input) }
}

#[target_feature(enable = "avx2,fma")]
fn single_avx2<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    state: &mut RippleState<T, M>,
    input: &RippleInput<T>,
) -> Result<RippleOutput<T>, Error> {
    super::filter::single::<T, M, true>(model, state, input, None)
}

#[target_feature(enable = "avx2,fma")]
fn step_avx2<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) {
    fill::<T, M, J, true>(model, bank, input, None, out);
}

#[cfg(test)]
mod tests {
    use super::super::path_check::close_to_general;
    use super::super::{BankOutput, Order, Reference, ReferenceValues, RippleInput, RippleModel, RippleState};
    use super::{available, single, step};
    use crate::Real;

    /// Agreement per step with the portable general path (relative to each number's
    /// magnitude, at least 1), f64 and f32: rounding differences of a few ulp, grown by
    /// the cancellation in the innovation `y − ŷ` (NIS is its square).
    const TOL: [f64; 2] = [1e-10, 2e-4];

    fn tol<T: Real>() -> f64 {
        if T::EPSILON.to_f64() > 1e-10 {
            TOL[1]
        } else {
            TOL[0]
        }
    }

    /// The bank step of this build against the portable general path.
    fn bank_close<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>) {
        close_to_general::<T, M, J>(&model, tol::<T>(), |m, b, i| {
            let mut out = BankOutput::default();
            step(m, b, i, &mut out);
            out
        });
    }

    #[test]
    fn bank_build_agrees_with_the_portable_build() {
        if !available() {
            eprintln!("this CPU has no AVX2 and FMA: nothing to compare");
            return;
        }
        bank_close::<f32, 3, 8>(RippleModel::seed_6th_order(1000.0).unwrap());
        bank_close::<f32, 3, 16>(RippleModel::product(1000.0, 0.05).unwrap());
        bank_close::<f64, 5, 4>(RippleModel::full(1000.0, 0.05).unwrap());
        bank_close::<f64, 3, 2>(RippleModel::seed_6th_order(1000.0).unwrap());
        bank_close::<f32, 2, 3>(RippleModel::seed_4th_order(1000.0).unwrap());
    }

    /// One joint's step of this build against the portable general path.
    fn single_close<T: Real, const M: usize>(model: RippleModel<T, M>) {
        close_to_general::<T, M, 1>(&model, tol::<T>(), |m, b, i| {
            let r = &i.references;
            let mut one =
                RippleInput::new(i.torque_nm[0], ReferenceValues::new(r.relative[0], r.output[0], r.motor[0]));
            one.expected_torque_nm = i.expected_torque_nm[0];
            one.dt_s = i.dt_s;
            let mut state = RippleState::new(m);
            state.bank = *b;
            let o = single(m, &mut state, &one).expect("no covariance reset in this run");
            *b = state.bank;
            let mut out = BankOutput::default();
            (out.torque_nm[0], out.ripple_nm[0], out.misalignment_nm[0]) =
                (o.torque_nm, o.ripple_nm, o.misalignment_nm);
            (out.torque_state_nm[0], out.innovation_nm[0]) = (o.torque_state_nm, o.innovation_nm);
            (out.innovation_variance_nm2[0], out.nis[0], out.flags[0]) = (o.innovation_variance_nm2, o.nis, o.flags);
            out
        });
    }

    #[test]
    fn single_joint_build_agrees_with_the_portable_build() {
        if !available() {
            eprintln!("this CPU has no AVX2 and FMA: nothing to compare");
            return;
        }
        // Models the one-loop step takes, then one only the scalar `lean` step takes.
        single_close(RippleModel::<f64, 3>::seed_6th_order(1000.0).unwrap());
        single_close(RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap());
        single_close(RippleModel::<f32, 2>::seed_4th_order(1000.0).unwrap());
        single_close(RippleModel::<f64, 5>::full(1000.0, 0.05).unwrap());
        let motor = [Order::new(Reference::Motor, 1.0).unwrap(), Order::new(Reference::Relative, 2.0).unwrap()];
        single_close(RippleModel::<f32, 2>::new(motor, 1.0, 1000.0).unwrap());
    }

    /// The fused arithmetic is really in this build: some sample differs from the
    /// portable build in its last bits (else the test above would compare a build
    /// with itself).
    #[test]
    fn this_build_rounds_differently() {
        if !available() {
            return;
        }
        let model = RippleModel::<f64, 3>::seed_6th_order(1000.0).unwrap();
        let (mut a, mut b) = (RippleState::new(&model), RippleState::new(&model));
        let mut differ = 0;
        for k in 0..2000 {
            let t = 0.08 * k as f64;
            let input = RippleInput::new(
                2.0 + (2.0 * t).cos(),
                ReferenceValues::new(t.rem_euclid(core::f64::consts::TAU), -t / 50.0, 0.0),
            );
            let fast = single(&model, &mut a, &input).unwrap();
            let portable = super::super::filter::single::<f64, 3, false>(&model, &mut b, &input, None).unwrap();
            differ += usize::from(fast.torque_nm.to_bits() != portable.torque_nm.to_bits());
            b = a;
        }
        assert!(differ > 100, "{differ}");
    }
}
