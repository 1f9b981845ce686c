//! The joint bank's step, and one joint's step of the smallest model in f32, compiled for
//! AVX2, chosen at run time on x86-64 CPUs that have it (std builds only; `no_std`
//! builds use what the target enables at compile time).
//!
//! The same source as [`step_many`](super::step_many) and [`step`](super::step): no
//! fused multiply–add is formed (Rust never contracts `a * b + c`), so the results are
//! bit for bit those of the portable build; only the vector width and the instruction
//! encoding change. For one joint the gain is the three-operand encoding (no register
//! copies); it is taken only where it measured faster ([`single_pays`]).

// The one place the project uses `unsafe`: calling a function compiled for a CPU
// feature, after checking that the CPU has it.
#![allow(unsafe_code)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::filter::RippleState;
use super::io::{RippleInput, RippleOutput};
use super::kernel::fill;
use super::model::RippleModel;
use super::trig::is_single;
use crate::{Error, Real};

/// Whether one joint's step runs the AVX2 build: only the 4-state model in f32, where
/// it measured faster. Criterion, fastest sample of three alternating runs each (x86-64,
/// Zen 3): 4 states f32 44–46 ns against 53–54 portable; 4 states f64 60–62 against
/// 54–72; 6 and 11 states no faster or slower (probe, fastest pass over 6000 samples).
#[inline(always)]
pub(crate) fn single_pays<T: Real, const M: usize>() -> bool {
    M <= 2 && is_single::<T>()
}

/// Whether this CPU runs [`step`] (checked once, then cached by the standard library).
#[inline]
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx2")
}

/// [`fill`] for banks, with AVX2 enabled. Call only when [`available`] is true.
#[inline]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) {
    debug_assert!(available());
    // SAFETY: callers check `available()`, so the CPU executes AVX2 instructions.
    unsafe { step_avx2(model, bank, input, out) }
}

/// One joint's step ([`step`](super::step)), with AVX2 enabled. Call only when
/// [`available`] is true.
#[inline]
pub(crate) fn single<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    state: &mut RippleState<T, M>,
    input: &RippleInput<T>,
) -> Result<RippleOutput<T>, Error> {
    debug_assert!(available());
    // SAFETY: callers check `available()`, so the CPU executes AVX2 instructions.
    unsafe { single_avx2(model, state, input) }
}

#[target_feature(enable = "avx2")]
fn single_avx2<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    state: &mut RippleState<T, M>,
    input: &RippleInput<T>,
) -> Result<RippleOutput<T>, Error> {
    super::filter::single(model, state, input, None)
}

#[target_feature(enable = "avx2")]
fn step_avx2<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) {
    fill(model, bank, input, None, out);
}

#[cfg(test)]
mod tests {
    use super::super::path_check::against_general;
    use super::super::{BankOutput, Order, Reference, ReferenceValues, RippleInput, RippleModel, RippleState};
    use super::{available, single, step};
    use crate::Real;

    /// The AVX2 build against the portable general path, bit for bit.
    fn same<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>) {
        let took = against_general::<T, M, J>(&model, 5000, |m, b, i| {
            let mut out = BankOutput::default();
            step(m, b, i, &mut out);
            Some(out)
        });
        assert_eq!(took, 6000);
    }

    #[test]
    fn avx2_build_is_the_portable_build() {
        if !available() {
            eprintln!("this CPU has no AVX2: nothing to compare");
            return;
        }
        same::<f32, 3, 8>(RippleModel::seed_6th_order(1000.0).unwrap());
        same::<f32, 3, 16>(RippleModel::product(1000.0, 0.05).unwrap());
        same::<f64, 5, 4>(RippleModel::full(1000.0, 0.05).unwrap());
        same::<f32, 2, 3>(RippleModel::seed_4th_order(1000.0).unwrap());
    }

    /// One joint's AVX2 step against the portable general path, bit for bit, over the
    /// whole run (it takes every sample, the general ones included).
    fn single_same<T: Real, const M: usize>(model: RippleModel<T, M>) {
        let took = against_general::<T, M, 1>(&model, usize::MAX, |m, b, i| {
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
            Some(out)
        });
        assert_eq!(took, 6000);
    }

    #[test]
    fn avx2_single_joint_is_the_portable_build() {
        if !available() {
            eprintln!("this CPU has no AVX2: nothing to compare");
            return;
        }
        // Models the one-loop step takes, then one only the scalar `lean` step takes.
        single_same(RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap());
        single_same(RippleModel::<f32, 2>::seed_4th_order(1000.0).unwrap());
        single_same(RippleModel::<f64, 5>::full(1000.0, 0.05).unwrap());
        let motor = [Order::new(Reference::Motor, 1.0).unwrap(), Order::new(Reference::Relative, 2.0).unwrap()];
        single_same(RippleModel::<f32, 2>::new(motor, 1.0, 1000.0).unwrap());
    }
}
