//! The joint bank's step compiled for AVX2, chosen at run time on x86-64 CPUs that have
//! it (std builds only; `no_std` builds use what the target enables at compile time).
//!
//! The same source as [`step_many`](super::step_many): no fused multiply–add is
//! formed (Rust never contracts `a * b + c`), so the results are bit for bit those
//! of the portable build; only the vector width and the instruction encoding change.

// The one place the project uses `unsafe`: calling a function compiled for a CPU
// feature, after checking that the CPU has it.
#![allow(unsafe_code)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::kernel::run;
use super::model::RippleModel;
use crate::Real;

/// Whether this CPU runs [`step`] (checked once, then cached by the standard library).
#[inline]
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx2")
}

/// [`run`] for banks, with AVX2 enabled. Call only when [`available`] is true.
#[inline]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> BankOutput<T, J> {
    debug_assert!(available());
    // SAFETY: callers check `available()`, so the CPU executes AVX2 instructions.
    unsafe { step_avx2(model, bank, input) }
}

#[target_feature(enable = "avx2")]
fn step_avx2<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
) -> BankOutput<T, J> {
    run(model, bank, input, None)
}

#[cfg(test)]
mod tests {
    use super::super::{BankInput, ReferenceValues, RippleBank, RippleModel};
    use super::{available, run, step};
    use crate::Real;

    /// The AVX2 build and the portable one give the same outputs and state, bit for bit,
    /// through NaNs, jumps, gaps and load steps.
    fn same<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>) {
        let mut a = RippleBank::<T, M, J>::new(&model);
        let mut b = a;
        let c = T::from_f64;
        for k in 0..4000 {
            let theta = |j: usize| 0.11 * k as f64 + 0.3 * j as f64 + if k % 997 == 500 { 2.0 } else { 0.0 };
            let mut input = BankInput::new(
                core::array::from_fn(|j| c(2.0 + (2.0 * theta(j)).cos() + if k % 1500 == 700 { 40.0 } else { 0.0 })),
                ReferenceValues::new(
                    core::array::from_fn(|j| c(theta(j).rem_euclid(core::f64::consts::TAU))),
                    core::array::from_fn(|j| c(-theta(j) / 50.0)),
                    [T::ZERO; J],
                ),
            );
            if k % 611 == 3 {
                input.torque_nm[J - 1] = c(f64::NAN);
            }
            if k % 1777 == 900 {
                input.dt_s = Some(c(0.01));
            }
            let out_a = step(&model, &mut a, &input);
            let out_b = run(&model, &mut b, &input, None);
            assert_eq!(format!("{out_a:?}"), format!("{out_b:?}"), "k {k}");
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "k {k}");
        }
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
}
